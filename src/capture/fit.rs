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

use super::align::{take_out_shared, warp, Corrections, Free};
use super::density::{
    cube_around, decoder_start, grid_shape, in_box, prior_start, start_density, start_shape, upsample, voxel_params,
    Params,
};
use super::lighting::{
    candidate_lights, disc_points, fit_gains, fit_gains_and_blacks, fit_lights, light_share, place_lights, weights_of,
};
use super::observe::{real_silhouette, SILHOUETTE_MARGIN_PX};
use super::priors::{smoothness, sparsity, total_variation};
use super::settings::{FitSettings, ImageModel};
use crate::error::{Error, Result};
use crate::grad::loss::mse;
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::image::Image;
use crate::math::Vec3;
use crate::recon::hull::carve;
use crate::render::frozen::Frozen;
use crate::render::render_photon;
use crate::scene::{Camera, Medium, RenderSettings, Scene};
use crate::volume::Grid;
use serde::Serialize;
use std::time::Instant;

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
    let state = FrameFit::new(cameras, images, smoke_box, settings, fixed)?;
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
    smoke_box: (Vec3, Vec3),
    settings: &FitSettings,
    start: &Corrections,
    progress: &mut dyn FnMut(&FitRow),
) -> Result<Fit> {
    settings.validate()?;
    let mut state = FrameFit::new(cameras, images, smoke_box, settings, Some(start))?;
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
    let mut state = FrameFit::new(cameras, images, smoke_box, settings, fixed)?;
    state.scene.density = density;
    for _ in 0..LIGHTING_ROUNDS {
        state.scene.render.seed = settings.seed.wrapping_add(state.renders);
        state.renders += 1;
        state.last = Some(render_photon(&state.scene).images);
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
    let mut state = FrameFit::new(cameras, images, smoke_box, &settings, fixed)?;
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

/// A frame's fit between two updates: what [`fit`] carries from one to the next.
struct FrameFit<'a> {
    settings: &'a FitSettings,
    fixed: Option<&'a Corrections>,
    /// Whether cameras corrected by `fixed` are aligned again.
    realign: bool,
    smoke_box: (Vec3, Vec3),
    /// The photographs as decoded: where the silhouettes come from.
    codes: &'a [Image],
    /// The training cameras at the working resolution, as corrected so far:
    /// what the silhouettes are carved through.
    working: Vec<Camera>,
    /// The photographs through the inverse response at the working resolution.
    working_photographs: Vec<Image>,
    /// How many times coarser than the working resolution this stage's
    /// images are ([`FitSettings::image_pyramid`]); the scene's cameras,
    /// `photographs` and `images` are at it.
    scale: usize,
    /// The photographs through the inverse response: linear in the lights.
    photographs: Vec<Image>,
    /// The photographs less their cameras' black levels, over their gains:
    /// what the renders are fitted to.
    images: Vec<Image>,
    gains: Vec<f64>,
    blacks: Vec<f64>,
    /// Whether the gains are a rig's, held ([`FitSettings::rig_gains`]).
    gains_held: bool,
    /// The capture's black threshold in linear units.
    threshold: f64,
    offsets: Vec<[f64; 2]>,
    zooms: Vec<f64>,
    rolls: Vec<f64>,
    /// The training cameras, the density of the last stage, lights and emission.
    scene: Scene,
    /// Whether the emission term is fitted: emission-absorption has no lights, its emission is its image.
    ambient: bool,
    /// The smoothness term's weight along each grid axis (1 along the vertical).
    smoothness_axes: [f64; 3],
    /// The last update's images: where the lights are fitted again, they censor the targets.
    last: Option<Vec<Image>>,
    /// Levenberg-Marquardt damping of the lights' places, kept between calls.
    damping: f64,
    /// Renders so far: each update's seed.
    renders: u64,
    log: Vec<FitRow>,
    start: Instant,
}

impl<'a> FrameFit<'a> {
    fn new(
        cameras: &[Camera],
        codes: &'a [Image],
        smoke_box: (Vec3, Vec3),
        settings: &'a FitSettings,
        fixed: Option<&'a Corrections>,
    ) -> Result<Self> {
        let n = cameras.len();
        let (cameras, offsets, zooms, rolls) = match fixed {
            Some(fixed) => {
                let (cameras, offsets) = fixed.apply(cameras, settings.factor)?;
                (cameras, offsets, fixed.zooms.clone(), fixed.rolls.clone())
            }
            None => (cameras.to_vec(), vec![[0.0; 2]; n], vec![1.0; n], vec![0.0; n]),
        };
        let start = Instant::now();
        let (lo, hi) = smoke_box;
        let photographs: Vec<Image> = codes.iter().map(|im| im.map(|v| v.powf(settings.gamma))).collect();
        let held = fixed.and_then(|f| f.gains.clone()).filter(|_| settings.rig_gains);
        let gains_held = held.is_some();
        let gains = held.unwrap_or_else(|| vec![1.0; n]);
        let blacks = vec![0.0; n];
        let images = over_response(&photographs, &gains, &blacks);
        let mut smoothness_axes = [settings.horizontal_smoothness; 3];
        smoothness_axes[up_axis(&cameras)] = 1.0;
        let scene = Scene {
            density: Grid::new(lo, hi, [1, 1, 1], vec![0.0]),
            medium: Medium {
                sigma_t_scale: 1.0,
                albedo: settings.albedo,
                g: settings.g,
                max_order: settings.model.max_order(settings.orders),
                emission: 0.0,
            },
            lights: if settings.model.lit() {
                candidate_lights(&lo, &hi, settings.light_radius_deg)
            } else {
                Vec::new()
            },
            cameras: cameras.clone(),
            render: RenderSettings {
                photons: if settings.model == ImageModel::Multiple { settings.photons } else { 0 },
                spp: settings.spp,
                seed: settings.seed,
                shadows: settings.shadows,
                ..RenderSettings::default()
            },
        };
        Ok(FrameFit {
            settings,
            fixed,
            realign: false,
            smoke_box,
            codes,
            working: cameras,
            working_photographs: photographs.clone(),
            scale: 1,
            images,
            photographs,
            gains,
            blacks,
            gains_held,
            threshold: settings.threshold.powf(settings.gamma),
            offsets,
            zooms,
            rolls,
            scene,
            ambient: settings.ambient || !settings.model.lit(),
            smoothness_axes,
            last: None,
            damping: 1e-3,
            renders: 0,
            log: Vec::new(),
            start,
        })
    }

    /// One stage: `updates` Adam steps on a level's grid (`None`: the decoder's cube).
    fn stage(
        &mut self,
        stage: usize,
        level: Option<usize>,
        updates: usize,
        progress: &mut dyn FnMut(&FitRow),
    ) -> Result<()> {
        self.set_scale(level.map_or(1, |level| self.settings.image_scale(level, &self.working)));
        let (grid, hull) = self.grid_and_hull(level)?;
        let (mut density, mut params) = self.stage_start(stage, level, &grid, &hull)?;
        let support =
            Grid::new(grid.lo, grid.hi, grid.shape, hull.iter().map(|&h| if h { 1.0 } else { 0.0 }).collect());
        for update in 0..updates {
            self.scene.density = density.clone();
            if update % self.settings.refit_every == 0 {
                self.refit(stage)?;
            }
            let (grad, row) = self.gradient(stage, update, &density, &hull, &support)?;
            params.step(&mut density, &hull, &grad);
            let row = FitRow { seconds: self.start.elapsed().as_secs_f64(), ..row };
            progress(&row);
            self.log.push(row);
        }
        if level.is_none() && !density.data.iter().any(|&d| d > 0.0) {
            return Err(Error("the decoder's fit went to 0 everywhere in the hull: try another seed".into()));
        }
        self.scene.density = density;
        Ok(())
    }

    /// Puts the scene's cameras and the photographs at 1/`scale` of the
    /// working resolution, and renders the scene anew there if it was
    /// rendered before at another (the lighting's refit reads the last render).
    fn set_scale(&mut self, scale: usize) {
        if scale == self.scale {
            return;
        }
        self.scale = scale;
        self.scene.cameras = self.stage_cameras();
        self.photographs = self.working_photographs.iter().map(|p| p.downsample(scale)).collect();
        self.images = over_response(&self.photographs, &self.gains, &self.blacks);
        if self.last.is_some() {
            self.scene.render.seed = self.settings.seed.wrapping_add(self.renders);
            self.renders += 1;
            self.last = Some(render_photon(&self.scene).images);
        }
    }

    /// The working cameras at this stage's scale.
    fn stage_cameras(&self) -> Vec<Camera> {
        self.working.iter().map(|c| at_scale(c, self.scale)).collect()
    }

    /// A stage's grid and its visual hull, carved through the cameras as they
    /// are now, with the aligned margin once they are aligned.
    fn grid_and_hull(&self, level: Option<usize>) -> Result<(Grid<f64>, Vec<bool>)> {
        let (lo, hi) = self.smoke_box;
        let settings = self.settings;
        let levels = settings.updates.len();
        let grid = match level {
            Some(level) => {
                let shape = grid_shape(&lo, &hi, settings.resolution >> (levels - 1 - level));
                Grid::new(lo, hi, shape, vec![0.0; shape.iter().product()])
            }
            None if settings.prior_stretched => {
                let n = settings.resolution;
                Grid::new(lo, hi, [n, n, n], vec![0.0; n * n * n])
            }
            None => cube_around(&lo, &hi, settings.resolution),
        };
        let aligned = self.fixed.is_some() || self.offsets.iter().any(|o| o[0] != 0.0 || o[1] != 0.0);
        let margin = if aligned { settings.aligned_margin } else { SILHOUETTE_MARGIN_PX };
        let silhouettes: Vec<Vec<bool>> =
            self.codes.iter().map(|im| real_silhouette(im, settings.factor, margin)).collect();
        let inside = in_box(&grid, &lo, &hi);
        let hull: Vec<bool> =
            carve(&grid, &self.working, &silhouettes).iter().zip(&inside).map(|(&h, &i)| h && i).collect();
        if !hull.iter().any(|&h| h) {
            return Err(Error("the training cameras' silhouettes have no voxel in common: no smoke in the box".into()));
        }
        Ok((grid, hull))
    }

    /// A stage's first density and what its steps move: the decoder's, the
    /// start's on the first level, the last stage's upsampled after it.
    fn stage_start(
        &self,
        stage: usize,
        level: Option<usize>,
        grid: &Grid<f64>,
        hull: &[bool],
    ) -> Result<(Grid<f64>, Params)> {
        let settings = self.settings;
        Ok(match (stage, level) {
            (0, None) if settings.prior > 0 => {
                prior_start(grid, hull, settings, crate::image::mean_square(&self.images))?
            }
            (0, None) => decoder_start(grid, hull, settings)?,
            (_, None) => unreachable!("the decoder's stage is the first"),
            (0, Some(_)) => {
                let shape = start_shape(grid, hull, &self.scene.cameras, &self.photographs, settings.start_shape);
                voxel_params(start_density(grid, &shape, settings.start_depth), hull, settings)
            }
            (_, Some(_)) => voxel_params(upsample(&self.scene.density, grid, hull), hull, settings),
        })
    }

    /// The cameras aligned (from the second stage on, without a rig), then
    /// the lights' intensities and the emission, the gains, and the lights' places.
    fn refit(&mut self, stage: usize) -> Result<()> {
        let settings = self.settings;
        let held = self.fixed.is_some() && !self.realign;
        if let (true, true, false, Some(rendered)) = (settings.align, stage > 0, held, &self.last) {
            let free = Free { zoom: settings.zoom, roll: settings.roll };
            let moves = Moves { offsets: &mut self.offsets, zooms: &mut self.zooms, rolls: &mut self.rolls };
            let seen = Seen { cameras: &self.scene.cameras, rendered, photos: &self.images, scale: self.scale };
            align_cameras(&mut self.working, moves, free, seen);
            self.scene.cameras = self.stage_cameras();
        }
        let (targets, basis) = self.refit_lighting(stage > 0)?;
        if settings.lights > 0 && stage > 0 && settings.model.lit() {
            let (ambient, lights) = (self.ambient, settings.lights);
            place_lights(&mut self.scene, &targets, &basis, lights, ambient, &mut self.damping, &mut self.renders);
        }
        Ok(())
    }

    /// The lights' intensities and the emission fitted to the photographs
    /// (censored by the last render), then, with `gains` and if the
    /// settings fit them, the gains. Returns the targets and the unit renders.
    fn refit_lighting(&mut self, gains: bool) -> Result<(Vec<Image>, Vec<Vec<Image>>)> {
        let targets = censored(&self.images, self.last.as_deref(), self.threshold, &self.gains, &self.blacks);
        let per = disc_points(self.settings.light_radius_deg);
        let basis = fit_lights(&mut self.scene, &targets, self.ambient, per, &mut self.renders)?;
        if self.settings.gains && gains && !self.gains_held {
            let weights = weights_of(&self.scene, per);
            if self.settings.black_level {
                let (photographs, threshold) = (&self.photographs, self.threshold);
                fit_gains_and_blacks(&mut self.gains, &mut self.blacks, &weights, &basis, photographs, threshold);
            } else {
                fit_gains(&mut self.gains, &weights, &basis, &targets);
            }
            self.images = over_response(&self.photographs, &self.gains, &self.blacks);
        }
        Ok((targets, basis))
    }

    /// One update's render of the scene as it is: its images' gradient with
    /// the priors' (0 outside the hull), and its row of the log.
    fn gradient(
        &mut self,
        stage: usize,
        update: usize,
        density: &Grid<f64>,
        hull: &[bool],
        support: &Grid<f64>,
    ) -> Result<(Vec<f64>, FitRow)> {
        let settings = self.settings;
        self.scene.render.seed = settings.seed.wrapping_add(self.renders);
        self.renders += 1;
        let frozen = Frozen::new(&self.scene, Some(support));
        let targets = censored(&self.images, Some(&frozen.images), self.threshold, &self.gains, &self.blacks);
        let reverse = reverse_gradient(&frozen, &targets, Subset::full());
        self.last = Some(frozen.images.clone());
        let (smooth, smooth_grad) = smoothness(density, hull, settings.smoothness, self.smoothness_axes);
        let (sparse, sparse_grad) = sparsity(density, hull, settings.sparsity);
        let (tv, tv_grad) = total_variation(density, hull, settings.total_variation);
        let grad: Vec<f64> = (0..density.len())
            .map(|v| if hull[v] { reverse.grad[v] + smooth_grad[v] + sparse_grad[v] + tv_grad[v] } else { 0.0 })
            .collect();
        if grad.iter().any(|g| !g.is_finite()) {
            return Err(Error(format!("stage {stage}, update {update}: the gradient is not finite")));
        }
        let row = FitRow {
            level: stage,
            update,
            image_mse: reverse.loss,
            smoothness: smooth,
            sparsity: sparse,
            total_variation: tv,
            seconds: 0.0,
        };
        Ok((grad, row))
    }

    /// The lights and emission fitted once more to the last density: the fit.
    fn finish(mut self) -> Result<Fit> {
        let targets = censored(&self.images, self.last.as_deref(), self.threshold, &self.gains, &self.blacks);
        let per = disc_points(self.settings.light_radius_deg);
        let basis = fit_lights(&mut self.scene, &targets, self.ambient, per, &mut self.renders)?;
        let model = self.settings.model;
        let light_share = if model.lit() { light_share(&basis, &weights_of(&self.scene, per)) } else { None };
        Ok(Fit {
            scene: self.scene,
            settings: self.settings.clone(),
            offsets: self.offsets,
            zooms: self.zooms,
            rolls: self.rolls,
            gains: self.gains,
            black_levels: self.blacks,
            log: self.log,
            light_share,
            seconds: self.start.elapsed().as_secs_f64(),
        })
    }
}

/// The training cameras' corrections so far, per camera: what
/// [`align_cameras`] adds to.
struct Moves<'m> {
    offsets: &'m mut [[f64; 2]],
    zooms: &'m mut [f64],
    rolls: &'m mut [f64],
}

