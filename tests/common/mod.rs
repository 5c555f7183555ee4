//! Small scenes for the integration tests: the library's own
//! (`dualphoton::eval::scenes`), plus a camera on the +z axis.
#![allow(dead_code, unused_imports)]

pub use dualphoton::eval::scenes::{blob, homogeneous, medium, scene};

use dualphoton::eval::scenes::look_at_origin;
use dualphoton::math::Vec3;
use dualphoton::scene::Camera;

/// A camera on the +z axis at distance `d` looking at the origin.
pub fn camera(d: f64, fov: f64, res: usize) -> Camera {
    look_at_origin(Vec3::new(0.0, 0.0, d), res, fov)
}
