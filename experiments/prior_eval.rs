//! Evaluates the learned prior against the paper's per-scene decoder on
//! plumes no part of training saw: test plumes from the training
//! distribution (unseen seeds), the Table 1 plume, and plumes deliberately
//! outside it (three sources, still air, strong turbulence, cut off by the
//! top of the box, thick and smooth), and the Table 1 plume in images of
//! another renderer (the path tracer). Every plume is seen by the paper's rig
//! (4 training cameras, camera 4 held out) and reconstructed by
//! - `paper`: the per-scene decoder (the main job's default settings),
//! - `prior`: the prior's latent only (fwd-full over its 64 coordinates),
//! - `prior_refine`: that, then the per-voxel refinement;
//! - `prior_tune` (a study, on request): the latent fit, then latent and
//!   decoder weights fine-tuned near the prior; `prior_tune_refine`: then
//!   the refinement.
//! - `oracle` (a study, on request): starts no reconstruction could have,
//!   each measured as it is and after the prior's refinement: the truth
//!   blurred as the prior learned it (`oracle_truth`, a perfect prior), and
//!   the prior's latent fitted to that blurred truth directly, without
//!   rendering (`oracle_latent`, the best the latent can represent); and
//!   the truth itself, measured only (`oracle_exact`: its held-out error is
//!   the render noise's floor).
//!
//! Resumable: each (plume, method) row is written as it finishes under
//! `<out>/rows/`, and a later run skips the rows it finds (`--fresh`
//! recomputes). The estimates are cached under `cache/<name of --out>/` for the
//! slice figures. Writes `<out>/{table.csv, table.md, scatter.svg,
//! slices_<plume>.svg, manifest.json}`.

