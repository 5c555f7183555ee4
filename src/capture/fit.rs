//! Fitting one frame of a real capture: the density on a grid over the
//! capture's smoke box, the lights' intensities and the medium's emission
//! (the ambient term), from the training cameras' images at a working
//! resolution.
//!
//! The image is linear in every light's intensity and in the emission, so
//! for a given density they follow exactly from a non-negative least-squares
//! fit to one render per light and one of the emission alone. The density
//! follows the images' reverse-mode gradient (Adam on its logarithm,
//! inside the visual hull of the real silhouettes) plus the priors of
//! [`super::priors`], coarse to fine (or, with [`FitSettings::decoder`],
//! from the paper's latent-and-decoder model at the finest level). The
//! camera response is a power law shared by every camera
//! ([`FitSettings::gamma`]) and a gain per training camera; the
//! held-out camera's response follows from a rule fixed in advance, never
//! from its photograph.
//!
//! Scale: only the product of density and light is seen where the smoke is
//! thin; the density's level is fixed by the start (an optical depth of
//! [`FitSettings::start_depth`] across the hull) and moves only where
//! attenuation in the images asks for it.

use super::align::{take_out_shared, warp, Corrections};
use super::lighting::{candidate_lights, fit_gains, fit_lights, light_share, place_lights, weights_of};
use super::observe::{real_silhouette, SILHOUETTE_MARGIN_PX};
use super::priors::{smoothness, sparsity};
use crate::error::{Error, Result};
use crate::grad::loss::mse;
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::image::Image;
use crate::math::Vec3;
use crate::model::{Decoder, Model};
use crate::optim::Adam;
use crate::recon::hull::carve;
use crate::recon::train::TrainSettings;
use crate::render::frozen::Frozen;
use crate::render::render_photon;
use crate::scene::{Camera, Medium, RenderSettings, Scene};
use crate::volume::Grid;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// How the rendered image arises from the density.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ImageModel {
    /// The lights scattered several times (`orders` in the fit settings), plus the ambient term.
    Multiple,
    /// The lights scattered once, plus the ambient term.
    Single,
    /// No lights: brightness proportional to density along the ray,
    /// attenuated (the image model of PINF and HyFluid).
    EmissionAbsorption,
}

impl ImageModel {
    /// The name in files and tables.
    pub fn name(self) -> &'static str {
        match self {
            ImageModel::Multiple => "multiple",
            ImageModel::Single => "single",
            ImageModel::EmissionAbsorption => "emission-absorption",
        }
    }

    /// Most scattering events on a light path, where the multiple model
    /// scatters up to `orders` times.
    fn max_order(self, orders: u32) -> u32 {
        match self {
            ImageModel::Multiple => orders,
            _ => 1,
        }
    }

    /// Whether the model has lights.
    fn lit(self) -> bool {
        self != ImageModel::EmissionAbsorption
    }
}

