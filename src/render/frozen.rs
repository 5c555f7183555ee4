//! The photon-mapping estimator with every sampling decision made once and
//! kept ("frozen", docs/DESIGN.md §3): marching steps, photon paths and their
//! kernel weights, pixel jitter. What is left is a smooth function of the
//! density, evaluated in any [`Real`] type: `f64` for the image, dual
//! numbers for directional derivatives, the tape for reverse mode. The
//! primal is bit-identical whichever type evaluates it.

use super::camera_rays::CameraRays;
use super::light_depth::{Depths, LightDepth};
use super::march::{Marcher, Step};
use super::photons::{emitters, Emitter, Flights, Photon, Tracer};
use super::splat::{Estimate, Kernel, SplatGeometry};
use super::thick::ThickVoxels;
use crate::ad::Real;
use crate::image::Image;
use crate::par;
use crate::scene::{Camera, Scene, Shadows};
use crate::volume::majorant::MAJORANT_BLOCK;
use crate::volume::{Grid, Majorant};
use rayon::prelude::*;
use std::time::Instant;

/// Wall-clock seconds per stage.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    /// Photon tracing.
    pub trace: f64,
    /// Photon estimate onto the grids (gathering).
    pub gather: f64,
    /// The light-depth grids (0 with marched shadow rays).
    pub shadows: f64,
    /// Camera rays: single scattering and reading the estimate.
    pub camera: f64,
    /// Everything, setup included.
    pub total: f64,
}

/// The frozen estimator of one scene at its density (the sampling density).
pub struct Frozen<'a> {
    /// The scene; its density is the sampling density.
    pub scene: &'a Scene,
    marcher: Marcher,
    /// The marcher of photon flights (its own step).
    photon_marcher: Marcher,
    emitters: Vec<Emitter>,
    /// Camera positions guiding photon scattering.
    guide: Vec<crate::math::Vec3>,
    /// Stored photons, grouped by path in path order.
    pub photons: Vec<Photon>,
    /// Photons of path `i` are `photons[path_start[i]..path_start[i + 1]]`.
    path_start: Vec<usize>,
    /// Every path's flights, for replays.
    flights: Flights,
    geometry: Option<SplatGeometry>,
    kernel: Kernel,
    /// The light-depth grids' nodes (`None`: marched shadow rays).
    light_depth: Option<LightDepth>,
    /// `auto` shadows: the voxels too deep for the grids, near which
    /// samples march their shadow rays (`None`: none, or not `auto`).
    thick: Option<ThickVoxels>,
    /// The light-depth grids of the primal density, kept for reverse mode
    /// (which would otherwise march them again; `None`: marched shadow rays).
    depths: Option<Depths<f64>>,
    /// Index of each camera's first pixel among all pixels (names the pixel streams).
    first_pixel: Vec<u64>,
    /// The rendered images (primal), one per camera.
    pub images: Vec<Image>,
    /// Stage times of building this.
    pub timings: Timings,
}

impl<'a> Frozen<'a> {
    /// Traces the photons and renders the images of `scene`. `support`, if
    /// given, widens where the medium may be (marching does not skip it):
    /// use it when derivatives are wanted for voxels whose density is 0 now.
    pub fn new(scene: &'a Scene, support: Option<&Grid<f64>>) -> Self {
        Self::build(scene, support, true)
    }

