//! The `dualphoton` command line: `render`, `grad`, `fit`, `judge` and `scene` (see `--help`).

use clap::{Args, Parser, Subcommand, ValueEnum};
use dualphoton::capture::settings::FitSettings;
use dualphoton::capture::BoxChoice;
use dualphoton::data::{plume, scalarflow};
use dualphoton::error::{Error, Result};
use dualphoton::eval::fit_quality::{fit_quality, fit_quality_markdown, FitQualitySettings, FitTarget};
use dualphoton::grad::forward::Directions;
use dualphoton::grad::loss::mse;
use dualphoton::grad::{forward_at, voxel_gradient, Estimator, GradOptions, LANES};
use dualphoton::image::Image;
use dualphoton::io::rows::write_rows;
use dualphoton::io::{npy, png};
use dualphoton::prior::{self, Prior};
use dualphoton::recon::methods::{MethodOptions, Methods};
use dualphoton::recon::outputs::Outputs;
use dualphoton::recon::problem::Problem;
use dualphoton::recon::reconstruct::{reconstruct, ReconstructSettings};
use dualphoton::recon::study::{apply_study, read_study};
use dualphoton::render::frozen::Frozen;
use dualphoton::render::path::{render_path_with_progress, PathOptions};
use dualphoton::render::render_photon;
use dualphoton::scene::{file, rig, Scene, Shadows};
use dualphoton::volume::Grid;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "dualphoton", version, about = "Differentiable photon mapping of smoke and fog")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum Method {
    /// Single scattering by ray marching + photon mapping for orders 2..max_order.
    Photon,
    /// Unbiased volumetric path tracer (the reference; slow). Also writes camN_stderr.npy.
    Path,
}

#[derive(Clone, Copy, ValueEnum)]
enum Preset {
    /// The paper's rig (5 cameras, 3 lights, g 0.9, albedo 0.9) around a smoke plume.
    Paper,
}

#[derive(Subcommand)]
enum Command {
    /// Render every camera of a scene to DIR/cam0.npy, DIR/cam0.png, DIR/cam1.npy, ...
    Render(RenderArgs),
    /// Gradient of the MSE between the rendered images and target images with
    /// respect to every density voxel, written as float32 (Z, Y, X).
    Grad(GradArgs),
    /// Reconstruct a density from images: visual hull, then the learned prior's
    /// 64-d latent (or the paper's per-scene decoder), then a per-voxel
    /// refinement. Writes density_estimated.npy, density_initial.npy, hull.npy,
    /// log.csv, fig5_loss.svg, fit_quality.csv (the estimate against your
    /// images, as `judge --images`; also printed) into OUT, and camera 2
    /// during training (fig6_camera2.png/.svg) and the first held-out camera
    /// (fig8_held_out.png/.svg) where those cameras exist. With --capture,
    /// one frame of a real capture instead: scene.json with density.npy (the
    /// fitted density, lights and emission), log.csv, fit_quality.csv (per
    /// camera), held_out.npy/.png (its test camera, if it has one) and, where
    /// its cameras are aligned once for every frame, rig.json and settings.json.
    Fit(FitArgs),
    /// Judge how well a density explains images: per camera, the relative RMSE
    /// at 1x1, 2x2 and 4x4 pixel blocks of its high-quality render against the
    /// truth's (--truth) or against images (--images), next to the noise floor.
    Judge(JudgeArgs),
    /// Write a built-in scene (scene.json + density.npy) to DIR.
    Scene(SceneArgs),
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (JSON, docs/DESIGN.md §1).
    #[arg(long)]
    scene: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Rendering method.
    #[arg(long, value_enum, default_value = "photon")]
    method: Method,
    /// Seed of every random stream (default: the scene's render.seed, else 0).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Photons emitted (default: render.photons, else 300000).
    #[arg(long)]
    photons: Option<u64>,
    /// Photon kernel radius in world units (default: render.kernel_radius, else 1 voxel).
    #[arg(long)]
    radius: Option<f64>,
    /// Ray-marching step in world units (default: render.step, else half a voxel).
    #[arg(long)]
    step: Option<f64>,
    /// Samples per pixel of the photon renderer (default: render.spp, else 4).
    #[arg(long)]
    spp: Option<u32>,
    /// Samples per pixel of the path tracer (default: render.path_spp, else 256).
    #[arg(long)]
    path_spp: Option<u32>,
    /// The lights' transmittance: auto (light-depth grids, with shadow rays marched near voxels too
    /// thick for them), grid, or marched (a shadow ray from every sample: exact, slower; for checks).
    #[arg(long, value_enum)]
    shadows: Option<Shadows>,
    /// Fixed PNG white point (radiance mapped to full white); default per image.
    #[arg(long)]
    white: Option<f64>,
}

