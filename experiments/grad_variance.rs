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
use dualphoton::io::manifest::write_manifest;
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::{fmt, markdown_table, read_rows, write_rows};
use dualphoton::model::Model;
use dualphoton::recon::estimator::Estimator::RevFull;
use dualphoton::recon::estimator::EstimatorSettings;
use dualphoton::recon::grad_study::{compared_settings, forward_gradient_theory, sample_estimators};
use dualphoton::recon::level::Level;
use dualphoton::recon::problem::{paper_problem, PaperProblem, Problem};
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::recon::train::{train, TrainSettings};
use dualphoton::scene::rig;
use rayon::current_num_threads as num_threads;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

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
const PARTS: [&str; 2] = ["latent", "weights"];

/// One line of `variance.csv`: one method, one part, one point.
#[derive(Serialize, Deserialize)]
struct Row {
    point: String,
    part: String,
    method: String,
    n: usize,
    #[serde(serialize_with = "fmt::e6")]
    rel_variance: f64,
    #[serde(serialize_with = "fmt::e6")]
    bias: f64,
    #[serde(serialize_with = "fmt::e6", rename = "bias_noise_floor")]
    bias_floor: f64,
    #[serde(serialize_with = "fmt::e6")]
    rel_mse: f64,
    #[serde(serialize_with = "fmt::f6")]
    cosine_mean: f64,
    #[serde(serialize_with = "fmt::f6")]
    cosine_of_mean: f64,
    #[serde(serialize_with = "fmt::e6")]
    estimator_noise: f64,
    #[serde(serialize_with = "fmt::opt_f4")]
    theory: Option<f64>,
    #[serde(serialize_with = "fmt::f4")]
    seconds: f64,
    #[serde(serialize_with = "fmt::f4")]
    primal_seconds: f64,
    #[serde(serialize_with = "fmt::f1")]
    peak_mib: f64,
    #[serde(serialize_with = "fmt::e6")]
    efficiency: f64,
}

/// Every (point, part) pair, in the order of the tables and plots.
fn panels() -> impl Iterator<Item = (&'static str, &'static str)> {
    ["initial", "midway"].into_iter().flat_map(|point| PARTS.map(|part| (point, part)))
}

fn main() -> std::process::ExitCode {
    dualphoton::process::keep_freed_memory();
    dualphoton::error::exit_code(run(Args::parse()))
}