    /// [`new`](Self::new), keeping the paths' flights only if `replayable`:
    /// a render that is never differentiated (a high-quality reference of
    /// a million photons) need not hold them.
    pub(super) fn build(scene: &'a Scene, support: Option<&Grid<f64>>, replayable: bool) -> Self {
        let start = Instant::now();
        let settings = &scene.render;
        let density = &scene.density;
        let mut bounds = density.clone();
        if let Some(s) = support {
            assert_eq!(s.shape, density.shape, "support grid must match the density grid");
            bounds.data.iter_mut().zip(&s.data).for_each(|(b, s)| *b = b.max(*s));
        }
        let marcher = Marcher::new(density, Majorant::build(&bounds, MAJORANT_BLOCK), settings.step_for(density));
        let mut timings = Timings::default();

        let t = Instant::now();
        let emitters = emitters(&scene.lights, &marcher.majorant, &density.lo, &density.hi);
        // Photon flights integrate smooth transmittance: a coarser step than the camera rays'.
        let photon_marcher = Marcher { step: settings.photon_step_for(density), ..marcher.clone() };
        let guide: Vec<_> = scene.cameras.iter().map(|c| c.position).collect();
        let tracer =
            Tracer { density, medium: &scene.medium, marcher: &photon_marcher, emitters: &emitters, guide: &guide };
        let (photons, flights) = tracer.trace(settings.photons, settings.seed, replayable);
        let path_start = path_starts(&photons, settings.photons as usize);
        timings.trace = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let (geometry, kernel) = if photons.is_empty() {
            (None, Kernel::default())
        } else {
            let mut geometry = SplatGeometry::new(density, settings.kernel_radius_for(density));
            let kernel = geometry.kernel(&photons);
            (Some(geometry), kernel)
        };
        timings.gather = t.elapsed().as_secs_f64();
        let first_pixel = first_pixels(&scene.cameras);
        let scale = scene.medium.sigma_t_scale;
        let cell = settings.shadow_cell_for(density, scale);
        let light_depth = cell.map(|c| LightDepth::new(&marcher, density, c, &scene.lights, scale, settings.seed));
        let thick =
            cell.filter(|_| settings.shadows == Shadows::Auto).and_then(|c| ThickVoxels::new(density, scale, c));
        let mut frozen = Frozen {
            scene,
            marcher,
            photon_marcher,
            emitters,
            guide,
            photons,
            path_start,
            flights,
            geometry,
            kernel,
            light_depth,
            thick,
            depths: None,
            first_pixel,
            images: vec![],
            timings,
        };
        frozen.render_primal();
        frozen.timings.total = start.elapsed().as_secs_f64();
        frozen
    }

    /// The primal images (and the light-depth grids reverse mode keeps),
    /// timing the photon estimate, the grids and the camera rays.
    fn render_primal(&mut self) {
        let scene = self.scene;
        let t = Instant::now();
        let multiple = self.multiple_with(|p| self.photons[p].power, scene.cameras.len());
        let gather = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let depths = self.light_depths(&scene.density);
        let shadows = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let rays = self.camera_rays(&scene.density, None, depths.as_ref());
        let images = rays
            .images(&self.camera_list(scene.cameras.len(), multiple.as_deref()))
            .into_iter()
            .zip(&scene.cameras)
            .map(|(data, camera)| Image { width: camera.width, height: camera.height, data })
            .collect();
        let camera = t.elapsed().as_secs_f64();
        self.images = images;
        self.depths = depths;
        self.timings.gather += gather;
        self.timings.shadows = shadows;
        self.timings.camera = camera;
    }

