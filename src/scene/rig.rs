//! The paper's rig (docs/DESIGN.md §4, paper Fig. 4): five cameras at azimuths
//! -60..60 degrees on a circle of radius 2.5, three point lights at -45, 0,
//! 45 degrees on a circle of radius 3, all in the y = 0 plane around the
//! volume. Azimuth `phi` is measured from +z towards +x.

use super::{Camera, Lens, Light, Medium, RenderSettings, Scene};
use crate::math::Vec3;
use crate::volume::Grid;

/// Camera azimuths in degrees; cameras 0-3 train, camera 4 is held out.
pub const CAMERA_AZIMUTHS_DEG: [f64; 5] = [-60.0, -30.0, 0.0, 30.0, 60.0];
/// Light azimuths in degrees.
pub const LIGHT_AZIMUTHS_DEG: [f64; 3] = [-45.0, 0.0, 45.0];
/// Camera circle radius.
pub const CAMERA_RADIUS: f64 = 2.5;
/// Light circle radius.
pub const LIGHT_RADIUS: f64 = 3.0;
/// Light intensity (W/sr): exposes the paper plume's back-scatter to order-one radiance.
pub const LIGHT_INTENSITY: f64 = 300.0;
/// Index of the held-out camera.
pub const HELD_OUT_CAMERA: usize = 4;

/// Position at azimuth `deg` on a circle of radius `r` in the y = 0 plane.
pub fn on_circle(r: f64, deg: f64) -> Vec3 {
    let phi = deg.to_radians();
    Vec3::new(r * phi.sin(), 0.0, r * phi.cos())
}

/// The paper's medium: g = 0.9, albedo 0.9, sigma_t_scale 20, up to 3rd order.
pub fn paper_medium() -> Medium {
    Medium { sigma_t_scale: 20.0, albedo: 0.9, g: 0.9, max_order: 3, emission: 0.0 }
}

/// The paper's five cameras with `res x res` images.
pub fn paper_cameras(res: usize) -> Vec<Camera> {
    CAMERA_AZIMUTHS_DEG
        .iter()
        .map(|&a| Camera {
            position: on_circle(CAMERA_RADIUS, a),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: Lens::FovY(40.0),
            width: res,
            height: res,
        })
        .collect()
}

/// `n` more cameras like the paper's, spread evenly over the far side of
/// the circle (azimuths 90..270 degrees, looking towards the lights): extra
/// training views for studying how much the paper's four constrain the density.
pub fn extra_cameras(n: usize, res: usize) -> Vec<Camera> {
    let template = paper_cameras(res).remove(0);
    (0..n)
        .map(|i| Camera {
            position: on_circle(CAMERA_RADIUS, 90.0 + 180.0 * (i as f64 + 0.5) / n as f64),
            ..template.clone()
        })
        .collect()
}

/// The paper's three lights.
pub fn paper_lights() -> Vec<Light> {
    LIGHT_AZIMUTHS_DEG
        .iter()
        .map(|&a| Light { position: on_circle(LIGHT_RADIUS, a), intensity: LIGHT_INTENSITY })
        .collect()
}

/// The paper's scene around `density` (box [-0.5, 0.5]^3 expected), images `res x res`.
pub fn paper_scene(density: Grid<f64>, res: usize) -> Scene {
    Scene {
        density,
        medium: paper_medium(),
        lights: paper_lights(),
        cameras: paper_cameras(res),
        render: RenderSettings::default(),
    }
}

/// [`paper_scene`] with only the training cameras (0-3): what the renderer
/// benchmarks measure.
pub fn paper_training_scene(density: Grid<f64>, res: usize) -> Scene {
    let mut scene = paper_scene(density, res);
    scene.cameras.truncate(HELD_OUT_CAMERA);
    scene
}