#[derive(Args)]
struct GradArgs {
    /// Scene file (JSON, docs/DESIGN.md §1).
    #[arg(long)]
    scene: PathBuf,
    /// Directory with one target image per camera: cam0.npy, cam1.npy, ... (as `render` writes them).
    #[arg(long)]
    target: PathBuf,
    /// Output file (.npy).
    #[arg(long)]
    out: PathBuf,
    /// Gradient estimator.
    #[arg(long, value_enum, default_value = "rev-full")]
    estimator: Estimator,
    /// Seed of the render (the images differentiated are those `render --seed N` writes).
    #[arg(long)]
    seed: Option<u64>,
    /// Seed of the estimator's own draws (pixel/path subsets, random directions).
    #[arg(long, default_value_t = 0)]
    estimator_seed: u64,
    /// Directions per forward pass: 1, 2, 4, ..., 64.
    #[arg(long, default_value_t = 8)]
    lanes: usize,
    /// rev-sub: pixels differentiated per gradient (the paper: 1000).
    #[arg(long, default_value_t = 1000)]
    pixels: usize,
    /// rev-sub: photon paths differentiated per gradient (the paper: 5000).
    #[arg(long, default_value_t = 5000)]
    paths: usize,
    /// Also compute these voxels by forward mode and print both: "k,j,i;k,j,i;...".
    #[arg(long)]
    voxels: Option<String>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Photons emitted (default: the scene's render.photons).
    #[arg(long)]
    photons: Option<u64>,
}

#[derive(Args)]
struct FitArgs {
    /// Scene file: cameras, lights, medium; its density only fixes the grid (shape and box).
    #[arg(long, required_unless_present = "capture")]
    scene: Option<PathBuf>,
    /// Directory with one image per camera: cam0.npy, cam1.npy, ...
    #[arg(long, required_unless_present = "capture")]
    images: Option<PathBuf>,
    /// A real capture instead of --scene and --images: its calibration (info.json or transforms.json, or
    /// the folder holding it). Fits one --frame on its training cameras (lights, emission and density)
    /// and renders its test cameras at full resolution (OUT/held_out.npy).
    #[arg(long, conflicts_with_all = [
        "scene", "images", "held_out", "prior", "iterations", "time_budget", "refine", "photons", "spp",
        "judge_photons",
    ])]
    capture: Option<PathBuf>,
    /// The frame of --capture to fit.
    #[arg(long, requires = "capture")]
    frame: Option<usize>,
    /// The smoke box of --capture.
    #[command(flatten)]
    smoke_box: BoxChoice,
    /// ScalarFlow's own camera file (GlobTrans's scalaFlow_cameras.json): each camera of --capture gets
    /// the focal length of its vertical field of view instead of the calibration's horizontal one.
    #[arg(long, requires = "capture")]
    focal_lengths: Option<PathBuf>,
    /// The OUT of an earlier fit of --capture (or experiment_real's folder): its rig.json, the training
    /// cameras' alignment, is taken instead of fitted again (most of one frame's time). Refused unless
    /// it was made with the same cameras and settings.
    #[arg(long, requires = "capture", value_name = "DIR")]
    rig: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Cameras held out from training (the last N of the scene).
    #[arg(long, default_value_t = 0)]
    held_out: usize,
    /// A learned prior's directory, or `none` for the paper's per-scene decoder. Default: the project's
    /// prior (models/plume64, beside the working directory or in the source tree) when it decodes the
    /// scene's grid, else the per-scene decoder; an error if it cannot be found.
    #[arg(long)]
    prior: Option<String>,
    #[command(flatten)]
    method: MethodOptions,
    /// Photons of the renders that judge the fit (fit_quality.csv).
    #[arg(long, help = format!(
        "Photons of the renders that judge the fit (fit_quality.csv, {} spp) [default: {}]",
        FitQualitySettings::default().spp, FitQualitySettings::default().photons
    ))]
    judge_photons: Option<u64>,
    /// Seed of every random stream of the fit [default: the --study file's, else 0].
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// A study file: JSON setting any library setting by name, {"paper": {"train": {...}, "refine": {...}},
    /// "prior": {...}} (experiments/studies/ has examples); the options above override it. With --capture,
    /// the capture fit's settings (fields of dualphoton::capture::settings::FitSettings), e.g. {"threshold": 0}
    /// for photographs whose dark pixels were not set to 0.
    #[arg(long)]
    study: Option<PathBuf>,
}