/// How a frame is fitted. Every default was chosen on frames and cameras
/// other than those reported (docs/studies/real_settings.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitSettings {
    /// The image model.
    pub model: ImageModel,
    /// Working resolution: 1/`factor` of the capture's, by area averaging.
    pub factor: usize,
    /// Voxels along the smoke box's longest edge at the finest level.
    pub resolution: usize,
    /// Adam updates per level, coarsest first; each level doubles the
    /// resolution of the one before, the last is at `resolution`. On the
    /// settings study's frames 80 at the finest level scored better than 40
    /// and 160 (which fits the training cameras closer and the unseen one
    /// worse), by the additive update and again by the logarithmic one.
    pub updates: Vec<usize>,
    /// Adam step: with `log_density`, of the density's logarithm (a
    /// fraction of each voxel's own density); without, in units of the
    /// level's mean density over the hull. 0.05: on the settings study's
    /// frames 0.1 scored 0.01 dB lower on the logarithm.
    pub lr: f64,
    /// Take the Adam steps on the density's logarithm instead of the
    /// density: each voxel then moves by a fraction of itself, as a
    /// multiplicative tomography update (MART) does, and thin voxels change
    /// slowly where thick ones change fast. On by default: on the settings
    /// study's frames it gained 0.29 dB on the scoring camera for multiple
    /// scattering, on every frame (the one model studied; all three use it).
    pub log_density: bool,
    /// Weight of the smoothness term: the mean over neighbouring voxel
    /// pairs of the squared difference of their optical depth across one
    /// voxel, against the images' mean squared error.
    pub smoothness: f64,
    /// Factor on the smoothness term's pairs across the vertical (the grid
    /// axes other than the one nearest the training cameras' mean up
    /// direction). Cameras on one level arc each see every height of the
    /// smoke, but leave it open across. On the settings study's frames the
    /// factors 3 and 10 lost 0.17 and 0.63 dB on the scoring camera and 0.3
    /// gained 0.01 dB: 1, as along the vertical.
    pub horizontal_smoothness: f64,
    /// Weight of the sparsity term ([`sparsity`]) against the images' mean
    /// squared error. Off: on the settings study's frames 0.0001 changed
    /// nothing and 0.001 lost 0.7-1.4 dB on the scoring camera.
    pub sparsity: f64,
    /// Optical depth across the hull's mean chord at the start. On the
    /// settings study's frames (docs/studies/real_settings.md) 1 and 2 scored best
    /// on the scoring camera, within 0.05 dB of each other for multiple
    /// scattering (0.15 for single); 1 fits the training cameras better.
    pub start_depth: f64,
    /// How the start's density is spread over the hull ([`StartShape`]).
    /// Even: on the settings study's frames both shaped starts lost 0.1-0.3 dB
    /// on the scoring camera.
    pub start_shape: StartShape,
    /// The lights and emission are fitted again every this many updates.
    pub refit_every: usize,
    /// Photons per render (multiple scattering only).
    pub photons: u64,
    /// Most scattering events on a light path of the multiple model
    /// (orders 2 and up by photon mapping), 2 to 16. On the settings
    /// study's frames 2, 3 and 5 scored 33.43, 33.49 and 33.49 dB on the
    /// scoring camera: the fewest within 0.05 dB of the best is 3.
    pub orders: u32,
    /// Camera samples per pixel per update. The lit models' pixels are
    /// noisy at 1 (each sample gathers the light at one jittered point);
    /// on the settings study's frames 2 gained 0.3 dB on the scoring camera
    /// for multiple scattering over 1, and 4 no more than 2.
    pub spp: u32,
    /// Henyey-Greenstein asymmetry assumed for the fog.
    pub g: f64,
    /// Single-scattering albedo assumed for the fog (water droplets absorb almost nothing).
    pub albedo: f64,
    /// The capture's black threshold (code value / full scale): its
    /// processing set everything up to it to 0 (ScalarFlow's background
    /// subtraction: codes up to 8). Where a photograph is 0, a rendered
    /// value below it is no error; a rendered view is set to 0 below it.
    pub threshold: f64,
    /// Correct every training camera's principal point so that its
    /// photograph agrees with the render ([`super::align`]), from the second
    /// stage on (level, or the finest after the decoder's), whenever the lights are fitted again; the offsets' mean
    /// over the cameras stays 0 (the calibration's average is kept).
    pub align: bool,
    /// With `align`, also correct every training camera's focal lengths by
    /// the magnification that best moves its photograph onto the render,
    /// about its principal point; the magnifications' geometric mean over
    /// the cameras stays 1. A held-out camera keeps its calibration's, by
    /// this rule fixed in advance. On by default: on the settings study's
    /// frames it gained 0.7-0.85 dB on the scoring camera for every model.
    pub zoom: bool,
    /// With `align`, align the training cameras once for every frame of the
    /// capture ([`super::rig`]) instead of on each frame: the cameras never
    /// move, and a thin plume constrains them poorly. On by default: on the
    /// settings study's frames it gained 0.2 dB on the scoring camera for
    /// multiple scattering and emission-absorption (0.5-0.6 dB on the thin
    /// frame 5) and 0.4 dB for single scattering.
    pub shared_alignment: bool,
    /// With `shared_alignment`, how many calibration frames (at least one)
    /// the training cameras are aligned on ([`super::rig::calibration_frames`]).
    /// On the settings study's frames 5 instead of 3 gained 0.03 dB on the
    /// scoring camera (multiple scattering) at 1.6 times the rig's time.
    pub rig_frames: usize,
    /// With `shared_alignment`, the working resolution of the calibration
    /// frames' fits, 1/`rig_factor` of the capture's; none: `factor`. On the
    /// settings study's frames 4 gained 0.07 dB at almost 4 times the rig's time.
    pub rig_factor: Option<usize>,
    /// Dilation of the silhouettes (full-resolution pixels) once the
    /// training cameras are aligned: from then on each level's hull is
    /// carved through the aligned cameras with this margin. Before, the
    /// margin is the calibration's disagreement ([`SILHOUETTE_MARGIN_PX`]).
    /// On the settings study's frames 20 scored best of 0, 8, 20 and 40
    /// (0.3-0.5 dB over 40, every model) by the additive update; by the
    /// logarithmic one 8 scored 0.08 dB above 20, too little to change it.
    pub aligned_margin: f64,
    /// Lights whose places are fitted ([`super::lights`]): from the second
    /// stage on, the strongest this many candidates are kept and move
    /// whenever the lights are fitted again. 0: every candidate stays in
    /// its place and only the intensities are fitted.
    pub lights: usize,
    /// Fit a gain per training camera (the cameras' brightest smoke differs
    /// by up to about a third between them): the photographs are divided by
    /// their gains, whose geometric mean over the training cameras is held
    /// at 1. A held-out camera's gain is that mean, 1, by this rule fixed
    /// in advance. Off: one gain for every camera, absorbed by the lights.
    /// On by default: on the settings study's frames it gained 0.0-0.2 dB
    /// on the scoring camera for every model.
    pub gains: bool,
    /// Fit the emission beside the lights in the lit models: an ambient
    /// term, light that reaches every voxel alike and unshadowed. With it,
    /// the lit models contain emission-absorption (their lights all at 0).
    /// Off: the lights must explain every pixel, with their shadows.
    pub ambient: bool,
    /// The cameras' response curve, shared by all: a photograph's code
    /// value / full scale is the radiance (times the camera's gain) to the
    /// power 1/`gamma`. The fit works on the photographs to the power
    /// `gamma`, where the image is linear in the lights; rendered views go
    /// back through the curve. 1: the codes are proportional to radiance,
    /// which scored best on the settings study's frames (0.8, 1.5 and 2.2
    /// lost 0.2-2.9 dB on the scoring camera, every model).
    pub gamma: f64,
    /// Adam updates of the paper's density model before the per-voxel
    /// fit: a 64-d latent and a small decoder, fitted from scratch, whose
    /// output is the density on a cube of `resolution` voxels a side around
    /// the smoke box ([`crate::model::Decoder::paper_small`]). The per-voxel
    /// fit then runs at the finest level only, from the decoder's density,
    /// as the paper's refinement does (`start_shape` and the coarser
    /// levels' `updates` are then unused). 0: no decoder; the per-voxel fit
    /// runs coarse to fine from an even start. Off: on the settings study's
    /// frames 250 updates fitted the training cameras closer and lost 0.4 dB
    /// on the scoring camera, at 4-5 times the time.
    pub decoder: usize,
    /// Seed of every render.
    pub seed: u64,
}

/// How the start's density is spread over the hull; its mean is set by
/// [`FitSettings::start_depth`] either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StartShape {
    /// The same density everywhere in the hull.
    Even,
    /// Each voxel in proportion to the darkest of the training photographs
    /// where its centre appears: a soft hull that already carries the
    /// plume's shape from every view.
    Darkest,
    /// Each voxel in proportion to the geometric mean of the training
    /// photographs where its centre appears.
    GeometricMean,
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            model: ImageModel::Multiple,
            factor: 8,
            resolution: 64,
            updates: vec![40, 40, 80],
            lr: 0.05,
            log_density: true,
            smoothness: 0.001,
            horizontal_smoothness: 1.0,
            sparsity: 0.0,
            start_depth: 1.0,
            start_shape: StartShape::Even,
            refit_every: 10,
            photons: 20_000,
            orders: 3,
            spp: 2,
            g: 0.6,
            albedo: 1.0,
            threshold: 8.0 / 255.0,
            align: true,
            zoom: true,
            shared_alignment: true,
            rig_frames: 3,
            rig_factor: None,
            aligned_margin: 20.0,
            lights: 0,
            gains: true,
            ambient: true,
            gamma: 1.0,
            decoder: 0,
            seed: 0,
        }
    }
}