/// What the cameras are aligned on: their views at one stage's scale.
struct Seen<'s> {
    /// The cameras at 1/`scale` of the working resolution.
    cameras: &'s [Camera],
    /// Their render before the move.
    rendered: &'s [Image],
    /// Their photographs.
    photos: &'s [Image],
    /// How many times coarser than the working resolution they are.
    scale: usize,
}

/// `camera` (at the working resolution) at 1/`scale` of it: itself at 1.
fn at_scale(camera: &Camera, scale: usize) -> Camera {
    if scale == 1 {
        camera.clone()
    } else {
        camera.downsample(scale)
    }
}

/// Moves every camera's principal point (and as `free` says scales its
/// focal lengths and turns it about its optical axis) so that its
/// photograph agrees with its render, as `seen` at one scale, keeping
/// the mean move and turn 0 and the magnifications' geometric mean 1: a
/// shift, turn or magnification shared by every camera is the density's to
/// explain, not the cameras'. `cameras` and `totals` are at the working
/// resolution: a move of one pixel at the scale is `scale` pixels there.
fn align_cameras(cameras: &mut [Camera], totals: Moves, free: Free, seen: Seen) {
    let warps: Vec<_> = seen
        .rendered
        .iter()
        .zip(seen.photos)
        .zip(seen.cameras)
        .map(|((r, p), c)| {
            let [_, _, cx, cy] = c.intrinsics();
            warp(r, p, [cx, cy], free)
        })
        .collect();
    let mut moves: Vec<[f64; 2]> = warps.iter().map(|w| w.offset).collect();
    let mut factors: Vec<f64> = warps.iter().map(|w| 1.0 + w.zoom).collect();
    let mut turns: Vec<f64> = warps.iter().map(|w| w.roll).collect();
    take_out_shared(&mut moves, &mut factors, &mut turns);
    for (c, camera) in cameras.iter_mut().enumerate() {
        let [dx, dy] = moves[c].map(|d| d * seen.scale as f64);
        *camera = camera.shift(dx, dy).zoom(factors[c]).roll(turns[c]);
        totals.offsets[c] = [totals.offsets[c][0] + dx, totals.offsets[c][1] + dy];
        totals.zooms[c] *= factors[c];
        totals.rolls[c] += turns[c];
    }
}