use clap::Parser;
use dualphoton::data::plume::variation::{TEST_SEEDS, VALIDATION_SEEDS};
use dualphoton::data::plume::{plume, plume_with, unusual_plume, Unusual, Variation};
use dualphoton::error::{Error, Result};
use dualphoton::eval::density::{density_metrics, DensityMetrics};
use dualphoton::eval::metrics::{block_mask, block_means, rel_rmse};
use dualphoton::image::Image;
use dualphoton::io::figures::estimate_scatter;
use dualphoton::io::manifest::write_manifest;
use dualphoton::io::npy;
use dualphoton::io::panels::labelled_strip;
use dualphoton::io::rows::write_rows;
use dualphoton::prior::train::fit_latent;
use dualphoton::prior::Prior;
use dualphoton::recon::hull::{visual_hull, HullSettings};
use dualphoton::recon::methods::{
    paper_method, prior_method, prior_tuning, PaperFitArgs, PriorFitArgs, PriorTuneArgs, UpdateRenders,
};
use dualphoton::recon::paper;
use dualphoton::recon::problem::{paper_problem_of, target_render, PaperProblem, Problem};
use dualphoton::recon::reconstruct::{prior_model, reconstruct, ReconstructSettings};
use dualphoton::recon::refine::{refine, refine_density};
use dualphoton::recon::train::train;
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::render::render_photon;
use dualphoton::scene::rig;
use dualphoton::volume::blur::gaussian_blur;
use dualphoton::volume::Grid;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Parser, Serialize)]
#[command(about = "Evaluate the learned prior against the paper's per-scene decoder on unseen plumes")]
struct Args {
    /// Grid resolution (res^3) and image size.
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Plumes, comma-separated: table1, test0..test99, val0..val99 (validation: for choosing settings,
    /// never reported as test), three_sources, no_drafts, strong_turbulence, cut_off, smooth,
    /// table1_path (the Table 1 plume, its images path-traced); default: table1, test0-test7, the
    /// five unusual plumes and table1_path.
    #[arg(long)]
    plumes: Option<String>,
    /// Methods, comma-separated: paper, prior (also writes prior_refine when --prior-refine > 0),
    /// prior_tune (a study: the latent fit, then --prior-tune updates of latent and decoder weights; also
    /// writes prior_tune_refine), oracle (a study: the prior's refinement from the blurred truth,
    /// oracle_truth[_refine], and from the latent fitted to it without rendering, oracle_latent[_refine]; also
    /// oracle_exact, the truth measured as an estimate).
    #[arg(long, default_value = "paper,prior")]
    methods: String,
    /// The prior's directory.
    #[arg(long, default_value = "models/plume64")]
    prior: PathBuf,
    #[command(flatten)]
    fit: PriorFitArgs,
    #[command(flatten)]
    tune: PriorTuneArgs,
    #[command(flatten)]
    #[serde(flatten)]
    paper_fit: PaperFitArgs,
    #[command(flatten)]
    #[serde(flatten)]
    renders: UpdateRenders,
    /// Silhouette threshold of the visual hull (fraction of each image's 99.5th-percentile radiance).
    #[arg(long, default_value_t = dualphoton::recon::hull::SILHOUETTE_THRESHOLD)]
    hull_threshold: f64,
    /// Silhouette dilation of the visual hull (pixels).
    #[arg(long, default_value_t = dualphoton::recon::hull::SILHOUETTE_DILATION)]
    hull_dilate: usize,
    /// Samples per pixel of the path-traced images of `table1_path`.
    #[arg(long, default_value_t = 4096)]
    path_spp: u32,
    /// Recompute rows that exist.
    #[arg(long)]
    fresh: bool,
    /// Output directory.
    #[arg(long, default_value = "results/prior_eval")]
    out: PathBuf,
}

/// The methods `--methods` names.
const METHODS: [&str; 4] = ["paper", "prior", "prior_tune", "oracle"];
/// The rows a plume can have, in table order.
const ROWS: [&str; 10] = [
    "paper",
    "prior",
    "prior_refine",
    "prior_tune",
    "prior_tune_refine",
    "oracle_exact",
    "oracle_truth",
    "oracle_truth_refine",
    "oracle_latent",
    "oracle_latent_refine",
];
/// The rows a method writes: a method runs again while any of them is missing (a
/// latent fit whose refinement was cut off is fitted again; the fit is deterministic).
fn rows_of(method: &str, refine_updates: usize) -> Vec<String> {
    let refined =
        |m: &str| if refine_updates > 0 { vec![m.to_string(), format!("{m}_refine")] } else { vec![m.to_string()] };
    match method {
        "oracle" => ROWS.iter().filter(|r| r.starts_with("oracle")).map(|r| r.to_string()).collect(),
        "paper" => vec!["paper".into()],
        m => refined(m),
    }
}

/// The blur (voxels) `train_prior` learned its plumes with (models/plume64/manifest.json).
const PRIOR_BLUR: f64 = 1.0;

/// One plume of the evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Which {
    Table1,
    /// The Table 1 plume, its images made by the path tracer (another renderer) instead of the photon mapper.
    PathTraced,
    Test(u64),
    Validation(u64),
    Unusual(Unusual),
}

impl Which {
    fn parse(name: &str) -> Result<Which> {
        let number = |prefix: &str, range: &std::ops::Range<u64>| {
            name.strip_prefix(prefix).and_then(|n| n.parse::<u64>().ok()).filter(|&n| n < range.end - range.start)
        };
        if name == "table1" {
            return Ok(Which::Table1);
        }
        if name == "table1_path" {
            return Ok(Which::PathTraced);
        }
        if let Some(n) = number("test", &TEST_SEEDS) {
            return Ok(Which::Test(n));
        }
        if let Some(n) = number("val", &VALIDATION_SEEDS) {
            return Ok(Which::Validation(n));
        }
        Unusual::ALL
            .iter()
            .find(|u| u.name() == name)
            .map(|&u| Which::Unusual(u))
            .ok_or_else(|| Error(format!("--plumes: unknown plume '{name}'")))
    }

    fn name(self) -> String {
        match self {
            Which::Table1 => "table1".into(),
            Which::PathTraced => "table1_path".into(),
            Which::Test(n) => format!("test{n}"),
            Which::Validation(n) => format!("val{n}"),
            Which::Unusual(u) => u.name().into(),
        }
    }