#[derive(Args)]
struct JudgeArgs {
    /// Scene file: cameras, lights, medium (its density is not used).
    #[arg(long)]
    scene: PathBuf,
    /// The density to judge (.npy, the scene's grid shape).
    #[arg(long)]
    estimate: PathBuf,
    /// The true density (.npy): truth and estimate are rendered with the same seed.
    #[arg(long, conflicts_with = "images")]
    truth: Option<PathBuf>,
    /// Or images of every camera (DIR/cam0.npy, ...) when no truth is known.
    #[arg(long)]
    images: Option<PathBuf>,
    /// Cameras held out from training (the last N of the scene), labelled so.
    #[arg(long, default_value_t = 0)]
    held_out: usize,
    /// Photons per render.
    #[arg(long, default_value_t = FitQualitySettings::default().photons)]
    photons: u64,
    /// Samples per pixel per render.
    #[arg(long, default_value_t = FitQualitySettings::default().spp)]
    spp: u32,
    /// Write the table as CSV here too.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(Args)]
struct SceneArgs {
    /// Which scene.
    #[arg(long, value_enum, default_value = "paper")]
    preset: Preset,
    /// Density grid resolution (res^3) and image size (res x res).
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Seed of the plume.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Use this ScalarFlow frame (.npz, key `data`, shape (z, y, x, 1)) instead of the built-in plume.
    #[arg(long)]
    from_scalarflow: Option<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
}

fn main() -> ExitCode {
    dualphoton::process::keep_freed_memory();
    let result = match Cli::parse().command {
        Command::Render(a) => render(a),
        Command::Grad(a) => grad(a),
        Command::Fit(a) => fit(a),
        Command::Judge(a) => judge(a),
        Command::Scene(a) => scene(a),
    };
    dualphoton::error::exit_code(result)
}

fn render(a: RenderArgs) -> Result<()> {
    set_threads(a.threads)?;
    let mut scene = file::load(&a.scene)?;
    let r = &mut scene.render;
    r.seed = a.seed.unwrap_or(r.seed);
    r.photons = a.photons.unwrap_or(r.photons);
    r.kernel_radius = a.radius.or(r.kernel_radius);
    r.step = a.step.or(r.step);
    r.spp = a.spp.unwrap_or(r.spp);
    r.path_spp = a.path_spp.unwrap_or(r.path_spp);
    r.shadows = a.shadows.unwrap_or(r.shadows);
    file::validate(&scene)?;
    if let Some(w) = a.white.filter(|w| !(w.is_finite() && *w > 0.0)) {
        return Err(Error(format!("--white: {w} must be finite and > 0")));
    }
    match a.method {
        Method::Photon => render_photon_cmd(&scene, &a.out, a.white),
        Method::Path => render_path_cmd(&scene, &a.out, a.white),
    }
}

fn grad(a: GradArgs) -> Result<()> {
    set_threads(a.threads)?;
    if !LANES.contains(&a.lanes) {
        return Err(Error(format!("--lanes: {} is not one of {LANES:?}", a.lanes)));
    }
    let mut scene = file::load(&a.scene)?;
    scene.render.seed = a.seed.unwrap_or(scene.render.seed);
    scene.render.photons = a.photons.unwrap_or(scene.render.photons);
    file::validate(&scene)?;
    let opts = GradOptions {
        estimator: a.estimator,
        lanes: a.lanes,
        pixels: a.pixels,
        paths: a.paths,
        directions: Directions::Gaussian,
        seed: a.estimator_seed,
    };
    let listed = a.voxels.map(|v| parse_voxels(&v, scene.density.shape)).transpose()?;
    let targets = read_targets(&a.target, &scene, "--target")?;
    grad_cmd(&scene, &targets, &opts, listed.as_deref(), &a.out)
}

fn fit(a: FitArgs) -> Result<()> {
    // Every option is checked before any work.
    set_threads(a.threads)?;
    if let Some(capture) = &a.capture {
        let frame = a.frame.ok_or_else(|| Error::new("--frame: give the frame of --capture to fit"))?;
        let smoke_box = a.smoke_box.corners()?;
        let settings = FitSettings::read_option(a.study.as_deref(), "--study")?;
        let settings = FitSettings { seed: a.seed.unwrap_or(settings.seed), ..settings };
        return dualphoton::capture::outputs::fit_and_write(
            capture,
            a.focal_lengths.as_deref(),
            smoke_box,
            frame,
            &settings,
            a.rig.as_deref(),
            &a.out,
        );
    }
    if a.smoke_box.smoke_box.is_some() {
        return Err(Error::new("--box: the smoke box of a --capture; a --scene gives its own"));
    }
    a.method.check()?;
    let (Some(scene), Some(images)) = (&a.scene, &a.images) else {
        return Err(Error::new("fit: give --scene and --images, or --capture"));
    };
    let scene = file::load(scene)?;
    let n_train = training_cameras(&scene, a.held_out)?;
    let mut methods = Methods::default();
    if let Some(path) = &a.study {
        apply_study(&mut methods, &read_study(path)?)?;
    }
    // Both methods are checked: which one runs is known only once the prior is found.
    for (name, m) in [("paper", &mut methods.paper), ("prior", &mut methods.prior)] {
        a.method.apply(m);
        m.check().map_err(|e| Error(format!("{name}.{}", e.0)))?;
        file::check_photons(m.train.photons, scene.medium.max_order, "--photons")?;
    }
    let max_order = scene.medium.max_order;
    let judge = FitQualitySettings::default();
    let judge = FitQualitySettings { photons: a.judge_photons.unwrap_or(judge.photons), ..judge };
    file::check_photons(judge.photons, max_order, "--judge-photons")?;
    let all = read_targets(images, &scene, "--images")?;
    let (targets, held) = all.split_at(n_train);
    let prior = choose_prior(a.prior.as_deref(), scene.density.shape)?;
    let method = if prior.is_some() { methods.prior } else { methods.paper };
    let method = match a.seed {
        Some(seed) => method.seeded(seed),
        None => method,
    };

    let mut settings = ReconstructSettings::new(method, scene.render.photons, scene.render.spp);
    settings.prior = prior;
    let problem = Problem { scene: &scene, targets, held_out: held, truth: None };
    let mut outputs = Outputs::create(&a.out).map_err(|e| Error(format!("--out: {e}")))?;
    let r = reconstruct(&problem, &settings, &mut |p| {
        outputs.log(p.row);
        eprint!("\r{p}   ");
    })?;
    eprintln!();
    outputs.finish(&r, &problem)?;
    eprintln!("judging the fit against your images ({} photons, {} spp) ...", judge.photons, judge.spp);
    let quality = fit_quality(&scene, &r.estimated, FitTarget::Images(&all), n_train, &judge)?;
    write_rows(&a.out.join("fit_quality.csv"), &quality)?;
    print!("{}", fit_quality_markdown(&quality));
    eprintln!(
        "fit: {} hull voxels, final loss {:.4e} -> {}",
        r.model.mask.iter().filter(|&&m| m).count(),
        r.log.last().map_or(0.0, |l| l.train_loss),
        a.out.display()
    );
    Ok(())
}

fn judge(a: JudgeArgs) -> Result<()> {
    set_threads(a.threads)?;
    if a.truth.is_none() && a.images.is_none() {
        return Err(Error::new("judge: give --truth FILE (a density) or --images DIR (one image per camera)"));
    }
    if a.spp == 0 {
        return Err(Error::new("--spp: must be at least 1"));
    }
    let scene = file::load(&a.scene)?;
    file::check_photons(a.photons, scene.medium.max_order, "--photons")?;
    let n_train = training_cameras(&scene, a.held_out)?;
    let estimate = read_density(&a.estimate, &scene, "--estimate")?;
    let settings = FitQualitySettings { photons: a.photons, spp: a.spp, ..Default::default() };
    let rows = match (a.truth, a.images) {
        (Some(t), _) => {
            let truth = read_density(&t, &scene, "--truth")?;
            fit_quality(&scene, &estimate, FitTarget::Truth(&truth), n_train, &settings)?
        }
        (None, Some(dir)) => {
            let images = read_targets(&dir, &scene, "--images")?;
            fit_quality(&scene, &estimate, FitTarget::Images(&images), n_train, &settings)?
        }
        (None, None) => unreachable!("checked above"),
    };
    print!("{}", fit_quality_markdown(&rows));
    if let Some(out) = a.out {
        write_rows(&out, &rows)?;
    }
    Ok(())
}

fn scene(a: SceneArgs) -> Result<()> {
    let Preset::Paper = a.preset;
    let res = a.res;
    if res == 0 || res > 512 {
        return Err(Error(format!("--res: {res} must be in 1..=512")));
    }
    let density = match a.from_scalarflow {
        Some(path) => scalarflow::load_scalarflow(&path, res)?,
        None => plume::plume(res, a.seed),
    };
    let scene: Scene = rig::paper_scene(density, res);
    file::validate(&scene)?;
    file::save(&scene, &a.out, "scene")?;
    let s = plume::plume_stats(&scene.density);
    eprintln!(
        "wrote {}/scene.json and density.npy: {res}^3, {} occupied voxels ({:.1} %), mean {:.4} over them, max {:.4}",
        a.out.display(),
        s.occupied,
        100.0 * s.fraction_occupied,
        s.mean_occupied,
        s.max
    );
    Ok(())
}

/// How many of `scene`'s cameras train when the last `held_out` are held
/// out (`fit` and `judge`); errors if none would.
fn training_cameras(scene: &Scene, held_out: usize) -> Result<usize> {
    let n = scene.cameras.len();
    if held_out >= n {
        return Err(Error(format!("--held-out: {held_out} leaves no training camera of {n}")));
    }
    Ok(n - held_out)
}

/// The prior `fit` uses, announced on its first line: `none` (the
/// per-scene decoder), a directory (errors if it cannot be used), or by
/// default the project's prior ([`prior::DEFAULT_DIR`] beside the working
/// directory, else in the source tree this was built from) when it decodes
/// the scene's grid, else the per-scene decoder. A default prior found in
/// neither place is an error, not a silent change of method.
fn choose_prior(choice: Option<&str>, shape: [usize; 3]) -> Result<Option<Prior>> {
    let loaded = match choice {
        Some("none") => {
            eprintln!("fit: the paper's per-scene decoder (--prior none)");
            return Ok(None);
        }
        Some(dir) => {
            let p = Prior::load(Path::new(dir))?;
            p.check_grid(shape)?;
            p
        }
        None => {
            let dir = prior::default_dir()
                .map_err(|e| Error(format!("--prior: {}: pass --prior DIR or --prior none", e.0)))?;
            let p = Prior::load(&dir)?;
            if let Err(e) = p.check_grid(shape) {
                eprintln!("fit: the paper's per-scene decoder, not the default prior ({e})");
                return Ok(None);
            }
            p
        }
    };
    eprintln!(
        "fit: the learned prior {} (its 64-d latent, then the refinement; --prior none: the per-scene decoder)",
        loaded.dir.display()
    );
    Ok(Some(loaded))
}

/// Parses "k,j,i;k,j,i" into flat voxel indices of a grid of `shape`.
fn parse_voxels(text: &str, shape: [usize; 3]) -> Result<Vec<usize>> {
    text.split(';')
        .filter(|s| !s.trim().is_empty())
        .map(|item| {
            let idx: Vec<usize> = item
                .split(',')
                .map(|x| x.trim().parse::<usize>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| Error(format!("--voxels: {item:?} is not k,j,i")))?;
            if idx.len() != 3 || idx[0] >= shape[0] || idx[1] >= shape[1] || idx[2] >= shape[2] {
                return Err(Error(format!("--voxels: {item:?} is not a voxel of a grid of shape {shape:?}")));
            }
            Ok((idx[0] * shape[1] + idx[1]) * shape[2] + idx[2])
        })
        .collect()
}

/// A density grid from a `.npy` file, checked against the scene's grid shape.
fn read_density(path: &Path, scene: &Scene, what: &str) -> Result<Grid<f64>> {
    let a = npy::read_f32_range(path, what)?;
    let shape = scene.density.shape;
    if a.shape != shape {
        return Err(Error(format!(
            "{what}: {} has shape {:?}, the scene's grid is {shape:?}",
            path.display(),
            a.shape
        )));
    }
    if a.data.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(Error(format!("{what}: {} has NaN, Inf or negative values", path.display())));
    }
    let mut grid = scene.density.clone();
    grid.data = a.data;
    Ok(grid)
}

