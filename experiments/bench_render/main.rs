//! Renderer speed and accuracy on the paper rig.
//!
//! For each resolution (64^3 with 64x64 images, 128^3 with 128x128): the
//! four training cameras, three lights, up to 3rd order, the built-in plume.
//! Writes into `results/bench_render/`:
//! - `timing.csv`: stage times (median of repeats) at 300,000 photons and
//!   the default kernel radius; photons per second;
//! - `sweep.csv` + `error_vs_time.svg`: block relative RMSE against a
//!   converged path-traced reference as photon count and kernel radius vary;
//! - `shadows.csv`: the lights' transmittance from the light-depth grids
//!   (default, and one node per voxel) against marched shadow rays, for
//!   single scattering alone (the only order it enters) and for orders 1-3,
//!   against references of the same orders; and blurred plumes (the
//!   built-in one blurred: an eighth and a quarter of the box) seen by all
//!   five cameras; and the built-in plume with its densest voxel (or 8)
//!   made twice too deep for the grids, where `auto` marches near them;
//! - `blurred.csv`: the blurred plumes' stage times at the defaults;
//! - `summary.md`, `manifest.json`;
//! - `reference_<res>/`, `reference_blur<blur>_<res>/`: the reference
//!   images (rendered once, reused when their manifest matches).
//!
//! `--res` with no value leaves out the built-in plume: only the blurred
//! plumes are measured (a few minutes).
//!
//! `--smoke` runs a tiny version (for tests of this binary).

use clap::Parser;
use dualphoton::data::plume::{plume, plume_stats};
use dualphoton::error::Result;
use dualphoton::eval::metrics::{reference_noise, rel_mean_diff};
use dualphoton::eval::reference::{self, REF_SEED};
use dualphoton::eval::scenes::blurred_plume;
use dualphoton::eval::sweep::{error, median_of, photon_sweep, shadow_comparison, timed, ERROR_BLOCK};
use dualphoton::experiment::{self, Run};
use dualphoton::io::plot::Series;
use dualphoton::scene::{rig, Scene, GRID_MAX_DEPTH};
use dualphoton::volume::Grid;
use rows::{BlurredRow, ShadowRow, SweepRow, Tables, TimingRow};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;

mod rows;
mod write;

#[derive(Parser, Serialize)]
#[command(about = "Photon-mapping speed and error against a path-traced reference on the paper rig")]
struct Args {
    /// Resolutions to run (grid res^3, images res x res); none: only the blurred plumes.
    #[arg(long, value_delimiter = ',', num_args = 0.., default_value = "64,128")]
    res: Vec<usize>,
    /// Samples per pixel of the path-traced reference, per resolution (same order as --res).
    #[arg(long, value_delimiter = ',', default_value = "16384,4096")]
    ref_spp: Vec<u32>,
    /// Timed repeats per configuration (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Photon counts of the sweep.
    #[arg(long, value_delimiter = ',', default_value = "30000,100000,300000,500000,1000000,3000000")]
    photons: Vec<u64>,
    /// Kernel radii of the sweep, in voxels.
    #[arg(long, value_delimiter = ',', default_value = "1,1.5,2,3")]
    radii: Vec<f64>,
    /// Resolution of the blurred plumes (0: leave them out).
    #[arg(long, default_value_t = 64)]
    thick_res: usize,
    /// Blurs of the blurred plumes, in voxels at 64^3 (scaled with the resolution).
    #[arg(long, value_delimiter = ',', default_value = "3,5")]
    blurs: Vec<f64>,
    /// Samples per pixel of the blurred plumes' references.
    #[arg(long, default_value_t = 4096)]
    thick_ref_spp: u32,
    /// At `--thick-res`, the built-in plume with this many of its densest
    /// voxels made twice too deep for the light-depth grids, each a case
    /// of the shadows' comparison.
    #[arg(long, value_delimiter = ',', default_value = "1,8")]
    thick_voxels: Vec<usize>,
    /// Output directory.
    #[arg(long, default_value = "results/bench_render")]
    out: PathBuf,
    /// Tiny sizes, for a quick check that the binary works.
    #[arg(long)]
    smoke: bool,
}

/// Seed of the plume.
const SEED: u64 = 0;

/// What the manifest records besides provenance.
#[derive(Serialize)]
struct Manifest<'a> {
    #[serde(flatten)]
    settings: &'a Args,
    plume_seed: u64,
    reference_seed: u64,
}

fn main() -> std::process::ExitCode {
    experiment::main(run)
}

impl Args {
    /// The tiny sizes of `--smoke`.
    fn smoke(&mut self) {
        // An empty --res stays empty: only the blurred plumes.
        self.res.truncate(1);
        self.res.iter_mut().for_each(|r| *r = 16);
        self.ref_spp = vec![64];
        self.repeats = 1;
        self.photons = vec![10_000, 30_000];
        self.radii = vec![1.0, 2.0];
        self.thick_res = 16;
        self.thick_ref_spp = 64;
    }
}