impl FitSettings {
    /// Whether the training cameras are aligned once for every frame, by a
    /// rig ([`FitSettings::shared_alignment`]).
    pub fn aligns_once(&self) -> bool {
        self.align && self.shared_alignment
    }

    /// The settings in the JSON file at `path` (fields not given keep their
    /// defaults), checked.
    pub fn read(path: &std::path::Path) -> Result<FitSettings> {
        let text = std::fs::read_to_string(path).map_err(|e| Error(format!("{}: {e}", path.display())))?;
        let settings: FitSettings =
            serde_json::from_str(&text).map_err(|e| Error(format!("{}: {e}", path.display())))?;
        settings.validate()?;
        Ok(settings)
    }

    /// One-line errors for settings no fit can run with.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str| Err(Error(format!("fit settings: {what}")));
        if self.factor == 0 {
            return bad("factor must be at least 1");
        }
        if self.rig_factor == Some(0) {
            return bad("rig_factor must be at least 1");
        }
        if self.rig_frames == 0 {
            return bad("rig_frames must be at least 1");
        }
        if self.updates.is_empty() || self.resolution >> (self.updates.len() - 1) < 2 {
            return bad("resolution must give at least 2 voxels along the longest edge at the coarsest level");
        }
        if !(self.horizontal_smoothness.is_finite() && self.horizontal_smoothness >= 0.0) {
            return bad("horizontal_smoothness must be finite and >= 0");
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad("lr must be finite and > 0");
        }
        if !(self.smoothness.is_finite() && self.smoothness >= 0.0) {
            return bad("smoothness must be finite and >= 0");
        }
        if !(self.sparsity.is_finite() && self.sparsity >= 0.0) {
            return bad("sparsity must be finite and >= 0");
        }
        if !(self.start_depth.is_finite() && self.start_depth > 0.0) {
            return bad("start_depth must be finite and > 0");
        }
        if self.refit_every == 0 || self.spp == 0 {
            return bad("refit_every and spp must be at least 1");
        }
        // 1 is the single model; past 16 the photon map's memory grows for
        // light the images cannot see (5 orders score as 3).
        if !(2..=16).contains(&self.orders) {
            return bad("orders must be in 2..=16 (1 is the single model)");
        }
        crate::scene::validate::check_photons(self.photons, self.orders, "fit settings: photons")?;
        if !(0.0..1.0).contains(&self.threshold) {
            return bad("threshold must be in [0, 1)");
        }
        if !(self.aligned_margin.is_finite() && self.aligned_margin >= 0.0) {
            return bad("aligned_margin must be finite and >= 0");
        }
        if !(self.gamma.is_finite() && (0.25..=4.0).contains(&self.gamma)) {
            return bad("gamma must be in [0.25, 4]");
        }
        if !(self.g.abs() < 1.0 && (0.0..=1.0).contains(&self.albedo)) {
            return bad("g must be in (-1, 1) and albedo in [0, 1]");
        }
        if self.decoder > 0 && crate::model::Decoder::paper_small(self.resolution).is_err() {
            return bad("with decoder, resolution must be 8, 16, 32, 64, 128, ... (the decoder's cube)");
        }
        // Aligned on the frame, the finest stage would carve its hull before any alignment.
        if self.decoder > 0 && self.align && !self.shared_alignment {
            return bad("decoder needs the cameras aligned once per capture (shared_alignment) or not at all");
        }
        Ok(())
    }
}

/// One row of a fit's log.
#[derive(Clone, Debug, Serialize)]
pub struct FitRow {
    /// Stage: the levels coarsest first (0), after the decoder's stage
    /// when there is one (then 0 is the decoder's, 1 the finest level).
    pub level: usize,
    /// Update within the stage.
    pub update: usize,
    /// The images' mean squared error (code value / full scale, squared).
    pub image_mse: f64,
    /// The smoothness term.
    pub smoothness: f64,
    /// The sparsity term.
    pub sparsity: f64,
    /// Seconds since the fit began.
    pub seconds: f64,
}

/// A fitted frame.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The training cameras at the working resolution, the fitted density,
    /// lights and emission.
    pub scene: Scene,
    /// The settings it was fitted with.
    pub settings: FitSettings,
    /// Per training camera, how far its principal point was moved (working
    /// resolution pixels, right and down).
    pub offsets: Vec<[f64; 2]>,
    /// Per training camera, the factor its focal lengths were multiplied by
    /// (1 without `zoom`).
    pub zooms: Vec<f64>,
    /// Per training camera, its gain: its photograph is its render times it.
    pub gains: Vec<f64>,
    /// Per update.
    pub log: Vec<FitRow>,
    /// The lights' share of the training images' light at the end, the
    /// rest the emission's; `None` for emission-absorption, or with no light.
    pub light_share: Option<f64>,
    /// Seconds the fit took.
    pub seconds: f64,
}

impl Fit {
    /// Per training camera, how far its principal point was moved, in
    /// pixels of the capture's full resolution (right and down).
    pub fn offsets_px(&self) -> Vec<[f64; 2]> {
        let f = self.settings.factor as f64;
        self.offsets.iter().map(|o| [o[0] * f, o[1] * f]).collect()
    }
}

