//! The image loss (docs/DESIGN.md §3): `L = (1/N) Σ_cameras Σ_pixels (Î - I)^2`,
//! N the total number of pixels of all cameras.

use crate::ad::Real;
use crate::image::Image;

/// The mean squared error of `images` (one `Vec` per camera) against `targets`.
pub fn mse<R: Real>(images: &[Vec<R>], targets: &[Image]) -> R {
    let n: usize = targets.iter().map(|t| t.data.len()).sum();
    let mut sum = R::cst(0.0);
    for (image, target) in images.iter().zip(targets) {
        for (v, t) in image.iter().zip(&target.data) {
            let d = *v - *t;
            sum += d * d;
        }
    }
    sum * (1.0 / n.max(1) as f64)
}

/// `dL/dÎ` of every pixel: `2 (Î - I) / N`, one `Vec` per camera.
pub fn mse_residuals(images: &[Image], targets: &[Image]) -> Vec<Vec<f64>> {
    let n: usize = targets.iter().map(|t| t.data.len()).sum();
    images
        .iter()
        .zip(targets)
        .map(|(i, t)| i.data.iter().zip(&t.data).map(|(a, b)| 2.0 * (a - b) / n.max(1) as f64).collect())
        .collect()
}