fn run(mut args: Args) -> Result<()> {
    if args.smoke {
        args.smoke();
    }
    args.res
        .iter()
        .chain(std::iter::once(&args.thick_res).filter(|&&r| r > 0))
        .try_for_each(|&r| experiment::check_res(r))?;
    let run = Run::start(&args.out)?;
    let (mut tables, mut series) = (Tables::default(), vec![]);
    let mut summary =
        String::from("# Renderer speed and error (paper rig, 4 training cameras, 3 lights, orders 1-3)\n\n");
    for (n, &res) in args.res.iter().enumerate() {
        let spp = args.ref_spp.get(n).copied().unwrap_or(4096);
        measure_res(&args, res, spp, &mut tables, &mut series, &mut summary)?;
    }
    if args.thick_res > 0 {
        measure_blurred(&args, &mut tables)?;
        measure_thick_voxels(&args, &mut tables)?;
    }
    write::blurred_table(&mut summary, &tables.blurred);
    write::shadows_table(&mut summary, &tables.shadows);
    write::files(&run, &tables, &series)?;
    let _ = writeln!(
        summary,
        "Regenerate: `cargo run --release --bin bench_render{}` ({:.0} s).",
        write::command_options(),
        run.seconds()
    );
    std::fs::write(run.path("summary.md"), &summary)?;
    run.write_manifest(&Manifest { settings: &args, plume_seed: SEED, reference_seed: REF_SEED })?;
    print!("{summary}");
    Ok(())
}

/// The built-in plume at one resolution: stage times, the lights'
/// transmittance, error against time over photon count and radius.
fn measure_res(
    args: &Args,
    res: usize,
    spp: u32,
    tables: &mut Tables,
    series: &mut Vec<Series>,
    summary: &mut String,
) -> Result<()> {
    let scene = rig::paper_training_scene(plume(res, SEED), res);
    eprintln!("res {res}: reference at {spp} spp");
    let reference = reference::reference(&scene, SEED, spp, &args.out.join(format!("reference_{res}")))?;
    let noise = reference_noise(&reference.radiance, &reference.std_err, ERROR_BLOCK);
    let voxel = scene.density.voxel_size().max();

    // Stage timing at the defaults, plus a single-scattering-only render.
    let (r, times) = timed(&scene, args.repeats);
    let mut single_scene = scene.clone();
    single_scene.medium.max_order = 1;
    let row = TimingRow {
        res,
        photons: scene.render.photons,
        stored_photons: r.stored_photons,
        trace_s: median_of(&times, |t| t.trace),
        gather_s: median_of(&times, |t| t.gather),
        shadows_s: median_of(&times, |t| t.shadows),
        camera_s: median_of(&times, |t| t.camera),
        single_scattering_only_s: median_of(&timed(&single_scene, args.repeats).1, |t| t.total),
        total_s: median_of(&times, |t| t.total),
        photons_per_s: scene.render.photons as f64 / median_of(&times, |t| t.trace),
        block_rel_rmse: error(&r.images, &reference),
        threads: rayon::current_num_threads(),
    };
    let _ = writeln!(
        summary,
        "## {res}^3, {res}x{res} images\n\n- reference: {spp} spp path tracing, block (4x4) noise {:.2} %\n\
         - default render ({} photons, radius {:.1} voxels): total {:.3} s (median of {}; {} threads): tracing {:.3} s ({:.2} M photons/s), gathering {:.3} s, light-depth grids {:.3} s, camera rays {:.3} s; single scattering alone {:.3} s\n\
         - block relative RMSE against the reference (its noise removed): {:.2} %, image-sum difference {:+.2} %\n",
        100.0 * noise,
        row.photons,
        scene.render.kernel_radius_for(&scene.density) / voxel,
        row.total_s,
        args.repeats,
        row.threads,
        row.trace_s,
        row.photons_per_s / 1e6,
        row.gather_s,
        row.shadows_s,
        row.camera_s,
        row.single_scattering_only_s,
        100.0 * row.block_rel_rmse,
        100.0 * rel_mean_diff(&r.images, &reference.radiance),
    );
    tables.timing.push(row);

    // The lights' transmittance: single scattering alone, where it enters, and all orders.
    let single_reference =
        reference::reference(&single_scene, SEED, spp, &args.out.join(format!("reference_{res}_order1")))?;
    for (orders, s, rf) in [("1", &single_scene, &single_reference), ("1-3", &scene, &reference)] {
        eprintln!("res {res}, orders {orders}:");
        for point in shadow_comparison(s, rf, args.repeats) {
            tables.shadows.push(ShadowRow::new("plume".into(), res, s.cameras.len(), orders, point));
        }
    }

    // Error against time over photon count and radius.
    let _ = writeln!(
        summary,
        "| photons | radius (voxels) | time (s) | block rel. RMSE | image-sum diff |\n|---|---|---|---|---|"
    );
    let repeats = |photons: u64| if photons >= 1_000_000 { args.repeats.min(3) } else { args.repeats };
    let points = photon_sweep(&scene, &reference, &args.photons, &args.radii, repeats);
    for p in &points {
        let _ = writeln!(
            summary,
            "| {} | {} | {:.3} | {:.2} % | {:+.2} % |",
            p.photons,
            p.radius_voxels,
            p.seconds,
            100.0 * p.block_rel_rmse,
            100.0 * p.mean_rel_diff
        );
    }
    for radius in &args.radii {
        series.push(Series {
            name: format!("{res}^3, r = {radius} vox"),
            points: points
                .iter()
                .filter(|p| p.radius_voxels == *radius)
                .map(|p| (p.seconds, 100.0 * p.block_rel_rmse))
                .collect(),
            markers: true,
        });
    }
    tables.sweep.extend(points.into_iter().map(|p| SweepRow::new(res, p)));
    summary.push('\n');
    Ok(())
}