/// Fits the frame whose training images (at 1/`settings.factor` of the
/// capture's resolution) are `images`, seen by `cameras` (at the same
/// resolution), with the density on a grid over `smoke_box`. With `fixed`
/// corrections (a capture's rig) the cameras are corrected by them from the
/// start and not aligned again.
pub fn fit(
    cameras: &[Camera],
    images: &[Image],
    smoke_box: (Vec3, Vec3),
    settings: &FitSettings,
    fixed: Option<&Corrections>,
    progress: &mut dyn FnMut(&FitRow),
) -> Result<Fit> {
    settings.validate()?;
    let (cameras, mut offsets, mut zooms) = match fixed {
        Some(fixed) => {
            let (cameras, offsets) = fixed.apply(cameras, settings.factor)?;
            (cameras, offsets, fixed.zooms.clone())
        }
        None => (cameras.to_vec(), vec![[0.0; 2]; cameras.len()], vec![1.0; cameras.len()]),
    };
    let start = Instant::now();
    let (lo, hi) = smoke_box;
    let codes = images;
    // The photographs through the inverse response: linear in the lights.
    let photographs: Vec<Image> = images.iter().map(|im| im.map(|v| v.powf(settings.gamma))).collect();
    let threshold = settings.threshold.powf(settings.gamma);
    // The photographs over their cameras' gains: what the renders are fitted to.
    let mut gains = vec![1.0; images.len()];
    let mut images = photographs.clone();
    let levels = settings.updates.len();
    let mut smoothness_axes = [settings.horizontal_smoothness; 3];
    smoothness_axes[up_axis(&cameras)] = 1.0;
    let mut scene = Scene {
        density: Grid::new(lo, hi, [1, 1, 1], vec![0.0]),
        medium: Medium {
            sigma_t_scale: 1.0,
            albedo: settings.albedo,
            g: settings.g,
            max_order: settings.model.max_order(settings.orders),
            emission: 0.0,
        },
        lights: if settings.model.lit() { candidate_lights(&lo, &hi) } else { Vec::new() },
        cameras,
        render: RenderSettings {
            photons: if settings.model == ImageModel::Multiple { settings.photons } else { 0 },
            spp: settings.spp,
            seed: settings.seed,
            ..RenderSettings::default()
        },
    };
    let mut log = Vec::new();
    let mut renders = 0u64;
    // The last update's images: where the lights are fitted again, they censor the targets.
    let mut last: Option<Vec<Image>> = None;
    // Levenberg-Marquardt damping of the lights' places, kept between calls.
    let mut damping = 1e-3;
    // Emission-absorption has no lights: its emission is its image.
    let ambient = settings.ambient || !settings.model.lit();
    // The stages: every level, coarsest first; or the decoder's, then the finest level.
    let stages: Vec<(Option<usize>, usize)> = if settings.decoder > 0 {
        vec![(None, settings.decoder), (Some(levels - 1), settings.updates[levels - 1])]
    } else {
        settings.updates.iter().enumerate().map(|(level, &updates)| (Some(level), updates)).collect()
    };
    for (stage, &(level, updates)) in stages.iter().enumerate() {
        let grid = match level {
            Some(level) => {
                let shape = grid_shape(&lo, &hi, settings.resolution >> (levels - 1 - level));
                Grid::new(lo, hi, shape, vec![0.0; shape.iter().product()])
            }
            None => cube_around(&lo, &hi, settings.resolution),
        };
        let aligned = fixed.is_some() || offsets.iter().any(|o| o[0] != 0.0 || o[1] != 0.0);
        let margin = if aligned { settings.aligned_margin } else { SILHOUETTE_MARGIN_PX };
        let silhouettes: Vec<Vec<bool>> = codes.iter().map(|im| real_silhouette(im, settings.factor, margin)).collect();
        let inside = in_box(&grid, &lo, &hi);
        let hull: Vec<bool> =
            carve(&grid, &scene.cameras, &silhouettes).iter().zip(&inside).map(|(&h, &i)| h && i).collect();
        if !hull.iter().any(|&h| h) {
            return Err(Error("the training cameras' silhouettes have no voxel in common: no smoke in the box".into()));
        }
        let (mut density, mut params) = match (stage, level) {
            (0, None) => decoder_start(&grid, &hull, settings)?,
            (_, None) => unreachable!("the decoder's stage is the first"),
            (0, Some(_)) => {
                let shape = start_shape(&grid, &hull, &scene.cameras, &photographs, settings.start_shape);
                voxel_params(start_density(&grid, &shape, settings.start_depth), &hull, settings)
            }
            (_, Some(_)) => voxel_params(upsample(&scene.density, &grid, &hull), &hull, settings),
        };
        let support =
            Grid::new(grid.lo, grid.hi, grid.shape, hull.iter().map(|&h| if h { 1.0 } else { 0.0 }).collect());
        for update in 0..updates {
            scene.density = density.clone();
            if update % settings.refit_every == 0 {
                if let (true, true, None, Some(rendered)) = (settings.align, stage > 0, fixed, &last) {
                    align_cameras(&mut scene.cameras, &mut offsets, &mut zooms, settings.zoom, rendered, &images);
                }
                let targets = censored(&images, last.as_deref(), threshold, &gains);
                let basis = fit_lights(&mut scene, &targets, ambient, &mut renders)?;
                if settings.gains && stage > 0 {
                    fit_gains(&mut gains, &weights_of(&scene), &basis, &targets);
                    images = photographs.iter().zip(&gains).map(|(p, g)| p.map(|v| v / g)).collect();
                }
                if settings.lights > 0 && stage > 0 && settings.model.lit() {
                    place_lights(&mut scene, &targets, &basis, settings.lights, ambient, &mut damping, &mut renders);
                }
            }
            scene.render.seed = settings.seed.wrapping_add(renders);
            renders += 1;
            let frozen = Frozen::new(&scene, Some(&support));
            let targets = censored(&images, Some(&frozen.images), threshold, &gains);
            let reverse = reverse_gradient(&frozen, &targets, Subset::full());
            last = Some(frozen.images.clone());
            let (smooth, smooth_grad) = smoothness(&density, &hull, settings.smoothness, smoothness_axes);
            let (sparse, sparse_grad) = sparsity(&density, &hull, settings.sparsity);
            let grad: Vec<f64> = (0..density.len())
                .map(|v| if hull[v] { reverse.grad[v] + smooth_grad[v] + sparse_grad[v] } else { 0.0 })
                .collect();
            if grad.iter().any(|g| !g.is_finite()) {
                return Err(Error(format!("stage {stage}, update {update}: the gradient is not finite")));
            }
            params.step(&mut density, &hull, &grad);
            let row = FitRow {
                level: stage,
                update,
                image_mse: reverse.loss,
                smoothness: smooth,
                sparsity: sparse,
                seconds: start.elapsed().as_secs_f64(),
            };
            progress(&row);
            log.push(row);
        }
        if level.is_none() && !density.data.iter().any(|&d| d > 0.0) {
            return Err(Error("the decoder's fit went to 0 everywhere in the hull: try another seed".into()));
        }
        scene.density = density;
    }
    let targets = censored(&images, last.as_deref(), threshold, &gains);
    let basis = fit_lights(&mut scene, &targets, ambient, &mut renders)?;
    let light_share = if settings.model.lit() { light_share(&basis, &weights_of(&scene)) } else { None };
    let seconds = start.elapsed().as_secs_f64();
    Ok(Fit { scene, settings: settings.clone(), offsets, zooms, gains, log, light_share, seconds })
}