    /// `training distribution`, `unusual` or `validation`.
    fn group(self) -> &'static str {
        match self {
            Which::Table1 | Which::Test(_) => "training distribution",
            Which::Validation(_) => "validation",
            Which::Unusual(_) | Which::PathTraced => "unusual",
        }
    }

    fn seed(self) -> u64 {
        match self {
            Which::Table1 | Which::PathTraced => 0,
            Which::Test(n) => TEST_SEEDS.start + n,
            Which::Validation(n) => VALIDATION_SEEDS.start + n,
            Which::Unusual(u) => u.seed(),
        }
    }

    fn truth(self, res: usize) -> Result<Grid<f64>> {
        match self {
            Which::Table1 | Which::PathTraced => Ok(plume(res, 0)),
            Which::Test(_) | Which::Validation(_) => plume_with(res, self.seed(), &Variation::sample(self.seed())),
            Which::Unusual(u) => Ok(unusual_plume(res, u)),
        }
    }
}

/// One (plume, method) result.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Row {
    plume: String,
    group: String,
    method: String,
    hull_voxels: usize,
    /// Voxels of the hull the fit ran in (None in rows written before it was recorded: the default hull).
    #[serde(default)]
    fit_hull_voxels: Option<usize>,
    /// Fraction of the truth's mass outside the fit's hull (None in rows written before it was recorded).
    #[serde(default)]
    carved_mass: Option<f64>,
    block_pearson_r: f64,
    block_rel_l1_epsilon: f64,
    block_max_error: f64,
    pearson_r: f64,
    rel_l1_epsilon: f64,
    max_error: f64,
    mass_error: f64,
    held_out_rel_rmse: f64,
    blur_ceiling_r: f64,
    /// Fraction of the truth's mass in voxels the estimate leaves at 0 (None in rows written before it was recorded).
    #[serde(default)]
    empty_truth_mass: Option<f64>,
    /// Fraction of the estimate's mass in voxels where the truth is 0 (None in rows written before it was recorded).
    #[serde(default)]
    haze_mass: Option<f64>,
    wall_s: f64,
    updates: usize,
}

impl Row {
    fn new(
        which: Which,
        method: &str,
        m: &DensityMetrics,
        fit: &FitHull,
        held: f64,
        wall_s: f64,
        updates: usize,
    ) -> Row {
        Row {
            plume: which.name(),
            group: which.group().into(),
            method: method.into(),
            hull_voxels: m.hull_voxels,
            fit_hull_voxels: Some(fit.voxels),
            carved_mass: Some(fit.carved_mass),
            block_pearson_r: m.block_pearson_r,
            block_rel_l1_epsilon: m.block_rel_l1_epsilon,
            block_max_error: m.block_max_error,
            pearson_r: m.pearson_r,
            rel_l1_epsilon: m.rel_l1_epsilon,
            max_error: m.max_error,
            mass_error: m.mass_error,
            held_out_rel_rmse: held,
            blur_ceiling_r: m.blur_ceiling_r,
            empty_truth_mass: Some(m.empty_truth_mass),
            haze_mass: Some(m.haze_mass),
            wall_s,
            updates,
        }
    }
}

fn main() -> std::process::ExitCode {
    dualphoton::process::keep_freed_memory();
    dualphoton::error::exit_code(run(Args::parse()))
}