    /// Camera rays reading `density`, with sampling decisions from `sampling`
    /// (`None`: the primal of `density`) and the lights' transmittance from
    /// `depths` ([`light_depths`](Self::light_depths) of the same density;
    /// `None`: marched shadow rays).
    pub fn camera_rays<'b, R: Real>(
        &'b self,
        density: &'b Grid<R>,
        sampling: Option<&'b Grid<f64>>,
        depths: Option<&'b Depths<R>>,
    ) -> CameraRays<'b, R> {
        CameraRays {
            density,
            sampling,
            medium: &self.scene.medium,
            lights: &self.scene.lights,
            marcher: &self.marcher,
            depths,
            marched_near: self.thick.as_ref(),
            spp: self.scene.render.spp,
            seed: self.scene.render.seed,
        }
    }

    /// The light-depth grids of `density` with this estimator's shadow rays;
    /// `None` where the scene asks for marched shadow rays.
    pub fn light_depths<R: Real>(&self, density: &Grid<R>) -> Option<Depths<R>> {
        self.light_depth.as_ref().map(|d| d.depths(&self.marcher, density))
    }

    /// The light-depth grids of the primal density, as
    /// [`light_depths`](Self::light_depths) of it gives them (same bits).
    pub fn primal_depths(&self) -> Option<&Depths<f64>> {
        self.depths.as_ref()
    }

    /// The light-depth grids' nodes and shadow rays (`None`: marched shadow rays).
    pub fn light_depth(&self) -> Option<&LightDepth> {
        self.light_depth.as_ref()
    }

    /// The marcher every ray of this estimator uses.
    pub fn marcher(&self) -> &Marcher {
        &self.marcher
    }

    /// Photon tracing with this estimator's decisions.
    pub fn tracer(&self) -> Tracer<'_> {
        Tracer {
            density: &self.scene.density,
            medium: &self.scene.medium,
            marcher: &self.photon_marcher,
            emitters: &self.emitters,
            guide: &self.guide,
        }
    }

    /// The voxels any lookup of this estimator can read: the only ones with
    /// possibly non-zero derivatives.
    pub fn reachable_voxels(&self) -> Vec<usize> {
        self.marcher.majorant.reachable_voxels(self.scene.density.shape, MAJORANT_BLOCK)
    }

    /// Number of emitted photons (paths).
    pub fn paths(&self) -> usize {
        self.path_start.len() - 1
    }

    /// Indices of the stored photons of path `i`.
    pub fn path_photons(&self, i: usize) -> std::ops::Range<usize> {
        self.path_start[i]..self.path_start[i + 1]
    }

    /// Index of camera `c`'s first pixel among all pixels.
    pub fn first_pixel(&self, c: usize) -> u64 {
        self.first_pixel[c]
    }

    /// The photon estimate towards each of the first `cameras` cameras with
    /// photon `p`'s power given by `power(p)`; `None` if there are no photons.
    pub fn multiple_with<R: Real>(
        &self,
        power: impl Fn(usize) -> R + Sync,
        cameras: usize,
    ) -> Option<Vec<Estimate<'_, R>>> {
        let geometry = self.geometry.as_ref()?;
        let cams: Vec<_> = self.scene.cameras.iter().take(cameras).map(|c| c.position).collect();
        let m = &self.scene.medium;
        Some(geometry.estimate_with(&self.photons, power, &self.kernel, &cams, m.albedo, m.g))
    }

    /// The splat geometry and kernel weights (`None` without photons).
    pub fn kernel(&self) -> Option<(&SplatGeometry, &Kernel)> {
        self.geometry.as_ref().map(|g| (g, &self.kernel))
    }

    /// Appends the powers of path `i`'s stored photons, as functions of
    /// `density`, to `powers` (the path replayed with its decisions
    /// unchanged, [`Tracer::replay`]); `steps` is scratch.
    pub fn replay_path<R: Real>(&self, i: usize, density: &Grid<R>, steps: &mut Vec<Step>, powers: &mut Vec<R>) {
        let (count, seed) = (self.scene.render.photons, self.scene.render.seed);
        self.tracer().replay(i as u64, count, seed, self.flights.of(i), density, steps, powers);
    }

    /// Powers of all stored photons as functions of `density` (path replay).
    pub fn photon_powers<R: Real>(&self, density: &Grid<R>) -> Vec<R> {
        const CHUNK: usize = 256;
        let parts: Vec<Vec<R>> = (0..self.paths().div_ceil(CHUNK))
            .into_par_iter()
            .with_max_len(1)
            .map(|c| {
                let mut steps = vec![];
                let mut powers = vec![];
                for i in c * CHUNK..((c + 1) * CHUNK).min(self.paths()) {
                    if !self.path_photons(i).is_empty() {
                        self.replay_path(i, density, &mut steps, &mut powers);
                    }
                }
                powers
            })
            .collect();
        par::concat(parts)
    }

    /// The images of the first `cameras` cameras as functions of `density`,
    /// frozen at this estimator's decisions (one `Vec` per camera, row-major).
    pub fn images_with<R: Real>(&self, density: &Grid<R>, cameras: usize) -> Vec<Vec<R>> {
        let cameras = cameras.min(self.scene.cameras.len());
        let powers = self.photon_powers(density);
        let multiple = self.multiple_with(|p| powers[p], cameras);
        let depths = self.light_depths(density);
        let rays = self.camera_rays(density, Some(&self.scene.density), depths.as_ref());
        rays.images(&self.camera_list(cameras, multiple.as_deref()))
    }

    /// The first `cameras` cameras, each with the index of its first pixel
    /// and its photon estimate, as [`CameraRays::images`] takes them.
    fn camera_list<'b, R: Real>(
        &'b self,
        cameras: usize,
        multiple: Option<&'b [Estimate<'b, R>]>,
    ) -> Vec<(&'b Camera, u64, Option<&'b Estimate<'b, R>>)> {
        (0..cameras).map(|c| (&self.scene.cameras[c], self.first_pixel[c], multiple.map(|m| &m[c]))).collect()
    }
}

/// Where each path's photons start in `photons` (grouped by path, in path
/// order), for `paths` paths, with the end as a last entry.
fn path_starts(photons: &[Photon], paths: usize) -> Vec<usize> {
    let mut start = vec![0usize; paths + 1];
    for p in photons {
        start[p.path as usize + 1] += 1;
    }
    for i in 0..paths {
        start[i + 1] += start[i];
    }
    start
}

/// Each camera's first pixel among all the cameras' pixels, in order: the
/// pixel streams' names.
fn first_pixels(cameras: &[Camera]) -> Vec<u64> {
    cameras
        .iter()
        .scan(0u64, |acc, c| {
            let first = *acc;
            *acc += c.pixels() as u64;
            Some(first)
        })
        .collect()
}
