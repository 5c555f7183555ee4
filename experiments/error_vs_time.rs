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
use dualphoton::eval::metrics::{pearson, reference_noise, rel_l1, rel_rmse};
use dualphoton::eval::reference::reference;
use dualphoton::eval::sweep::{error, photon_sweep, ERROR_BLOCK};
use dualphoton::grad::Estimator;
use dualphoton::io::manifest::write_manifest;
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::write_rows;
use dualphoton::recon::methods::Method;
use dualphoton::recon::problem::{paper_problem, PaperProblem, Problem};
use dualphoton::recon::reconstruct::{reconstruct, ReconstructSettings};
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::scene::rig;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

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
    dualphoton::process::keep_freed_memory();
    dualphoton::error::exit_code(run(Args::parse()))
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
    if !(args.budget > 0.0 && args.budget.is_finite()) {
        return Err(Error(format!("--budget: {} is not a positive number of seconds", args.budget)));
    }
    if !(args.refine_budget >= 0.0 && args.refine_budget.is_finite()) {
        return Err(Error(format!("--refine-budget: {} is not a number of seconds >= 0", args.refine_budget)));
    }
    let estimators = args.estimators.clone();
    std::fs::create_dir_all(&args.out)?;
    let started = Instant::now();
    let mut summary = format!(
        "# Error against run time ({}^3 paper rig, {} threads)\n\nRegenerate: `cargo run --release --bin error_vs_time`.\n\n",
        args.res,
        rayon::current_num_threads()
    );
    reconstruction(&args, &estimators, &mut summary)?;
    renderer(&args, &mut summary)?;
    let _ = writeln!(summary, "\nWall time of the whole study: {:.0} s.", started.elapsed().as_secs_f64());
    std::fs::write(args.out.join("summary.md"), &summary)?;
    write_manifest(&args.out.join("manifest.json"), &args, started.elapsed().as_secs_f64())?;
    print!("{summary}");
    Ok(())
}

/// Caps the updates of a run that its time budgets stop.
const UPDATE_CAP: usize = 1_000_000;

/// Part 1: every estimator fits with the main job's settings under the same
/// wall-clock budgets (training, then the refinement, which is reverse mode for all).
fn reconstruction(args: &Args, estimators: &[Estimator], summary: &mut String) -> Result<()> {
    let target_photons = if args.smoke { 20_000 } else { 1_000_000 };
    eprintln!("rendering the targets ...");
    let PaperProblem { truth, scene, images } = paper_problem(args.res, args.seed, target_photons, 0);
    let (targets, held_out) = images.split_at(rig::HELD_OUT_CAMERA);
    let problem = Problem { scene: &scene, targets, held_out, truth: Some(&truth) };

    let mut log = String::from("estimator,iteration,phase,wall_s,train_loss,held_out_rel_rmse,density_rel_l1\n");
    let mut finals =
        String::from("estimator,updates,refine_updates,seconds,density_rel_l1,pearson_r,held_out_rel_rmse\n");
    let (mut eps_series, mut held_series) = (vec![], vec![]);
    let _ = writeln!(
        summary,
        "## Reconstruction under a {:.0} s + {:.0} s budget per estimator\n\n\
         The main job's problem, seed, initial model and fitting (`experiment_table1 --prior none`), each estimator \
         training for {:.0} s (the first 80 % of it at half resolution), then the same per-voxel refinement (reverse \
         mode, whatever the estimator) for {:.0} s. The per-update held-out error comes from that update's own quick \
         render (50,000 photons, 2 spp, half resolution in the coarse phase), so it carries render noise; the final \
         columns re-render the estimate with {target_photons} photons at 8 spp.\n\n\
         | estimator | training updates | refinement updates | final epsilon | final Pearson r | final held-out rel. RMSE |\n\
         |---|---|---|---|---|---|",
        args.budget, args.refine_budget, args.budget, args.refine_budget
    );
    for &estimator in estimators {
        // The budgets stop both parts; the update counts are only caps.
        let mut method = Method::paper().seeded(args.seed);
        method.train.gradient.estimator = estimator;
        (method.train.iterations, method.train.time_budget) = (UPDATE_CAP, Some(args.budget));
        method.refine.updates = if args.refine_budget > 0.0 { UPDATE_CAP } else { 0 };
        method.refine.time_budget = (args.refine_budget > 0.0).then_some(args.refine_budget);
        let settings = ReconstructSettings::new(method, target_photons, 8);
        let result = reconstruct(&problem, &settings, &mut |p| {
            eprint!(
                "\r{}: update {}  {:.0}/{:.0} s  eps {:.3}   ",
                estimator.name(),
                p.row.iteration + 1,
                p.row.wall_s,
                args.budget + args.refine_budget,
                p.row.density_rel_l1
            );
        })?;
        eprintln!();
        let rows = &result.log;
        let (trained, refined) = (result.trained, rows.len() - result.trained);
        for (i, r) in rows.iter().enumerate() {
            let phase = if i < trained { "train" } else { "refine" };
            let _ = writeln!(
                log,
                "{},{},{phase},{:.3},{:.6e},{:.6},{:.6}",
                estimator.name(),
                r.iteration,
                r.wall_s,
                r.train_loss,
                r.held_out_rel_rmse,
                r.density_rel_l1
            );
        }
        let estimated = &result.estimated;
        let eps = rel_l1(&estimated.data, &truth.data, &result.model.mask);
        let r = pearson(&truth.data, &estimated.data, &result.model.mask);
        let held = rel_rmse(&result.final_images[rig::HELD_OUT_CAMERA].data, &held_out[0].data);
        let seconds = rows.last().map_or(0.0, |r| r.wall_s);
        let _ = writeln!(finals, "{},{trained},{refined},{seconds:.2},{eps:.6},{r:.6},{held:.6}", estimator.name());
        let _ = writeln!(
            summary,
            "| `{}` | {trained} | {refined} | {eps:.3} | {r:.3} | {:.1} % |",
            estimator.name(),
            100.0 * held
        );
        eps_series.push(Series {
            name: estimator.name().into(),
            points: rows.iter().map(|r| (r.wall_s, r.density_rel_l1)).collect(),
            markers: false,
        });
        held_series.push(Series {
            name: estimator.name().into(),
            points: rows.iter().map(|r| (r.wall_s, 100.0 * r.held_out_rel_rmse)).collect(),
            markers: false,
        });
    }
    std::fs::write(args.out.join("reconstruction.csv"), log)?;
    std::fs::write(args.out.join("reconstruction_final.csv"), finals)?;
    let axes = |title, y| Axes { title, x: "wall-clock time (s, 2 cores)", y, log_x: false, log_y: true };
    line_chart(
        &args.out.join("reconstruction_epsilon.svg"),
        &axes("Density error against fitting time", "voxel relative L1 error epsilon"),
        &eps_series,
    )?;
    line_chart(
        &args.out.join("reconstruction_held_out.svg"),
        &axes("Held-out camera error against fitting time", "held-out relative RMSE (%, per-update render)"),
        &held_series,
    )?;
    Ok(())
}

