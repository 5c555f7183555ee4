//! A whole reconstruction: visual hull from the training images, a latent
//! and decoder initialised inside it, training (reporting progress and an
//! ETA), snapshots of one camera along the way and final renders of the
//! estimate. It computes and returns; [`super::outputs`] writes the files.

use super::level::Level;
use super::methods::Method;
use super::paper;
use super::problem::Problem;
use super::progress::{fine_over_coarse, Eta, Part, Phase, Progress};
use super::refine::{refine, RefineSettings};
use super::train::{check_finite, coarse_updates, train, LogRow, TrainSettings};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::model::Decoder;
use crate::model::Model;
use crate::prior::Prior;
use crate::recon::hull::{visual_hull, HullSettings};
use crate::render::render_photon;
use crate::scene::Scene;
use crate::volume::Grid;
use std::time::Instant;

/// What a reconstruction produced.
pub struct Reconstruction {
    /// The trained model (its mask is the hull).
    pub model: Model,
    /// The density before training.
    pub initial: Grid<f64>,
    /// The density after training.
    pub estimated: Grid<f64>,
    /// The log: the training updates', then the refinement's.
    pub log: Vec<LogRow>,
    /// How many of the log's rows are training updates (fewer than asked under a time budget).
    pub trained: usize,
    /// Images of every camera rendered from the estimate (final quality).
    pub final_images: Vec<Image>,
    /// The camera of the snapshots.
    pub snapshot_camera: usize,
    /// Its images at the settings' snapshot iterations and the last one
    /// (iteration, image at full size; coarse updates' images enlarged).
    pub snapshots: Vec<(usize, Image)>,
}

/// Settings of a reconstruction beyond training.
#[derive(Clone, Debug)]
pub struct ReconstructSettings {
    /// Training; its seed also seeds the model's initial values
    /// ([`ReconstructSettings::init_seed`]) and the final renders
    /// ([`ReconstructSettings::final_seed`]).
    pub train: TrainSettings,
    /// The per-voxel refinement after training (`updates` 0: none).
    pub refine: RefineSettings,
    /// Photons of the final renders.
    pub final_photons: u64,
    /// Samples per pixel of the final renders.
    pub final_spp: u32,
    /// Camera whose image is kept at the snapshot iterations (none if out of range).
    pub snapshot_camera: usize,
    /// Iterations whose image of the snapshot camera is kept (the last one is added).
    pub snapshot_iterations: Vec<usize>,
    /// How the visual hull is carved.
    pub hull: HullSettings,
    /// A learned prior: its decoder and weights replace the per-scene
    /// decoder and the latent starts at the prior's mean (none: the paper's
    /// per-scene decoder, initialised from [`ReconstructSettings::init_seed`]).
    pub prior: Option<Prior>,
}

impl ReconstructSettings {
    /// `method` (seeded, [`Method::seeded`]) with the paper's choices around
    /// it: snapshots for Fig. 6 ([`paper::FIG6_CAMERA`] at
    /// [`paper::FIG6_ITERATIONS`]) and final renders with `final_photons`,
    /// `final_spp` and [`paper::final_seed`]; no prior.
    pub fn new(method: Method, final_photons: u64, final_spp: u32) -> ReconstructSettings {
        ReconstructSettings {
            final_photons,
            final_spp,
            snapshot_camera: paper::FIG6_CAMERA,
            snapshot_iterations: paper::FIG6_ITERATIONS.to_vec(),
            train: method.train,
            refine: method.refine,
            hull: HullSettings::default(),
            prior: None,
        }
    }

    /// Seed of the model's initial values: training's.
    pub fn init_seed(&self) -> u64 {
        self.train.seed
    }

    /// Seed of the final renders, derived from training's.
    pub fn final_seed(&self) -> u64 {
        paper::final_seed(self.train.seed)
    }
}

/// The model before training: the visual hull of the training cameras
/// (the first `targets.len()` of the scene's) as its mask, a decoder for the
/// scene's cubic grid, latent and weights initialised from `init_seed`.
pub fn initial_model(scene: &Scene, targets: &[Image], init_seed: u64) -> Result<Model> {
    initial_model_in(scene, targets, init_seed, HullSettings::default())
}

/// [`initial_model`] with the hull carved by `hull`.
pub fn initial_model_in(
    scene: &Scene,
    targets: &[Image],
    init_seed: u64,
    hull_settings: HullSettings,
) -> Result<Model> {
    let mask = hull(scene, targets, hull_settings)?;
    let res = scene.density.shape[0];
    if scene.density.shape != [res, res, res] {
        return Err(Error(format!("volume.density: the decoder needs a cubic grid, got {:?}", scene.density.shape)));
    }
    let decoder = Decoder::paper_small(res).map_err(|e| Error(format!("volume.density: {e}")))?;
    let w = decoder.init(init_seed);
    let z = decoder.init_latent(init_seed);
    Ok(Model { decoder, z, w, mask })
}

/// The model before fitting with a learned prior: the visual hull as in
/// [`initial_model`], the prior's decoder and weights, the latent at the
/// prior's mean (0: its latents are whitened). Errors if the prior does
/// not decode the scene's grid.
pub fn prior_model(scene: &Scene, targets: &[Image], prior: &Prior, hull_settings: HullSettings) -> Result<Model> {
    prior.check_grid(scene.density.shape)?;
    let mask = hull(scene, targets, hull_settings)?;
    let z = vec![0.0; prior.decoder.latent()];
    Ok(Model { decoder: prior.decoder.clone(), z, w: prior.w.clone(), mask })
}