fn run(args: Args) -> Result<()> {
    let started = Instant::now();
    let plumes: Vec<Which> = match &args.plumes {
        Some(list) => list.split(',').map(|s| Which::parse(s.trim())).collect::<Result<_>>()?,
        None => std::iter::once(Which::Table1)
            .chain((0..8).map(Which::Test))
            .chain(Unusual::ALL.iter().map(|&u| Which::Unusual(u)))
            .chain(std::iter::once(Which::PathTraced))
            .collect(),
    };
    let methods: Vec<&str> = args.methods.split(',').map(str::trim).collect();
    if let Some(m) = methods.iter().find(|m| !METHODS.contains(m)) {
        return Err(Error(format!("--methods: unknown method '{m}' ({})", METHODS.join(", "))));
    }
    let prior = if methods.iter().any(|m| m.starts_with("prior") || *m == "oracle") {
        Some(Prior::load(&args.prior)?)
    } else {
        None
    };
    let hull = HullSettings { threshold: args.hull_threshold, dilate: args.hull_dilate };
    let rows_dir = args.out.join("rows");
    let name = args.out.file_name().map_or("prior_eval".into(), |n| n.to_string_lossy().into_owned());
    let cache = PathBuf::from("cache").join(name);
    std::fs::create_dir_all(&rows_dir)?;
    std::fs::create_dir_all(&cache)?;
    for (p, &which) in plumes.iter().enumerate() {
        let wanted: Vec<&str> = methods
            .iter()
            .copied()
            .filter(|m| {
                args.fresh
                    || rows_of(m, args.fit.prior_refine)
                        .iter()
                        .any(|row| !rows_dir.join(format!("{}_{row}.json", which.name())).exists())
            })
            .collect();
        if wanted.is_empty() {
            continue;
        }
        eprintln!("[{}/{}] {} ({}): rendering the truth ...", p + 1, plumes.len(), which.name(), which.group());
        let truth = which.truth(args.res)?;
        let PaperProblem { truth, mut scene, mut images } =
            paper_problem_of(truth, which.seed(), paper::TARGET_PHOTONS, 0);
        target_render(&mut scene, which.seed(), paper::TARGET_PHOTONS);
        if which == Which::PathTraced {
            let opts =
                PathOptions { spp: args.path_spp, seed: paper::target_seed(which.seed()), ..PathOptions::default() };
            images = render_path(&scene, &opts).radiance;
        }
        let n_train = rig::HELD_OUT_CAMERA;
        let (targets, held_out) = images.split_at(n_train);
        let problem = Problem { scene: &scene, targets, held_out, truth: Some(&truth) };
        let d = HullSettings::default();
        let default_hull = visual_hull(&scene.density, &scene.cameras[..n_train], targets, d.threshold, d.dilate);
        let renders = UpdateRenders { seed: which.seed(), ..args.renders };
        let (fp, fs) = (scene.render.photons, scene.render.spp);
        let final_render = |density: &Grid<f64>, settings: &ReconstructSettings| {
            let mut s = scene.clone();
            s.density = density.clone();
            (s.render.photons, s.render.spp, s.render.seed) = (fp, fs, settings.final_seed);
            render_photon(&s).images
        };
        // Every row's measures: the density over the region, the held-out camera in the images.
        let measure = |density: &Grid<f64>, region: &[bool], images: &[Image]| {
            (
                density_metrics(density, &truth, region).expect("a plume and its images are never all zero"),
                rel_rmse(&images[n_train].data, &held_out[0].data).expect("a plume and its images are never all zero"),
            )
        };
        let save = |method: &str, density: &Grid<f64>, row: &Row| -> Result<()> {
            let text = serde_json::to_string_pretty(row).map_err(|e| Error(e.to_string()))?;
            std::fs::write(rows_dir.join(format!("{}_{method}.json", which.name())), text)?;
            npy::write_f32(&cache.join(format!("{}_{method}.npy", which.name())), &[density.len()], &density.data)
        };
        for method in wanted {
            let t0 = Instant::now();
            let label = format!("{} {method}", which.name());
            let progress = |p: &dualphoton::recon::progress::Progress| eprint!("\r{label}: {p}   ");
            if method == "paper" {
                let mut settings = paper_method(&args.paper_fit, renders, fp, fs)?;
                settings.hull = hull;
                let r = reconstruct(&problem, &settings, &mut |p| progress(p))?;
                eprintln!();
                let (region, fit_hull) = measured_region(&default_hull, &r.model.mask, &truth);
                let (m, held) = measure(&r.estimated, &region, &r.final_images);
                let row = Row::new(which, "paper", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), r.log.len());
                save("paper", &r.estimated, &row)?;
                continue;
            }
            let Some(prior) = &prior else { continue };
            let mut settings = prior_method(prior.clone(), &args.fit, renders, fp, fs);
            settings.hull = hull;
            if method == "oracle" {
                let mut decoded = prior_model(&scene, targets, prior, hull)?;
                let mask = decoded.mask.clone();
                let (region, fit_hull) = measured_region(&default_hull, &mask, &truth);
                let blurred = gaussian_blur(&truth, PRIOR_BLUR);
                // As train_prior's validation fits: 200 Adam steps of 0.05, its latent penalty.
                (decoded.z, _) = fit_latent(&prior.decoder, &prior.w, &blurred.data, &decoded.z, 200, 0.05, 1e-4);
                let mut in_hull = blurred;
                in_hull.data.iter_mut().zip(&mask).for_each(|(v, &m)| *v = if m { *v } else { 0.0 });
                let first = settings.train.iterations;
                // The truth itself, measured only: the floor of the held-out camera's error (render noise).
                let t0 = Instant::now();
                let (m, held) = measure(&truth, &region, &final_render(&truth, &settings));
                save(
                    "oracle_exact",
                    &truth,
                    &Row::new(which, "oracle_exact", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), 0),
                )?;
                for (name, start) in [("oracle_truth", in_hull), ("oracle_latent", decoded.density(&scene.density))] {
                    let t0 = Instant::now();
                    let (m, held) = measure(&start, &region, &final_render(&start, &settings));
                    save(name, &start, &Row::new(which, name, &m, &fit_hull, held, t0.elapsed().as_secs_f64(), 0))?;
                    let refined = refine_density(&problem, &start, &mask, &settings.refine, first, &mut |row| {
                        eprint!("\r{label} {name} refine: update {} ({:.0} s)   ", row.iteration, row.wall_s)
                    })?;
                    eprintln!();
                    let (m, held) = measure(&refined, &region, &final_render(&refined, &settings));
                    let name = format!("{name}_refine");
                    let row = Row::new(
                        which,
                        &name,
                        &m,
                        &fit_hull,
                        held,
                        t0.elapsed().as_secs_f64(),
                        settings.refine.updates,
                    );
                    save(&name, &refined, &row)?;
                }
                continue;
            }
            // The refinement runs below, after the row of the latent fit (or its tuning).
            let refinement = settings.refine.clone();
            settings.refine.updates = 0;
            let r = reconstruct(&problem, &settings, &mut |p| progress(p))?;
            eprintln!();
            let (region, fit_hull) = measured_region(&default_hull, &r.model.mask, &truth);
            let (mut model, mut updates) = (r.model.clone(), r.log.len());
            if method == "prior" {
                let (m, held) = measure(&r.estimated, &region, &r.final_images);
                let row = Row::new(which, "prior", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), updates);
                save("prior", &r.estimated, &row)?;
            } else {
                let tuning = prior_tuning(&args.fit, &args.tune, renders);
                train(&problem, &mut model, &tuning, &mut |row, _, _| {
                    eprint!("\r{label}: tuning update {} ({:.0} s)   ", row.iteration, row.wall_s)
                })?;
                eprintln!();
                updates += tuning.iterations;
                let density = model.density(&scene.density);
                let (m, held) = measure(&density, &region, &final_render(&density, &settings));
                save(
                    "prior_tune",
                    &density,
                    &Row::new(which, "prior_tune", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), updates),
                )?;
            }
            if refinement.updates > 0 {
                let refined = refine(&problem, &model, &refinement, updates, &mut |row| {
                    eprint!("\r{label} refine: update {} ({:.0} s)   ", row.iteration, row.wall_s)
                })?;
                eprintln!();
                let (m, held) = measure(&refined, &region, &final_render(&refined, &settings));
                let name = format!("{method}_refine");
                let total = updates + refinement.updates;
                let row = Row::new(which, &name, &m, &fit_hull, held, t0.elapsed().as_secs_f64(), total);
                save(&name, &refined, &row)?;
            }
        }
    }
    let rows = read_rows(&rows_dir, &plumes)?;
    write_rows(&args.out.join("table.csv"), &rows)?;
    std::fs::write(args.out.join("table.md"), table_markdown(&rows))?;
    figures(&args, &plumes, &cache)?;
    write_manifest(&args.out.join("manifest.json"), &args, started.elapsed().as_secs_f64())?;
    print!("{}", table_markdown(&rows));
    Ok(())
}

