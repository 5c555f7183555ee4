//! Renderer speed and accuracy on the paper rig (issue 2, item 7).
//!
//! For each resolution (64^3 with 64x64 images, 128^3 with 128x128): the
//! four training cameras, three lights, up to 3rd order, the built-in plume.
//! Writes into `results/bench_render/`:
//! - `timing.csv`: stage times (median of repeats) at 300,000 photons and
//!   the default kernel radius; photons per second;
//! - `sweep.csv` + `error_vs_time.svg`: block relative RMSE against a
//!   converged path-traced reference as photon count and kernel radius vary;
//! - `summary.md`, `manifest.json`;
//! - `reference_<res>/`: the reference images (rendered once, reused when
//!   their manifest matches).
//!
//! `--smoke` runs a tiny version (for tests of this binary).

use clap::Parser;
use dualphoton::data::plume::plume;
use dualphoton::error::Result;
use dualphoton::eval::metrics::{block_rel_rmse, reference_noise, rel_mean_diff};
use dualphoton::eval::reference::{reference, REF_SEED};
use dualphoton::eval::stats::median;
use dualphoton::io::manifest::{git_revision, write_json};
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::render::photon::Timings;
use dualphoton::render::{render_photon, PhotonRender};
use dualphoton::scene::{rig, Scene};
use serde_json::json;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(about = "Photon-mapping speed and error against a path-traced reference on the paper rig")]
struct Args {
    /// Resolutions to run (grid res^3, images res x res).
    #[arg(long, value_delimiter = ',', default_value = "64,128")]
    res: Vec<usize>,
    /// Samples per pixel of the path-traced reference, per resolution (same order as --res).
    #[arg(long, value_delimiter = ',', default_value = "16384,4096")]
    ref_spp: Vec<u32>,
    /// Timed repeats per configuration (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Photon counts of the sweep.
    #[arg(long, value_delimiter = ',', default_value = "30000,100000,300000,1000000,3000000")]
    photons: Vec<u64>,
    /// Kernel radii of the sweep, in voxels.
    #[arg(long, value_delimiter = ',', default_value = "1,1.5,2,3")]
    radii: Vec<f64>,
    /// Output directory.
    #[arg(long, default_value = "results/bench_render")]
    out: PathBuf,
    /// Tiny sizes, for a quick check that the binary works.
    #[arg(long)]
    smoke: bool,
}

/// Seed of the plume.
const SEED: u64 = 0;

fn training_scene(res: usize) -> Scene {
    let mut scene = rig::paper_scene(plume(res, SEED), res);
    scene.cameras.truncate(4);
    scene
}

/// The last of `repeats` renders, and the stage times of all of them.
fn timed(scene: &Scene, repeats: usize) -> (PhotonRender, Vec<Timings>) {
    let mut times = vec![];
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let r = render_photon(scene);
        times.push(r.timings.clone());
        last = Some(r);
    }
    (last.unwrap(), times)
}

/// Median of one stage's time over repeats.
fn median_of(times: &[Timings], stage: fn(&Timings) -> f64) -> f64 {
    median(&times.iter().map(stage).collect::<Vec<_>>())
}

