//! Gradient-variance study: every estimator of the
//! parameter gradient (64-d latent and decoder weights), at the initial
//! parameters and midway through the default training run, over many
//! independent seeds: mean, total variance, bias and cosine against a
//! high-sample reference, time and peak memory per estimate, efficiency,
//! and the measured forward-gradient noise against theory.
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
use dualphoton::eval::stats::median;
use dualphoton::grad::forward::Directions;
use dualphoton::grad::reverse::Subset;
use dualphoton::io::manifest::{git_revision, peak_memory_mib, reset_peak_memory, write_json};
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::model::Model;
use dualphoton::recon::level::Level;
use dualphoton::recon::param_grad;
use dualphoton::recon::problem::{paper_problem, PaperProblem, Problem};
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::recon::train::{train, TrainSettings};
use dualphoton::render::frozen::Frozen;
use dualphoton::rng::{Purpose, Rng};
use dualphoton::scene::{rig, Scene};
use serde_json::json;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
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
    out: PathBuf,
    /// A tiny run (16^3, 3 seeds) to check that everything works.
    #[arg(long)]
    smoke: bool,
    /// Only redraw the plots from the variance.csv an earlier run left in --out.
    #[arg(long)]
    replot: bool,
}

/// Which parameters a gradient is taken with respect to.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    Latent,
    Weights,
}

impl Part {
    fn name(self) -> &'static str {
        match self {
            Part::Latent => "latent",
            Part::Weights => "weights",
        }
    }
}

/// (dL/dz, dL/dw), each where a method gives it.
type ByPart = (Option<Vec<f64>>, Option<Vec<f64>>);

/// One way of estimating the gradient.
#[derive(Clone, Copy)]
enum Method {
    /// Reverse mode on (pixels, paths), `None` = all.
    Reverse(Option<(usize, usize)>),
    /// Forward mode, all 64 latent coordinates, 16 lanes per pass.
    LatentExact,
    /// Forward mode, K random latent directions in one pass.
    LatentRandom(usize, Directions),
    /// Forward mode, K random weight directions (16 lanes per pass).
    WeightsRandom(usize, Directions),
    /// Forward mode, projection onto a guessed and K - 1 random weight directions.
    WeightsGuided(usize),
}

impl Method {
    fn name(self) -> String {
        let kind = |d: Directions| if d == Directions::Gaussian { "gaussian" } else { "orthonormal" };
        match self {
            Method::Reverse(None) => "rev-full".into(),
            Method::Reverse(Some((px, paths))) => format!("rev-sub {px}px/{paths}paths"),
            Method::LatentExact => "fwd-full".into(),
            Method::LatentRandom(k, d) | Method::WeightsRandom(k, d) => format!("fwd-rand {} K={k}", kind(d)),
            Method::WeightsGuided(k) => format!("fwd-guided K={k}"),
        }
    }

    fn parts(self) -> &'static [Part] {
        match self {
            Method::Reverse(_) => &[Part::Latent, Part::Weights],
            Method::LatentExact | Method::LatentRandom(..) => &[Part::Latent],
            Method::WeightsRandom(..) | Method::WeightsGuided(_) => &[Part::Weights],
        }
    }

    /// The forward-gradient theory's added noise `E|g_hat - g|^2 / |g|^2` over `n` parameters.
    fn theory(self, n: usize) -> Option<f64> {
        let (n, k) = (n as f64, |k: usize| k as f64);
        match self {
            Method::LatentRandom(kk, Directions::Gaussian) | Method::WeightsRandom(kk, Directions::Gaussian) => {
                Some((n + 1.0) / k(kk))
            }
            Method::LatentRandom(kk, Directions::Orthonormal) | Method::WeightsRandom(kk, Directions::Orthonormal) => {
                Some(n / k(kk) - 1.0)
            }
            Method::LatentExact => Some(0.0),
            _ => None,
        }
    }

    /// (dL/dz, dL/dw) where this method gives them.
    fn estimate(self, level: &Level, model: &Model, frozen: &Frozen, rng: &mut Rng) -> Result<ByPart> {
        Ok(match self {
            Method::Reverse(sizes) => {
                let subset = match sizes {
                    None => Subset::full(),
                    Some((px, paths)) => Subset { pixels: Some(px), paths: Some(paths), seed: rng.below(u64::MAX) },
                };
                let (dz, dw) = param_grad::reverse(level, model, frozen, subset);
                (Some(dz), Some(dw))
            }
            Method::LatentExact => (Some(param_grad::latent_exact(level, model, frozen, 16)?), None),
            Method::LatentRandom(k, d) => (Some(param_grad::latent_random(level, model, frozen, k, d, rng)?), None),
            Method::WeightsRandom(k, d) => {
                (None, Some(param_grad::weights_random(level, model, frozen, k, d, 16.min(k), rng)?))
            }
            Method::WeightsGuided(k) => {
                (None, Some(param_grad::weights_guided(level, model, frozen, k, 16.min(k), rng)?))
            }
        })
    }
}

