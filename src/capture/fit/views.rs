//! A fitted frame seen through cameras: the training cameras' views and
//! their error against the photographs, and any other camera's view (the
//! held-out one's) at any resolution.

use super::response::{respond, through_lens};
use super::Fit;
use crate::grad::loss::mse;
use crate::image::Image;
use crate::render::render_photon;
use crate::scene::Camera;

/// The training cameras' views of a fitted frame at the working
/// resolution, through their lenses, gains and the response.
pub fn training_views(fit: &Fit) -> Vec<Image> {
    let rendered = render_photon(&fit.scene).images.into_iter().zip(&fit.scene.cameras);
    let responses = fit.gains.iter().zip(&fit.black_levels);
    rendered
        .zip(responses)
        .map(|((image, camera), (&gain, &black))| {
            respond(&through_lens(image, camera, &fit.settings, false), gain, black, &fit.settings)
        })
        .collect()
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
    let seen = through_lens(render_photon(&scene).images.swap_remove(0), camera, &fit.settings, false);
    respond(&seen, 1.0, held_out_black(fit), &fit.settings)
}

/// A held-out camera's black level: the training cameras' mean, by the
/// rule fixed in advance ([`FitSettings::black_level`]); 0 without it.
///
/// [`FitSettings::black_level`]: crate::capture::settings::FitSettings::black_level
pub fn held_out_black(fit: &Fit) -> f64 {
    fit.black_levels.iter().sum::<f64>() / fit.black_levels.len().max(1) as f64
}
