//! How a real capture's frame is fitted: the image model and every
//! setting of [`super::fit`], with the defaults the settings study chose
//! on frames and cameras other than those reported
//! (docs/studies/real_settings.md), and their checks.

use crate::error::{Error, Result};
use crate::scene::{Camera, Shadows};
use serde::{Deserialize, Serialize};

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
    pub(super) fn max_order(self, orders: u32) -> u32 {
        match self {
            ImageModel::Multiple => orders,
            _ => 1,
        }
    }

    /// Whether the model has lights.
    pub(super) fn lit(self) -> bool {
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
    ///
    /// [`sparsity`]: crate::capture::priors::sparsity
    pub sparsity: f64,
    /// Weight of the total-variation term ([`super::priors::total_variation`])
    /// against the images' mean squared error. Off: on the settings study's
    /// frames 0.003 and 0.01 lost 0.10 and 0.46 dB on the scoring camera.
    pub total_variation: f64,
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
    /// Where a photograph is 0 and a render above the threshold, measure
    /// the error to the threshold, the most the hidden value can have been
    /// (the distance from the interval the photograph allows), rather than
    /// to 0; in the black level's line too. Off by default: on the settings
    /// study's frames it moved every model by at most 0.03 dB.
    pub hidden_to_threshold: bool,
    /// Fit each working pixel to an interval rather than a value: from its
    /// photograph to its ceiling, the mean of its area with every code the
    /// threshold hid raised to the threshold
    /// ([`crate::capture::observe::area_ceiling`]). A render inside it is
    /// no error, one outside it is fitted to the nearer end. It extends
    /// `hidden_to_threshold` (a pixel hidden whole) to pixels the threshold
    /// hid part of, at the plume's edges. Off by default: on the settings
    /// study's frames multiple scattering lost 0.03 dB on the scoring
    /// camera, and every model fitted the training cameras 4 % less closely.
    pub interval_censoring: bool,
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
    /// With `align`, also turn every training camera about its optical axis
    /// by the angle that best turns its photograph onto the render, about
    /// its principal point; the angles' mean over the cameras stays 0. Off
    /// by default: on the settings study's frames it did not gain the
    /// 0.1 dB on the scoring camera a rule fixed before the run asked for.
    pub roll: bool,
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
    /// With `shared_alignment`, how many times the rig is fitted (1 to 10),
    /// each round's calibration frames starting from the last round's
    /// corrections and aligning the cameras again: a fit absorbs part of a
    /// camera's error into the density before the cameras move, so one
    /// round finds only part of it (in a test scene with one view moved 3
    /// pixels, 1.2 pixels after one round, 2.5 after three). 1 by default:
    /// on the settings study's frames 3 rounds lost 0.9 dB, the horizontal
    /// offsets drifting, traded with the density's sideways place.
    pub rig_rounds: usize,
    /// With `shared_alignment`, the working resolution of the calibration
    /// frames' fits, 1/`rig_factor` of the capture's; none: `factor`. On the
    /// settings study's frames 4 gained 0.07 dB at almost 4 times the rig's time.
    pub rig_factor: Option<usize>,
    /// With `shared_alignment`, the image model the calibration frames are
    /// fitted under; every model then sees the same cameras.
    /// Emission-absorption by default: on the settings study's frames
    /// multiple scattering placed the cameras within 0.2 pixels of it and
    /// scored the same, at 2.4 times the rig's time. Where the lights shape
    /// the images (a made capture), it gained 1.5 dB on the held-out camera.
    pub rig_model: ImageModel,
    /// With `shared_alignment` and a `rig_model` other than multiple: fit
    /// the first calibration frame under multiple scattering first, and
    /// fit the rig under multiple scattering if the lights carry more than
    /// this share of that frame's training images' light (the rest is the
    /// ambient term's). 0.1, a bound fixed before its study: on made
    /// captures whose probe gave the lights 22-24 % the rig under multiple
    /// scattering gained 0.47 dB on the held-out camera once and tied once;
    /// on the real clip the probe gives 1.6 % and the rig stays. The probe
    /// costs one fit. 1 or none: the rig keeps `rig_model`.
    pub rig_lit_share: Option<f64>,
    /// Dilation of the silhouettes (full-resolution pixels) once the
    /// training cameras are aligned: from then on each level's hull is
    /// carved through the aligned cameras with this margin. Before, the
    /// margin is the calibration's disagreement ([`SILHOUETTE_MARGIN_PX`]).
    /// On the settings study's frames 20 scored best of 0, 8, 20 and 40
    /// (0.3-0.5 dB over 40, every model) by the additive update; by the
    /// logarithmic one 8 scored 0.08 dB above 20, too little to change it.
    ///
    /// [`SILHOUETTE_MARGIN_PX`]: crate::capture::observe::SILHOUETTE_MARGIN_PX
    pub aligned_margin: f64,
    /// Lights whose places are fitted ([`super::lights`]): from the second
    /// stage on, the strongest this many candidates are kept and move
    /// whenever the lights are fitted again. 0: every candidate stays in
    /// its place and only the intensities are fitted.
    pub lights: usize,
    /// The candidate lights' angular radius seen from the box's centre
    /// (degrees, below 45): each a disc facing the box, as studio softboxes
    /// are, whose shadows are soft ([`super::lighting::candidate_lights`]).
    /// 0: points, by default: on the settings study's frames discs of 15
    /// degrees scored as points (within 0.01 dB on the scoring camera,
    /// with per-camera gains or one gain) at about 2-4 times the fit's time.
    pub light_radius_deg: f64,
    /// Fit a gain per training camera (the cameras' brightest smoke differs
    /// by up to about a third between them): the photographs are divided by
    /// their gains, whose geometric mean over the training cameras is held
    /// at 1. A held-out camera's gain is that mean, 1, by this rule fixed
    /// in advance. Off: one gain for every camera, absorbed by the lights.
    /// On by default: on the settings study's frames it gained 0.0-0.2 dB
    /// on the scoring camera for every model.
    pub gains: bool,
    /// Hold each training camera's gain at its rig's (the median over the
    /// rig's calibration frames, their geometric mean 1) instead of fitting
    /// it on every frame: a camera's exposure does not change during a
    /// capture, so how its view's brightness differs from frame to frame
    /// is left to the lights. Needs `gains` and `shared_alignment`; with
    /// `align` off there is no rig, and every frame fits its gains. Off by
    /// default: on the settings study's frames the lights took up the
    /// difference where the rig's gains were furthest from a frame's own,
    /// and multiple scattering lost 0.17 dB on the scoring camera (0.49 dB
    /// on that frame), emission-absorption 0.05.
    pub rig_gains: bool,
    /// Fit a black level per training camera beside its gain: its
    /// photograph is its render times the gain plus the black level (in
    /// code value / full scale, within the capture's threshold either way),
    /// an offset the capture's processing (background subtraction,
    /// rescaling) may have left. A held-out camera's black level is the
    /// training cameras' mean, by this rule fixed in advance. Needs `gains`;
    /// not with `rig_gains`. Off by default: on the settings study's frames
    /// the offsets came out at -1 to -8 codes and lowered the training
    /// error 4 %, and the scoring camera moved by 0.01 dB.
    pub black_level: bool,
    /// Model the lenses' natural fall-off (vignetting): every camera passes
    /// cos^4 of the angle between a pixel's ray and its optical axis, as an
    /// ideal thin lens does, so a photograph is divided by it before the fit
    /// and every rendered view multiplied by it. Off by default: cameras
    /// at one height and tilt see a point of the smoke through nearly the
    /// same part of their lenses, so the density takes the fall-off up;
    /// on the settings study's frames it cost 0.03 dB.
    pub lens_falloff: bool,
    /// Fit the emission beside the lights in the lit models: an ambient
    /// term, light that reaches every voxel alike and unshadowed. With it,
    /// the lit models contain emission-absorption (their lights all at 0).
    /// Off: the lights must explain every pixel, with their shadows.
    pub ambient: bool,
    /// The cameras' response curve, shared by all: a photograph's code
    /// value / full scale is the radiance (times the camera's gain) to the
    /// power 1/`gamma`. The fit works on the photographs to the power
    /// `gamma`, where the image is linear in the lights (each averaged over
    /// a working pixel after that power); rendered views go back through the
    /// curve. 1: the codes are proportional to radiance, which scored best
    /// on the settings study's frames (0.8, 1.5 and 2.2 lost 0.27-3.4 dB on
    /// the scoring camera under multiple scattering, every model lost).
    pub gamma: f64,
    /// Fit each level coarser than the finest on images downsampled twice
    /// as far as the next level's (area averaging; the finest level's at
    /// 1/`factor`), so that a voxel spans about as many pixels on every
    /// level: the coarse levels, which hand the finest one its start, then
    /// render a quarter of the pixels per level down. Never coarser than
    /// [`MIN_PYRAMID_PIXELS`] along an image's shorter side. On by default:
    /// on the settings study's frames both multiple scattering and
    /// emission-absorption scored 0.02 dB lower on the scoring camera, at
    /// 36 % fewer seconds a frame (the rig's 35 % fewer).
    pub image_pyramid: bool,
    /// How the fit's renders find a light's transmittance from a camera
    /// ray ([`Shadows`]). `auto` (the default) reads a grid of optical
    /// depths and marches shadow rays only near voxels too deep for it;
    /// `grid` reads the grid everywhere. Under the renderer's earlier
    /// `auto`, which marched every shadow ray of a render once one voxel
    /// passed an optical depth of 1 (the real clip's densest voxels hover
    /// about 1 during a fit), `grid` scored the same to 0.001 dB on the
    /// settings study's frames but saved only 4 % of multiple scattering's
    /// seconds a frame and 11 % of the rig's, short of the 15 % its rule
    /// asked.
    pub shadows: Shadows,
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
    /// Adam updates of the learned prior's latent before the per-voxel fit:
    /// the project's decoder pretrained on simulated plumes
    /// ([`crate::prior::default_dir`], its weights held), its 64^3 output
    /// on the cube around the smoke box, under the latent penalty of Table
    /// 1's prior fit. What it may bring: where four views leave the smoke's
    /// place along their rays open, a plume's shape instead of an even
    /// spread. The per-voxel fit then runs at the finest level only, from
    /// its density, as after `decoder`. 0: none. Off: on the settings
    /// study's frames 60 updates fitted the training cameras 11 % less
    /// closely and lost 0.35 dB on the scoring camera, and 3 dB on a
    /// capture made from the prior's own simulator.
    pub prior: usize,
    /// With `prior`: its 64^3 grid stretched over the smoke box itself, as
    /// a made capture's plume is ([`super::density::plume_in_box`]),
    /// instead of on the cube around the box (the prior's own proportions).
    pub prior_stretched: bool,
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
            total_variation: 0.0,
            start_depth: 1.0,
            start_shape: StartShape::Even,
            refit_every: 10,
            photons: 20_000,
            orders: 3,
            spp: 2,
            g: 0.6,
            albedo: 1.0,
            threshold: 8.0 / 255.0,
            hidden_to_threshold: false,
            interval_censoring: false,
            align: true,
            zoom: true,
            roll: false,
            shared_alignment: true,
            rig_frames: 3,
            rig_rounds: 1,
            rig_factor: None,
            rig_model: ImageModel::EmissionAbsorption,
            rig_lit_share: Some(0.1),
            aligned_margin: 20.0,
            lights: 0,
            light_radius_deg: 0.0,
            gains: true,
            rig_gains: false,
            black_level: false,
            lens_falloff: false,
            ambient: true,
            gamma: 1.0,
            image_pyramid: true,
            shadows: Shadows::Auto,
            decoder: 0,
            prior: 0,
            prior_stretched: false,
            seed: 0,
        }
    }
}