/// The blurred plumes at `--thick-res`: first the built-in plume's default
/// render, as in `timing.csv` (4 training cameras: this run's machine against
/// the one that wrote another run's rows), then each blur's stage times and
/// the lights' transmittance against its reference.
fn measure_blurred(args: &Args, tables: &mut Tables) -> Result<()> {
    let res = args.thick_res;
    for blur in std::iter::once(0.0).chain(args.blurs.iter().copied()) {
        let scene = if blur > 0.0 {
            rig::paper_scene(blurred_plume(res, SEED, blur), res)
        } else {
            rig::paper_training_scene(plume(res, SEED), res)
        };
        let occupied = plume_stats(&scene.density).fraction_occupied;
        let (_, times) = timed(&scene, args.repeats);
        tables.blurred.push(BlurredRow {
            res,
            blur_voxels: blur,
            occupied,
            cameras: scene.cameras.len(),
            trace_s: median_of(&times, |t| t.trace),
            gather_s: median_of(&times, |t| t.gather),
            shadows_s: median_of(&times, |t| t.shadows),
            camera_s: median_of(&times, |t| t.camera),
            total_s: median_of(&times, |t| t.total),
            threads: rayon::current_num_threads(),
        });
        if blur <= 0.0 {
            continue;
        }
        let name = format!("plume blurred by {blur} voxels ({:.0} % occupied)", 100.0 * occupied);
        compare_shadows(args, tables, &scene, &name, &format!("reference_blur{blur}_{res}"))?;
    }
    Ok(())
}

/// The built-in plume at `--thick-res` with a few of its densest voxels
/// made twice too deep for the light-depth grids (`GRID_MAX_DEPTH`): the
/// lights' transmittance against its reference and against marched shadow
/// rays, where `auto` shadows march near those voxels only.
fn measure_thick_voxels(args: &Args, tables: &mut Tables) -> Result<()> {
    let res = args.thick_res;
    for &n in &args.thick_voxels {
        let scene = rig::paper_scene(thickened(plume(res, SEED), n, res), res);
        let name =
            if n == 1 { "plume, densest voxel 2 deep".into() } else { format!("plume, {n} densest voxels 2 deep") };
        compare_shadows(args, tables, &scene, &name, &format!("reference_thick{n}_{res}"))?;
    }
    Ok(())
}

/// `scene`'s shadow estimators against its reference (cached in
/// `--out`/`reference_dir`) and against marched shadow rays, as rows `name`.
fn compare_shadows(args: &Args, tables: &mut Tables, scene: &Scene, name: &str, reference_dir: &str) -> Result<()> {
    let res = args.thick_res;
    eprintln!("{name} {res}^3: reference at {} spp", args.thick_ref_spp);
    let rf = reference::reference(scene, SEED, args.thick_ref_spp, &args.out.join(reference_dir))?;
    for point in shadow_comparison(scene, &rf, args.repeats) {
        tables.shadows.push(ShadowRow::new(name.to_string(), res, scene.cameras.len(), "1-3", point));
    }
    Ok(())
}

/// `density` with its `n` densest voxels raised to an optical depth of
/// twice [`GRID_MAX_DEPTH`] across a voxel in the paper scene at `res`.
fn thickened(mut density: Grid<f64>, n: usize, res: usize) -> Grid<f64> {
    let depth_per_unit = rig::paper_scene(density.clone(), res).medium.sigma_t_scale * density.voxel_size().max();
    let mut order: Vec<usize> = (0..density.len()).collect();
    order.sort_by(|&a, &b| density.data[b].total_cmp(&density.data[a]).then(a.cmp(&b)));
    for &v in order.iter().take(n) {
        density.data[v] = 2.0 * GRID_MAX_DEPTH / depth_per_unit;
    }
    density
}
