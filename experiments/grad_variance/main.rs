//! Gradient-variance study: every estimator of the parameter gradient
//! (64-d latent and decoder weights), at the initial parameters and midway
//! through the default training run, over many independent seeds: mean,
//! total variance, bias and cosine against a high-sample reference, time
//! and peak memory per estimate, efficiency, and the measured
//! forward-gradient noise against theory.
//!
//! Two kinds of noise add up in every estimate: the renderer's Monte Carlo
//! noise (photons and pixel samples, redrawn per seed; exact estimators
//! have only this) and the estimator's own (random directions or subsets).
//! The second one is measured on its own, per seed, against `rev-full` on
//! the same frozen paths, which is what the forward-gradient theory
//! predicts: Gaussian directions add (n+1)/K |g|^2, orthonormal ones
//! (n/K - 1) |g|^2.
//!
//! Writes `results/grad_variance/{variance.csv, summary.md, *.svg, manifest.json}`.

use clap::Parser;
use dualphoton::error::{Error, Result};
use dualphoton::eval::stats::{median, EstimateStats};
use dualphoton::experiment::{self, Run};
use dualphoton::io::rows::{fmt, read_rows, write_rows};
use dualphoton::model::Model;
use dualphoton::recon::estimator::Estimator::RevFull;
use dualphoton::recon::estimator::EstimatorSettings;
use dualphoton::recon::grad_study::{compared_settings, forward_gradient_theory, sample_estimators};
use dualphoton::recon::level::Level;
use dualphoton::recon::problem::{paper_problem, PaperProblem, Problem};
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::recon::train::{train, TrainSettings};
use dualphoton::scene::rig;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

mod write;

#[derive(Parser, Serialize)]
#[command(about = "Variance, bias, cost and efficiency of every gradient estimator over many seeds")]
struct Args {
    /// Grid resolution (res^3) and image size (res x res).
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Independent seeds per estimator (renderer and estimator draws).
    #[arg(long, default_value_t = 32)]
    seeds: usize,
    /// Seeds of the high-sample reference gradient.
    #[arg(long, default_value_t = 4)]
    reference_seeds: usize,
    /// The reference uses this many times the photons and the pixel samples.
    #[arg(long, default_value_t = 4)]
    reference_factor: u32,
    /// Training updates before the "midway" parameters (the default run has 250).
    #[arg(long, default_value_t = 125)]
    midway: usize,
    /// Seed of the plume, the model and the study.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output directory.
    #[arg(long, default_value = "results/grad_variance")]
    #[serde(skip)]
    out: PathBuf,
    /// A tiny run (16^3, 3 seeds) to check that everything works.
    #[arg(long)]
    #[serde(skip)]
    smoke: bool,
    /// Only redraw the plots from the variance.csv an earlier run left in --out.
    #[arg(long)]
    #[serde(skip)]
    replot: bool,
}

/// What a run writes beside its results.
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    args: &'a Args,
    photons: u64,
    spp: u32,
}

/// The parameter vectors, in the order of [`Samples::parts`].
pub const PARTS: [&str; 2] = ["latent", "weights"];

/// One line of `variance.csv`: one method, one part, one point.
#[derive(Serialize, Deserialize)]
pub struct Row {
    pub point: String,
    pub part: String,
    pub method: String,
    pub n: usize,
    #[serde(serialize_with = "fmt::e6")]
    pub rel_variance: f64,
    #[serde(serialize_with = "fmt::e6")]
    pub bias: f64,
    #[serde(serialize_with = "fmt::e6", rename = "bias_noise_floor")]
    pub bias_floor: f64,
    #[serde(serialize_with = "fmt::e6")]
    pub rel_mse: f64,
    #[serde(serialize_with = "fmt::f6")]
    pub cosine_mean: f64,
    #[serde(serialize_with = "fmt::f6")]
    pub cosine_of_mean: f64,
    #[serde(serialize_with = "fmt::e6")]
    pub estimator_noise: f64,
    #[serde(serialize_with = "fmt::opt_f4")]
    pub theory: Option<f64>,
    #[serde(serialize_with = "fmt::f4")]
    pub seconds: f64,
    #[serde(serialize_with = "fmt::f4")]
    pub primal_seconds: f64,
    #[serde(serialize_with = "fmt::f1")]
    pub peak_mib: f64,
    #[serde(serialize_with = "fmt::e6")]
    pub efficiency: f64,
}