/// Moves every camera's principal point (and with `zoom` scales its focal
/// lengths) so that its photograph agrees with `rendered` (its render
/// before the move), keeping the mean move 0 and the magnifications'
/// geometric mean 1: a shift or magnification shared by every camera is
/// the density's to explain, not the cameras'.
fn align_cameras(
    cameras: &mut [Camera],
    offsets: &mut [[f64; 2]],
    zooms: &mut [f64],
    zoom: bool,
    rendered: &[Image],
    photos: &[Image],
) {
    let warps: Vec<_> = rendered
        .iter()
        .zip(photos)
        .zip(cameras.iter())
        .map(|((r, p), c)| {
            let [_, _, cx, cy] = c.intrinsics();
            warp(r, p, [cx, cy], zoom)
        })
        .collect();
    let mut moves: Vec<[f64; 2]> = warps.iter().map(|w| w.offset).collect();
    let mut factors: Vec<f64> = warps.iter().map(|w| 1.0 + w.zoom).collect();
    take_out_shared(&mut moves, &mut factors);
    for (((camera, total), factor), ([dx, dy], k)) in
        cameras.iter_mut().zip(offsets).zip(zooms).zip(moves.into_iter().zip(factors))
    {
        *camera = camera.shift(dx, dy).zoom(k);
        *total = [total[0] + dx, total[1] + dy];
        *factor *= k;
    }
}

/// `targets` where the capture's threshold hides nothing, and `rendered`
/// itself (no error) where a target is 0 and the render is below the
/// threshold: there the photograph cannot tell the render is wrong.
/// `threshold` is in linear units of a camera of gain 1; a camera's render
/// meets it at `threshold / gain`. Without a render (none yet), `targets`
/// as they are.
fn censored(targets: &[Image], rendered: Option<&[Image]>, threshold: f64, gains: &[f64]) -> Vec<Image> {
    let Some(rendered) = rendered else { return targets.to_vec() };
    targets
        .iter()
        .zip(rendered)
        .zip(gains)
        .map(|((t, r), gain)| Image {
            width: t.width,
            height: t.height,
            data: t
                .data
                .iter()
                .zip(&r.data)
                .map(|(&t, &r)| if t == 0.0 && r * gain < threshold { r } else { t })
                .collect(),
        })
        .collect()
}

/// A rendered view through a camera of `gain` and the response of
/// `settings`: the gain, the curve ([`FitSettings::gamma`]), then the
/// capture's processing (0 below its threshold), in code value / full scale.
pub fn respond(image: &Image, gain: f64, settings: &FitSettings) -> Image {
    image.map(|v| {
        let code = (gain * v).max(0.0).powf(1.0 / settings.gamma);
        if code < settings.threshold {
            0.0
        } else {
            code
        }
    })
}

/// The training cameras' views of a fitted frame at the working
/// resolution, through their gains and the response.
pub fn training_views(fit: &Fit) -> Vec<Image> {
    let rendered = render_photon(&fit.scene).images;
    rendered.iter().zip(&fit.gains).map(|(image, &gain)| respond(image, gain, &fit.settings)).collect()
}

/// Root mean square difference, in code value / full scale, between the
/// training cameras' views of a fitted frame and their photographs `images`.
pub fn training_rmse(fit: &Fit, images: &[Image]) -> f64 {
    let views: Vec<Vec<f64>> = training_views(fit).into_iter().map(|v| v.data).collect();
    mse(&views, images).sqrt()
}

/// What a stage's Adam steps move.
enum Params {
    /// The density itself, projected to >= 0.
    Density(Adam),
    /// The density's logarithm inside the hull.
    Log(Adam, Vec<f64>),
    /// The paper's model: the density is `scale` times the decoder's output.
    Decoder { model: Model, scale: f64, latent: Adam, weights: Adam },
}

impl Params {
    /// One Adam step along `grad` (d loss / d density), `density` set to where it leads.
    fn step(&mut self, density: &mut Grid<f64>, hull: &[bool], grad: &[f64]) {
        match self {
            Params::Density(adam) => {
                adam.step(&mut density.data, grad);
                density.data.iter_mut().for_each(|d| *d = d.max(0.0));
            }
            Params::Log(adam, log_values) => {
                // d L / d ln(rho) = rho d L / d rho.
                let log_grad: Vec<f64> = grad.iter().zip(&density.data).map(|(g, d)| g * d).collect();
                adam.step(log_values, &log_grad);
                from_log(density, log_values, hull);
            }
            Params::Decoder { model, scale, latent, weights } => {
                let grad_out: Vec<f64> = grad.iter().map(|g| g * *scale).collect();
                let (grad_z, grad_w) = model.decoder.backward(&model.z, &model.w, &model.mask, &grad_out);
                latent.step(&mut model.z, &grad_z);
                weights.step(&mut model.w, &grad_w);
                let out = model.decoder.forward(&model.z, &model.w, &model.mask);
                density.data = out.iter().map(|v| v * *scale).collect();
            }
        }
    }
}

/// A per-voxel stage from `density`: its steps on the logarithm or on the density.
fn voxel_params(mut density: Grid<f64>, hull: &[bool], settings: &FitSettings) -> (Grid<f64>, Params) {
    let mean = mean_inside(&density, hull).max(f64::MIN_POSITIVE);
    let params = if settings.log_density {
        let log_values = to_log(&mut density, hull, mean);
        Params::Log(Adam::new(density.len(), settings.lr), log_values)
    } else {
        Params::Density(Adam::new(density.len(), settings.lr * mean))
    };
    (density, params)
}