/// The target images DIR/cam0.npy, ... one per camera, checked against the
/// cameras' sizes; errors name the option `what`.
fn read_targets(dir: &Path, scene: &Scene, what: &str) -> Result<Vec<Image>> {
    scene
        .cameras
        .iter()
        .enumerate()
        .map(|(c, cam)| {
            let path = dir.join(format!("cam{c}.npy"));
            let a = npy::read_f32_range(&path, what)?;
            if a.shape != [cam.height, cam.width] {
                return Err(Error(format!(
                    "{what}: {} has shape {:?}, camera {c} needs ({}, {})",
                    path.display(),
                    a.shape,
                    cam.height,
                    cam.width
                )));
            }
            if a.data.iter().any(|v| !v.is_finite()) {
                return Err(Error(format!("{what}: {} has NaN or Inf pixels", path.display())));
            }
            Ok(Image { width: cam.width, height: cam.height, data: a.data })
        })
        .collect()
}

fn grad_cmd(scene: &Scene, targets: &[Image], opts: &GradOptions, listed: Option<&[usize]>, out: &Path) -> Result<()> {
    let start = std::time::Instant::now();
    let frozen = Frozen::new(scene, None);
    let progress = |done: usize, total: usize| {
        let t = start.elapsed().as_secs_f64();
        eprint!(
            "\rfwd-full: {done}/{total} directions, {t:.0} s, ETA {:.0} s   ",
            t * (total - done) as f64 / done.max(1) as f64
        );
    };
    let grad = voxel_gradient(&frozen, targets, opts, &progress)?;
    if opts.estimator == Estimator::FwdFull {
        eprintln!();
    }
    if grad.iter().any(|g| !g.is_finite()) {
        return Err(Error::new("internal error: the gradient has non-finite entries; please report this scene"));
    }
    npy::write_f32(out, &scene.density.shape, &grad)?;
    let loss = mse(&frozen.images.iter().map(|i| i.data.clone()).collect::<Vec<_>>(), targets);
    eprintln!(
        "grad ({}): loss {loss:.6e}, |grad| {:.6e}, {:.2} s -> {}",
        opts.estimator.name(),
        grad.iter().map(|g| g * g).sum::<f64>().sqrt(),
        start.elapsed().as_secs_f64(),
        out.display()
    );
    if let Some(voxels) = listed {
        let fwd = forward_at(&frozen, targets, voxels, opts.lanes)?;
        let [_, ny, nx] = scene.density.shape;
        println!("voxel (k, j, i)\t{}\tforward", opts.estimator.name());
        for (&v, f) in voxels.iter().zip(fwd) {
            println!("({}, {}, {})\t{:.9e}\t{:.9e}", v / (ny * nx), (v / nx) % ny, v % nx, grad[v], f);
        }
    }
    Ok(())
}