/// `targets` where the capture's threshold hides nothing, and `rendered`
/// itself (no error) where a target is 0 and the render is below the
/// threshold: there the photograph cannot tell the render is wrong.
/// `threshold` is in linear units of the photographs; a camera's render
/// `r` meets it where `gain r + black` does. Without a render (none yet),
/// `targets` as they are.
fn censored(
    targets: &[Image],
    rendered: Option<&[Image]>,
    threshold: f64,
    gains: &[f64],
    blacks: &[f64],
) -> Vec<Image> {
    let Some(rendered) = rendered else { return targets.to_vec() };
    targets
        .iter()
        .zip(rendered)
        .zip(gains.iter().zip(blacks))
        .map(|((t, r), (gain, black))| Image {
            width: t.width,
            height: t.height,
            data: t
                .data
                .iter()
                .zip(&r.data)
                .map(|(&t, &r)| if t == 0.0 && r * gain + black < threshold { r } else { t })
                .collect(),
        })
        .collect()
}

/// `photographs` (linear) less each camera's black level where they are
/// not 0 (the threshold hid the rest), over its gain.
fn over_response(photographs: &[Image], gains: &[f64], blacks: &[f64]) -> Vec<Image> {
    let cameras = photographs.iter().zip(gains.iter().zip(blacks));
    cameras.map(|(p, (g, b))| p.map(|v| if v > 0.0 { (v - b) / g } else { 0.0 })).collect()
}