/// The estimators compared, with the paper's subset second.
fn methods(pixels: usize, paths: usize) -> Vec<Method> {
    let mut m = vec![Method::Reverse(None)];
    for f in [4, 1] {
        m.push(Method::Reverse(Some((pixels / f, paths / f))));
    }
    for f in [4, 16] {
        m.push(Method::Reverse(Some((pixels * f, paths * f))));
    }
    m.push(Method::LatentExact);
    for k in [1, 4, 8, 16] {
        m.push(Method::LatentRandom(k, Directions::Gaussian));
    }
    for k in [4, 16] {
        m.push(Method::LatentRandom(k, Directions::Orthonormal));
    }
    for k in [1, 16] {
        m.push(Method::WeightsRandom(k, Directions::Gaussian));
    }
    m.push(Method::WeightsRandom(16, Directions::Orthonormal));
    for k in [8, 16] {
        m.push(Method::WeightsGuided(k));
    }
    m
}

/// Per-seed estimates of one method at one point.
#[derive(Default)]
struct Samples {
    latent: Vec<Vec<f64>>,
    weights: Vec<Vec<f64>>,
    seconds: Vec<f64>,
    peak_mib: f64,
}

impl Samples {
    fn of(&self, part: Part) -> &[Vec<f64>] {
        match part {
            Part::Latent => &self.latent,
            Part::Weights => &self.weights,
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm2(a: &[f64]) -> f64 {
    dot(a, a)
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum()
}

fn cosine(a: &[f64], b: &[f64]) -> f64 {
    let d = (norm2(a) * norm2(b)).sqrt();
    if d > 0.0 {
        dot(a, b) / d
    } else {
        0.0
    }
}

fn mean_of(xs: &[Vec<f64>]) -> Vec<f64> {
    let mut m = vec![0.0; xs[0].len()];
    for x in xs {
        m.iter_mut().zip(x).for_each(|(a, b)| *a += b / xs.len() as f64);
    }
    m
}

/// Unbiased total variance (trace of the covariance) of the samples.
fn total_variance(xs: &[Vec<f64>]) -> f64 {
    if xs.len() < 2 {
        return f64::NAN;
    }
    let m = mean_of(xs);
    xs.iter().map(|x| dist2(x, &m)).sum::<f64>() / (xs.len() - 1) as f64
}

/// The statistics of one method for one part at one point.
struct Row {
    point: &'static str,
    part: Part,
    method: String,
    n: usize,
    rel_variance: f64,
    bias: f64,
    bias_floor: f64,
    rel_mse: f64,
    cosine_mean: f64,
    cosine_of_mean: f64,
    estimator_noise: f64,
    theory: Option<f64>,
    seconds: f64,
    primal_seconds: f64,
    peak_mib: f64,
    efficiency: f64,
}

fn main() -> std::process::ExitCode {
    dualphoton::error::exit_code(run(Args::parse()))
}

fn run(mut args: Args) -> Result<()> {
    if args.replot {
        return plots(&args, &read_rows(&args.out.join("variance.csv"))?);
    }
    if args.smoke {
        args.res = 16;
        args.seeds = 3;
        args.reference_seeds = 2;
        args.midway = 2;
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
    let settings =
        TrainSettings { iterations: args.midway, seed: args.seed, coarse_fraction: 1.0, ..Default::default() };
    train(&problem, &mut midway, &settings, &mut |row, _, _| {
        eprint!("\r  update {}/{}  loss {:.4e}   ", row.iteration + 1, args.midway, row.train_loss)
    })?;
    eprintln!();

    let (pixels, paths) =
        (1000 * scene.render.photons as usize / 300_000, 5000 * scene.render.photons as usize / 300_000);
    let pixels = pixels.max(4);
    let paths = paths.max(4);
    let methods = methods(pixels, paths);
    let mut rows = vec![];
    for (point, model) in [("initial", &initial), ("midway", &midway)] {
        rows.extend(study_point(&args, &problem, &scene, point, model, &methods)?);
    }

    write_outputs(&args, &rows, &scene, started.elapsed().as_secs_f64())?;
    Ok(())
}

/// All methods at one set of parameters.
fn study_point(
    args: &Args,
    problem: &Problem,
    scene: &Scene,
    point: &'static str,
    model: &Model,
    methods: &[Method],
) -> Result<Vec<Row>> {
    let level = Level::full(problem, &model.mask);
    let decoded = model.density(&scene.density);
    let render = &scene.render;

    // High-sample reference: rev-full at more photons and samples, averaged over seeds.
    let mut reference = Samples::default();
    for r in 0..args.reference_seeds {
        let f = args.reference_factor;
        let seed = 1_000_000 + args.seed * 1000 + r as u64;
        let s = level.scene_at(&decoded, render.photons * f as u64, render.spp * f, seed);
        let frozen = Frozen::new(&s, Some(&level.support));
        let (dz, dw) = param_grad::reverse(&level, model, &frozen, Subset::full());
        reference.latent.push(dz);
        reference.weights.push(dw);
        eprintln!("{point}: reference {}/{} done", r + 1, args.reference_seeds);
    }

    let mut samples: Vec<Samples> = methods.iter().map(|_| Samples::default()).collect();
    let mut primal = vec![];
    for s in 0..args.seeds {
        let t = Instant::now();
        let seed = args.seed * 1000 + s as u64;
        let sc = level.scene_at(&decoded, render.photons, render.spp, seed);
        let frozen = Frozen::new(&sc, Some(&level.support));
        primal.push(t.elapsed().as_secs_f64());
        for (i, m) in methods.iter().enumerate() {
            let mut rng = Rng::new(seed, Purpose::Gradient, 7_000 + i as u64);
            reset_peak_memory();
            let t = Instant::now();
            let (dz, dw) = m.estimate(&level, model, &frozen, &mut rng)?;
            samples[i].seconds.push(t.elapsed().as_secs_f64());
            samples[i].peak_mib = samples[i].peak_mib.max(peak_memory_mib());
            samples[i].latent.extend(dz);
            samples[i].weights.extend(dw);
        }
        eprint!("\r{point}: seed {}/{}   ", s + 1, args.seeds);
    }
    eprintln!();

    let primal_s = median(&primal);
    // `rev-full` on each seed's frozen paths: the exact gradient the others estimate.
    let exact = methods
        .iter()
        .position(|m| matches!(m, Method::Reverse(None)))
        .map(|i| &samples[i])
        .ok_or_else(|| Error::new("the methods must include rev-full"))?;
    let mut rows = vec![];
    for (m, smp) in methods.iter().zip(&samples) {
        for &part in m.parts() {
            let xs = smp.of(part);
            let refs = reference.of(part);
            let g_ref = mean_of(refs);
            let g2 = norm2(&g_ref).max(f64::MIN_POSITIVE);
            let mean = mean_of(xs);
            let var = total_variance(xs);
            let ref_var = if refs.len() > 1 { total_variance(refs) / refs.len() as f64 } else { 0.0 };
            // The estimator's own noise, against rev-full on the same frozen paths.
            let own: Vec<f64> =
                xs.iter().zip(exact.of(part)).map(|(x, g)| dist2(x, g) / norm2(g).max(f64::MIN_POSITIVE)).collect();
            let seconds = median(&smp.seconds);
            let rel_variance = var / g2;
            rows.push(Row {
                point,
                part,
                method: m.name(),
                n: g_ref.len(),
                rel_variance,
                bias: (dist2(&mean, &g_ref) / g2).sqrt(),
                bias_floor: ((var / xs.len() as f64 + ref_var) / g2).sqrt(),
                rel_mse: xs.iter().map(|x| dist2(x, &g_ref)).sum::<f64>() / xs.len() as f64 / g2,
                cosine_mean: xs.iter().map(|x| cosine(x, &g_ref)).sum::<f64>() / xs.len() as f64,
                cosine_of_mean: cosine(&mean, &g_ref),
                estimator_noise: own.iter().sum::<f64>() / own.len() as f64,
                theory: m.theory(g_ref.len()),
                seconds,
                primal_seconds: primal_s,
                peak_mib: smp.peak_mib,
                efficiency: 1.0 / (rel_variance * (seconds + primal_s)),
            });
        }
    }
    Ok(rows)
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:.4}"))
}

fn write_outputs(args: &Args, rows: &[Row], scene: &Scene, wall_s: f64) -> Result<()> {
    let mut csv = String::from(
        "point,part,method,n,rel_variance,bias,bias_noise_floor,rel_mse,cosine_mean,cosine_of_mean,estimator_noise,theory,seconds,primal_seconds,peak_mib,efficiency\n",
    );
    for r in rows {
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6},{:.6},{:.6e},{},{:.4},{:.4},{:.1},{:.6e}",
            r.point,
            r.part.name(),
            r.method,
            r.n,
            r.rel_variance,
            r.bias,
            r.bias_floor,
            r.rel_mse,
            r.cosine_mean,
            r.cosine_of_mean,
            r.estimator_noise,
            fmt_opt(r.theory),
            r.seconds,
            r.primal_seconds,
            r.peak_mib,
            r.efficiency
        );
    }
    std::fs::write(args.out.join("variance.csv"), csv)?;

    let mut md = format!(
        "# Gradient variance of every estimator ({}^3 paper rig, {} seeds)\n\n\
         Regenerate: `cargo run --release --bin grad_variance` ({:.0} s on {} threads).\n\n\
         Gradient of the training loss with respect to the 64-d latent (`latent`) and the {} decoder weights \
         (`weights`), at the initial parameters and after {} training updates (`midway`). Each seed redraws the \
         renderer's photons and pixel samples ({} photons, {} spp) and the estimator's own directions or subsets. \
         Reference: `rev-full` at {}x photons and samples, mean of {} seeds.\n\n\
         - `rel. var.`: total variance over seeds / |g_ref|^2 (renderer noise + the estimator's own).\n\
         - `bias`: |mean - g_ref| / |g_ref|; `floor`: what noise alone would give (mean's and reference's standard error).\n\
         - `rel. MSE`: mean |g_hat - g_ref|^2 / |g_ref|^2 over seeds (variance + bias^2: the fair measure for biased estimators).\n\
         - `cos`: mean cosine of one estimate with g_ref; `cos(mean)`: of the mean of all seeds.\n\
         - `own noise`: E|g_hat - g|^2 / |g|^2 against `rev-full` on the same frozen paths (the estimator's \
         own noise, renderer noise excluded), next to the forward-gradient theory: (n+1)/K Gaussian, n/K - 1 orthonormal.\n\
         - `s`: median seconds per estimate (the primal render that freezes the estimator is extra); \
         `efficiency` = 1 / (rel. var. x (s + primal s)).\n",
        args.res,
        args.seeds,
        wall_s,
        rayon::current_num_threads(),
        rows.iter().find(|r| r.part == Part::Weights).map_or(0, |r| r.n),
        args.midway,
        scene.render.photons,
        scene.render.spp,
        args.reference_factor,
        args.reference_seeds,
    );
    for point in ["initial", "midway"] {
        for part in [Part::Latent, Part::Weights] {
            let sel: Vec<&Row> = rows.iter().filter(|r| r.point == point && r.part == part).collect();
            let Some(first) = sel.first() else { continue };
            let _ = writeln!(
                md,
                "\n## {point}, {} (n = {}; primal render {:.2} s)\n\n\
                 | method | rel. var. | bias | floor | rel. MSE | cos | cos(mean) | own noise | theory | s | peak MiB | efficiency |\n\
                 |---|---|---|---|---|---|---|---|---|---|---|---|",
                part.name(),
                first.n,
                first.primal_seconds
            );
            for r in sel {
                let _ = writeln!(
                    md,
                    "| {} | {:.3e} | {:.3} | {:.3} | {:.3e} | {:.3} | {:.3} | {:.3e} | {} | {:.2} | {:.0} | {:.3e} |",
                    r.method,
                    r.rel_variance,
                    r.bias,
                    r.bias_floor,
                    r.rel_mse,
                    r.cosine_mean,
                    r.cosine_of_mean,
                    r.estimator_noise,
                    r.theory.map_or(String::new(), |t| format!("{t:.3e}")),
                    r.seconds,
                    r.peak_mib,
                    r.efficiency
                );
            }
        }
    }
    std::fs::write(args.out.join("summary.md"), &md)?;
    plots(args, rows)?;
    write_json(
        &args.out.join("manifest.json"),
        &json!({
            "res": args.res, "seeds": args.seeds, "reference_seeds": args.reference_seeds,
            "reference_factor": args.reference_factor, "midway": args.midway, "seed": args.seed,
            "photons": scene.render.photons, "spp": scene.render.spp,
            "git": git_revision(), "wall_s": wall_s, "threads": rayon::current_num_threads(),
        }),
    )?;
    print!("{md}");
    Ok(())
}

/// The rows of a `variance.csv` this binary wrote.
fn read_rows(path: &std::path::Path) -> Result<Vec<Row>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error(format!("cannot read {}: {e}", path.display())))?;
    let bad = |line: usize| Error(format!("{}: line {} is not a row of this study", path.display(), line + 1));
    let mut rows = vec![];
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 16 {
            return Err(bad(i));
        }
        let num = |k: usize| f[k].parse::<f64>().map_err(|_| bad(i));
        rows.push(Row {
            point: match f[0] {
                "initial" => "initial",
                "midway" => "midway",
                _ => return Err(bad(i)),
            },
            part: if f[1] == "latent" { Part::Latent } else { Part::Weights },
            method: f[2].to_string(),
            n: f[3].parse().map_err(|_| bad(i))?,
            rel_variance: num(4)?,
            bias: num(5)?,
            bias_floor: num(6)?,
            rel_mse: num(7)?,
            cosine_mean: num(8)?,
            cosine_of_mean: num(9)?,
            estimator_noise: num(10)?,
            theory: f[11].parse().ok(),
            seconds: num(12)?,
            primal_seconds: num(13)?,
            peak_mib: num(14)?,
            efficiency: num(15)?,
        });
    }
    Ok(rows)
}

