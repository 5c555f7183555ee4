//! Diagnostic: how well can the latent + decoder represent the ground truth
//! at all? Fits (z, w) by Adam straight to the plume's density inside the
//! visual hull (no rendering), and prints the Table 1 measures of the best
//! fit: an upper bound on what training through the renderer can reach.
//! Also prints the training loss of the ground truth itself at a training
//! update's render settings: the floor below which the images carry no
//! more information (render noise), to compare with the trained model's.
//! `cargo run --release --example decoder_capacity -- [res] [iterations]`
use dualphoton::eval::metrics::{hull_stats, pearson, rel_l1};
use dualphoton::grad::loss::mse;
use dualphoton::recon::adam::Adam;
use dualphoton::recon::problem::paper_problem;
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::render::render_photon;
use dualphoton::scene::rig;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let res: usize = args.get(1).map_or(64, |s| s.parse().expect("res"));
    let iterations: usize = args.get(2).map_or(500, |s| s.parse().expect("iterations"));
    let problem = paper_problem(res, 0, 1_000_000, 0);
    let targets = &problem.images[..rig::HELD_OUT_CAMERA];
    let n_train = targets.len();
    for seed in 0..3 {
        let mut scene = problem.scene.clone();
        scene.cameras.truncate(n_train);
        let defaults = dualphoton::recon::train::TrainSettings::default();
        scene.render.photons = defaults.photons;
        scene.render.spp = defaults.spp;
        scene.render.seed = 100 + seed;
        let images: Vec<Vec<f64>> = render_photon(&scene).images.into_iter().map(|i| i.data).collect();
        println!("ground truth's own training loss (render seed {seed}): {:.4e}", mse(&images, targets));
    }
    let mut model = initial_model(&problem.scene, targets, 0).expect("model");
    let truth = &problem.truth.data;
    let mask = model.mask.clone();
    let hull = mask.iter().filter(|&&m| m).count() as f64;
    let (mut adam_z, mut adam_w) = (Adam::new(model.z.len(), 0.05), Adam::new(model.w.len(), 0.01));
    let report = |it: usize, d: &[f64]| {
        let (s, t) = (hull_stats(d, &mask), hull_stats(truth, &mask));
        println!(
            "{it:5}  eps {:.3}  r {:.3}  mean {:.4} (truth {:.4})  max {:.3} (truth {:.3})",
            rel_l1(d, truth, &mask),
            pearson(truth, d, &mask),
            s.mean,
            t.mean,
            s.max,
            t.max
        );
    };
    for it in 0..iterations {
        let d = model.decoder.forward(&model.z, &model.w, &mask);
        if it % 250 == 0 {
            report(it, &d);
        }
        // Mean squared density error over the hull.
        let g: Vec<f64> =
            d.iter().zip(truth).zip(&mask).map(|((a, b), &m)| if m { 2.0 * (a - b) / hull } else { 0.0 }).collect();
        let (gz, gw) = model.decoder.backward(&model.z, &model.w, &mask, &g);
        adam_z.step(&mut model.z, &gz);
        adam_w.step(&mut model.w, &gw);
    }
    report(iterations, &model.decoder.forward(&model.z, &model.w, &mask));
}