fn main() -> std::process::ExitCode {
    dualphoton::error::exit_code(run(Args::parse()))
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.res = vec![16];
        args.ref_spp = vec![64];
        args.repeats = 1;
        args.photons = vec![10_000, 30_000];
        args.radii = vec![1.0, 2.0];
    }
    std::fs::create_dir_all(&args.out)?;
    let started = Instant::now();
    let mut timing =
        csv::Writer::from_path(args.out.join("timing.csv")).map_err(|e| dualphoton::Error(e.to_string()))?;
    timing
        .write_record([
            "res",
            "photons",
            "stored_photons",
            "trace_s",
            "gather_s",
            "camera_s",
            "single_scattering_only_s",
            "total_s",
            "photons_per_s",
            "block_rel_rmse",
            "threads",
        ])
        .map_err(|e| dualphoton::Error(e.to_string()))?;
    let mut sweep = csv::Writer::from_path(args.out.join("sweep.csv")).map_err(|e| dualphoton::Error(e.to_string()))?;
    sweep
        .write_record(["res", "photons", "radius_voxels", "radius", "total_s", "block_rel_rmse", "mean_rel_diff"])
        .map_err(|e| dualphoton::Error(e.to_string()))?;
    let mut summary =
        String::from("# Renderer speed and error (paper rig, 4 training cameras, 3 lights, orders 1-3)\n\n");
    let mut series = vec![];
    for (n, &res) in args.res.iter().enumerate() {
        let spp = args.ref_spp.get(n).copied().unwrap_or(4096);
        let scene = training_scene(res);
        eprintln!("res {res}: reference at {spp} spp");
        let reference = reference(&scene, SEED, spp, &args.out.join(format!("reference_{res}")))?;
        let noise = reference_noise(&reference.radiance, &reference.std_err, 4);
        let voxel = scene.density.voxel_size().max();

        // Stage timing at the defaults, plus a single-scattering-only render.
        let (r, times) = timed(&scene, args.repeats);
        let trace = median_of(&times, |t| t.trace);
        let gather = median_of(&times, |t| t.gather);
        let camera = median_of(&times, |t| t.camera);
        let total = median_of(&times, |t| t.total);
        let mut single_scene = scene.clone();
        single_scene.medium.max_order = 1;
        let single = median_of(&timed(&single_scene, args.repeats).1, |t| t.total);
        let err = block_rel_rmse(&r.images, &reference.radiance, Some(&reference.std_err), 4);
        let threads = rayon::current_num_threads();
        timing
            .write_record([
                res.to_string(),
                scene.render.photons.to_string(),
                r.stored_photons.to_string(),
                format!("{trace:.4}"),
                format!("{gather:.4}"),
                format!("{camera:.4}"),
                format!("{single:.4}"),
                format!("{total:.4}"),
                format!("{:.0}", scene.render.photons as f64 / trace),
                format!("{err:.4}"),
                threads.to_string(),
            ])
            .map_err(|e| dualphoton::Error(e.to_string()))?;
        let _ = writeln!(
            summary,
            "## {res}^3, {res}x{res} images\n\n- reference: {spp} spp path tracing, block (4x4) noise {:.2} %\n\
             - default render ({} photons, radius {:.1} voxels): total {:.3} s (median of {}; {threads} threads): tracing {:.3} s ({:.2} M photons/s), gathering {:.3} s, camera rays {:.3} s; single scattering alone {:.3} s\n\
             - block relative RMSE against the reference (its noise removed): {:.2} %, image-sum difference {:+.2} %\n",
            100.0 * noise,
            scene.render.photons,
            scene.render.kernel_radius_for(&scene.density) / voxel,
            total,
            args.repeats,
            trace,
            scene.render.photons as f64 / trace / 1e6,
            gather,
            camera,
            single,
            100.0 * err,
            100.0 * rel_mean_diff(&r.images, &reference.radiance),
        );

        // Error against time over photon count and radius.
        let _ = writeln!(
            summary,
            "| photons | radius (voxels) | time (s) | block rel. RMSE | image-sum diff |\n|---|---|---|---|---|"
        );
        for &radius in &args.radii {
            let mut points = vec![];
            for &photons in &args.photons {
                let mut s = scene.clone();
                s.render.photons = photons;
                s.render.kernel_radius = Some(radius * voxel);
                let reps = if photons >= 1_000_000 { args.repeats.min(3) } else { args.repeats };
                let (r, times) = timed(&s, reps);
                let t = median_of(&times, |t| t.total);
                let e = block_rel_rmse(&r.images, &reference.radiance, Some(&reference.std_err), 4);
                let d = rel_mean_diff(&r.images, &reference.radiance);
                eprintln!("  {photons} photons, radius {radius} voxels: {t:.3} s, block rel RMSE {:.2} %", 100.0 * e);
                sweep
                    .write_record([
                        res.to_string(),
                        photons.to_string(),
                        radius.to_string(),
                        format!("{:.5}", radius * voxel),
                        format!("{t:.4}"),
                        format!("{e:.5}"),
                        format!("{d:.5}"),
                    ])
                    .map_err(|e| dualphoton::Error(e.to_string()))?;
                let _ =
                    writeln!(summary, "| {photons} | {radius} | {t:.3} | {:.2} % | {:+.2} % |", 100.0 * e, 100.0 * d);
                points.push((t, 100.0 * e));
            }
            series.push(Series { name: format!("{res}^3, r = {radius} vox"), points, markers: true });
        }
        summary.push('\n');
    }
    timing.flush()?;
    sweep.flush()?;
    line_chart(
        &args.out.join("error_vs_time.svg"),
        &Axes {
            title: "Photon mapping: error against render time (photon count swept)",
            x: "render time (s, 2 cores)",
            y: "block relative RMSE vs path tracer (%)",
            log_x: true,
            log_y: true,
        },
        &series,
    )?;
    let _ = writeln!(
        summary,
        "Regenerate: `cargo run --release --bin bench_render` ({:.0} s).",
        started.elapsed().as_secs_f64()
    );
    std::fs::write(args.out.join("summary.md"), &summary)?;
    write_json(
        &args.out.join("manifest.json"),
        &json!({"res": args.res, "ref_spp": args.ref_spp, "repeats": args.repeats, "photons": args.photons,
                "radii_voxels": args.radii, "plume_seed": SEED, "reference_seed": REF_SEED,
                "threads": rayon::current_num_threads(), "git": git_revision(), "seconds": started.elapsed().as_secs_f64()}),
    )?;
    print!("{summary}");
    Ok(())
}