/// Every (point, part) pair, in the order of the tables and plots.
pub fn panels() -> impl Iterator<Item = (&'static str, &'static str)> {
    ["initial", "midway"].into_iter().flat_map(|point| PARTS.map(|part| (point, part)))
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(mut args: Args) -> Result<()> {
    if args.replot {
        return write::plots(&args.out, &read_rows::<Row>(&args.out.join("variance.csv"))?);
    }
    if args.smoke {
        (args.res, args.seeds, args.reference_seeds, args.midway) = (16, 3, 2, 2);
    }
    experiment::check_decoder_res(args.res)?;
    if args.seeds < 2 {
        return Err(Error::new("--seeds: need at least 2 to measure a variance"));
    }
    if args.reference_seeds == 0 || args.reference_factor == 0 {
        return Err(Error::new("--reference-seeds and --reference-factor must be at least 1"));
    }
    let run = Run::start(&args.out)?;

    // The problem of the main job: the plume seen by the paper rig.
    eprintln!("rendering the targets ...");
    let target_photons = if args.smoke { 20_000 } else { 1_000_000 };
    let PaperProblem { truth, mut scene, images } = paper_problem(args.res, args.seed, target_photons, 0);
    if args.smoke {
        scene.render.photons = 20_000;
    }
    let (targets, held_out) = images.split_at(rig::HELD_OUT_CAMERA);
    let problem = Problem { scene: &scene, targets, held_out, truth: Some(&truth) };

    let initial = initial_model(&scene, targets, args.seed)?;
    let mut midway = initial.clone();
    eprintln!("training {} updates for the midway parameters ...", args.midway);
    // The default run's first updates: all of them are coarse there (80 % of 250).
    let settings = TrainSettings {
        iterations: args.midway,
        seed: args.seed,
        coarse_fraction: 1.0,
        decorrelate: false,
        ..Default::default()
    };
    train(&problem, &mut midway, &settings, &mut |row, _, _| {
        eprint!("\r  update {}/{}  loss {:.4e}   ", row.iteration + 1, args.midway, row.train_loss)
    })?;
    eprintln!();

    let photons = scene.render.photons as usize;
    let methods = compared_settings((1000 * photons / 300_000).max(4), (5000 * photons / 300_000).max(4));
    let mut rows = vec![];
    for (point, model) in [("initial", &initial), ("midway", &midway)] {
        rows.extend(study_point(&args, &problem, point, model, &methods)?);
    }

    let wall_s = run.seconds();
    write_rows(&run.path("variance.csv"), &rows)?;
    let (photons, spp) = (scene.render.photons, scene.render.spp);
    let md = write::summary(&args, &rows, photons, spp, wall_s);
    std::fs::write(run.path("summary.md"), &md)?;
    write::plots(&run.out, &rows)?;
    run.write_manifest_timed(&Manifest { args: &args, photons, spp }, wall_s)?;
    print!("{md}");
    Ok(())
}

/// All methods at one set of parameters.
fn study_point(
    args: &Args,
    problem: &Problem,
    point: &str,
    model: &Model,
    methods: &[(String, EstimatorSettings)],
) -> Result<Vec<Row>> {
    let level = Level::full(problem, &model.mask);
    let settings: Vec<EstimatorSettings> = methods.iter().map(|m| m.1).collect();
    let reference = (args.reference_seeds, args.reference_factor);
    let mut progress = |s: &str| eprint!("\r{point}: {s}   ");
    let study = sample_estimators(&level, model, &settings, args.seeds, reference, args.seed, &mut progress)?;
    eprintln!();

    // `rev-full` on each seed's frozen paths: the exact gradient the others estimate.
    let exact = methods
        .iter()
        .position(|m| m.1.estimator == RevFull)
        .map(|i| &study.samples[i])
        .ok_or_else(|| Error::new("the methods must include rev-full"))?;
    let mut rows = vec![];
    for ((method, settings), smp) in methods.iter().zip(&study.samples) {
        for (p, part) in PARTS.iter().enumerate().filter(|(p, _)| !smp.part(*p).is_empty()) {
            let st = EstimateStats::of(smp.part(p), exact.part(p), study.reference.part(p));
            let (seconds, primal_seconds) = (median(&smp.seconds), study.primal_seconds);
            rows.push(Row {
                point: point.into(),
                part: part.to_string(),
                method: method.clone(),
                n: st.n,
                rel_variance: st.rel_variance,
                bias: st.bias,
                bias_floor: st.bias_floor,
                rel_mse: st.rel_mse,
                cosine_mean: st.cosine_mean,
                cosine_of_mean: st.cosine_of_mean,
                estimator_noise: st.estimator_noise,
                theory: forward_gradient_theory(settings, st.n),
                seconds,
                primal_seconds,
                peak_mib: smp.peak_mib,
                efficiency: 1.0 / (st.rel_variance * (seconds + primal_seconds)),
            });
        }
    }
    Ok(rows)
}