/// The fewest pixels along an image's shorter side that a level of
/// [`FitSettings::image_pyramid`] fits (a frame of ScalarFlow's at 1/8 is
/// 135 pixels across; its coarsest level, at 1/32, 33).
pub const MIN_PYRAMID_PIXELS: usize = 24;

impl FitSettings {
    /// Whether the training cameras are aligned once for every frame, by a
    /// rig ([`FitSettings::shared_alignment`]).
    pub fn aligns_once(&self) -> bool {
        self.align && self.shared_alignment
    }

    /// These settings for a capture of `frames` frames. A capture of one
    /// frame is its own rig's only calibration frame, so a rig would fit
    /// that frame twice before its fit: it is aligned during its fit
    /// instead, where the settings allow it (a density per voxel, the
    /// rig's gains not held). On five one-frame captures of the settings
    /// study that scored within 0.003 dB of the rig's mean in 40-50 % of
    /// the time.
    pub fn for_capture(&self, frames: usize) -> FitSettings {
        let aligns_on_the_frame = self.decoder == 0 && self.prior == 0 && !self.rig_gains;
        if frames == 1 && self.aligns_once() && aligns_on_the_frame {
            FitSettings { shared_alignment: false, ..self.clone() }
        } else {
            self.clone()
        }
    }