/// A method's family: the sizes of one estimator joined into one line.
fn family(method: &str) -> String {
    if method.starts_with("rev-sub") {
        "rev-sub (subsets 1/4 to 16 x the paper's)".into()
    } else if let Some((head, _)) = method.split_once(" K=") {
        format!("{head} (over K)")
    } else {
        method.into()
    }
}

/// Relative variance against cost per point and part (each estimator
/// family one line over its sizes), and the theory check.
fn plots(args: &Args, rows: &[Row]) -> Result<()> {
    for point in ["initial", "midway"] {
        for part in [Part::Latent, Part::Weights] {
            let mut series: Vec<Series> = vec![];
            for r in rows.iter().filter(|r| r.point == point && r.part == part) {
                let name = family(&r.method);
                let p = (r.seconds + r.primal_seconds, r.rel_variance);
                match series.iter_mut().find(|s| s.name == name) {
                    Some(s) => s.points.push(p),
                    None => series.push(Series { name, points: vec![p], markers: true }),
                }
            }
            series.iter_mut().for_each(|s| s.points.sort_by(|a, b| a.0.total_cmp(&b.0)));
            line_chart(
                &args.out.join(format!("variance_vs_time_{}_{point}.svg", part.name())),
                &Axes {
                    title: &format!("Gradient w.r.t. the {} ({point}): variance against cost", part.name()),
                    x: "seconds per estimate (incl. the primal render)",
                    y: "total variance / |g_ref|^2",
                    log_x: true,
                    log_y: true,
                },
                &series,
            )?;
        }
    }
    // Theory check: measured own noise against (n+1)/K or n/K - 1.
    let mut series = vec![];
    for point in ["initial", "midway"] {
        let pts = |pred: &dyn Fn(&Row) -> bool| -> Vec<(f64, f64)> {
            rows.iter()
                .filter(|r| r.point == point && pred(r))
                .filter_map(|r| Some((r.theory?, r.estimator_noise)))
                .collect()
        };
        series.push(Series {
            name: format!("fwd-rand, {point}"),
            points: pts(&|r| r.theory.is_some_and(|t| t > 0.0)),
            markers: true,
        });
    }
    let all: Vec<f64> = rows.iter().filter_map(|r| r.theory).filter(|&t| t > 0.0).collect();
    let (lo, hi) = all.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
    series.push(Series {
        name: "theory (measured = predicted)".into(),
        points: vec![(lo, lo), (hi, hi)],
        markers: false,
    });
    line_chart(
        &args.out.join("theory_check.svg"),
        &Axes {
            title: "Forward-gradient noise: measured against theory",
            x: "predicted E|g_hat - g|^2 / |g|^2  ((n+1)/K or n/K - 1)",
            y: "measured over seeds",
            log_x: true,
            log_y: true,
        },
        &series,
    )
}
