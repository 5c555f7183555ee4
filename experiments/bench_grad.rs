//! Cost of one gradient: time and peak memory of each
//! estimator and lane count K, as ratios to one primal render, on the paper
//! rig at 64^3 and 128^3 (4 training cameras, 3 lights, orders 1-3, 300,000
//! photons), and the exact latent gradient of the reconstruction's model
//! (64 directions through the decoder, `fwd-full`).
//! Writes `results/bench_grad/{bench.csv, summary.md, manifest.json}`.
//!
//! Peak memory is the process's resident high-water mark (VmHWM), reset
//! before each measurement through /proc/self/clear_refs.

use clap::Parser;
use dualphoton::data::plume::plume;
use dualphoton::error::{Error, Result};
use dualphoton::eval::stats::median;
use dualphoton::experiment::{self, Run};
use dualphoton::grad::forward::{coordinate_gradient, random_gradient, Directions};
use dualphoton::grad::reverse::{reverse_gradient, Subset};
use dualphoton::grad::Estimator;
use dualphoton::io::manifest::{peak_memory_mib, reset_peak_memory};
use dualphoton::recon::level::Level;
use dualphoton::recon::param_grad::latent_exact;
use dualphoton::recon::problem::{paper_problem, Problem};
use dualphoton::recon::reconstruct::initial_model;
use dualphoton::render::frozen::Frozen;
use dualphoton::rng::Rng;
use dualphoton::scene::{rig, Scene};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser, Serialize)]
#[command(about = "Time and peak memory of one gradient per estimator and lane count")]
struct Args {
    /// Grid resolutions (images res x res).
    #[arg(long, value_delimiter = ',', default_value = "64,128")]
    res: Vec<usize>,
    /// Lane counts K of the forward estimators, per resolution: all of
    /// them at the first resolution, only the largest at the others; the
    /// latent's exact gradient at every K of 16 or more, at every resolution.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32,64")]
    lanes: Vec<usize>,
    /// Repeats per measurement (median reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Coordinate directions of the fwd-full measurement (the latent's 64).
    #[arg(long, default_value_t = 64)]
    directions: usize,
    /// Output directory.
    #[arg(long, default_value = "results/bench_grad")]
    out: PathBuf,
    /// Tiny sizes, for a quick check that the binary works.
    #[arg(long)]
    smoke: bool,
}

/// Median seconds and peak MiB of `f` over `repeats` runs.
fn measure(repeats: usize, mut f: impl FnMut()) -> (f64, f64) {
    let mut times = vec![];
    let mut peak = 0.0f64;
    for _ in 0..repeats.max(1) {
        reset_peak_memory();
        let t = Instant::now();
        f();
        times.push(t.elapsed().as_secs_f64());
        peak = peak.max(peak_memory_mib());
    }
    (median(&times), peak)
}

/// What the manifest records besides provenance.
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    settings: &'a Args,
    peak_reset_supported: bool,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

/// One measured gradient.
struct Row {
    res: usize,
    name: String,
    lanes: usize,
    directions: usize,
    seconds: f64,
    primal_s: f64,
    peak_mib: f64,
    primal_mib: f64,
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.res = vec![16, 32];
        args.repeats = 1;
        args.directions = 8;
    }
    args.res.iter().try_for_each(|&r| experiment::check_decoder_res(r))?;
    if let Some(k) = args.lanes.iter().find(|k| !dualphoton::grad::LANES.contains(k)) {
        return Err(Error(format!("--lanes: {k} is not one of {:?}", dualphoton::grad::LANES)));
    }
    let run = Run::start(&args.out)?;
    let mut rows = vec![];
    let mut md = String::from(
        "# Cost of one gradient, paper rig (4 cameras, 300000 photons)\n\n\
         Times are for the derivative passes alone, on top of the primal render that freezes the estimator;\n\
         `x primal` divides by that primal's time at the same resolution.\n\n",
    );
    for (n, &res) in args.res.iter().enumerate() {
        let lanes: Vec<usize> =
            if n == 0 { args.lanes.clone() } else { args.lanes.iter().max().into_iter().copied().collect() };
        let before = rows.len();
        measure_res(&args, res, &lanes, &mut rows)?;
        let r = &rows[before];
        let _ = writeln!(
            md,
            "## {res}^3, {res}x{res} images\n\nPrimal render: {:.3} s, peak {:.0} MiB (median of {}; {} threads).\n\n\
             | estimator | K | directions | time (s) | x primal | peak MiB |\n|---|---|---|---|---|---|",
            r.primal_s,
            r.primal_mib,
            args.repeats,
            rayon::current_num_threads()
        );
        for r in &rows[before..] {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.3} | {:.2} | {:.0} |",
                r.name,
                if r.lanes == 0 { "-".into() } else { r.lanes.to_string() },
                r.directions,
                r.seconds,
                r.seconds / r.primal_s,
                r.peak_mib
            );
        }
        md.push('\n');
    }
    let mut csv = csv::Writer::from_path(run.path("bench.csv")).map_err(|e| Error(e.to_string()))?;
    csv.write_record([
        "res",
        "estimator",
        "lanes",
        "directions",
        "seconds",
        "time_ratio_to_primal",
        "peak_mib",
        "primal_s",
        "primal_peak_mib",
    ])
    .map_err(|e| Error(e.to_string()))?;
    for r in &rows {
        csv.write_record([
            r.res.to_string(),
            r.name.clone(),
            r.lanes.to_string(),
            r.directions.to_string(),
            format!("{:.4}", r.seconds),
            format!("{:.3}", r.seconds / r.primal_s),
            format!("{:.1}", r.peak_mib),
            format!("{:.4}", r.primal_s),
            format!("{:.1}", r.primal_mib),
        ])
        .map_err(|e| Error(e.to_string()))?;
    }
    csv.flush()?;
    let _ = writeln!(md, "Regenerate: `cargo run --release --bin bench_grad` ({:.0} s).", run.seconds());
    std::fs::write(run.path("summary.md"), &md)?;
    let manifest = Manifest { settings: &args, peak_reset_supported: reset_peak_memory() };
    run.write_manifest(&manifest)?;
    print!("{md}");
    Ok(())
}