/// Most worker threads `--threads` may ask for.
const MAX_THREADS: usize = 1024;

fn set_threads(threads: Option<usize>) -> Result<()> {
    if let Some(n) = threads {
        if n == 0 || n > MAX_THREADS {
            return Err(Error(format!("--threads: {n} must be in 1..={MAX_THREADS}")));
        }
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().map_err(|e| Error(format!("--threads: {e}")))?;
    }
    Ok(())
}

fn write_image(dir: &Path, name: &str, image: &Image, white: Option<f64>) -> Result<()> {
    if image.data.iter().any(|v| !v.is_finite()) {
        return Err(Error(format!("internal error: {name} has non-finite pixels; please report this scene")));
    }
    npy::write_f32(&dir.join(format!("{name}.npy")), &[image.height, image.width], &image.data)?;
    png::write_preview(&dir.join(format!("{name}.png")), image.width, image.height, &image.data, white)
}

fn create_dir(out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error(format!("--out: cannot create {}: {e}", out.display())))
}

fn render_photon_cmd(scene: &Scene, out: &Path, white: Option<f64>) -> Result<()> {
    create_dir(out)?;
    let r = render_photon(scene);
    for (c, image) in r.images.iter().enumerate() {
        write_image(out, &format!("cam{c}"), image, white)?;
    }
    let t = &r.timings;
    eprintln!(
        "photon: {} cameras, {} photons emitted, {} stored; tracing {:.3} s, gathering {:.3} s, camera rays {:.3} s, total {:.3} s",
        r.images.len(),
        scene.render.photons,
        r.stored_photons,
        t.trace,
        t.gather,
        t.camera,
        t.total
    );
    Ok(())
}

