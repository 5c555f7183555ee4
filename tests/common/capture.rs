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

/// Writes `frames` grey 8-bit PNG frames `{name}_{n}.png` of `w` x `h`
/// pixels into `dir`, pixel `(x, y)` of frame `n` being `value(n, x, y)`,
/// and codes them as `{name}.mp4` with `ffmpeg` (H.264 with B-frames,
/// x264's default, all but lossless).
pub fn write_video(dir: &Path, name: &str, frames: u16, (w, h): (u32, u32), value: impl Fn(u16, u32, u32) -> u16) {
    for n in 0..frames {
        write_png(&dir.join(format!("{name}_{n}.png")), w, h, false, |x, y| value(n, x, y));
    }
    let status = std::process::Command::new("ffmpeg")
        .args(["-nostdin", "-v", "error", "-y", "-framerate", "30", "-i"])
        .arg(dir.join(format!("{name}_%d.png")))
        .args(["-pix_fmt", "yuv420p", "-c:v", "libx264", "-crf", "1"])
        .arg(dir.join(format!("{name}.mp4")))
        .status()
        .unwrap();
    assert!(status.success());
}