    /// How many times coarser than the working resolution the images of
    /// `level` (of [`FitSettings::updates`], coarsest first) are, for
    /// `cameras` at the working resolution: 1 without `image_pyramid`.
    pub fn image_scale(&self, level: usize, cameras: &[Camera]) -> usize {
        let below_finest = self.updates.len().saturating_sub(1 + level);
        if !self.image_pyramid || below_finest == 0 {
            return 1;
        }
        let shortest = cameras.iter().map(|c| c.width.min(c.height)).min().unwrap_or(0);
        (0..=below_finest).rev().map(|k| 1 << k).find(|&s| shortest / s >= MIN_PYRAMID_PIXELS).unwrap_or(1)
    }

    /// These settings with the density fitted per voxel from the even start
    /// (no `decoder`, no `prior`): what the rig and a fit from a given
    /// density run, whatever start the frames' own fits take.
    pub fn per_voxel(&self) -> FitSettings {
        FitSettings { decoder: 0, prior: 0, prior_stretched: false, ..self.clone() }
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

    /// The settings of the file a command-line `option` names, checked, its
    /// errors prefixed by the option; the defaults where none is given.
    pub fn read_option(path: Option<&std::path::Path>, option: &str) -> Result<FitSettings> {
        match path {
            Some(path) => FitSettings::read(path).map_err(|e| Error(format!("{option}: {e}"))),
            None => Ok(FitSettings::default()),
        }
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
        if self.rig_lit_share.is_some_and(|s| !(0.0..=1.0).contains(&s)) {
            return bad("rig_lit_share must be in [0, 1]");
        }
        if self.rig_frames == 0 {
            return bad("rig_frames must be at least 1");
        }
        if !(1..=10).contains(&self.rig_rounds) {
            return bad("rig_rounds must be in 1..=10");
        }
        if self.updates.is_empty() || self.resolution >> (self.updates.len() - 1) < 2 {
            return bad("resolution must give at least 2 voxels along the longest edge at the coarsest level");
        }
        // The gains, the cameras' alignment and the lights' places are
        // fitted from the second stage on, once a density explains the
        // photographs; with one level and no decoder or prior there is none.
        let one_stage = self.updates.len() == 1 && self.decoder == 0 && self.prior == 0;
        if one_stage && (self.gains || self.align || self.lights > 0) {
            return bad(
                "updates: one level leaves no stage to fit the gains, the cameras' alignment and the lights' places \
                 on (each starts at the second): give at least two levels, or set gains and align false and lights 0",
            );
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
        if !(self.total_variation.is_finite() && self.total_variation >= 0.0) {
            return bad("total_variation must be finite and >= 0");
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
        if !(self.light_radius_deg.is_finite() && (0.0..45.0).contains(&self.light_radius_deg)) {
            return bad("light_radius_deg must be in [0, 45) degrees");
        }
        if self.lights > 0 && self.light_radius_deg > 0.0 {
            return bad("lights (fitted places) moves point lights: it needs light_radius_deg 0");
        }
        if self.rig_gains && !(self.gains && self.shared_alignment) {
            return bad("rig_gains holds the rig's gains: it needs gains and shared_alignment");
        }
        if self.black_level && (!self.gains || self.rig_gains) {
            return bad("black_level is fitted with each camera's gain: it needs gains, and not rig_gains");
        }
        if !(self.g.abs() < 1.0 && (0.0..=1.0).contains(&self.albedo)) {
            return bad("g must be in (-1, 1) and albedo in [0, 1]");
        }
        if self.decoder > 0 && crate::model::Decoder::paper_small(self.resolution).is_err() {
            return bad("with decoder, resolution must be 8, 16, 32, 64, 128, ... (the decoder's cube)");
        }
        if self.decoder > 0 && self.prior > 0 {
            return bad("decoder and prior are two starts: set one of them");
        }
        if self.prior_stretched && self.prior == 0 {
            return bad("prior_stretched stretches the learned prior's grid: it needs prior");
        }
        if self.prior > 0 {
            let r = self.resolution;
            let prior = crate::prior::Prior::load(&crate::prior::default_dir()?)?;
            prior.check_grid([r, r, r]).map_err(|e| Error(format!("fit settings: prior: {}", e.0)))?;
        }
        // Aligned on the frame, the finest stage would carve its hull before any alignment.
        if (self.decoder > 0 || self.prior > 0) && self.align && !self.shared_alignment {
            return bad("decoder and prior need the cameras aligned once per capture (shared_alignment) or not at all");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bound_on_the_lights_share_outside_0_to_1_is_refused() {
        for bound in [-0.1, 1.5, f64::NAN] {
            let settings = FitSettings { rig_lit_share: Some(bound), ..FitSettings::default() };
            let err = settings.validate().unwrap_err().to_string();
            assert!(err.contains("rig_lit_share must be in [0, 1]"), "{bound}: {err}");
        }
        for bound in [0.0, 0.1, 1.0] {
            FitSettings { rig_lit_share: Some(bound), ..FitSettings::default() }.validate().unwrap();
        }
    }

    #[test]
    fn a_light_radius_outside_0_to_45_degrees_or_with_fitted_places_is_refused() {
        for radius in [-1.0, 45.0, f64::NAN] {
            let err = FitSettings { light_radius_deg: radius, ..FitSettings::default() }.validate().unwrap_err();
            assert!(err.to_string().contains("light_radius_deg must be in [0, 45)"), "{radius}: {err}");
        }
        let err = FitSettings { light_radius_deg: 15.0, lights: 3, ..FitSettings::default() }.validate().unwrap_err();
        assert!(err.to_string().contains("needs light_radius_deg 0"), "{err}");
        FitSettings { light_radius_deg: 15.0, ..FitSettings::default() }.validate().unwrap();
    }

    #[test]
    fn a_capture_of_one_frame_is_aligned_on_it_where_the_settings_allow() {
        let d = FitSettings::default();
        assert!(d.for_capture(2).aligns_once());
        let one = d.for_capture(1);
        assert!(one.align && !one.shared_alignment);
        one.validate().unwrap();
        assert_eq!(FitSettings { shared_alignment: true, ..one }, d, "nothing else changes");
        // A decoder's fit and the rig's gains need a rig; without alignment there is none.
        for keeps in [
            FitSettings { decoder: 250, ..d.clone() },
            FitSettings { rig_gains: true, ..d.clone() },
            FitSettings { align: false, ..d.clone() },
        ] {
            assert_eq!(keeps.for_capture(1), keeps);
        }
    }

    #[test]
    fn rig_gains_without_gains_or_a_rig_are_refused() {
        let rig_gains = FitSettings { rig_gains: true, ..FitSettings::default() };
        rig_gains.validate().unwrap();
        for settings in [
            FitSettings { gains: false, ..rig_gains.clone() },
            FitSettings { shared_alignment: false, ..rig_gains.clone() },
        ] {
            let err = settings.validate().unwrap_err().to_string();
            assert!(err.contains("rig_gains holds the rig's gains"), "{err}");
        }
    }

    #[test]
    fn a_black_level_without_gains_or_with_the_rigs_is_refused() {
        let black = FitSettings { black_level: true, ..FitSettings::default() };
        black.validate().unwrap();
        for settings in [FitSettings { gains: false, ..black.clone() }, FitSettings { rig_gains: true, ..black }] {
            let err = settings.validate().unwrap_err().to_string();
            assert!(err.contains("black_level is fitted with each camera's gain"), "{err}");
        }
    }

    #[test]
    fn the_image_pyramid_halves_each_coarser_level_down_to_its_smallest_images() {
        let camera = |width, height| Camera {
            position: crate::math::Vec3::new(0.0, 0.0, 2.0),
            look_at: crate::math::Vec3::zeros(),
            up: crate::math::Vec3::y(),
            lens: crate::scene::Lens::FovY(40.0),
            width,
            height,
        };
        // ScalarFlow's frames at 1/8: 135 x 240.
        let working = [camera(135, 240), camera(135, 240)];
        let on = FitSettings { image_pyramid: true, ..FitSettings::default() };
        assert_eq!((0..3).map(|l| on.image_scale(l, &working)).collect::<Vec<_>>(), [4, 2, 1]);
        let off = FitSettings { image_pyramid: false, ..on.clone() };
        assert!((0..3).all(|l| off.image_scale(l, &working) == 1));
        // 60 pixels across: 30 at 1/2, not 15 at 1/4.
        let small = [camera(60, 80), camera(135, 240)];
        assert_eq!((0..3).map(|l| on.image_scale(l, &small)).collect::<Vec<_>>(), [2, 2, 1]);
        let two_levels = FitSettings { updates: vec![40, 80], ..on };
        assert_eq!((0..2).map(|l| two_levels.image_scale(l, &working)).collect::<Vec<_>>(), [2, 1]);
    }

    #[test]
    fn one_level_is_refused_where_it_leaves_no_stage_for_the_gains_alignment_or_lights() {
        let one = FitSettings { updates: vec![80], ..FitSettings::default() };
        let err = one.validate().unwrap_err().to_string();
        assert!(err.contains("one level leaves no stage"), "{err}");
        FitSettings { gains: false, align: false, ..one.clone() }.validate().unwrap();
        FitSettings { decoder: 20, ..one }.validate().unwrap();
    }

    #[test]
    fn rig_rounds_outside_1_to_10_are_refused() {
        for rounds in [0, 11] {
            let err = FitSettings { rig_rounds: rounds, ..FitSettings::default() }.validate().unwrap_err().to_string();
            assert!(err.contains("rig_rounds must be in 1..=10"), "{rounds}: {err}");
        }
        FitSettings { rig_rounds: 10, ..FitSettings::default() }.validate().unwrap();
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
                "roll" => settings.roll && settings.align,
                "shared_alignment" => settings.aligns_once(),
                "per_frame_alignment" => !settings.shared_alignment && settings.align,
                n if n.starts_with("smooth_") => settings.smoothness.to_string() == n["smooth_".len()..],
                n if n.starts_with("horizontal_") => {
                    settings.horizontal_smoothness.to_string() == n["horizontal_".len()..]
                }
                n if n.starts_with("sparsity_") => settings.sparsity.to_string() == n["sparsity_".len()..],
                n if n.starts_with("tv_") => settings.total_variation.to_string() == n["tv_".len()..],
                n if n.starts_with("g_") => settings.g.to_string() == n["g_".len()..],
                n if n.starts_with("albedo_") => settings.albedo.to_string() == n["albedo_".len()..],
                "gains" => settings.gains,
                "one_gain" => !settings.gains,
                "rig_gains" => settings.rig_gains,
                "black_level" => settings.black_level,
                "lens_falloff" => settings.lens_falloff,
                "hidden_to_threshold" => settings.hidden_to_threshold,
                "interval_censoring" => settings.interval_censoring,
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
                n if n.starts_with("light_radius_deg_") => {
                    settings.light_radius_deg.to_string() == n["light_radius_deg_".len()..]
                }
                n if n.starts_with("updates_") => {
                    n["updates_".len()..].split('_').map(|u| u.parse().unwrap()).collect::<Vec<usize>>()
                        == settings.updates
                }
                n if n.starts_with("margin_") => settings.aligned_margin.to_string() == n["margin_".len()..],
                "darkest" => settings.start_shape == StartShape::Darkest,
                "geometric_mean" => settings.start_shape == StartShape::GeometricMean,
                n if n.starts_with("rig_frames_") => settings.rig_frames.to_string() == n["rig_frames_".len()..],
                n if n.starts_with("rig_rounds_") => settings.rig_rounds.to_string() == n["rig_rounds_".len()..],
                n if n.starts_with("rig_factor_") => settings.rig_factor == n["rig_factor_".len()..].parse().ok(),
                "rig_multiple" => settings.rig_model == ImageModel::Multiple,
                n if n.starts_with("rig_lit_share_") => {
                    settings.rig_lit_share == n["rig_lit_share_".len()..].parse().ok()
                }
                n if n.starts_with("orders_") => settings.orders.to_string() == n["orders_".len()..],
                n if n.starts_with("photons_") => settings.photons.to_string() == n["photons_".len()..],
                n if n.starts_with("spp_") => settings.spp.to_string() == n["spp_".len()..],
                n if n.starts_with("depth_") => settings.start_depth.to_string() == n["depth_".len()..],
                n if n.starts_with("gamma_") => settings.gamma.to_string() == n["gamma_".len()..],
                n if n.starts_with("decoder_") => settings.decoder.to_string() == n["decoder_".len()..],
                "prior_stretched" => settings.prior_stretched,
                "image_pyramid" => settings.image_pyramid,
                "no_image_pyramid" => !settings.image_pyramid,
                "shadows_grid" => settings.shadows == Shadows::Grid,
                "shadows_auto" => settings.shadows == Shadows::Auto,
                n if n.starts_with("prior_") => settings.prior.to_string() == n["prior_".len()..],
                _ => false,
            };
            let changed = name.split('+').all(says);
            assert!(changed, "{name}.json does not set what its name says");
            names.push(name);
        }
        assert!(names.len() >= 2, "{names:?}");
    }
}
