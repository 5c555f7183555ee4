//! Small scenes built in code, shared by the tests and the stability study:
//! grids on the unit box `[-0.5, 0.5]^3`, a heterogeneous blob, cameras
//! aimed at the origin, and the two lit blob scenes the checks start from.
//! They are small on purpose (8^3 to 16^3 voxels, a few cameras of a few
//! pixels): analytic and finite-difference checks render them many times.

use crate::math::Vec3;
use crate::scene::{Camera, Lens, Light, Medium, RenderSettings, Scene};
use crate::volume::Grid;

/// A grid of `shape` (z, y, x) over the unit box with `f(voxel centre)` in every voxel.
pub fn unit_grid(shape: [usize; 3], f: impl Fn(Vec3) -> f64) -> Grid<f64> {
    let mut g = homogeneous_shape(shape, 0.0);
    for k in 0..shape[0] {
        for j in 0..shape[1] {
            for i in 0..shape[2] {
                let idx = g.index(k, j, i);
                g.data[idx] = f(g.voxel_center(k, j, i));
            }
        }
    }
    g
}

fn homogeneous_shape(shape: [usize; 3], rho: f64) -> Grid<f64> {
    Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), shape, vec![rho; shape.iter().product()])
}

/// A homogeneous unit box of `n^3` voxels with density `rho`.
pub fn homogeneous(n: usize, rho: f64) -> Grid<f64> {
    homogeneous_shape([n; 3], rho)
}

/// The blob's density at `p`: a smooth bump plus a denser off-centre lump,
/// cut to 0 below 0.01 (as the paper cuts its plumes), so the corners are empty.
pub fn blob_density(p: Vec3) -> f64 {
    let a = (-p.norm_squared() / (2.0 * 0.18f64.powi(2))).exp();
    let b = (-(p - Vec3::new(0.12, 0.1, -0.05)).norm_squared() / (2.0 * 0.07f64.powi(2))).exp();
    let v = 0.25 * a + 0.6 * b;
    if v < 0.01 {
        0.0
    } else {
        v
    }
}

/// The blob on an `n^3` grid: heterogeneous, with empty corners.
pub fn blob(n: usize) -> Grid<f64> {
    unit_grid([n; 3], blob_density)
}

/// A square camera of `res` pixels at `position` looking at the origin,
/// vertical field of view `fov_y_deg` in degrees.
pub fn look_at_origin(position: Vec3, res: usize, fov_y_deg: f64) -> Camera {
    // Any up hint not parallel to the viewing direction will do.
    let up = if position.normalize().y.abs() > 0.9 { Vec3::new(1.0, 0.0, 0.0) } else { Vec3::new(0.0, 1.0, 0.0) };
    Camera { position, look_at: Vec3::zeros(), up, lens: Lens::FovY(fov_y_deg), width: res, height: res }
}

/// A medium of extinction scale 20 (a density of 0.05 is one mean free path per unit).
pub fn medium(albedo: f64, g: f64, max_order: u32) -> Medium {
    Medium { sigma_t_scale: 20.0, albedo, g, max_order, emission: 0.0 }
}

/// A scene of `density` with the default render settings.
pub fn scene(density: Grid<f64>, medium: Medium, lights: Vec<Light>, cameras: Vec<Camera>) -> Scene {
    Scene { density, medium, lights, cameras, render: RenderSettings::default() }
}

/// The `n^3` blob lit by one light (50 W/sr, above and in front), albedo
/// 0.9, g 0.6, orders 1-3, seen by a front and a side camera of `res`
/// pixels (field of view 35 degrees): the stability study's base scene.
pub fn one_light_blob(n: usize, res: usize) -> Scene {
    let lights = vec![Light { position: Vec3::new(1.2, 0.5, 1.5), intensity: 50.0 }];
    let cameras =
        vec![look_at_origin(Vec3::new(0.0, 0.0, 2.0), res, 35.0), look_at_origin(Vec3::new(2.0, 0.3, 0.0), res, 35.0)];
    scene(blob(n), medium(0.9, 0.6, 3), lights, cameras)
}

/// The `n^3` blob lit by a key light (100 W/sr) and a fill light from
/// behind (60 W/sr), albedo 0.9, asymmetry `g`, orders 1 to `max_order`,
/// seen by one front camera of `res` pixels (field of view 30 degrees):
/// the scene of the gradient and reference-renderer checks.
pub fn two_light_blob(n: usize, g: f64, max_order: u32, res: usize) -> Scene {
    let lights = vec![
        Light { position: Vec3::new(1.5, 0.8, 2.0), intensity: 100.0 },
        Light { position: Vec3::new(-2.0, -0.3, -1.0), intensity: 60.0 },
    ];
    scene(blob(n), medium(0.9, g, max_order), lights, vec![look_at_origin(Vec3::new(0.0, 0.0, 2.2), res, 30.0)])
}

/// The built-in plume of `seed`, blurred by a Gaussian of `blur` voxels
/// (at 64^3; scaled with the resolution) and rescaled to the plume's
/// maximum: thicker, smoother smoke, for timing the renderer where the
/// built-in plume is sparse. A blur of 3 fills about an eighth of the box
/// (12 % at 64^3), a blur of 5 about a quarter (25 %); 0 is the built-in
/// plume itself.
pub fn blurred_plume(res: usize, seed: u64, blur: f64) -> Grid<f64> {
    use crate::data::plume::{plume, CUTOFF, PLUME_MAX};
    if blur <= 0.0 {
        return plume(res, seed);
    }
    let mut g = crate::volume::blur::gaussian_blur(&plume(res, seed), blur * res as f64 / 64.0);
    let scale = PLUME_MAX / g.max_value().max(f64::MIN_POSITIVE);
    g.data.iter_mut().for_each(|v| *v = if *v * scale < CUTOFF { 0.0 } else { *v * scale });
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blob_is_heterogeneous_with_empty_corners() {
        let g = blob(8);
        assert_eq!(g.data[g.index(0, 0, 0)], 0.0);
        assert!(g.max_value() > 0.3 && g.data.iter().all(|v| (0.0..1.0).contains(v)));
    }

    #[test]
    fn cameras_look_at_the_origin_with_a_usable_up_hint() {
        for p in [Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.0, 3.0, 0.0), Vec3::new(2.0, 0.3, 0.0)] {
            let c = look_at_origin(p, 4, 30.0);
            let (x, y) = c.project(&Vec3::zeros()).unwrap();
            assert!((x - 2.0).abs() < 1e-9 && (y - 2.0).abs() < 1e-9, "{p:?}");
        }
    }
}