/// The visual hull of the training cameras (the first `targets.len()`).
fn hull(scene: &Scene, targets: &[Image], h: HullSettings) -> Result<Vec<bool>> {
    let n_train = targets.len();
    let mask = visual_hull(&scene.density, &scene.cameras[..n_train], targets, h.threshold, h.dilate);
    if !mask.iter().any(|&m| m) {
        return Err(Error::new("visual hull: no voxel is inside every training silhouette (are the images black?)"));
    }
    Ok(mask)
}

/// Reconstructs the density of `problem.scene` (cameras
/// `0..problem.targets.len()` train, the rest are held out) from its target
/// images; `progress` sees every log row with the time so far and the ETA.
/// Writes no file: [`super::outputs`] does.
pub fn reconstruct(
    problem: &Problem,
    settings: &ReconstructSettings,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Reconstruction> {
    let start = Instant::now();
    let (scene, targets) = (problem.scene, problem.targets);
    let mut model = match &settings.prior {
        Some(prior) => prior_model(scene, targets, prior, settings.hull)?,
        None => initial_model_in(scene, targets, settings.init_seed(), settings.hull)?,
    };
    let initial = model.density(&scene.density);

    settings.train.check()?;
    settings.refine.check()?;
    let train_settings = &settings.train;
    let (iterations, updates) = (train_settings.iterations, settings.refine.updates);
    let mut eta = eta_for(problem, &model, train_settings, &settings.refine);
    let mut log = vec![];
    let mut snapshots = vec![];
    let camera = settings.snapshot_camera;
    let truth_width = targets.iter().chain(problem.held_out).nth(camera).map(|im| im.width);
    let last = train_settings.iterations.saturating_sub(1);
    let train_started = Instant::now();
    train(problem, &mut model, train_settings, &mut |row, _, images| {
        let coarse = images.first().is_some_and(|im| im.width < scene.cameras[0].width);
        let eta_s = eta.observe(row.iteration, row.wall_s, if coarse { Phase::Coarse } else { Phase::Fine });
        let wanted = settings.snapshot_iterations.contains(&row.iteration) || row.iteration == last;
        if let (true, Some(image), Some(width)) = (wanted, images.get(camera), truth_width) {
            snapshots.push((row.iteration, upscale(image, width)));
        }
        let part = Part::Training { total: iterations };
        progress(&Progress { row, part, elapsed_s: start.elapsed().as_secs_f64(), eta_s });
        log.push(row.clone());
    })?;
    let train_s = train_started.elapsed().as_secs_f64();
    // Refinement updates number on from the training updates made (fewer than asked under a time budget).
    let trained = log.len();
    let estimated = if settings.refine.updates > 0 {
        refine(problem, &model, &settings.refine, trained, &mut |row| {
            let row = LogRow { wall_s: row.wall_s + train_s, ..row.clone() };
            let eta_s = eta.observe(row.iteration, row.wall_s, Phase::Refine);
            let part = Part::Refinement { first: trained, total: updates };
            progress(&Progress { row: &row, part, elapsed_s: start.elapsed().as_secs_f64(), eta_s });
            log.push(row);
        })?
    } else {
        let d = model.density(&scene.density);
        check_finite(&d, "training", trained.saturating_sub(1))?;
        d
    };
    let mut final_scene = scene.clone();
    final_scene.density = estimated.clone();
    final_scene.render.photons = settings.final_photons;
    final_scene.render.spp = settings.final_spp;
    final_scene.render.seed = settings.final_seed();
    let final_images = render_photon(&final_scene).images;
    Ok(Reconstruction { model, initial, estimated, log, trained, final_images, snapshot_camera: camera, snapshots })
}

/// The ETA of `settings` on `problem`; times one primal render per level
/// only when training will switch from half to full resolution.
fn eta_for(problem: &Problem, model: &Model, settings: &TrainSettings, refine: &RefineSettings) -> Eta {
    let has_half = settings.coarse_fraction > 0.0 && Level::half(problem, &model.mask).is_some();
    let coarse = coarse_updates(settings, has_half);
    let switches = settings.time_budget.is_none() && coarse > 0 && coarse < settings.iterations;
    let ratio = if switches { fine_over_coarse(problem, model, settings).unwrap_or(1.0) } else { 1.0 };
    // A cap on the whole run needs a budget for both parts (none for refinement when it makes no update).
    let refine_budget = if refine.updates == 0 { Some(0.0) } else { refine.time_budget };
    let budget = settings.time_budget.zip(refine_budget).map(|(t, r)| t + r);
    Eta::new(settings.iterations, coarse, refine.updates, ratio, budget)
}

/// `im` enlarged by pixel replication to `width` (a coarse update's image next to full-size ones).
fn upscale(im: &Image, width: usize) -> Image {
    let f = (width / im.width.max(1)).max(1);
    let (w, h) = (im.width * f, im.height * f);
    let data = (0..w * h).map(|p| im.data[(p / w / f) * im.width + (p % w) / f]).collect();
    Image { width: w, height: h, data }
}
