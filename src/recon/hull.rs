//! The visual hull (space carving): the voxels whose centre projects onto
//! the silhouette of every training camera. All other voxels are fixed at
//! density 0 during reconstruction.
//!
//! Silhouette of an image: the pixels brighter than `threshold` times the
//! image's 99.5th-percentile radiance, dilated by `dilate` pixels (so that
//! noise and the pixel footprint do not carve away thin wisps).

use crate::image::Image;
use crate::scene::Camera;
use crate::volume::Grid;

/// Silhouette threshold as a fraction of the image's 99.5th-percentile radiance.
pub const SILHOUETTE_THRESHOLD: f64 = 0.02;
/// Silhouette dilation in pixels.
pub const SILHOUETTE_DILATION: usize = 1;

/// How the hull is carved: the silhouette threshold (a fraction of each
/// image's 99.5th-percentile radiance) and dilation (pixels).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HullSettings {
    /// Silhouette threshold.
    pub threshold: f64,
    /// Silhouette dilation.
    pub dilate: usize,
}

impl Default for HullSettings {
    fn default() -> Self {
        HullSettings { threshold: SILHOUETTE_THRESHOLD, dilate: SILHOUETTE_DILATION }
    }
}

/// The silhouette of `image`: `true` where the medium is seen.
pub fn silhouette(image: &Image, threshold: f64, dilate: usize) -> Vec<bool> {
    let white = crate::image::auto_white(&image.data);
    let (w, h) = (image.width, image.height);
    let seen: Vec<bool> = image.data.iter().map(|&v| v > threshold * white && v > 0.0).collect();
    let mut out = vec![false; w * h];
    let d = dilate as i64;
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            out[(y as usize) * w + x as usize] = (-d..=d).any(|dy| {
                (-d..=d).any(|dx| {
                    let (u, v) = (x + dx, y + dy);
                    u >= 0 && v >= 0 && u < w as i64 && v < h as i64 && seen[(v as usize) * w + u as usize]
                })
            });
        }
    }
    out
}

/// The hull over the voxels of `grid`: `true` where every camera's
/// silhouette (from `images`, one per camera) covers the voxel centre.
pub fn visual_hull(grid: &Grid<f64>, cameras: &[Camera], images: &[Image], threshold: f64, dilate: usize) -> Vec<bool> {
    let silhouettes: Vec<Vec<bool>> = images.iter().map(|i| silhouette(i, threshold, dilate)).collect();
    carve(grid, cameras, &silhouettes)
}

/// The voxels of `grid` whose centre every camera sees inside its
/// silhouette (`silhouettes[c]` covers camera `c`'s image); a voxel outside
/// a camera's image is carved.
pub fn carve(grid: &Grid<f64>, cameras: &[Camera], silhouettes: &[Vec<bool>]) -> Vec<bool> {
    let [nz, ny, nx] = grid.shape;
    let mut hull = vec![false; grid.len()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = grid.voxel_center(k, j, i);
                hull[grid.index(k, j, i)] = cameras
                    .iter()
                    .zip(silhouettes)
                    .all(|(cam, sil)| cam.pixel_of(&c).is_some_and(|(x, y)| sil[y * cam.width + x]));
            }
        }
    }
    hull
}