/// The decoder's stage: the paper's model from scratch (seeded by the fit's
/// seed) on `grid`, its output scaled to the start's optical depth, with the
/// paper's Adam steps for latent and weights.
fn decoder_start(grid: &Grid<f64>, hull: &[bool], settings: &FitSettings) -> Result<(Grid<f64>, Params)> {
    let decoder = Decoder::paper_small(settings.resolution)?;
    let model =
        Model { z: decoder.init_latent(settings.seed), w: decoder.init(settings.seed), mask: hull.to_vec(), decoder };
    let out = model.decoder.forward(&model.z, &model.w, &model.mask);
    if !out.iter().any(|&v| v > 0.0) {
        return Err(Error("the decoder's first output is 0 everywhere in the hull: try another seed".into()));
    }
    let scale = depth_scale(grid, &out, settings.start_depth);
    let density = Grid::new(grid.lo, grid.hi, grid.shape, out.iter().map(|v| v * scale).collect());
    let paper = TrainSettings::default();
    let (latent, weights) = (Adam::new(model.z.len(), paper.lr_latent), Adam::new(model.w.len(), paper.lr_weights));
    Ok((density, Params::Decoder { model, scale, latent, weights }))
}

/// A cube of `n` voxels a side, centred on the box `lo`..`hi`, its edge the box's longest.
fn cube_around(lo: &Vec3, hi: &Vec3, n: usize) -> Grid<f64> {
    let half = (hi - lo).max() / 2.0;
    let centre = (lo + hi) / 2.0;
    let corner = Vec3::new(half, half, half);
    Grid::new(centre - corner, centre + corner, [n, n, n], vec![0.0; n * n * n])
}

/// Whether each voxel's centre lies in the box `lo`..`hi`: every voxel of
/// a level's grid; the decoder's cube reaches past the box's shorter edges.
fn in_box(grid: &Grid<f64>, lo: &Vec3, hi: &Vec3) -> Vec<bool> {
    let all = vec![true; grid.len()];
    let inside = over_hull(grid, &all, |c| if (0..3).all(|a| c[a] >= lo[a] && c[a] <= hi[a]) { 1.0 } else { 0.0 });
    inside.iter().map(|&v| v > 0.0).collect()
}

/// The grid's shape (Z, Y, X) over `lo..hi` with `longest` voxels along the
/// longest edge and cubic voxels as near as whole numbers allow.
fn grid_shape(lo: &Vec3, hi: &Vec3, longest: usize) -> [usize; 3] {
    let e = hi - lo;
    let max = e.x.max(e.y).max(e.z);
    let n = |x: f64| ((x / max * longest as f64).round() as usize).max(1);
    [n(e.z), n(e.y), n(e.x)]
}

/// Per voxel, the start's relative density (0 outside the hull).
fn start_shape(grid: &Grid<f64>, hull: &[bool], cameras: &[Camera], photos: &[Image], shape: StartShape) -> Vec<f64> {
    let out = over_hull(grid, hull, |centre| {
        let seen = cameras.iter().zip(photos).map(|(camera, photo)| match camera.pixel_of(&centre) {
            Some((x, y)) => photo.data[y * photo.width + x].max(0.0),
            None => 0.0,
        });
        match shape {
            StartShape::Even => 1.0,
            StartShape::Darkest => seen.fold(f64::INFINITY, f64::min),
            StartShape::GeometricMean => {
                let logs: Vec<f64> = seen.map(|v| v.max(1e-6).ln()).collect();
                (logs.iter().sum::<f64>() / logs.len().max(1) as f64).exp()
            }
        }
    });
    // Where every view is dark, the even start.
    if out.iter().all(|&v| v <= 0.0) {
        return hull.iter().map(|&h| if h { 1.0 } else { 0.0 }).collect();
    }
    out
}

/// The start: `shape` scaled so that its mean over the voxels where it is
/// positive is an optical depth of `depth` across their mean chord (their
/// volume over their largest cross-section, roughly).
fn start_density(grid: &Grid<f64>, shape: &[f64], depth: f64) -> Grid<f64> {
    let rho = depth_scale(grid, shape, depth);
    Grid::new(grid.lo, grid.hi, grid.shape, shape.iter().map(|&s| s * rho).collect())
}

/// The factor on `shape` that makes [`start_density`] of it.
fn depth_scale(grid: &Grid<f64>, shape: &[f64], depth: f64) -> f64 {
    let inside = shape.iter().filter(|&&s| s > 0.0).count().max(1) as f64;
    let mean = shape.iter().sum::<f64>() / inside;
    let v = grid.voxel_size();
    let voxel = (v.x * v.y * v.z).cbrt();
    let chord = inside.cbrt() * voxel;
    depth / chord / mean
}

/// `coarse` sampled at `grid`'s voxel centres (trilinear), 0 outside `hull`.
fn upsample(coarse: &Grid<f64>, grid: &Grid<f64>, hull: &[bool]) -> Grid<f64> {
    Grid::new(grid.lo, grid.hi, grid.shape, over_hull(grid, hull, |centre| coarse.at(&centre)))
}

/// `value` at the centre of every voxel of `grid` inside `hull`, 0 outside.
fn over_hull(grid: &Grid<f64>, hull: &[bool], value: impl Fn(Vec3) -> f64) -> Vec<f64> {
    let [nz, ny, nx] = grid.shape;
    let mut out = vec![0.0; grid.len()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let idx = grid.index(k, j, i);
                if hull[idx] {
                    out[idx] = value(grid.voxel_center(k, j, i));
                }
            }
        }
    }
    out
}

/// What Adam moves with `log_density`: the logarithm of `density` inside
/// `hull`, a voxel at 0 raised to a thousandth of `mean` first (`density`
/// is set to what the logarithm gives back).
fn to_log(density: &mut Grid<f64>, hull: &[bool], mean: f64) -> Vec<f64> {
    let log_values: Vec<f64> =
        density.data.iter().zip(hull).map(|(&d, &h)| if h { d.max(1e-3 * mean).ln() } else { 0.0 }).collect();
    from_log(density, &log_values, hull);
    log_values
}

/// `density` from its logarithm inside `hull`, 0 outside.
fn from_log(density: &mut Grid<f64>, log_values: &[f64], hull: &[bool]) {
    for ((d, &u), &h) in density.data.iter_mut().zip(log_values).zip(hull) {
        *d = if h { u.exp() } else { 0.0 };
    }
}

/// Mean density over the hull's voxels.
fn mean_inside(density: &Grid<f64>, hull: &[bool]) -> f64 {
    let (sum, n) =
        density.data.iter().zip(hull).filter(|(_, &h)| h).fold((0.0, 0usize), |(s, n), (d, _)| (s + d, n + 1));
    sum / n.max(1) as f64
}

