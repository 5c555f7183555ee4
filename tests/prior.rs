//! The learned prior end to end at 16^3: trained briefly on a few plumes,
//! saved and loaded, its latent gradient exact (forward equals reverse
//! mode), and a fit through the renderer that moves only the latent.

use dualphoton::grad::loss::mse;
use dualphoton::grad::reverse::Subset;
use dualphoton::image::Image;
use dualphoton::prior::train::{initial_state, targets, train, PriorSettings};
use dualphoton::prior::training_set::training_set;
use dualphoton::prior::Prior;
use dualphoton::recon::level::Level;
use dualphoton::recon::methods::Method;
use dualphoton::recon::param_grad;
use dualphoton::recon::problem::{paper_problem, Problem};
use dualphoton::recon::reconstruct::{prior_model, reconstruct, ReconstructSettings};
use dualphoton::render::frozen::Frozen;
use dualphoton::render::render_photon;
use dualphoton::scene::rig::HELD_OUT_CAMERA;
use std::path::PathBuf;
use std::process::Command;

/// A 16^3 prior trained for 3 epochs on 4 plumes, saved under a temporary directory.
fn tiny_prior(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dualphoton-prior-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let s = PriorSettings { res: 16, plumes: 4, epochs: 3, batch: 2, ..PriorSettings::default() };
    let plumes = targets(&s, training_set(16, 4, None).unwrap());
    let state = train(&s, &plumes, initial_state(&s).unwrap(), None, None, &mut |_, _| {}).unwrap();
    assert!(state.rows.iter().all(|r| r.loss.is_finite()));
    Prior::save(&state.decoder, &state.w, &state.latents(), &dir).unwrap();
    dir
}

#[test]
fn the_latent_gradient_of_a_prior_is_exact_in_both_modes() {
    let prior = Prior::load(&tiny_prior("grad")).unwrap();
    let paper = paper_problem(16, 2, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: Some(&paper.truth) };
    let mut model = prior_model(&paper.scene, targets, &prior, Default::default()).unwrap();
    model.z.iter_mut().enumerate().for_each(|(k, z)| *z = 0.3 * ((k % 7) as f64 - 3.0) / 3.0);
    let level = Level::full(&problem, &model.mask);
    let scene = level.scene_at(&model.density(&paper.scene.density), 10_000, 2, 5);
    let frozen = Frozen::new(&scene, Some(&level.support));
    let fwd = param_grad::latent_exact(&level, &model, &frozen, 16).unwrap();
    let (rev, _) = param_grad::reverse(&level, &model, &frozen, Subset::full());
    let scale = rev.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(scale > 0.0, "the latent has no effect");
    for (k, (a, b)) in fwd.iter().zip(&rev).enumerate() {
        assert!((a - b).abs() <= 1e-9 * scale, "coordinate {k}: forward {a} reverse {b}");
    }
}

/// The image loss of `density` against `targets` (the training cameras), rendered at a fixed seed.
fn image_loss(scene: &dualphoton::scene::Scene, density: &dualphoton::volume::Grid<f64>, targets: &[Image]) -> f64 {
    let mut s = scene.clone();
    s.density = density.clone();
    (s.render.photons, s.render.spp, s.render.seed) = (20_000, 2, 77);
    let images: Vec<Vec<f64>> = render_photon(&s).images.into_iter().take(targets.len()).map(|i| i.data).collect();
    mse(&images, targets)
}

#[test]
fn a_fit_with_the_prior_moves_only_the_latent_and_lowers_the_image_loss() {
    let prior = Prior::load(&tiny_prior("fit")).unwrap();
    let paper = paper_problem(16, 2, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: Some(&paper.truth) };
    // The latent alone (no refinement after it), so that the loss it lowers is its own (measured 0.83x).
    let mut method = Method::prior();
    (method.train.iterations, method.refine.updates) = (6, 0);
    (method.train.photons, method.refine.photons) = (5_000, 5_000);
    let mut settings = ReconstructSettings::new(method, 20_000, 2);
    settings.prior = Some(prior.clone());
    let r = reconstruct(&problem, &settings, &mut |_| {}).unwrap();
    assert_eq!(r.model.w, prior.w, "the prior's weights stay fixed");
    assert!(r.model.z.iter().any(|&z| z != 0.0), "the latent moved");
    assert_eq!(r.log.len(), 6, "6 latent updates");
    assert!(r.estimated.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(r.estimated.data.iter().zip(&r.model.mask).all(|(v, &m)| m || *v == 0.0), "nothing outside the hull");
    let (before, after) =
        (image_loss(&paper.scene, &r.initial, targets), image_loss(&paper.scene, &r.estimated, targets));
    eprintln!(
        "image loss: decoded mean latent {before:.4e}, after the latent fit {after:.4e} ({:.3}x)",
        after / before
    );
    assert!(after < 0.9 * before, "the latent fit did not lower the image loss: {before:e} -> {after:e}");
}

#[test]
fn fit_uses_a_prior_it_is_given_and_names_what_is_wrong_with_one() {
    let dir = tiny_prior("cli");
    let tmp = std::env::temp_dir().join(format!("dualphoton-prior-cli-{}", std::process::id()));
    let p = |s: &str| tmp.join(s).to_str().unwrap().to_string();
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_dualphoton")).args(args).output().unwrap();
    let ok = |args: &[&str]| {
        let out = run(args);
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let json = format!("{}/scene.json", p("scene16"));
    ok(&["scene", "--res", "16", "--out", &p("scene16")]);
    ok(&["render", "--scene", &json, "--out", &p("images16"), "--photons", "5000"]);
    let common = ["--held-out", "1", "--iterations", "2", "--refine", "1", "--judge-photons", "5000"];
    let prior = dir.to_str().unwrap();
    let (images16, fit16) = (p("images16"), p("fit16"));
    let args =
        [&["fit", "--scene", &json, "--images", &images16, "--out", &fit16, "--prior", prior][..], &common].concat();
    let said = ok(&args);
    assert!(said.lines().next().unwrap().starts_with("fit: the learned prior"), "{said}");
    assert!(tmp.join("fit16/density_estimated.npy").exists());
    // The same prior on a 32^3 scene, and a directory that holds none.
    ok(&["scene", "--res", "32", "--out", &p("scene32")]);
    ok(&["render", "--scene", &format!("{}/scene.json", p("scene32")), "--out", &p("images32"), "--photons", "5000"]);
    let scene32 = format!("{}/scene.json", p("scene32"));
    for (where_, expect) in
        [(prior, "decodes 16^3 grids, the scene's grid is 32x32x32"), ("/nonexistent", "prior.json: cannot read")]
    {
        let out =
            run(&["fit", "--scene", &scene32, "--images", &p("images32"), "--out", &p("fit32"), "--prior", where_]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(expect) && err.trim().lines().count() == 1, "{err}");
    }
}
