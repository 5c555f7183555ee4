//! A frame's fit between two updates: the training cameras as aligned so
//! far, the photographs through the response at the stage's scale, the
//! gains and black levels, the scene (density, lights, emission) and the
//! log. One stage is a level's updates, the lighting refitted (and the
//! cameras aligned) every few of them.

use super::aligning::{align_cameras, at_scale, Moves, Seen};
use super::response::{censored, over_response, through_lens, within};
use super::{Fit, FitRow};
use crate::capture::align::{Corrections, Free};
use crate::capture::density::{
    cube_around, decoder_start, grid_shape, in_box, prior_start, start_density, start_shape, upsample, voxel_params,
    Params,
};
use crate::capture::lighting::{
    candidate_lights, disc_points, fit_gains, fit_gains_and_blacks, fit_lights, light_share, place_lights, weights_of,
};
use crate::capture::observe::{real_silhouette, SILHOUETTE_MARGIN_PX};
use crate::capture::priors::{smoothness, sparsity, total_variation};
use crate::capture::settings::{FitSettings, ImageModel};
use crate::error::{Error, Result};
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::image::Image;
use crate::math::Vec3;
use crate::recon::hull::carve;
use crate::render::frozen::Frozen;
use crate::render::render_photon;
use crate::scene::{Camera, Medium, RenderSettings, Scene};
use crate::volume::Grid;
use std::time::Instant;

/// A frame's fit between two updates: what [`super::fit`] carries from one to the next.
pub(super) struct FrameFit<'a> {
    pub(super) settings: &'a FitSettings,
    fixed: Option<&'a Corrections>,
    /// Whether cameras corrected by `fixed` are aligned again.
    pub(super) realign: bool,
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
    /// With [`FitSettings::interval_censoring`], the photographs' ceilings
    /// through the inverse response at the working resolution, and at this
    /// stage's as `images` are.
    working_ceilings: Option<Vec<Image>>,
    ceilings: Option<Vec<Image>>,
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
    pub(super) scene: Scene,
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
    pub(super) fn new(
        cameras: &[Camera],
        codes: &'a [Image],
        ceilings: Option<&[Image]>,
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
        // Through the inverse response, and the lens's fall-off taken out
        // where the settings model it: what the renders are fitted to.
        let linear = |codes: &[Image]| -> Vec<Image> {
            let linear = codes.iter().map(|im| im.map(|v| v.powf(settings.gamma)));
            linear.zip(&cameras).map(|(im, camera)| through_lens(im, camera, settings, true)).collect()
        };
        let photographs = linear(codes);
        let working_ceilings = match (settings.interval_censoring, ceilings) {
            (false, _) => None,
            (true, Some(ceilings)) => Some(linear(ceilings)),
            (true, None) => {
                return Err(Error(
                    "interval_censoring needs the photographs' ceilings, which this fit is not given".into(),
                ))
            }
        };
        let held = fixed.and_then(|f| f.gains.clone()).filter(|_| settings.rig_gains);
        let gains_held = held.is_some();
        let gains = held.unwrap_or_else(|| vec![1.0; n]);
        let blacks = vec![0.0; n];
        let images = over_response(&photographs, &gains, &blacks);
        let ceilings = working_ceilings.as_ref().map(|c| over_response(c, &gains, &blacks));
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
            working_ceilings,
            ceilings,
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
    pub(super) fn stage(
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
        self.respond();
        if self.last.is_some() {
            self.render_last();
        }
    }

    /// Renders the scene as it is, with the next seed, as the last render
    /// (what the lighting's refit reads).
    pub(super) fn render_last(&mut self) {
        self.scene.render.seed = self.settings.seed.wrapping_add(self.renders);
        self.renders += 1;
        self.last = Some(render_photon(&self.scene).images);
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

    /// `images` (and `ceilings`) from the photographs at this stage's
    /// scale, through the gains and black levels as they now are.
    fn respond(&mut self) {
        self.images = over_response(&self.photographs, &self.gains, &self.blacks);
        let scale = self.scale;
        self.ceilings = self.working_ceilings.as_ref().map(|working| {
            let at_scale: Vec<Image> = working.iter().map(|c| c.downsample(scale)).collect();
            over_response(&at_scale, &self.gains, &self.blacks)
        });
    }

    /// What the renders are fitted to, censored by `rendered` where the
    /// capture's threshold hides their error: between each photograph and
    /// its ceiling ([`within`]) with `interval_censoring`, else
    /// [`censored`].
    fn targets(&self, rendered: Option<&[Image]>) -> Vec<Image> {
        match (&self.ceilings, rendered) {
            (Some(ceilings), Some(rendered)) => within(&self.images, ceilings, rendered),
            _ => {
                let to_threshold = self.settings.hidden_to_threshold;
                censored(&self.images, rendered, self.threshold, &self.gains, &self.blacks, to_threshold)
            }
        }
    }

    /// The lights' intensities and the emission fitted to the photographs
    /// (censored by the last render), then, with `gains` and if the
    /// settings fit them, the gains. Returns the targets and the unit renders.
    pub(super) fn refit_lighting(&mut self, gains: bool) -> Result<(Vec<Image>, Vec<Vec<Image>>)> {
        let targets = self.targets(self.last.as_deref());
        let per = disc_points(self.settings.light_radius_deg);
        let basis = fit_lights(&mut self.scene, &targets, self.ambient, per, &mut self.renders)?;
        if self.settings.gains && gains && !self.gains_held {
            let weights = weights_of(&self.scene, per);
            if self.settings.black_level {
                let (photographs, threshold) = (&self.photographs, self.threshold);
                let to_threshold = self.settings.hidden_to_threshold;
                let (gains, blacks) = (&mut self.gains, &mut self.blacks);
                fit_gains_and_blacks(gains, blacks, &weights, &basis, photographs, threshold, to_threshold);
            } else {
                fit_gains(&mut self.gains, &weights, &basis, &targets);
            }
            self.respond();
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
        let targets = self.targets(Some(&frozen.images));
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
    pub(super) fn finish(mut self) -> Result<Fit> {
        let targets = self.targets(self.last.as_deref());
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
}
