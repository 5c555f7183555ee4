//! Error against run time.
//!
//! 1. Reconstruction: the main job's fitting of the paper's method, the same
//!    wall-clock budgets for every estimator (training coarse to fine by
//!    time, the first 80 % of its budget at half resolution, then the
//!    per-voxel refinement), density error epsilon and held-out camera error
//!    logged against wall time, plus a final high-quality evaluation.
//! 2. Renderer: photon mapping's error against the path-traced reference
//!    over photon counts and kernel radii, next to the path tracer itself at
//!    low sample counts (equal-time comparison).
//!
//! Writes `results/error_vs_time/{reconstruction.csv, reconstruction_final.csv,
//! renderer.csv, *.svg, summary.md, manifest.json}`.

use clap::Parser;
use dualphoton::error::{Error, Result};
use dualphoton::experiment::{self, Run};
use dualphoton::grad::Estimator;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;

mod reconstruction;
mod renderer;

#[derive(Parser, Serialize)]
#[command(about = "Reconstruction error and renderer error against wall-clock time")]
struct Args {
    /// Grid resolution (res^3) and image size (res x res).
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Wall-clock budget of each estimator's training, seconds.
    #[arg(long, default_value_t = 200.0)]
    budget: f64,
    /// Wall-clock budget of the per-voxel refinement after training, seconds (0: none).
    #[arg(long, default_value_t = 100.0)]
    refine_budget: f64,
    /// Estimators to train with.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "fwd-full,fwd-rand,rev-sub,rev-full")]
    estimators: Vec<Estimator>,
    /// Photon counts of the renderer sweep.
    #[arg(long, value_delimiter = ',', default_value = "30000,100000,300000,1000000")]
    photons: Vec<u64>,
    /// Kernel radii of the renderer sweep, in voxels.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2")]
    radii: Vec<f64>,
    /// Samples per pixel of the path tracer's own points.
    #[arg(long, value_delimiter = ',', default_value = "16,64,256,1024")]
    path_spp: Vec<u32>,
    /// Samples per pixel of the path-traced reference.
    #[arg(long, default_value_t = 16384)]
    ref_spp: u32,
    /// Where the reference is cached (shared with bench_render).
    #[arg(long, default_value = "results/bench_render/reference_64")]
    reference_dir: PathBuf,
    /// Timed repeats per renderer configuration (median reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Seed of the plume, the model and the training.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output directory.
    #[arg(long, default_value = "results/error_vs_time")]
    out: PathBuf,
    /// A tiny run (16^3, seconds of budget) to check that everything works.
    #[arg(long)]
    smoke: bool,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.res = 16;
        args.budget = 3.0;
        args.refine_budget = 2.0;
        args.photons = vec![5_000, 20_000];
        args.radii = vec![1.0];
        args.path_spp = vec![4, 16];
        args.ref_spp = 256;
        args.repeats = 1;
        args.reference_dir = args.out.join("reference_16");
    }
    experiment::check_decoder_res(args.res)?;
    if !(args.budget > 0.0 && args.budget.is_finite()) {
        return Err(Error(format!("--budget: {} is not a positive number of seconds", args.budget)));
    }
    if !(args.refine_budget >= 0.0 && args.refine_budget.is_finite()) {
        return Err(Error(format!("--refine-budget: {} is not a number of seconds >= 0", args.refine_budget)));
    }
    let estimators = args.estimators.clone();
    let run = Run::start(&args.out)?;
    let mut summary = format!(
        "# Error against run time ({}^3 paper rig, {} threads)\n\nRegenerate: `cargo run --release --bin error_vs_time`.\n\n",
        args.res,
        rayon::current_num_threads()
    );
    reconstruction::reconstruction(&args, &estimators, &mut summary)?;
    renderer::renderer(&args, &mut summary)?;
    let _ = writeln!(summary, "\nWall time of the whole study: {:.0} s.", run.seconds());
    std::fs::write(run.path("summary.md"), &summary)?;
    run.write_manifest(&args)?;
    print!("{summary}");
    Ok(())
}