/// The hull a fit ran in: its voxels and the fraction of the truth's mass it carved away.
struct FitHull {
    voxels: usize,
    carved_mass: f64,
}

/// Where the measures are taken: the default hull, joined with the fit's
/// own hull `fit_mask` (the same for the default settings). One region for
/// every hull setting keeps the measures comparable: an estimate is 0
/// outside its hull, so mass a tighter hull carves away counts as error.
fn measured_region(default_hull: &[bool], fit_mask: &[bool], truth: &Grid<f64>) -> (Vec<bool>, FitHull) {
    let region = default_hull.iter().zip(fit_mask).map(|(&a, &b)| a || b).collect();
    let total: f64 = truth.data.iter().sum();
    let outside: f64 = truth.data.iter().zip(fit_mask).filter(|(_, &m)| !m).map(|(v, _)| v).sum();
    let carved_mass = if total > 0.0 { outside / total } else { 0.0 };
    (region, FitHull { voxels: fit_mask.iter().filter(|&&m| m).count(), carved_mass })
}

/// The rows of `plumes` found in `dir`, in plume then method order.
fn read_rows(dir: &Path, plumes: &[Which]) -> Result<Vec<Row>> {
    let mut rows = vec![];
    for which in plumes {
        for method in ROWS {
            let path = dir.join(format!("{}_{method}.json", which.name()));
            if let Ok(text) = std::fs::read_to_string(&path) {
                let row: Row =
                    serde_json::from_str(&text).map_err(|e| Error(format!("{}: damaged: {e}", path.display())))?;
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

/// Per-plume rows, then per group and method the mean and the worst.
fn table_markdown(rows: &[Row]) -> String {
    let mut md = String::from(
        "# The learned prior against the paper's per-scene decoder\n\n\
         Block measures are over 2x2x2 blocks at least half inside the visual hull; voxel measures over the hull \
         voxels (both over the default hull, whatever hull the fit ran in); the ceiling is r of the truth against \
         itself blurred by one voxel; fit hull: the voxels the fit ran in and the fraction of the truth's mass \
         outside them; empty: the fraction of the truth's mass where the estimate is 0; haze: the fraction of the \
         estimate's mass where the truth is 0.\n\n\
         | plume | group | method | fit hull (carved mass) | block r | block eps | block max err | r (ceiling) | eps | max err | mass err | empty | haze | held-out RMSE | wall s |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let carved = r.carved_mass.map_or("—".into(), |c| format!("{:.1} %", 100.0 * c));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} ({}) | {:.3} | {:.3} | {:+.0} % | {:.3} ({:.3}) | {:.3} | {:+.0} % | {:+.1} % | {} | {} | {:.1} % | {:.0} |",
            r.plume,
            r.group,
            r.method,
            r.fit_hull_voxels.unwrap_or(r.hull_voxels),
            carved,
            r.block_pearson_r,
            r.block_rel_l1_epsilon,
            100.0 * r.block_max_error,
            r.pearson_r,
            r.blur_ceiling_r,
            r.rel_l1_epsilon,
            100.0 * r.max_error,
            100.0 * r.mass_error,
            r.empty_truth_mass.map_or("—".into(), |e| format!("{:.1} %", 100.0 * e)),
            r.haze_mass.map_or("—".into(), |e| format!("{:.1} %", 100.0 * e)),
            100.0 * r.held_out_rel_rmse,
            r.wall_s
        );
    }
    md += "\n## Mean (worst) per group and method\n\n\
           | group | method | plumes | block r | block eps | abs block max err | r | eps | abs mass err | held-out RMSE | wall s |\n\
           |---|---|---|---|---|---|---|---|---|---|---|\n";
    let mut groups: Vec<&str> = rows.iter().map(|r| r.group.as_str()).collect();
    groups.dedup();
    groups.sort();
    groups.dedup();
    for g in groups {
        for method in ROWS {
            let sel: Vec<&Row> = rows.iter().filter(|r| r.group == g && r.method == method).collect();
            if sel.is_empty() {
                continue;
            }
            let n = sel.len() as f64;
            let mean = |f: &dyn Fn(&Row) -> f64| sel.iter().map(|r| f(r)).sum::<f64>() / n;
            let lo = |f: &dyn Fn(&Row) -> f64| sel.iter().map(|r| f(r)).fold(f64::INFINITY, f64::min);
            let hi = |f: &dyn Fn(&Row) -> f64| sel.iter().map(|r| f(r)).fold(f64::NEG_INFINITY, f64::max);
            let both_lo = |f: &dyn Fn(&Row) -> f64| format!("{:.3} ({:.3})", mean(f), lo(f));
            let both_hi = |f: &dyn Fn(&Row) -> f64, pct: bool| {
                if pct {
                    format!("{:.1} % ({:.1} %)", 100.0 * mean(f), 100.0 * hi(f))
                } else {
                    format!("{:.3} ({:.3})", mean(f), hi(f))
                }
            };
            let _ = writeln!(
                md,
                "| {g} | {method} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} ({:.0}) |",
                sel.len(),
                both_lo(&|r| r.block_pearson_r),
                both_hi(&|r| r.block_rel_l1_epsilon, false),
                both_hi(&|r| r.block_max_error.abs(), true),
                both_lo(&|r| r.pearson_r),
                both_hi(&|r| r.rel_l1_epsilon, false),
                both_hi(&|r| r.mass_error.abs(), true),
                both_hi(&|r| r.held_out_rel_rmse, true),
                mean(&|r| r.wall_s),
                hi(&|r| r.wall_s)
            );
        }
    }
    md
}

/// The scatter of block densities (truth against each method) for the
/// first plume, and horizontal slices of truth and estimates for up to
/// three plumes, from the cached estimates (plumes without them are skipped).
fn figures(args: &Args, plumes: &[Which], cache: &Path) -> Result<()> {
    let res = args.res;
    let load = |which: Which, method: &str| -> Option<Vec<f64>> {
        npy::read(&cache.join(format!("{}_{method}.npy", which.name())), "estimate").ok().map(|a| a.data)
    };
    let methods =
        [("paper", "paper's method"), ("prior", "prior, latent only"), ("prior_refine", "prior + refinement")];
    if let Some(&first) = plumes.first() {
        let truth = first.truth(res)?;
        let tb = block_means(&truth.data, res);
        let estimates: Vec<(&str, Vec<f64>)> =
            methods.iter().filter_map(|(m, label)| load(first, m).map(|d| (*label, block_means(&d, res)))).collect();
        if !estimates.is_empty() {
            let occupied: Vec<bool> = tb.iter().map(|&v| v > 0.0).collect();
            let mask: Vec<bool> =
                block_mask(&vec![true; res * res * res], res).iter().zip(&occupied).map(|(a, b)| *a && *b).collect();
            let named: Vec<(&str, &[f64])> = estimates.iter().map(|(n, d)| (*n, d.as_slice())).collect();
            let title = format!("{}: 2x2x2 block density, truth vs estimates", first.name());
            estimate_scatter(&title, &tb, &named, &mask, &args.out.join("scatter.svg"))?;
        }
    }
    for &which in plumes.iter().take(3) {
        let truth = which.truth(res)?;
        let mut panels: Vec<(Image, String)> = vec![];
        for frac in [0.3, 0.5, 0.7] {
            let y = ((frac * res as f64) as usize).min(res - 1);
            panels.push((slice(&truth.data, res, y), format!("truth, y = {frac}")));
            for (m, label) in methods {
                if let Some(d) = load(which, m) {
                    panels.push((slice(&d, res, y), label.to_string()));
                }
            }
        }
        if panels.len() > 3 {
            let refs: Vec<(&Image, String)> = panels.iter().map(|(im, s)| (im, s.clone())).collect();
            let title = format!("{}: horizontal slices at 30, 50 and 70 % of the height (white = 0.3)", which.name());
            labelled_strip(&refs, 0.3, &title, &args.out.join(format!("slices_{}.svg", which.name())))?;
        }
    }
    Ok(())
}

/// The horizontal slice `y` of a `res`^3 grid as an image (x across, z down).
fn slice(d: &[f64], res: usize, y: usize) -> Image {
    let data = (0..res * res).map(|p| d[((p / res) * res + y) * res + p % res]).collect();
    Image { width: res, height: res, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_method_runs_again_while_any_of_its_rows_is_missing() {
        assert_eq!(rows_of("prior", 200), ["prior", "prior_refine"]);
        assert_eq!(rows_of("prior", 0), ["prior"]);
        assert_eq!(rows_of("prior_tune", 5), ["prior_tune", "prior_tune_refine"]);
        assert_eq!(rows_of("paper", 200), ["paper"]);
        assert_eq!(rows_of("oracle", 0).len(), 5);
    }
}
