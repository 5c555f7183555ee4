//! Made captures for the capture tests: calibrations' camera matrices and
//! grey PNG frames.

use serde_json::{json, Value};
use std::path::Path;

/// A camera-to-world matrix at `(x, 0, z)` looking at the origin (OpenGL: the camera looks along -column 2).
pub fn looking_at_origin(x: f64, z: f64) -> Value {
    let d = (x * x + z * z).sqrt();
    let back = [x / d, 0.0, z / d];
    let right = [back[2], 0.0, -back[0]];
    json!([[right[0], 0.0, back[0], x], [0.0, 1.0, 0.0, 0.0], [right[2], 0.0, back[2], z], [0.0, 0.0, 0.0, 1.0]])
}

/// Writes a `w` x `h` grey PNG whose pixel `(x, y)` is `value(x, y)`, 8 or 16 bit.
pub fn write_png(path: &Path, w: u32, h: u32, sixteen: bool, value: impl Fn(u32, u32) -> u16) {
    if sixteen {
        image::ImageBuffer::from_fn(w, h, |x, y| image::Luma([value(x, y)])).save(path).unwrap();
    } else {
        image::ImageBuffer::from_fn(w, h, |x, y| image::Luma([value(x, y) as u8])).save(path).unwrap();
    }
}