fn render_path_cmd(scene: &Scene, out: &Path, white: Option<f64>) -> Result<()> {
    create_dir(out)?;
    let opts = PathOptions { spp: scene.render.path_spp, seed: scene.render.seed, max_order: None, min_order: 1 };
    let start = std::time::Instant::now();
    let progress = |done: usize, total: usize| {
        let elapsed = start.elapsed().as_secs_f64();
        let eta = if done > 0 { elapsed * (total - done) as f64 / done as f64 } else { 0.0 };
        eprint!("\rpath: {done}/{total} pixels, {elapsed:.0} s elapsed, ETA {eta:.0} s   ");
    };
    let r = render_path_with_progress(scene, &opts, &progress);
    eprintln!();
    for (c, (image, err)) in r.radiance.iter().zip(&r.std_err).enumerate() {
        write_image(out, &format!("cam{c}"), image, white)?;
        npy::write_f32(&out.join(format!("cam{c}_stderr.npy")), &[err.height, err.width], &err.data)?;
    }
    eprintln!("path: {} samples in {:.1} s", r.samples, start.elapsed().as_secs_f64());
    Ok(())
}

#[cfg(test)]
mod tests {
    /// clap checks its attributes (ids that conflicts and requirements
    /// name, defaults) only in debug builds; the tests run in release.
    #[test]
    fn the_command_line_is_consistent() {
        <super::Cli as clap::CommandFactory>::command().debug_assert();
    }
}