/// One renderer configuration: photon mapping or the path tracer.
#[derive(Serialize)]
struct RendererRow {
    method: &'static str,
    photons: Option<u64>,
    radius_voxels: Option<f64>,
    spp: u32,
    seconds: f64,
    block_rel_rmse: f64,
}

/// Part 2: photon mapping over photon counts and radii, and the path tracer, against the reference.
fn renderer(args: &Args, summary: &mut String) -> Result<()> {
    let scene = rig::paper_training_scene(dualphoton::data::plume::plume(args.res, args.seed), args.res);
    eprintln!("renderer: reference at {} spp ({})", args.ref_spp, args.reference_dir.display());
    let reference = reference(&scene, args.seed, args.ref_spp, &args.reference_dir)?;
    let noise = reference_noise(&reference.radiance, &reference.std_err, ERROR_BLOCK);
    let _ = writeln!(
        summary,
        "\n## Renderer error against render time\n\n\
         Block (4x4) relative RMSE of the 4 training cameras against a {} spp path-traced reference (its own noise, \
         {:.2} %, removed). Photon mapping uses {} spp at the camera; time is the median of {} renders.\n\n\
         | method | photons | radius (voxels) | spp | time (s) | block rel. RMSE |\n|---|---|---|---|---|---|",
        args.ref_spp,
        100.0 * noise,
        scene.render.spp,
        args.repeats
    );
    let spp = scene.render.spp;
    let points = photon_sweep(&scene, &reference, &args.photons, &args.radii, |_| args.repeats);
    let mut rows: Vec<RendererRow> = points
        .iter()
        .map(|p| RendererRow {
            method: "photon",
            photons: Some(p.photons),
            radius_voxels: Some(p.radius_voxels),
            spp,
            seconds: p.seconds,
            block_rel_rmse: p.block_rel_rmse,
        })
        .collect();
    for &spp in &args.path_spp {
        let opts = PathOptions { spp, seed: 99, max_order: None, min_order: 1 };
        let t = Instant::now();
        let r = render_path(&scene, &opts);
        let seconds = t.elapsed().as_secs_f64();
        let block_rel_rmse = error(&r.radiance, &reference);
        eprintln!("  path tracing: {spp} spp: {seconds:.3} s, {:.2} %", 100.0 * block_rel_rmse);
        rows.push(RendererRow { method: "path", photons: None, radius_voxels: None, spp, seconds, block_rel_rmse });
    }
    for r in &rows {
        let (name, opt) = (if r.method == "path" { "path tracing" } else { "photon mapping" }, |v: Option<String>| {
            v.unwrap_or_default()
        });
        let _ = writeln!(
            summary,
            "| {name} | {} | {} | {} | {:.3} | {:.2} % |",
            opt(r.photons.map(|p| p.to_string())),
            opt(r.radius_voxels.map(|v| v.to_string())),
            r.spp,
            r.seconds,
            100.0 * r.block_rel_rmse
        );
    }
    let mut series: Vec<Series> = args
        .radii
        .iter()
        .map(|radius| Series {
            name: format!("photon mapping, r = {radius} vox"),
            points: rows
                .iter()
                .filter(|r| r.radius_voxels == Some(*radius))
                .map(|r| (r.seconds, 100.0 * r.block_rel_rmse))
                .collect(),
            markers: true,
        })
        .collect();
    series.push(Series {
        name: "path tracing (unbiased)".into(),
        points: rows.iter().filter(|r| r.method == "path").map(|r| (r.seconds, 100.0 * r.block_rel_rmse)).collect(),
        markers: true,
    });
    write_rows(&args.out.join("renderer.csv"), &rows)?;
    line_chart(
        &args.out.join("renderer_error_vs_time.svg"),
        &Axes {
            title: "Renderer error against render time",
            x: "render time (s, 2 cores)",
            y: "block relative RMSE vs reference (%)",
            log_x: true,
            log_y: true,
        },
        &series,
    )
}
