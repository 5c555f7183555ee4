//! A capture's frames as a reconstruction sees them: downsampled by area
//! averaging (the cameras' intrinsics scaled with them), and the visual hull
//! carved from real silhouettes.
//!
//! Real silhouettes differ from rendered ones: the frames were
//! background-subtracted and thresholded (codes up to about 8 of 255 set to
//! 0) and carry faint codec ringing (codes 1-6) around the plume, and the
//! calibration places the same point up to a few tens of full-resolution
//! pixels apart in different cameras. So a pixel is in the silhouette where
//! its area average is above an absolute code value that ringing does not
//! reach, and the silhouette is dilated by a margin for the calibration.

use super::{frames, Capture};
use crate::error::Result;
use crate::image::Image;
use crate::scene::Camera;

/// Code value (of 255) above which an area-averaged pixel shows smoke:
/// above the capture's threshold (8) and its ringing (1-6).
pub const SILHOUETTE_CODE: f64 = 12.0;

/// Dilation of the silhouettes, in full-resolution pixels: the calibration's
/// disagreement between cameras (up to about 40 pixels for ScalarFlow's).
pub const SILHOUETTE_MARGIN_PX: f64 = 40.0;

/// The images of some cameras of a capture at one working resolution.
#[derive(Clone, Debug)]
pub struct Observed {
    /// The cameras, downsampled with the images.
    pub cameras: Vec<Camera>,
    /// Per frame (in the order asked for), one image per camera.
    pub images: Vec<Vec<Image>>,
    /// The cameras' names.
    pub names: Vec<String>,
}

/// Frames `wanted` of cameras `views` of `capture`, downsampled by
/// `factor` (area averaging; a partial block at an edge is dropped).
pub fn observe(capture: &Capture, views: &[usize], wanted: &[usize], factor: usize) -> Result<Observed> {
    let mut images = vec![Vec::with_capacity(views.len()); wanted.len()];
    let mut cameras = Vec::with_capacity(views.len());
    for &v in views {
        let view = &capture.views[v];
        for (per_frame, full) in images.iter_mut().zip(frames::read(view, wanted)?) {
            per_frame.push(full.downsample(factor));
        }
        cameras.push(view.camera.downsample(factor));
    }
    let names = views.iter().map(|&v| capture.views[v].name.clone()).collect();
    Ok(Observed { cameras, images, names })
}

/// The silhouette of a real frame (code value / 255) at 1/`factor` of the
/// full resolution: pixels above [`SILHOUETTE_CODE`], dilated by
/// [`SILHOUETTE_MARGIN_PX`] / `factor` pixels (a disc).
pub fn real_silhouette(image: &Image, factor: usize) -> Vec<bool> {
    let seen: Vec<bool> = image.data.iter().map(|&v| v * 255.0 > SILHOUETTE_CODE).collect();
    dilate(&seen, image.width, image.height, SILHOUETTE_MARGIN_PX / factor as f64)
}

/// `mask` grown by a disc of `radius` pixels.
fn dilate(mask: &[bool], width: usize, height: usize, radius: f64) -> Vec<bool> {
    let r = radius.floor() as i64;
    let offsets: Vec<(i64, i64)> = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| ((dx * dx + dy * dy) as f64) <= radius * radius)
        .collect();
    let mut out = vec![false; mask.len()];
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            if !mask[(y as usize) * width + x as usize] {
                continue;
            }
            for (dx, dy) in &offsets {
                let (u, v) = (x + dx, y + dy);
                if u >= 0 && v >= 0 && u < width as i64 && v < height as i64 {
                    out[(v as usize) * width + u as usize] = true;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ringing_is_not_smoke_and_the_margin_is_a_disc() {
        let mut image = Image::zeros(21, 21);
        image.data[10 * 21 + 10] = 100.0 / 255.0;
        image.data[0] = 6.0 / 255.0; // ringing
        let sil = real_silhouette(&image, 10);
        // Radius 4 pixels at a tenth of the resolution: (10 +- 4, 10) in, (13, 13) out (4.2 from the centre).
        assert!(sil[10 * 21 + 14] && sil[6 * 21 + 10] && !sil[10 * 21 + 15]);
        assert!(!sil[13 * 21 + 13] && sil[12 * 21 + 12]);
        assert!(!sil[0]);
        assert_eq!(sil.iter().filter(|&&s| s).count(), 49);
    }
}
