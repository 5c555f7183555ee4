//! The photon-mapping renderer: photon tracing, the photon estimate towards
//! each camera, and the camera rays, timed separately. Leaves out what a
//! scene does not need: no photons at max_order 1 or albedo 0, no work in
//! empty blocks, no photons from lights of zero intensity.

use super::frozen::Frozen;
pub use super::frozen::Timings;
use crate::image::Image;
use crate::scene::Scene;

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
    // Consumed here, never replayed: no flights kept.
    let frozen = Frozen::build(scene, None, false);
    PhotonRender { stored_photons: frozen.photons.len(), timings: frozen.timings, images: frozen.images }
}