fn run(mut args: Args) -> Result<()> {
    if args.replot {
        return plots(&args.out, &read_rows::<Row>(&args.out.join("variance.csv"))?);
    }
    if args.smoke {
        (args.res, args.seeds, args.reference_seeds, args.midway) = (16, 3, 2, 2);
    }
    if args.seeds < 2 {
        return Err(Error::new("--seeds: need at least 2 to measure a variance"));
    }
    if args.reference_seeds == 0 || args.reference_factor == 0 {
        return Err(Error::new("--reference-seeds and --reference-factor must be at least 1"));
    }
    let started = Instant::now();
    std::fs::create_dir_all(&args.out)?;

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

    let wall_s = started.elapsed().as_secs_f64();
    write_rows(&args.out.join("variance.csv"), &rows)?;
    let (photons, spp) = (scene.render.photons, scene.render.spp);
    let md = summary(&args, &rows, photons, spp, wall_s);
    std::fs::write(args.out.join("summary.md"), &md)?;
    plots(&args.out, &rows)?;
    write_manifest(&args.out.join("manifest.json"), &Manifest { args: &args, photons, spp }, wall_s)?;
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

/// The study's `summary.md`: what was measured, then one table per point and part.
fn summary(args: &Args, rows: &[Row], photons: u64, spp: u32, wall_s: f64) -> String {
    let Args { res, seeds, midway, reference_factor, reference_seeds, .. } = args;
    let (threads, weights) = (num_threads(), rows.iter().find(|r| r.part == PARTS[1]).map_or(0, |r| r.n));
    let mut md = format!(
        "# Gradient variance of every estimator ({res}^3 paper rig, {seeds} seeds)\n\n\
         Regenerate: `cargo run --release --bin grad_variance` ({wall_s:.0} s on {threads} threads).\n\n\
         Gradient of the training loss with respect to the 64-d latent (`latent`) and the {weights} decoder weights \
         (`weights`), at the initial parameters and after {midway} training updates (`midway`). Each seed redraws the \
         renderer's photons and pixel samples ({photons} photons, {spp} spp) and the estimator's own directions or \
         subsets. Reference: `rev-full` at {reference_factor}x photons and samples, mean of {reference_seeds} seeds.\n\n\
         - `rel. var.`: total variance over seeds / |g_ref|^2 (renderer noise + the estimator's own).\n\
         - `bias`: |mean - g_ref| / |g_ref|; `floor`: what noise alone would give (mean's and reference's standard error).\n\
         - `rel. MSE`: mean |g_hat - g_ref|^2 / |g_ref|^2 over seeds (variance + bias^2: the fair measure for biased estimators).\n\
         - `cos`: mean cosine of one estimate with g_ref; `cos(mean)`: of the mean of all seeds.\n\
         - `own noise`: E|g_hat - g|^2 / |g|^2 against `rev-full` on the same frozen paths (the estimator's \
         own noise, renderer noise excluded), next to the forward-gradient theory: (n+1)/K Gaussian, n/K - 1 orthonormal.\n\
         - `s`: median seconds per estimate (the primal render that freezes the estimator is extra); \
         `efficiency` = 1 / (rel. var. x (s + primal s)).\n",
    );
    for (point, part) in panels() {
        let sel: Vec<&Row> = rows.iter().filter(|r| r.point == point && r.part == part).collect();
        let Some(first) = sel.first() else { continue };
        md += &format!("\n## {point}, {part} (n = {}; primal render {:.2} s)\n\n", first.n, first.primal_seconds);
        let header = [
            "method",
            "rel. var.",
            "bias",
            "floor",
            "rel. MSE",
            "cos",
            "cos(mean)",
            "own noise",
            "theory",
            "s",
            "peak MiB",
            "efficiency",
        ];
        md += &markdown_table(
            &header,
            sel.iter().map(|r| {
                vec![
                    r.method.clone(),
                    format!("{:.3e}", r.rel_variance),
                    format!("{:.3}", r.bias),
                    format!("{:.3}", r.bias_floor),
                    format!("{:.3e}", r.rel_mse),
                    format!("{:.3}", r.cosine_mean),
                    format!("{:.3}", r.cosine_of_mean),
                    format!("{:.3e}", r.estimator_noise),
                    r.theory.map_or(String::new(), |t| format!("{t:.3e}")),
                    format!("{:.2}", r.seconds),
                    format!("{:.0}", r.peak_mib),
                    format!("{:.3e}", r.efficiency),
                ]
            }),
        );
    }
    md
}

/// Relative variance against cost per point and part (each estimator
/// family one line over its sizes), and the theory check.
fn plots(out: &Path, rows: &[Row]) -> Result<()> {
    // A method's family: the sizes of one estimator joined into one line.
    let family = |method: &str| match method.split_once(" K=") {
        _ if method.starts_with("rev-sub") => "rev-sub (subsets 1/4 to 16 x the paper's)".to_string(),
        Some((head, _)) => format!("{head} (over K)"),
        None => method.to_string(),
    };
    for (point, part) in panels() {
        let mut series: Vec<Series> = vec![];
        for r in rows.iter().filter(|r| r.point == point && r.part == part) {
            let (name, p) = (family(&r.method), (r.seconds + r.primal_seconds, r.rel_variance));
            match series.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(p),
                None => series.push(Series { name, points: vec![p], markers: true }),
            }
        }
        series.iter_mut().for_each(|s| s.points.sort_by(|a, b| a.0.total_cmp(&b.0)));
        let title = format!("Gradient w.r.t. the {} ({point}): variance against cost", part);
        let x = "seconds per estimate (incl. the primal render)";
        let axes = Axes { title: &title, x, y: "total variance / |g_ref|^2", log_x: true, log_y: true };
        line_chart(&out.join(format!("variance_vs_time_{}_{point}.svg", part)), &axes, &series)?;
    }
    // Theory check: measured own noise against (n+1)/K or n/K - 1.
    let random = |point: &str| -> Vec<(f64, f64)> {
        let rows = rows.iter().filter(|r| r.point == point && r.theory.is_some_and(|t| t > 0.0));
        rows.filter_map(|r| Some((r.theory?, r.estimator_noise))).collect()
    };
    let all = rows.iter().filter_map(|r| r.theory).filter(|&t| t > 0.0);
    let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(a, b), t| (a.min(t), b.max(t)));
    let series = [
        Series { name: "fwd-rand, initial".into(), points: random("initial"), markers: true },
        Series { name: "fwd-rand, midway".into(), points: random("midway"), markers: true },
        Series { name: "theory (measured = predicted)".into(), points: vec![(lo, lo), (hi, hi)], markers: false },
    ];
    let x = "predicted E|g_hat - g|^2 / |g|^2  ((n+1)/K or n/K - 1)";
    let title = "Forward-gradient noise: measured against theory";
    let axes = Axes { title, x, y: "measured over seeds", log_x: true, log_y: true };
    line_chart(&out.join("theory_check.svg"), &axes, &series)
}
