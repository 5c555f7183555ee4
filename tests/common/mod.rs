//! Small scenes for the integration tests: the library's own
//! (`dualphoton::eval::scenes`), plus a camera on the +z axis.
#![allow(dead_code, unused_imports)]

pub mod capture;

pub use dualphoton::eval::scenes::{blob, homogeneous, medium, scene};

use dualphoton::eval::scenes::look_at_origin;
use dualphoton::math::Vec3;
use dualphoton::scene::Camera;

/// A camera on the +z axis at distance `d` looking at the origin.
pub fn camera(d: f64, fov: f64, res: usize) -> Camera {
    look_at_origin(Vec3::new(0.0, 0.0, d), res, fov)
}

/// A fresh, empty scratch directory named after the test binary's process
/// and `name`, so that tests running side by side never share one.
pub fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("dualphoton-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
