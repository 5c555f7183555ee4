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
//!
//! Its parts: what a fit carries from one update to the next
//! (`frame_fit`), the training cameras' alignment between updates
//! (`aligning`), the camera response both ways (`response`), and a fitted
//! frame seen through any camera (`views`).

mod aligning;
mod frame_fit;
mod response;
#[cfg(test)]
mod tests;
mod views;

pub use response::respond;
pub use views::{held_out_black, render_view, training_rmse, training_views, VIEW_PHOTONS, VIEW_SPP};

use super::align::Corrections;
use super::settings::FitSettings;
use crate::error::Result;
use crate::image::Image;
use crate::math::Vec3;
use crate::scene::{Camera, Scene};
use crate::volume::Grid;
use frame_fit::FrameFit;
use serde::Serialize;

/// One row of a fit's log.
#[derive(Clone, Debug, Serialize)]
pub struct FitRow {
    /// Stage: the levels coarsest first (0), after the decoder's stage
    /// when there is one (then 0 is the decoder's, 1 the finest level).
    pub level: usize,
    /// Update within the stage.
    pub update: usize,
    /// The images' mean squared error against the photographs over their
    /// cameras' responses (linear: code value / full scale to the power
    /// gamma, less the black level, over the gain; where a photograph is
    /// 0, a render below the threshold counts as no error).
    pub image_mse: f64,
    /// The smoothness term.
    pub smoothness: f64,
    /// The sparsity term.
    pub sparsity: f64,
    /// The total-variation term.
    pub total_variation: f64,
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
    /// Per training camera, the angle it was turned by about its optical
    /// axis (radians, [`Camera::roll`]; 0 without `roll`).
    pub rolls: Vec<f64>,
    /// Per training camera, its gain: its photograph is its render times it
    /// (plus its black level).
    pub gains: Vec<f64>,
    /// Per training camera, its black level in code value / full scale
    /// (through the inverse response curve); 0 without
    /// [`FitSettings::black_level`].
    pub black_levels: Vec<f64>,
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
/// resolution), with the density on a grid over `smoke_box`; `ceilings`,
/// where given, are the most each pixel can have been
/// ([`Observed::ceilings`](crate::capture::observe::Observed::ceilings),
/// for [`FitSettings::interval_censoring`]). With `fixed`
/// corrections (a capture's rig) the cameras are corrected by them from the
/// start and not aligned again.
pub fn fit(
    cameras: &[Camera],
    images: &[Image],
    ceilings: Option<&[Image]>,
    smoke_box: (Vec3, Vec3),
    settings: &FitSettings,
    fixed: Option<&Corrections>,
    progress: &mut dyn FnMut(&FitRow),
) -> Result<Fit> {
    settings.validate()?;
    let state = FrameFit::new(cameras, images, ceilings, smoke_box, settings, fixed)?;
    all_stages(state, progress)
}

/// [`fit`] with the cameras corrected by `start` from the first stage on
/// and aligned again from the second (with `settings.align`), the
/// corrections adding up. Why: a fit absorbs part of a camera's error into
/// the density before the cameras move, so one fit's alignment finds only
/// part of it; a rig fitted again from its own corrections finds more
/// ([`FitSettings::rig_rounds`]).
pub fn fit_aligning_from(
    cameras: &[Camera],
    images: &[Image],
    ceilings: Option<&[Image]>,
    smoke_box: (Vec3, Vec3),
    settings: &FitSettings,
    start: &Corrections,
    progress: &mut dyn FnMut(&FitRow),
) -> Result<Fit> {
    settings.validate()?;
    let mut state = FrameFit::new(cameras, images, ceilings, smoke_box, settings, Some(start))?;
    state.realign = true;
    all_stages(state, progress)
}

/// Every stage of a fit, then its lighting once more.
fn all_stages(mut state: FrameFit, progress: &mut dyn FnMut(&FitRow)) -> Result<Fit> {
    let settings = state.settings;
    let levels = settings.updates.len();
    // The stages: every level, coarsest first; or a decoder's (the paper's
    // or the learned prior's), then the finest level.
    let decoded = settings.decoder.max(settings.prior);
    let stages: Vec<(Option<usize>, usize)> = if decoded > 0 {
        vec![(None, decoded), (Some(levels - 1), settings.updates[levels - 1])]
    } else {
        settings.updates.iter().enumerate().map(|(level, &updates)| (Some(level), updates)).collect()
    };
    for (stage, &(level, updates)) in stages.iter().enumerate() {
        state.stage(stage, level, updates, progress)?;
    }
    state.finish()
}

/// The lighting a fit would give a density held as it is: the lights'
/// intensities, the emission and the gains from [`LIGHTING_ROUNDS`] of the
/// refits a fit makes between its density's updates, each after a render
/// of the scene as it then is; the training cameras as calibrated, or
/// corrected by `fixed`. Why: given a made capture's true density, it says
/// whether the training views can tell the lights apart at all, apart from
/// the density's fit; given any other density, what it is worth.
pub fn fit_lighting(
    cameras: &[Camera],
    images: &[Image],
    smoke_box: (Vec3, Vec3),
    density: Grid<f64>,
    settings: &FitSettings,
    fixed: Option<&Corrections>,
) -> Result<Fit> {
    settings.validate()?;
    let mut state = FrameFit::new(cameras, images, None, smoke_box, settings, fixed)?;
    state.scene.density = density;
    for _ in 0..LIGHTING_ROUNDS {
        state.render_last();
        // As on a fit's finest level: the gains too, the cameras held.
        state.refit_lighting(true)?;
    }
    state.finish()
}

/// [`fit`]'s last stage alone, its density starting from `start` (sampled
/// onto the finest level's grid, in its hull) instead of from a coarser
/// level's: the finest level's updates, the lighting and gains refitted as
/// on that level, the cameras corrected by `fixed` if given, else as
/// calibrated (never aligned: there is no coarser stage to align them on).
/// Why: a density another way gives (e.g. from neighbouring frames) is
/// tried as where the fit of this frame's images starts.
pub fn fit_from(
    cameras: &[Camera],
    images: &[Image],
    smoke_box: (Vec3, Vec3),
    start: Grid<f64>,
    settings: &FitSettings,
    fixed: Option<&Corrections>,
    progress: &mut dyn FnMut(&FitRow),
) -> Result<Fit> {
    let settings = FitSettings { align: false, ..settings.per_voxel() };
    settings.validate()?;
    let mut state = FrameFit::new(cameras, images, None, smoke_box, &settings, fixed)?;
    state.scene.density = start;
    let finest = settings.updates.len() - 1;
    // Numbered as a later stage (at least 1), so that it starts from the
    // density held and its refits fit the gains, as a fit's last stage does.
    state.stage(finest.max(1), Some(finest), settings.updates[finest], progress)?;
    state.finish()
}

/// How many times [`fit_lighting`] fits the lighting: as many as a fit's
/// last level does by default (80 updates, a refit every 10).
pub const LIGHTING_ROUNDS: usize = 8;