/// A rendered view through a camera of `gain` and `black` level and the
/// response of `settings`: the gain and black level, the curve
/// ([`FitSettings::gamma`]), then the capture's processing (0 below its
/// threshold), in code value / full scale.
pub fn respond(image: &Image, gain: f64, black: f64, settings: &FitSettings) -> Image {
    image.map(|v| {
        let code = (gain * v + black).max(0.0).powf(1.0 / settings.gamma);
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
    let responses = fit.gains.iter().zip(&fit.black_levels);
    rendered.iter().zip(responses).map(|(image, (&gain, &black))| respond(image, gain, black, &fit.settings)).collect()
}

/// Root mean square difference, in code value / full scale, between the
/// training cameras' views of a fitted frame and their photographs `images`.
pub fn training_rmse(fit: &Fit, images: &[Image]) -> f64 {
    let views: Vec<Vec<f64>> = training_views(fit).into_iter().map(|v| v.data).collect();
    mse(&views, images).sqrt()
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
    respond(&render_photon(&scene).images[0], 1.0, held_out_black(fit), &fit.settings)
}

/// A held-out camera's black level: the training cameras' mean, by the
/// rule fixed in advance ([`FitSettings::black_level`]); 0 without it.
pub fn held_out_black(fit: &Fit) -> f64 {
    fit.black_levels.iter().sum::<f64>() / fit.black_levels.len().max(1) as f64
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

    /// One photograph of a ball moved 3 pixels down, which no density
    /// explains (the cameras share their vertical). One fit's alignment
    /// finds part of it, the density having taken up the rest; fitted again
    /// from its own corrections, the cameras move on towards the 3 pixels.
    #[test]
    fn a_fit_aligning_from_its_own_corrections_finds_more_of_a_moved_camera() {
        let (cameras, mut images) = ball_views(64, 12.0);
        let down = |i: usize| if i < 3 * 64 { 0.0 } else { images[0].data[i - 3 * 64] };
        images[0] = Image { data: (0..64 * 64).map(down).collect(), ..images[0].clone() };
        let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let settings = FitSettings {
            model: ImageModel::EmissionAbsorption,
            factor: 4,
            resolution: 16,
            updates: vec![80, 20, 20],
            zoom: false,
            shared_alignment: false,
            gains: false,
            threshold: 0.0,
            ..FitSettings::default()
        };
        // Camera 0's move against the other two's, in working pixels.
        let moved = |f: &Fit| f.offsets[0][1] - (f.offsets[1][1] + f.offsets[2][1]) / 2.0;
        let corrections = |f: &Fit| Corrections {
            offsets_px: f.offsets_px(),
            zooms: f.zooms.clone(),
            rolls: f.rolls.clone(),
            gains: None,
        };
        let first = fit(&cameras, &images, smoke_box, &settings, None, &mut |_| {}).unwrap();
        let second =
            fit_aligning_from(&cameras, &images, smoke_box, &settings, &corrections(&first), &mut |_| {}).unwrap();
        let third =
            fit_aligning_from(&cameras, &images, smoke_box, &settings, &corrections(&second), &mut |_| {}).unwrap();
        let found = [moved(&first), moved(&second), moved(&third)];
        assert!(found[0] > 0.5 && found[0] < 2.0, "{found:?}");
        assert!(found[1] > found[0] + 0.4 && found[2] > found[1] && found[2] < 3.5, "{found:?}");
        // Held by the same corrections (a rig's), the cameras do not move again.
        let held = fit(&cameras, &images, smoke_box, &settings, Some(&corrections(&second)), &mut |_| {}).unwrap();
        assert_eq!(held.offsets, corrections(&second).apply(&cameras, 4).unwrap().1);
    }

    /// With the image pyramid a coarse stage aligns the cameras on images
    /// at half the working resolution: a photograph one pixel off there is
    /// two pixels off at the working resolution, where the cameras move.
    #[test]
    fn a_coarse_stage_moves_the_cameras_in_working_pixels() {
        let (cameras, _) = ball_views(64, 12.0);
        let blob = |dx: f64| Image {
            width: 32,
            height: 32,
            data: (0..32 * 32)
                .map(|i| {
                    let (x, y) = ((i % 32) as f64 - 15.5 - dx, (i / 32) as f64 - 15.5);
                    (-(x * x + y * y) / 18.0).exp()
                })
                .collect(),
        };
        let rendered = vec![blob(0.0); 3];
        let photos = vec![blob(1.0), blob(0.0), blob(0.0)];
        let coarse: Vec<Camera> = cameras.iter().map(|c| at_scale(c, 2)).collect();
        let mut working = cameras.to_vec();
        let (mut offsets, mut zooms, mut rolls) = (vec![[0.0; 2]; 3], vec![1.0; 3], vec![0.0; 3]);
        let moves = Moves { offsets: &mut offsets, zooms: &mut zooms, rolls: &mut rolls };
        let seen = Seen { cameras: &coarse, rendered: &rendered, photos: &photos, scale: 2 };
        align_cameras(&mut working, moves, Free { zoom: false, roll: false }, seen);
        // Camera 0 against the other two: one coarse pixel, two working ones.
        let apart = offsets[0][0] - offsets[1][0];
        assert!((apart.abs() - 2.0).abs() < 0.2, "{offsets:?}");
        assert!((offsets[1][0] - offsets[2][0]).abs() < 1e-9 && offsets.iter().all(|o| o[1].abs() < 0.05));
        let moved = working[0].intrinsics()[2] - cameras[0].intrinsics()[2];
        assert!((moved - offsets[0][0]).abs() < 1e-9, "the camera moved {moved}, its total {}", offsets[0][0]);
        assert_eq!(working[0].width, 64, "the working camera was downsampled");
    }

    /// With the image pyramid a fit of three views of a ball runs its
    /// coarse levels on coarser images, still lowers the error, and ends
    /// with its cameras at the working resolution.
    #[test]
    fn a_fit_on_the_image_pyramid_fits_a_ball() {
        let (cameras, images) = ball_views(64, 16.0);
        let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let run = |image_pyramid: bool| {
            let settings = FitSettings {
                model: ImageModel::EmissionAbsorption,
                factor: 4,
                resolution: 16,
                updates: vec![10, 10, 20],
                gains: false,
                shared_alignment: false,
                threshold: 0.0,
                image_pyramid,
                ..FitSettings::default()
            };
            fit(&cameras, &images, smoke_box, &settings, None, &mut |_| {}).unwrap()
        };
        let (flat, pyramid) = (run(false), run(true));
        assert_ne!(flat.log[0].image_mse, pyramid.log[0].image_mse, "the pyramid changed nothing");
        let first = pyramid.log[0].image_mse;
        let last = pyramid.log.last().unwrap().image_mse;
        assert!(last < first / 2.0, "the images' error fell from {first} to only {last}");
        assert!(pyramid.scene.cameras.iter().all(|c| (c.width, c.height) == (64, 64)));
        assert!(
            pyramid.offsets.iter().all(|o| o.iter().all(|v| v.is_finite() && v.abs() < 3.0)),
            "{:?}",
            pyramid.offsets
        );
        // The finest level works at the same resolution either way: its errors are comparable.
        assert!(last < 2.0 * flat.log.last().unwrap().image_mse, "{last} against {:?}", flat.log.last());
    }

    /// A box longer along y (a decoder's cube holds voxels outside it).
    const TALL_BOX: (Vec3, Vec3) = (Vec3::new(-0.4, -0.5, -0.4), Vec3::new(0.4, 0.5, 0.4));

    /// Three views of a ball in [`TALL_BOX`] fitted under emission-absorption
    /// on the images alone, with `settings`' grid, updates and start: the
    /// fit, and each update's image error in its first and second stage.
    fn decoded_ball_fit(settings: &FitSettings) -> (Fit, Vec<f64>, Vec<f64>) {
        let (cameras, images) = ball_views(64, 10.0);
        let settings = FitSettings {
            model: ImageModel::EmissionAbsorption,
            // The silhouettes' margin is 10 pixels at 1/4: the hull leaves voxels out.
            factor: 4,
            // The images alone: in so small a scene the smoothness term pulls
            // a decoder's rough density back up the images' error.
            smoothness: 0.0,
            align: false,
            gains: false,
            threshold: 0.0,
            ..settings.clone()
        };
        let done = fit(&cameras, &images, TALL_BOX, &settings, None, &mut |_| {}).unwrap();
        let stage = |s: usize| done.log.iter().filter(|r| r.level == s).map(|r| r.image_mse).collect::<Vec<f64>>();
        let (first, second) = (stage(0), stage(1));
        (done, first, second)
    }

    /// The paper's model fits three views of a ball, then the finest level
    /// goes on from its density; settings it cannot run with are refused.
    #[test]
    fn the_decoder_stage_fits_a_ball_before_the_finest_level() {
        let settings = FitSettings { resolution: 8, updates: vec![10, 15], decoder: 30, ..FitSettings::default() };
        let (done, decoder, finest) = decoded_ball_fit(&settings);
        let smoke_box = TALL_BOX;
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
        assert!(done.scene.density.data.contains(&0.0), "the hull left no voxel out");
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

    /// A fit is the seed's alone: every update (multiple scattering's photon
    /// map, the reverse-mode gradient, the lights' and gains' refits, the
    /// cameras' alignment) gives the same bits with one thread and with three.
    #[test]
    fn a_fit_is_bit_identical_for_any_thread_count() {
        let (cameras, images) = ball_views(48, 9.0);
        let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let settings = FitSettings {
            model: ImageModel::Multiple,
            factor: 4,
            resolution: 8,
            updates: vec![10, 10],
            photons: 2_000,
            shared_alignment: false,
            threshold: 0.0,
            ..FitSettings::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| fit(&cameras, &images, smoke_box, &settings, None, &mut |_| {}).unwrap())
        };
        let (one, three) = (run(1), run(3));
        assert!(one.offsets.iter().any(|o| o[0] != 0.0), "the cameras never moved: the test exercises no alignment");
        assert_eq!(one.scene.density.data, three.scene.density.data);
        let losses = |f: &Fit| f.log.iter().map(|r| r.image_mse).collect::<Vec<f64>>();
        assert_eq!(losses(&one), losses(&three));
        assert_eq!((&one.gains, &one.offsets, &one.zooms), (&three.gains, &three.offsets, &three.zooms));
        assert_eq!(one.scene.lights, three.scene.lights);
    }

    /// The learned prior's latent fits three views of a ball from the
    /// training plumes' mean, then the finest level goes on from its
    /// density; a prior together with the paper's decoder, or on a grid it
    /// does not decode, is refused.
    #[test]
    fn the_learned_prior_stage_fits_a_ball_before_the_finest_level() {
        let settings = FitSettings { resolution: 64, updates: vec![10, 5], prior: 20, ..FitSettings::default() };
        let (done, prior, finest) = decoded_ball_fit(&settings);
        let smoke_box = TALL_BOX;
        assert_eq!((prior.len(), finest.len()), (20, 5));
        assert!(
            prior[19] < 0.7 * prior[0],
            "the prior's stage lowered the error from {} to only {}",
            prior[0],
            prior[19]
        );
        assert!(finest[0] < 0.7 * prior[0], "the finest level did not start from the prior's fit");
        assert!(finest[4] < prior[19], "the finest level did not go on from the prior's fit");
        assert_eq!(done.scene.density.shape, grid_shape(&smoke_box.0, &smoke_box.1, 64));
        assert!(done.scene.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
        // Stretched over the box, the prior's grid has the box's proportions.
        let stretched = FitSettings { prior_stretched: true, ..settings.clone() };
        let (_, prior_stage, _) = decoded_ball_fit(&stretched);
        assert!(prior_stage[19] < 0.7 * prior_stage[0], "stretched, the prior's stage fitted nothing");
        assert_ne!(prior_stage, prior, "prior_stretched changed nothing");
        let alone = FitSettings { prior: 0, ..stretched };
        assert!(alone.validate().unwrap_err().0.contains("needs prior"));
        let both = FitSettings { decoder: 10, ..settings.clone() };
        assert!(both.validate().unwrap_err().0.contains("set one of them"));
        let coarse = FitSettings { resolution: 32, ..settings };
        assert!(coarse.validate().unwrap_err().0.contains("decodes 64^3 grids"), "{:?}", coarse.validate());
    }

    /// With the density held at the truth's, the lighting comes back: two
    /// candidates' intensities, no emission, the gains 1. A camera made
    /// twice as bright gets the largest gain, and the images are fitted as
    /// closely (on a ball the lights' view-dependent light can stand in for
    /// part of a gain, so the split is not asked).
    #[test]
    fn the_lighting_of_a_known_density_comes_back() {
        let (cameras, _) = ball_views(24, 6.0);
        let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let settings = FitSettings { model: ImageModel::Single, threshold: 0.0, ..FitSettings::default() };
        let mut density = Grid::new(smoke_box.0, smoke_box.1, [8, 8, 8], vec![0.0; 512]);
        for v in 0..512 {
            if density.voxel_center(v / 64, (v / 8) % 8, v % 8).norm() < 0.3 {
                density.data[v] = 4.0;
            }
        }
        let mut truth = Scene {
            density: density.clone(),
            medium: Medium { sigma_t_scale: 1.0, albedo: 1.0, g: settings.g, max_order: 1, emission: 0.0 },
            lights: candidate_lights(&smoke_box.0, &smoke_box.1, 0.0),
            cameras: cameras.to_vec(),
            render: RenderSettings { photons: 0, spp: 8, seed: 99, ..RenderSettings::default() },
        };
        truth.lights[0].intensity = 2.0;
        truth.lights[3].intensity = 1.0;
        let images = render_photon(&truth).images;
        let done = fit_lighting(&cameras, &images, smoke_box, density.clone(), &settings, None).unwrap();
        assert_eq!(done.scene.density.data, density.data, "the density moved");
        let lights: Vec<f64> = done.scene.lights.iter().map(|l| l.intensity).collect();
        // A ball's views tell its lights apart by their shading alone: the
        // truth's two the strongest, near their intensities, the rest small.
        assert!((lights[0] / 2.0 - 1.0).abs() < 0.1 && (lights[3] - 1.0).abs() < 0.15, "lights {lights:?}");
        let others: f64 = lights.iter().enumerate().filter(|(l, _)| ![0, 3].contains(l)).map(|(_, w)| w).sum();
        assert!(others < 0.15 * (lights[0] + lights[3]), "lights {lights:?}");
        assert!(done.scene.medium.emission < 0.02, "emission {}", done.scene.medium.emission);
        assert!(done.gains.iter().all(|g| (g - 1.0).abs() < 0.05), "gains {:?}", done.gains);
        let error = training_rmse(&done, &images);
        let scale = (images.iter().flat_map(|im| &im.data).map(|v| v * v).sum::<f64>() / (3.0 * 576.0)).sqrt();
        // The renders' own noise (2 camera samples a pixel) is most of it.
        assert!(error < 0.15 * scale, "RMSE {error} against the images' {scale}");
        let mut brighter = images.clone();
        brighter[1] = brighter[1].map(|v| 2.0 * v);
        let done = fit_lighting(&cameras, &brighter, smoke_box, density, &settings, None).unwrap();
        assert!(done.gains[1] > 1.3 * done.gains[0].max(done.gains[2]), "gains {:?}", done.gains);
        let brighter_error = training_rmse(&done, &brighter);
        assert!(brighter_error < 2.0 * error, "RMSE {brighter_error}, against {error} at gains 1");
        // A rig's gains are held where the settings say so, fitted where not.
        let rig = Corrections {
            offsets_px: vec![[0.0; 2]; 3],
            zooms: vec![1.0; 3],
            rolls: vec![0.0; 3],
            gains: Some(vec![0.8, 1.25, 1.0]),
        };
        let held_settings = FitSettings { rig_gains: true, ..settings.clone() };
        let held =
            fit_lighting(&cameras, &brighter, smoke_box, truth.density.clone(), &held_settings, Some(&rig)).unwrap();
        assert_eq!(held.gains, vec![0.8, 1.25, 1.0]);
        let fitted = fit_lighting(&cameras, &brighter, smoke_box, truth.density, &settings, Some(&rig)).unwrap();
        assert!(fitted.gains[1] > 1.3 * fitted.gains[0].max(fitted.gains[2]), "gains {:?}", fitted.gains);
    }

    /// A photograph through the inverse response, over a camera's gain, comes
    /// back through `respond` as it was; below the threshold, as 0.
    #[test]
    fn the_response_inverts_what_the_fit_works_on() {
        let settings = FitSettings { gamma: 2.2, ..FitSettings::default() };
        let photo = Image { width: 4, height: 1, data: vec![0.0, 5.0 / 255.0, 0.1, 0.9] };
        let gain = 1.3;
        let linear = photo.map(|v| v.powf(settings.gamma) / gain);
        let back = respond(&linear, gain, 0.0, &settings);
        assert_eq!(back.data[..2], [0.0, 0.0]);
        for (b, p) in back.data[2..].iter().zip(&photo.data[2..]) {
            assert!((b - p).abs() < 1e-12, "{back:?}");
        }
        let raw = respond(&linear, gain, 0.0, &FitSettings::default());
        assert!((raw.data[3] - 0.9f64.powf(2.2)).abs() < 1e-12, "gamma 1 must pass radiance through: {raw:?}");
        // With a black level, through what the fit works on and back.
        let black = 0.0003; // below the threshold in linear units, (8 / 255)^2.2
        let linear = &over_response(&[photo.map(|v| v.powf(settings.gamma))], &[gain], &[black])[0];
        let back = respond(linear, gain, black, &settings);
        assert_eq!(back.data[..2], [0.0, 0.0]);
        for (b, p) in back.data[2..].iter().zip(&photo.data[2..]) {
            assert!((b - p).abs() < 1e-12, "{back:?}");
        }
    }
}
