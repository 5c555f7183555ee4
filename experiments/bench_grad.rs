//! Cost of one gradient: time and peak memory of each
//! estimator and lane count K, as ratios to one primal render, on the paper
//! rig at 64^3 (4 training cameras, 3 lights, orders 1-3, 300,000 photons).
//! Writes `results/bench_grad/{bench.csv, summary.md, manifest.json}`.
//!
//! Peak memory is the process's resident high-water mark (VmHWM), reset
//! before each measurement through /proc/self/clear_refs.

use clap::Parser;
use dualphoton::data::plume::plume;
use dualphoton::error::{Error, Result};
use dualphoton::eval::stats::median;
use dualphoton::grad::forward::{coordinate_gradient, random_gradient, Directions};
use dualphoton::grad::reverse::{reverse_gradient, Subset};
use dualphoton::grad::Estimator;
use dualphoton::io::manifest::{peak_memory_mib, reset_peak_memory, write_manifest};
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
    /// Grid resolution (images res x res).
    #[arg(long, default_value_t = 64)]
    res: usize,
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
    dualphoton::error::exit_code(run(Args::parse()))
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.res = 16;
        args.repeats = 1;
        args.directions = 8;
    }
    std::fs::create_dir_all(&args.out)?;
    let started = Instant::now();
    // Ground truth images from the plume; the gradient is taken at half its density.
    let mut truth: Scene = rig::paper_scene(plume(args.res, 0), args.res);
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
    eprintln!("primal: {primal_s:.3} s, {primal_mib:.0} MiB; {} reachable voxels", reach.len());

    let mut rows: Vec<(String, usize, usize, f64, f64)> = vec![];
    let (s, m) = measure(args.repeats, || {
        reverse_gradient(&frozen, &targets, Subset::full());
    });
    rows.push((Estimator::RevFull.name().into(), 0, reach.len(), s, m));
    let (s, m) = measure(args.repeats, || {
        reverse_gradient(&frozen, &targets, Subset { pixels: Some(1000), paths: Some(5000), seed: 1 });
    });
    rows.push((format!("{} (1000 px, 5000 paths)", Estimator::RevSub.name()), 0, reach.len(), s, m));
    macro_rules! forward {
        ($($k:literal),*) => {$(
            let (s, m) = measure(args.repeats, || {
                random_gradient::<$k>(&frozen, &reach, &targets, Directions::Gaussian, &mut Rng::from_seed(1));
            });
            rows.push((Estimator::FwdRand.name().into(), $k, $k, s, m));
            let (s, m) = measure(args.repeats.min(2), || {
                coordinate_gradient::<$k>(&frozen, &coords, &targets, &|_, _| {});
            });
            rows.push((format!("{} ({} directions)", Estimator::FwdFull.name(), coords.len()), $k, coords.len(), s, m));
            eprintln!("K = {}: done", $k);
        )*};
    }
    forward!(1, 2, 4, 8, 16);

    let mut csv = csv::Writer::from_path(args.out.join("bench.csv")).map_err(|e| Error(e.to_string()))?;
    csv.write_record([
        "estimator",
        "lanes",
        "directions",
        "seconds",
        "time_ratio_to_primal",
        "peak_mib",
        "primal_peak_mib",
    ])
    .map_err(|e| Error(e.to_string()))?;
    let mut md = format!(
        "# Cost of one gradient, paper rig {r}^3 ({} cameras of {r}x{r}, {} photons)\n\n\
         Primal render (photon tracing + estimate + camera rays): {primal_s:.3} s, peak {primal_mib:.0} MiB (median of {}; {} threads).\n\
         Times below are for the derivative passes alone, on top of the primal that freezes the estimator.\n\n\
         | estimator | K | directions | time (s) | x primal | peak MiB |\n|---|---|---|---|---|---|\n",
        scene.cameras.len(),
        scene.render.photons,
        args.repeats,
        rayon::current_num_threads(),
        r = args.res
    );
    for (name, k, dirs, s, m) in &rows {
        csv.write_record([
            name.clone(),
            k.to_string(),
            dirs.to_string(),
            format!("{s:.4}"),
            format!("{:.3}", s / primal_s),
            format!("{m:.1}"),
            format!("{primal_mib:.1}"),
        ])
        .map_err(|e| Error(e.to_string()))?;
        let _ = writeln!(
            md,
            "| {name} | {} | {dirs} | {s:.3} | {:.2} | {m:.0} |",
            if *k == 0 { "-".into() } else { k.to_string() },
            s / primal_s
        );
    }
    csv.flush()?;
    let _ = writeln!(
        md,
        "\nRegenerate: `cargo run --release --bin bench_grad` ({:.0} s).",
        started.elapsed().as_secs_f64()
    );
    std::fs::write(args.out.join("summary.md"), &md)?;
    let manifest = Manifest { settings: &args, peak_reset_supported: reset_peak_memory() };
    write_manifest(&args.out.join("manifest.json"), &manifest, started.elapsed().as_secs_f64())?;
    print!("{md}");
    Ok(())
}
