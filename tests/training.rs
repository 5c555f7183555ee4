//! The experiment binaries end to end at a tiny size (`--smoke`): they run,
//! write every promised file, and their numbers are finite; and a short
//! training really lowers the loss.

use dualphoton::grad::loss::mse;
use dualphoton::grad::Estimator;
use dualphoton::model::Model;
use dualphoton::recon::estimator::EstimatorSettings;
use dualphoton::recon::level::Level;
use dualphoton::recon::methods::Method;
use dualphoton::recon::problem::{paper_problem, Problem};
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::recon::refine::{refine, refine_density, RefineSettings};
use dualphoton::recon::train::{train, TrainSettings};
use dualphoton::render::frozen::Frozen;
use dualphoton::render::render_photon;
use dualphoton::scene::rig::HELD_OUT_CAMERA;
use dualphoton::volume::Grid;
use std::process::Command;

#[test]
fn experiment_table1_smoke_run_writes_everything() {
    let dir = std::env::temp_dir().join(format!("dualphoton-table1-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_experiment_table1"))
        .args(["--smoke", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in [
        "density_gt.npy",
        "density_initial.npy",
        "density_estimated.npy",
        "hull.npy",
        "scene.json",
        "log.csv",
        "manifest.json",
        "table1.csv",
        "table1.md",
        "table1.svg",
        "fit_quality.csv",
        "fig5_loss.svg",
        "fig6_camera2.png",
        "fig6_camera2.svg",
        "fig7_scatter.svg",
        "fig8_held_out.png",
        "fig8_held_out.svg",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let svg = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    let (fig6, fig8, table1) = (svg("fig6_camera2.svg"), svg("fig8_held_out.svg"), svg("table1.svg"));
    // Fig. 6: iterations 0 and 2 of the smoke run, then the target, each an embedded image with its label.
    assert_eq!(fig6.matches("<image").count(), 3, "{fig6}");
    for label in ["iteration 0", "iteration 2", "ground truth"] {
        assert!(fig6.contains(label), "fig6 lacks {label:?}");
    }
    // Fig. 8: three panels and the colour bar, titled.
    assert_eq!(fig8.matches("<image").count(), 4);
    assert!(fig8.contains("signed error") && fig8.contains("estimate"));
    for label in ["before training", "after training", "ground truth", "ours", "paper"] {
        assert!(table1.contains(label), "table1.svg lacks {label:?}");
    }
    let manifest: serde_json::Value = serde_json::from_str(&svg("manifest.json")).unwrap();
    for key in [
        "seed",
        "paper",
        "prior",
        "fit_photons",
        "target_photons",
        "hull_voxels",
        "revision",
        "tree_clean",
        "command",
        "date",
        "wall_s",
        "threads",
    ] {
        assert!(manifest.get(key).is_some(), "manifest lacks {key}");
    }
    // No option given: both methods are the library's defaults, the paper's
    // as `--smoke` shortens it (every setting by name in the manifest).
    let mut paper = Method::paper();
    (paper.train.iterations, paper.train.gradient.weight_directions, paper.refine.updates) = (3, 4, 3);
    (paper.train.photons, paper.refine.photons) = (5_000, 5_000);
    assert_eq!(manifest["paper"], serde_json::to_value(paper).unwrap());
    assert_eq!(manifest["prior"], serde_json::to_value(Method::prior()).unwrap());
    let log = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    assert_eq!(log.lines().count(), 7, "header + 3 training + 3 refinement updates");
    assert!(!log.contains("NaN") && !log.contains("inf"), "{log}");
    for bin in [env!("CARGO_BIN_EXE_fig5"), env!("CARGO_BIN_EXE_fig7")] {
        let out = Command::new(bin).args(["--dir", dir.to_str().unwrap()]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
}

#[test]
fn the_eight_views_study_file_sets_cameras_and_method() {
    // experiments/studies/eight_views.json: 4 more training cameras, rev-full, no refinement.
    let dir = std::env::temp_dir().join(format!("dualphoton-eight-views-{}", std::process::id()));
    let study = concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/studies/eight_views.json");
    let out = Command::new(env!("CARGO_BIN_EXE_experiment_table1"))
        .args(["--smoke", "--study", study, "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["extra_views"], 4);
    assert_eq!(manifest["paper"]["train"]["gradient"]["estimator"], "rev-full");
    let table = std::fs::read_to_string(dir.join("table1.md")).unwrap();
    assert!(table.contains("8 training cameras") && table.contains("then 0 per-voxel refinement updates"), "{table}");
}

#[test]
fn rev_full_training_runs_and_logs_finite_losses() {
    // rev-full on a 16^3 plume, through the experiment binary (that the loss
    // really falls is `a_short_training_lowers_the_loss`).
    let dir = std::env::temp_dir().join(format!("dualphoton-train-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_experiment_table1"))
        .args(["--smoke", "--estimator", "rev-full", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let log = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    let losses: Vec<f64> = log.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
    assert!(losses.iter().all(|l| l.is_finite()));
}

/// The refinement without its global factor, additive terms, blocks,
/// falling steps and decorrelated residual: each test turns on what it tests.
fn plain_refinement() -> RefineSettings {
    RefineSettings {
        global: false,
        additive: false,
        blocks: vec![],
        lr_final: 1.0,
        decorrelate: false,
        ..RefineSettings::default()
    }
}

/// Updates of the short training.
const ITERATIONS: usize = 15;
/// The loss after them must be below this share of the loss before (it
/// falls about 8x; with the gradient's sign flipped it rises about 13x).
const RATIO: f64 = 0.5;

/// The training loss of `model`: its density rendered with one fixed seed,
/// photon count and sampling, so that two models are compared on the same
/// random numbers and only the density differs.
fn fixed_loss(problem: &Problem, model: &Model) -> f64 {
    let level = Level::full(problem, &model.mask);
    let scene = level.scene_at(&model.density(&problem.scene.density), 20_000, 4, 12_345);
    let frozen = Frozen::new(&scene, Some(&level.support));
    let images: Vec<Vec<f64>> = frozen.images[..problem.targets.len()].iter().map(|i| i.data.clone()).collect();
    mse(&images, problem.targets)
}

/// Trains the 8^3 plume briefly with `settings` and checks that the loss on fixed random numbers falls below half.
fn assert_training_lowers_the_loss(settings: TrainSettings) {
    let paper = paper_problem(8, 3, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: Some(&paper.truth) };
    let mut model = initial_model(&paper.scene, targets, 0).unwrap();
    let before = fixed_loss(&problem, &model);
    let mut logged = vec![];
    train(&problem, &mut model, &settings, &mut |row, _, _| logged.push(row.train_loss)).unwrap();
    let after = fixed_loss(&problem, &model);
    let logged: Vec<String> = logged.iter().map(|l| format!("{l:.2e}")).collect();
    eprintln!("loss {before:.4e} -> {after:.4e}; logged per update: {}", logged.join(" "));
    assert_eq!(logged.len(), ITERATIONS);
    assert!(before.is_finite() && before > 0.0);
    assert!(after < RATIO * before, "training did not lower the loss: {before:.4e} -> {after:.4e}");
}

/// rev-full (exact gradients) on an 8^3 plume, without coarse-to-fine.
fn exact_settings() -> TrainSettings {
    TrainSettings {
        iterations: ITERATIONS,
        gradient: EstimatorSettings { estimator: Estimator::RevFull, ..Default::default() },
        photons: 5_000,
        coarse_fraction: 0.0,
        seed: 1,
        decorrelate: false,
        ..TrainSettings::default()
    }
}

#[test]
fn a_short_training_lowers_the_loss() {
    // Adam ignores the gradient's scale, not its direction: a gradient of
    // the wrong sign, or one unrelated to the loss, would raise the loss or leave it be.
    assert_training_lowers_the_loss(exact_settings());
}

#[test]
fn a_decorrelated_training_lowers_the_loss() {
    // The residual from a second render must still descend (a residual
    // mixed up with the derivative's render would not).
    assert_training_lowers_the_loss(TrainSettings { decorrelate: true, ..exact_settings() });
}

#[test]
fn a_training_that_diverges_stops_with_an_error() {
    // Steps of 1e30 send latent and weights, and with them the density, past
    // what float32 holds: training must stop with a message, not go on with Inf.
    let paper = paper_problem(8, 3, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: Some(&paper.truth) };
    let mut model = initial_model(&paper.scene, targets, 0).unwrap();
    let settings = TrainSettings { lr_latent: 1e30, lr_weights: 1e30, iterations: 4, ..exact_settings() };
    let e = train(&problem, &mut model, &settings, &mut |_, _, _| {}).unwrap_err().to_string();
    assert!(e.contains("no longer finite") && !e.contains('\n'), "{e}");
    for bad in [f64::NAN, 0.0, -1.0] {
        let settings = TrainSettings { lr_latent: bad, ..exact_settings() };
        let e = train(&problem, &mut model, &settings, &mut |_, _, _| {}).unwrap_err().to_string();
        assert!(e.contains("lr_latent"), "{e}");
    }
}

#[test]
fn benchmarks_run_at_smoke_size() {
    for (bin, name) in [(env!("CARGO_BIN_EXE_bench_render"), "render"), (env!("CARGO_BIN_EXE_bench_grad"), "grad")] {
        let dir = std::env::temp_dir().join(format!("dualphoton-bench-{name}-{}", std::process::id()));
        let out = Command::new(bin).args(["--smoke", "--out", dir.to_str().unwrap()]).output().unwrap();
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(dir.join("summary.md").exists() && dir.join("manifest.json").exists());
    }
    // Only the blurred plumes (and the built-in plume's timing row), as `results/bench_render_blurred/`.
    let dir = std::env::temp_dir().join(format!("dualphoton-bench-blurred-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_bench_render"))
        .args(["--smoke", "--res", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rows = std::fs::read_to_string(dir.join("blurred.csv")).unwrap();
    assert_eq!(rows.lines().count(), 4, "header, the built-in plume and two blurred plumes:\n{rows}");
    assert!(!dir.join("sweep.csv").exists());
}

#[test]
fn stability_study_passes_every_case_at_smoke_size() {
    let dir = std::env::temp_dir().join(format!("dualphoton-stability-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_stability"))
        .args(["--smoke", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in ["report.csv", "summary.md", "fd_error.svg", "manifest.json"] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let mut report = csv::Reader::from_path(dir.join("report.csv")).unwrap();
    let header = report.headers().unwrap().clone();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
    for name in ["case", "passed", "values_finite", "derivatives_finite", "fd_rel_error", "seconds", "note"] {
        column(name);
    }
    let rows: Vec<csv::StringRecord> = report.records().map(|r| r.unwrap()).collect();
    // One row per case, each printed as one progress line.
    let stderr = String::from_utf8_lossy(&out.stderr);
    let progress = stderr.lines().filter(|l| l.starts_with("ok ") || l.starts_with("FAIL ")).count();
    assert_eq!(rows.len(), progress, "rows and progress lines differ");
    let cases: Vec<&str> = rows.iter().map(|r| &r[column("case")]).collect();
    for case in ["optical depth 1e4", "zero density", "albedo 1", "g 0.9999", "zero photons", "invalid: g = 1"] {
        assert!(cases.contains(&case), "no row for {case}");
    }
    for r in &rows {
        assert_eq!(&r[column("passed")], "true", "{} failed: {}", &r[column("case")], &r[column("note")]);
    }
}

#[test]
fn fit_writes_its_log_arrays_and_figures() {
    // A 16^3 paper scene, its images, then `fit` with the last camera held out.
    let dir = std::env::temp_dir().join(format!("dualphoton-fit-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = |p: &str| dir.join(p).to_str().unwrap().to_string();
    let (scene, images, fit) = (d("scene"), d("images"), d("fit"));
    let json = format!("{scene}/scene.json");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_dualphoton")).args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    run(&["scene", "--res", "16", "--out", &scene]);
    run(&["render", "--scene", &json, "--out", &images, "--photons", "5000"]);
    let fit_args = ["--out", &fit, "--held-out", "1", "--iterations", "2", "--refine", "3", "--judge-photons", "5000"];
    let (stdout, stderr) = run(&[&["fit", "--scene", &json, "--images", &images][..], &fit_args].concat());
    // Progress counts training and refinement apart; the quality table goes to stdout, as judge's does.
    assert!(stderr.contains("training 2/2") && stderr.contains("refinement 3/3"), "{stderr}");
    assert!(stdout.contains("held-out") && stdout.starts_with('|'), "{stdout}");
    let files = [
        "log.csv",
        "density_estimated.npy",
        "hull.npy",
        "fig5_loss.svg",
        "fig6_camera2.svg",
        "fig8_held_out.svg",
        "fit_quality.csv",
    ];
    for f in files {
        assert!(dir.join("fit").join(f).exists(), "{f} missing");
    }
    let log = std::fs::read_to_string(dir.join("fit/log.csv")).unwrap();
    assert_eq!(log.lines().count(), 6, "header + 2 training + 3 refinement updates: {log}");
    // Without a truth the density error is unknown: its cells are empty, never NaN.
    assert!(!log.to_lowercase().contains("nan") && !log.contains("inf"), "{log}");
    let judged = std::fs::read_to_string(dir.join("fit/fit_quality.csv")).unwrap();
    assert_eq!(judged.lines().count(), 1 + 5, "header + one row per camera: {judged}");
    assert!(judged.contains(",held-out,"), "{judged}");
}

#[test]
fn the_per_voxel_refinement_lowers_the_loss() {
    // From the untrained model: only the per-voxel factors move.
    let paper = paper_problem(8, 3, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: Some(&paper.truth) };
    let model = initial_model(&paper.scene, targets, 0).unwrap();
    let settings = RefineSettings { updates: ITERATIONS, lr: 0.1, photons: 5_000, seed: 1, ..plain_refinement() };
    let mut rows = 0;
    let refined = refine(&problem, &model, &settings, 0, &mut |_| rows += 1).unwrap();
    assert_eq!(rows, ITERATIONS);
    let loss = |density: &Grid<f64>| {
        let level = Level::full(&problem, &model.mask);
        let scene = level.scene_at(density, 20_000, 4, 12_345);
        let frozen = Frozen::new(&scene, Some(&level.support));
        let images: Vec<Vec<f64>> = frozen.images[..targets.len()].iter().map(|i| i.data.clone()).collect();
        mse(&images, targets)
    };
    let (before, after) = (loss(&model.density(&paper.scene.density)), loss(&refined));
    eprintln!("refinement: loss {before:.4e} -> {after:.4e}");
    assert!(after < RATIO * before, "refinement did not lower the loss: {before:.4e} -> {after:.4e}");
    // Voxels outside the hull or where the decoder gives 0 stay 0.
    let base = model.density(&paper.scene.density);
    assert!(base.data.iter().zip(&refined.data).all(|(b, r)| (*b == 0.0) == (*r == 0.0)));
}

#[test]
fn the_global_factor_corrects_the_mass_faster() {
    // Targets rendered from the model's own density times 1.5: the global
    // factor's gradient sums every voxel's, so with it the mass must rise
    // further in a few updates than with the per-voxel factors alone.
    let paper = paper_problem(8, 3, 20_000, 0);
    let model = initial_model(&paper.scene, &paper.images[..HELD_OUT_CAMERA], 0).unwrap();
    let base = model.density(&paper.scene.density);
    let mut scene = paper.scene.clone();
    scene.density = base.clone();
    scene.density.data.iter_mut().for_each(|v| *v *= 1.5);
    let images = render_photon(&scene).images;
    let (targets, held_out) = images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &scene, targets, held_out, truth: None };
    let mass_ratio = |global: bool| {
        let settings = RefineSettings { updates: 10, photons: 5_000, seed: 1, global, ..plain_refinement() };
        let refined = refine(&problem, &model, &settings, 0, &mut |_| {}).unwrap();
        refined.data.iter().sum::<f64>() / base.data.iter().sum::<f64>()
    };
    let (local, global) = (mass_ratio(false), mass_ratio(true));
    eprintln!("mass after 10 updates, target 1.5: per-voxel {local:.3}, with the global factor {global:.3}");
    assert!(global > local + 0.05 && global < 1.6, "per-voxel {local:.3}, global {global:.3}");
}

#[test]
fn the_additive_term_fills_voxels_the_decoder_leaves_empty() {
    // The 16^3 truth with a slab of its hull emptied (hundreds of voxels
    // where the truth has smoke), refined against the truth's images: with
    // the additive term the slab must fill towards the truth (a factor
    // cannot: 0 times any factor is 0), without it stay empty, and nothing
    // outside the hull may fill.
    let paper = paper_problem(16, 3, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: None };
    let model = initial_model(&paper.scene, targets, 0).unwrap();
    let mut base = paper.truth.clone();
    base.data.iter_mut().zip(&model.mask).for_each(|(v, &m)| *v = if m { *v } else { 0.0 });
    let slab = |i: usize| (i / 256) % 16 >= 6 && (i / 256) % 16 < 10;
    let emptied: Vec<usize> =
        (0..base.data.len()).filter(|&i| slab(i) && model.mask[i] && base.data[i] > 0.0).collect();
    emptied.iter().for_each(|&i| base.data[i] = 0.0);
    let truth_mean = emptied.iter().map(|&i| paper.truth.data[i]).sum::<f64>() / emptied.len() as f64;
    assert!(emptied.len() >= 200, "the test needs hundreds of emptied voxels, got {}", emptied.len());
    let filled = |additive: bool| {
        let settings = RefineSettings { updates: 30, lr: 0.1, photons: 5_000, seed: 1, additive, ..plain_refinement() };
        let refined = refine_density(&problem, &base, &model.mask, &settings, 0, &mut |_| {}).unwrap();
        assert!(refined.data.iter().zip(&model.mask).all(|(v, &m)| (m || *v == 0.0) && v.is_finite() && *v >= 0.0));
        emptied.iter().map(|&i| refined.data[i]).sum::<f64>() / emptied.len() as f64
    };
    let (with, without) = (filled(true), filled(false));
    eprintln!(
        "{} emptied hull voxels (truth mean {truth_mean:.4}): mean after 30 updates {with:.4} with the additive term, {without} without",
        emptied.len()
    );
    assert_eq!(without, 0.0);
    assert!(with > 0.25 * truth_mean && with < 2.0 * truth_mean, "{with} against the truth's {truth_mean}");
}

#[test]
fn block_factors_correct_a_coarse_misfit_faster() {
    // Targets rendered from the model's own density times 1.6 in the half
    // x >= 0 of the grid: a block's factor sums its voxels' gradients, so
    // with blocks of 4^3 that half's mass must rise further in a few updates
    // than with the per-voxel factors alone, and the other half stay near.
    let paper = paper_problem(8, 3, 20_000, 0);
    let model = initial_model(&paper.scene, &paper.images[..HELD_OUT_CAMERA], 0).unwrap();
    let base = model.density(&paper.scene.density);
    let right = |i: usize| i % 8 >= 4;
    let mut scene = paper.scene.clone();
    scene.density = base.clone();
    scene.density.data.iter_mut().enumerate().filter(|(i, _)| right(*i)).for_each(|(_, v)| *v *= 1.6);
    let images = render_photon(&scene).images;
    let (targets, held_out) = images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &scene, targets, held_out, truth: None };
    let half_mass =
        |d: &Grid<f64>, r: bool| d.data.iter().enumerate().filter(|(i, _)| right(*i) == r).map(|(_, v)| v).sum::<f64>();
    let ratios = |blocks: Vec<usize>| {
        let settings = RefineSettings { updates: 10, photons: 5_000, seed: 1, blocks, ..plain_refinement() };
        let refined = refine(&problem, &model, &settings, 0, &mut |_| {}).unwrap();
        (half_mass(&refined, true) / half_mass(&base, true), half_mass(&refined, false) / half_mass(&base, false))
    };
    let ((voxels, voxels_left), (blocks, blocks_left)) = (ratios(vec![]), ratios(vec![4]));
    eprintln!("x >= 0 half after 10 updates, target 1.6: voxels {voxels:.3}, with 4^3 blocks {blocks:.3}; other half {voxels_left:.3} / {blocks_left:.3}");
    assert!(blocks > voxels + 0.05 && blocks < 1.8, "voxels {voxels:.3}, blocks {blocks:.3}");
    assert!((blocks_left - 1.0).abs() < (blocks - 1.0).abs(), "{blocks_left:.3} vs {blocks:.3}");
    let bad = RefineSettings { updates: 1, blocks: vec![1], ..plain_refinement() };
    let err = refine(&problem, &model, &bad, 0, &mut |_| {}).unwrap_err();
    assert!(err.0.contains("refine.blocks"), "{}", err.0);
}

/// Runs `f` on the 8^3 paper problem (its training cameras) and the initial model.
fn on_small_problem(f: impl FnOnce(&Problem, &Model)) {
    let paper = paper_problem(8, 3, 20_000, 0);
    let (targets, held_out) = paper.images.split_at(HELD_OUT_CAMERA);
    let problem = Problem { scene: &paper.scene, targets, held_out, truth: None };
    let model = initial_model(&paper.scene, targets, 0).unwrap();
    f(&problem, &model)
}

#[test]
fn refining_a_given_density_is_refining_the_model_that_decodes_it() {
    on_small_problem(|problem, model| {
        let settings = RefineSettings { updates: 2, photons: 5_000, seed: 1, additive: true, ..plain_refinement() };
        let base = model.density(&problem.scene.density);
        let from_model = refine(problem, model, &settings, 3, &mut |_| {}).unwrap();
        let from_density = refine_density(problem, &base, &model.mask, &settings, 3, &mut |_| {}).unwrap();
        assert_eq!(from_model.data, from_density.data);
        let err = refine_density(problem, &base, &model.mask[1..], &settings, 3, &mut |_| {}).unwrap_err();
        assert!(err.0.contains("must match the scene's grid"), "{}", err.0);
    });
}

#[test]
fn a_refinement_that_diverges_stops_with_an_error() {
    // Steps of 1e6 on the log-factors overflow exp: the refinement must stop
    // with a message instead of returning an Inf density.
    on_small_problem(|problem, model| {
        let settings = RefineSettings { updates: 5, lr: 1e6, photons: 5_000, seed: 1, ..plain_refinement() };
        let e = refine(problem, model, &settings, 0, &mut |_| {}).unwrap_err().to_string();
        assert!(e.contains("refinement") && e.contains("no longer finite"), "{e}");
        let nan = RefineSettings { lr: f64::NAN, ..settings };
        assert!(refine(problem, model, &nan, 0, &mut |_| {}).unwrap_err().to_string().contains("refine.lr"));
    });
}

#[test]
fn the_refinement_steps_fall_to_lr_final() {
    // With steps falling to 1e-6 of the first over two updates, the second
    // update barely moves the density; at a constant step it moves it.
    on_small_problem(|problem, model| {
        let run = |updates: usize, lr_final: f64| {
            let settings = RefineSettings {
                updates,
                lr_final,
                photons: 5_000,
                seed: 1,
                additive: true,
                global: true,
                ..plain_refinement()
            };
            refine(problem, model, &settings, 0, &mut |_| {})
        };
        let one = run(1, 1.0).unwrap();
        assert_eq!(one.data, run(1, 1e-6).unwrap().data, "the first update takes the full step");
        let moved = |d: &Grid<f64>| d.data.iter().zip(&one.data).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let (constant, decayed) = (moved(&run(2, 1.0).unwrap()), moved(&run(2, 1e-6).unwrap()));
        eprintln!("second update moves a voxel by at most {constant:.3e} (constant step), {decayed:.3e} (decayed)");
        assert!(constant > 1e-5 && decayed < 1e-4 * constant, "{constant} {decayed}");
        let err = run(2, 0.0).unwrap_err();
        assert!(err.0.contains("lr_final"), "{}", err.0);
    });
}

#[test]
fn prior_eval_runs_every_method_at_smoke_size() {
    // A 16^3 prior from train_prior's smoke run, then one validation plume
    // through every method of the evaluation with a few updates each.
    let out = Command::new(env!("CARGO_BIN_EXE_train_prior")).arg("--smoke").output().unwrap();
    assert!(out.status.success(), "train_prior: {}", String::from_utf8_lossy(&out.stderr));
    let name = format!("dualphoton-prior-eval-{}", std::process::id());
    let dir = std::env::temp_dir().join(&name);
    let few = ["--iterations", "2", "--refine", "2"];
    let out = Command::new(env!("CARGO_BIN_EXE_prior_eval"))
        .args(["--res", "16", "--prior", "target/prior_smoke", "--plumes", "val0"])
        .args(["--methods", "paper,prior,oracle", "--photons", "2000", "--spp", "1"])
        .args(few)
        .args(["--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(std::path::Path::new("cache").join(&name));
    assert!(out.status.success(), "prior_eval: {}", String::from_utf8_lossy(&out.stderr));
    let rows = ["paper", "prior", "prior_refine", "oracle_exact", "oracle_truth", "oracle_truth_refine"];
    for row in rows.iter().chain(&["oracle_latent", "oracle_latent_refine"]) {
        assert!(dir.join("rows").join(format!("val0_{row}.json")).exists(), "row {row} missing");
    }
    let table = std::fs::read_to_string(dir.join("table.md")).unwrap();
    assert!(table.contains("| val0 | validation | oracle_truth_refine |"), "{table}");
    // The truth rendered as an estimate sets the held-out camera's floor
    // (render noise alone): above 0, and every estimate's error above it.
    let row = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(format!("rows/val0_{name}.json"))).unwrap()).unwrap()
    };
    let floor = row("oracle_exact")["held_out_rel_rmse"].as_f64().unwrap();
    assert!(floor > 0.0 && floor.is_finite(), "{floor}");
    for name in ["paper", "prior", "prior_refine", "oracle_truth", "oracle_latent_refine"] {
        let (held, eps) =
            (row(name)["held_out_rel_rmse"].as_f64().unwrap(), row(name)["rel_l1_epsilon"].as_f64().unwrap());
        eprintln!("{name}: held-out {held:.4} against the floor {floor:.4}, epsilon {eps:.3}");
        assert!(held > floor && eps > 0.0, "{name}: held-out {held} against the floor {floor}, epsilon {eps}");
    }
}