/// The rows of one resolution: the primal, reverse mode, the forward
/// estimators at each of `lanes`, and the model's exact latent gradient.
fn measure_res(args: &Args, res: usize, lanes: &[usize], rows: &mut Vec<Row>) -> Result<()> {
    // Ground truth images from the plume; the gradient is taken at half its density.
    let mut truth: Scene = rig::paper_scene(plume(res, 0), res);
    truth.cameras.truncate(4);
    if args.smoke {
        truth.render.photons = 20_000;
    }
    let targets = Frozen::new(&truth, None).images;
    let mut scene = truth.clone();
    scene.density.data.iter_mut().for_each(|v| *v *= 0.5);
    scene.render.seed = 1;

    let (primal_s, primal_mib) = measure(args.repeats, || {
        Frozen::new(&scene, None);
    });
    let frozen = Frozen::new(&scene, None);
    let reach = frozen.reachable_voxels();
    let coords: Vec<usize> =
        reach.iter().step_by((reach.len() / args.directions).max(1)).take(args.directions).copied().collect();
    eprintln!("{res}^3 primal: {primal_s:.3} s, {primal_mib:.0} MiB; {} reachable voxels", reach.len());
    let mut push = |name: String, lanes: usize, directions: usize, (seconds, peak_mib): (f64, f64)| {
        eprintln!("  {name}, K = {lanes}: {seconds:.3} s ({:.2} x primal)", seconds / primal_s);
        rows.push(Row { res, name, lanes, directions, seconds, primal_s, peak_mib, primal_mib });
    };
    push(
        Estimator::RevFull.name().into(),
        0,
        reach.len(),
        measure(args.repeats, || {
            reverse_gradient(&frozen, &targets, Subset::full());
        }),
    );
    push(
        format!("{} (1000 px, 5000 paths)", Estimator::RevSub.name()),
        0,
        reach.len(),
        measure(args.repeats, || {
            reverse_gradient(&frozen, &targets, Subset { pixels: Some(1000), paths: Some(5000), seed: 1 });
        }),
    );
    for &k in lanes {
        macro_rules! at_lanes {
            ($($k:literal),*) => {
                match k {
                    $($k => {
                        let t = measure(args.repeats, || {
                            random_gradient::<$k>(&frozen, &reach, &targets, Directions::Gaussian, &mut Rng::from_seed(1));
                        });
                        push(Estimator::FwdRand.name().into(), k, k, t);
                        let t = measure(args.repeats.min(2), || {
                            coordinate_gradient::<$k>(&frozen, &coords, &targets, &|_, _| {});
                        });
                        push(format!("{} ({} voxel directions)", Estimator::FwdFull.name(), coords.len()), k, coords.len(), t);
                    })*
                    _ => return Err(Error(format!("--lanes: {k} is not one of {:?}", dualphoton::grad::LANES))),
                }
            };
        }
        at_lanes!(1, 2, 4, 8, 16, 32, 64);
    }

    // The exact latent gradient of the reconstruction's model: the decoder in dual numbers, then the renderer.
    let problem = paper_problem(res, 0, truth.render.photons, 0);
    let (train, held_out) = problem.images.split_at(rig::HELD_OUT_CAMERA);
    let p = Problem { scene: &problem.scene, targets: train, held_out, truth: None };
    let model = initial_model(&problem.scene, train, 0)?;
    let level = Level::full(&p, &model.mask);
    let at = level.scene_at(&model.density(&problem.scene.density), truth.render.photons, truth.render.spp, 1);
    let frozen = Frozen::new(&at, Some(&level.support));
    // At every lane count of 16 or more (one of them: the largest given), the counts taken in turn, so that a
    // slow spell of a shared machine falls on each alike: the comparison is A B A B within one run.
    let mut latent_lanes: Vec<usize> = args.lanes.iter().copied().filter(|&k| k >= 16).collect();
    if latent_lanes.is_empty() {
        latent_lanes = lanes.iter().copied().max().into_iter().collect();
    }
    let mut samples = vec![(vec![], 0.0f64); latent_lanes.len()];
    for _ in 0..args.repeats.max(1) {
        for (&k, (times, peak)) in latent_lanes.iter().zip(&mut samples) {
            let (t, p) = measure(1, || {
                latent_exact(&level, &model, &frozen, k).expect("lanes are a supported count");
            });
            times.push(t);
            *peak = peak.max(p);
        }
    }
    for (&k, (times, peak)) in latent_lanes.iter().zip(&samples) {
        push(
            format!("{} latent ({} directions, decoder included)", Estimator::FwdFull.name(), model.z.len()),
            k,
            model.z.len(),
            (median(times), *peak),
        );
    }
    Ok(())
}
