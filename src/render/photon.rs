//! The photon-mapping renderer: photon tracing, the photon estimate towards
//! each camera, and the camera rays, timed separately. Leaves out what a
//! scene does not need: no photons at max_order 1 or albedo 0, no work in
//! empty blocks, no photons from lights of zero intensity.

use super::camera_rays::CameraRays;
use super::march::Marcher;
use super::photons::{emitters, Tracer};
use super::splat::SplatGeometry;
use super::Image;
use crate::scene::Scene;
use crate::volume::Majorant;
use std::time::Instant;

/// Voxels per majorant block edge: small enough to skip the plume's empty
/// surroundings, large enough that the block walk is cheap.
pub const MAJORANT_BLOCK: usize = 4;

/// Wall-clock seconds per stage.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    /// Photon tracing.
    pub trace: f64,
    /// Photon estimate onto the grids (gathering).
    pub gather: f64,
    /// Camera rays: single scattering and reading the estimate.
    pub camera: f64,
    /// Everything, setup included.
    pub total: f64,
}

/// Images (one per camera, scene order) and what it took to make them.
#[derive(Clone, Debug)]
pub struct PhotonRender {
    /// Radiance images.
    pub images: Vec<Image>,
    /// Photons stored (collisions 2..max_order).
    pub stored_photons: usize,
    /// Stage times.
    pub timings: Timings,
}

/// Renders every camera of `scene` with the settings in `scene.render`.
pub fn render_photon(scene: &Scene) -> PhotonRender {
    let start = Instant::now();
    let settings = &scene.render;
    let density = &scene.density;
    let majorant = Majorant::build(density, MAJORANT_BLOCK);
    let marcher = Marcher::new(density, &majorant, settings.step_for(density));
    let mut timings = Timings::default();

    let t = Instant::now();
    let emitters = emitters(&scene.lights, &majorant);
    let tracer = Tracer { density, medium: &scene.medium, marcher: &marcher, emitters: &emitters };
    let photons = tracer.trace(settings.photons, settings.seed);
    timings.trace = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let multiple = if photons.is_empty() {
        None
    } else {
        let geometry = SplatGeometry::new(density, settings.kernel_radius_for(density));
        let kernel = geometry.kernel(&photons);
        let positions: Vec<_> = scene.cameras.iter().map(|c| c.position).collect();
        Some(geometry.estimate(&photons, &kernel, &positions, scene.medium.albedo, scene.medium.g))
    };
    timings.gather = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let rays = CameraRays {
        density,
        sampling: None,
        medium: &scene.medium,
        lights: &scene.lights,
        marcher: &marcher,
        spp: settings.spp,
        seed: settings.seed,
    };
    let mut first_pixel = 0u64;
    let images = scene
        .cameras
        .iter()
        .enumerate()
        .map(|(c, camera)| {
            let data = rays.image(camera, first_pixel, multiple.as_ref().map(|m| &m[c]));
            first_pixel += camera.pixels() as u64;
            Image { width: camera.width, height: camera.height, data }
        })
        .collect();
    timings.camera = t.elapsed().as_secs_f64();
    timings.total = start.elapsed().as_secs_f64();
    PhotonRender { images, stored_photons: photons.len(), timings }
}
