//! Small scenes built in code for the integration tests.
#![allow(dead_code)]

use dualphoton::math::Vec3;
use dualphoton::scene::{Camera, Light, Medium, RenderSettings, Scene};
use dualphoton::volume::Grid;

/// A homogeneous unit box [-0.5, 0.5]^3 of `n^3` voxels with density `rho`.
pub fn homogeneous(n: usize, rho: f64) -> Grid<f64> {
    Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [n, n, n], vec![rho; n * n * n])
}

/// A small heterogeneous blob: a smooth bump plus a denser off-centre lump.
pub fn blob(n: usize) -> Grid<f64> {
    let mut g = homogeneous(n, 0.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = g.voxel_center(k, j, i);
                let a = (-(p.norm_squared()) / (2.0 * 0.18f64.powi(2))).exp();
                let b = (-((p - Vec3::new(0.12, 0.1, -0.05)).norm_squared()) / (2.0 * 0.07f64.powi(2))).exp();
                let v = 0.25 * a + 0.6 * b;
                let idx = g.index(k, j, i);
                g.data[idx] = if v < 0.01 { 0.0 } else { v };
            }
        }
    }
    g
}

/// A camera on the +z axis at distance `d` looking at the origin.
pub fn camera(d: f64, fov: f64, res: usize) -> Camera {
    Camera {
        position: Vec3::new(0.0, 0.0, d),
        look_at: Vec3::zeros(),
        up: Vec3::new(0.0, 1.0, 0.0),
        fov_y_deg: fov,
        width: res,
        height: res,
    }
}

/// A scene of `density` with the given medium, lights and cameras.
pub fn scene(density: Grid<f64>, medium: Medium, lights: Vec<Light>, cameras: Vec<Camera>) -> Scene {
    Scene { density, medium, lights, cameras, render: RenderSettings::default() }
}

/// A medium with sigma_t_scale 20.
pub fn medium(albedo: f64, g: f64, max_order: u32) -> Medium {
    Medium { sigma_t_scale: 20.0, albedo, g, max_order }
}