/// Photons of a rendered view of a fitted scene (multiple scattering only):
/// more than an update's, so that the view's noise is far below the fit's error.
pub const VIEW_PHOTONS: u64 = 200_000;

/// Camera samples per pixel of a rendered view: at the capture's resolution
/// a pixel is a small fraction of a voxel, so one sample is enough.
pub const VIEW_SPP: u32 = 1;

/// The image `camera` (at any resolution) sees of a fitted scene, rendered
/// with [`VIEW_PHOTONS`] and [`VIEW_SPP`].
pub fn render_view(fit: &Fit, camera: &Camera) -> Image {
    let mut scene = fit.scene.clone();
    scene.cameras = vec![camera.clone()];
    if scene.render.photons > 0 {
        scene.render.photons = VIEW_PHOTONS;
    }
    scene.render.spp = VIEW_SPP;
    scene.render.seed = fit.settings.seed.wrapping_add(u64::MAX / 2);
    respond(&render_photon(&scene).images[0], 1.0, &fit.settings)
}

/// The grid axis (z, y, x: 0, 1, 2, as a grid's shape) nearest the
/// cameras' mean up direction.
fn up_axis(cameras: &[Camera]) -> usize {
    let up = cameras.iter().fold(Vec3::zeros(), |sum, c| sum + c.basis().1);
    let along = [up.z.abs(), up.y.abs(), up.x.abs()];
    (0..3).max_by(|&a, &b| along[a].total_cmp(&along[b])).unwrap_or(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_up_axis_is_the_grid_axis_nearest_the_cameras_mean_up() {
        let camera = |x: f64, y: f64, z: f64, up: Vec3| Camera {
            position: Vec3::new(x, y, z),
            look_at: Vec3::zeros(),
            up,
            lens: crate::scene::Lens::FovY(40.0),
            width: 8,
            height: 8,
        };
        // On a level arc, tilted up as ScalarFlow's cameras are: y.
        let y_up =
            [camera(2.0, -0.6, 0.0, Vec3::y()), camera(0.0, -0.6, 2.0, Vec3::y()), camera(-1.4, -0.6, 1.4, Vec3::y())];
        assert_eq!(up_axis(&y_up), 1);
        // A capture whose up is z (as many transforms.json are): z, the grid's axis 0.
        let z_up = [camera(2.0, 0.0, 0.5, Vec3::z()), camera(0.0, -2.0, 0.5, Vec3::z())];
        assert_eq!(up_axis(&z_up), 0);
    }

    /// Three cameras of `size` pixels on a ring around the origin, each
    /// seeing a disc of `radius` pixels at 0.3 in its middle: a ball's views.
    fn ball_views(size: usize, radius: f64) -> ([Camera; 3], Vec<Image>) {
        let camera = |x: f64, z: f64| Camera {
            position: Vec3::new(x, 0.3, z),
            look_at: Vec3::zeros(),
            up: Vec3::y(),
            lens: crate::scene::Lens::FovY(40.0),
            width: size,
            height: size,
        };
        let centre = (size as f64 - 1.0) / 2.0;
        let disc = (0..size * size)
            .map(|i| {
                let (x, y) = ((i % size) as f64 - centre, (i / size) as f64 - centre);
                if x * x + y * y < radius * radius {
                    0.3
                } else {
                    0.0
                }
            })
            .collect();
        let cameras = [camera(2.5, 0.0), camera(0.0, 2.5), camera(-1.8, 1.8)];
        (cameras, vec![Image { width: size, height: size, data: disc }; 3])
    }

    /// Both updates fit three views of a bright disc (a ball) that fills
    /// only part of the box, so the hull leaves some voxels out. The
    /// multiplicative one takes other steps and keeps every voxel of the
    /// hull positive (the additive one's projection may zero some), and
    /// both lower the images' error.
    #[test]
    fn the_log_density_update_fits_a_ball() {
        let (cameras, images) = ball_views(64, 16.0);
        let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let run = |log_density: bool| {
            let settings = FitSettings {
                model: ImageModel::EmissionAbsorption,
                // The silhouettes' margin (40 pixels of the capture) is 10 at 1/4.
                factor: 4,
                resolution: 8,
                updates: vec![10, 20],
                align: false,
                gains: false,
                threshold: 0.0,
                log_density,
                ..FitSettings::default()
            };
            fit(&cameras, &images, smoke_box, &settings, None, &mut |_| {}).unwrap()
        };
        let (additive, multiplicative) = (run(false), run(true));
        for done in [&additive, &multiplicative] {
            let first = done.log[0].image_mse;
            let last = done.log.last().unwrap().image_mse;
            assert!(last < first / 2.0, "the images' error fell from {first} to only {last}");
            assert!(done.scene.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
        }
        assert_ne!(additive.scene.density.data, multiplicative.scene.density.data, "log_density changed no step");
        // Outside the hull both are 0; inside it the multiplicative density never is.
        let zero = |d: &Grid<f64>| d.data.iter().map(|&v| v == 0.0).collect::<Vec<bool>>();
        let (zero_add, zero_mul) = (zero(&additive.scene.density), zero(&multiplicative.scene.density));
        assert!(zero_mul.iter().any(|&z| z), "the hull left no voxel out: the test exercises nothing");
        assert!(zero_mul.iter().zip(&zero_add).all(|(&m, &a)| !m || a), "a voxel of the hull went to 0");
        assert!(zero_mul.iter().any(|&z| !z), "the multiplicative fit left no density");
    }

    /// The paper's model fits three views of a ball, then the finest level
    /// goes on from its density; settings it cannot run with are refused.
    #[test]
    fn the_decoder_stage_fits_a_ball_before_the_finest_level() {
        let (cameras, images) = ball_views(64, 10.0);
        // A box longer along y: the decoder's cube holds voxels outside it.
        let smoke_box = (Vec3::new(-0.4, -0.5, -0.4), Vec3::new(0.4, 0.5, 0.4));
        let settings = FitSettings {
            model: ImageModel::EmissionAbsorption,
            // The silhouettes' margin is 10 pixels at 1/4: the hull leaves voxels out.
            factor: 4,
            resolution: 8,
            updates: vec![10, 15],
            decoder: 30,
            // The images alone: in so small a scene the smoothness term pulls
            // the decoder's rough density back up the images' error.
            smoothness: 0.0,
            align: false,
            gains: false,
            threshold: 0.0,
            ..FitSettings::default()
        };
        let done = fit(&cameras, &images, smoke_box, &settings, None, &mut |_| {}).unwrap();
        let stage = |s: usize| done.log.iter().filter(|r| r.level == s).map(|r| r.image_mse).collect::<Vec<f64>>();
        let (decoder, finest) = (stage(0), stage(1));
        // The decoder's updates, then the finest level's only.
        assert_eq!((decoder.len(), finest.len(), done.log.len()), (30, 15, 45));
        assert!(
            decoder[29] < decoder[0] / 2.0,
            "the decoder's stage lowered the error from {} to only {}",
            decoder[0],
            decoder[29]
        );
        assert!(finest[0] < decoder[0] / 2.0, "the finest level did not start from the decoder's fit");
        assert!(finest[14] < decoder[29], "the finest level did not go on from the decoder's fit");
        assert!(done.scene.density.data.iter().any(|&d| d == 0.0), "the hull left no voxel out");
        assert_eq!(done.scene.density.shape, grid_shape(&smoke_box.0, &smoke_box.1, 8));
        assert!(done.scene.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
        // The cube's voxels past the box: centres at +-0.4375 along x and z.
        let inside = in_box(&cube_around(&smoke_box.0, &smoke_box.1, 8), &smoke_box.0, &smoke_box.1);
        assert_eq!(inside.iter().filter(|&&i| i).count(), 6 * 8 * 6);
        let cube = FitSettings { resolution: 12, ..settings };
        assert!(cube.validate().unwrap_err().0.contains("decoder"), "a decoder needs a cube of 4 * 2^n voxels");
        let per_frame = FitSettings { align: true, shared_alignment: false, ..cube };
        assert!(FitSettings { resolution: 8, ..per_frame }.validate().unwrap_err().0.contains("shared_alignment"));
    }

    #[test]
    fn the_shipped_fit_settings_are_valid_and_change_what_their_names_say() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/studies/real_dev");
        let mut names = Vec::new();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let settings: FitSettings = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            settings.validate().unwrap();
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            let d = FitSettings::default();
            // A name is one or more settings joined by '+'.
            let says = |part: &str| match part {
                "default" => settings == d,
                "no_align" => !settings.align,
                "zoom" => settings.zoom && settings.align,
                "no_zoom" => !settings.zoom,
                "shared_alignment" => settings.aligns_once(),
                "per_frame_alignment" => !settings.shared_alignment && settings.align,
                n if n.starts_with("smooth_") => settings.smoothness.to_string() == n["smooth_".len()..],
                n if n.starts_with("horizontal_") => {
                    settings.horizontal_smoothness.to_string() == n["horizontal_".len()..]
                }
                n if n.starts_with("sparsity_") => settings.sparsity.to_string() == n["sparsity_".len()..],
                n if n.starts_with("g_") => settings.g.to_string() == n["g_".len()..],
                n if n.starts_with("albedo_") => settings.albedo.to_string() == n["albedo_".len()..],
                "gains" => settings.gains,
                "log_density" => settings.log_density,
                "additive" => !settings.log_density,
                n if n.starts_with("lr_") => settings.lr.to_string() == n["lr_".len()..],
                "no_ambient" => !settings.ambient,
                "factor_4_res_96" => settings.factor == 4 && settings.resolution == 96,
                n if n.starts_with("factor_") && !n.contains("res") => {
                    settings.factor.to_string() == n["factor_".len()..]
                }
                n if n.starts_with("res_") => settings.resolution.to_string() == n["res_".len()..],
                n if n.starts_with("lights_") => settings.lights.to_string() == n["lights_".len()..],
                n if n.starts_with("updates_") => {
                    n["updates_".len()..].split('_').map(|u| u.parse().unwrap()).collect::<Vec<usize>>()
                        == settings.updates
                }
                n if n.starts_with("margin_") => settings.aligned_margin.to_string() == n["margin_".len()..],
                "darkest" => settings.start_shape == StartShape::Darkest,
                "geometric_mean" => settings.start_shape == StartShape::GeometricMean,
                n if n.starts_with("rig_frames_") => settings.rig_frames.to_string() == n["rig_frames_".len()..],
                n if n.starts_with("rig_factor_") => settings.rig_factor == n["rig_factor_".len()..].parse().ok(),
                n if n.starts_with("orders_") => settings.orders.to_string() == n["orders_".len()..],
                n if n.starts_with("photons_") => settings.photons.to_string() == n["photons_".len()..],
                n if n.starts_with("spp_") => settings.spp.to_string() == n["spp_".len()..],
                n if n.starts_with("depth_") => settings.start_depth.to_string() == n["depth_".len()..],
                n if n.starts_with("gamma_") => settings.gamma.to_string() == n["gamma_".len()..],
                n if n.starts_with("decoder_") => settings.decoder.to_string() == n["decoder_".len()..],
                _ => false,
            };
            let changed = name.split('+').all(says);
            assert!(changed, "{name}.json does not set what its name says");
            names.push(name);
        }
        assert!(names.len() >= 2, "{names:?}");
    }

    /// A photograph through the inverse response, over a camera's gain, comes
    /// back through `respond` as it was; below the threshold, as 0.
    #[test]
    fn the_response_inverts_what_the_fit_works_on() {
        let settings = FitSettings { gamma: 2.2, ..FitSettings::default() };
        let photo = Image { width: 4, height: 1, data: vec![0.0, 5.0 / 255.0, 0.1, 0.9] };
        let gain = 1.3;
        let linear = photo.map(|v| v.powf(settings.gamma) / gain);
        let back = respond(&linear, gain, &settings);
        assert_eq!(back.data[..2], [0.0, 0.0]);
        for (b, p) in back.data[2..].iter().zip(&photo.data[2..]) {
            assert!((b - p).abs() < 1e-12, "{back:?}");
        }
        let raw = respond(&linear, gain, &FitSettings::default());
        assert!((raw.data[3] - 0.9f64.powf(2.2)).abs() < 1e-12, "gamma 1 must pass radiance through: {raw:?}");
    }
}
