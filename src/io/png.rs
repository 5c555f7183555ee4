//! PNG previews of radiance images.
//!
//! Tone mapping (stated in docs/usage.md): `v = (L / white)^(1/2.2)` clipped to
//! [0, 1] and stored as 8-bit grey, where `white` is the 99.5th percentile of
//! the image's non-zero radiance unless the caller fixes it (so that several
//! images can share one exposure).

use crate::error::{Error, Result};
use crate::image::auto_white;
use std::path::Path;

/// 8-bit grey levels of `values` under the tone map with the given white point.
pub fn tone_map(values: &[f64], white: f64) -> Vec<u8> {
    values.iter().map(|&v| ((v / white).clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8).collect()
}

/// Writes a `width x height` radiance image (row 0 at the top) as a PNG preview.
pub fn write_preview(path: &Path, width: usize, height: usize, values: &[f64], white: Option<f64>) -> Result<()> {
    let white = white.unwrap_or_else(|| auto_white(values));
    let grey = tone_map(values, white);
    image::GrayImage::from_raw(width as u32, height as u32, grey)
        .ok_or_else(|| Error::new("image size does not match its data"))?
        .save(path)
        .map_err(|e| Error(format!("cannot write {}: {e}", path.display())))
}

/// Writes an image of code value / 255 (a real capture's units) as the 8-bit
/// codes it stands for: no tone map, so it reads like the capture's frames.
pub fn write_codes(path: &Path, width: usize, height: usize, values: &[f64]) -> Result<()> {
    let codes = values.iter().map(|&v| (v * 255.0).round().clamp(0.0, 255.0) as u8).collect();
    image::GrayImage::from_raw(width as u32, height as u32, codes)
        .ok_or_else(|| Error::new("image size does not match its data"))?
        .save(path)
        .map_err(|e| Error(format!("cannot write {}: {e}", path.display())))
}
