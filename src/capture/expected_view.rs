//! A held-out camera's view expected over its unknown calibration error.
//!
//! The training cameras are aligned on their photographs (their principal
//! points moved, their focal lengths scaled); the held-out camera cannot be,
//! and its own error is unknown. The training cameras' corrections show how
//! large such errors are. Under squared error the best prediction of a view
//! whose camera is uncertain is its mean over that uncertainty, so the
//! expected view averages the render over moves and magnifications drawn
//! from a normal distribution with the corrections' spread.
//!
//! The spread: camera errors `e_i`, independent with covariance `S`; a
//! training camera's correction is `e_i` less the mean error of the `n`
//! training cameras (a move every camera shares is the density's), and the
//! held-out camera is off by its own error less that mean, covariance
//! `S (n + 1) / n`. The corrections' sample covariance estimates `S` (they
//! have `n - 1` degrees of freedom). Moves are in the capture's pixels,
//! magnifications on a log scale; a turn about the optical axis is left
//! out. With fewer than two training cameras nothing is known of the
//! spread, and the expected view is the render itself.

use super::fit::Fit;
use super::protocol::{moved_pixel, Protocol, Score};
use crate::image::Image;
use crate::scene::Camera;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;

/// One move of the held-out camera and its weight in the mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    /// Weight (the weights sum to 1).
    pub weight: f64,
    /// Its principal point's move, in the capture's pixels (right, down).
    pub offset_px: [f64; 2],
    /// Its focal lengths' factor.
    pub zoom: f64,
}

/// Gauss-Hermite nodes and weights for a standard normal, three points:
/// exact for polynomials up to degree 5.
const NODES: [(f64, f64); 3] =
    [(-1.732_050_807_568_877_2, 1.0 / 6.0), (0.0, 2.0 / 3.0), (1.732_050_807_568_877_2, 1.0 / 6.0)];

/// The moves the expected view averages over (27, or one where the spread
/// is unknown), from the training cameras' corrections: their principal
/// points' moves (the capture's pixels) and focal-length factors.
pub fn moves(offsets_px: &[[f64; 2]], zooms: &[f64]) -> Vec<Move> {
    let n = offsets_px.len().min(zooms.len());
    let none = vec![Move { weight: 1.0, offset_px: [0.0, 0.0], zoom: 1.0 }];
    if n < 2 {
        return none;
    }
    let points: Vec<Vector3<f64>> =
        (0..n).map(|i| Vector3::new(offsets_px[i][0], offsets_px[i][1], zooms[i].ln())).collect();
    // A correction that is not a number says nothing of the spread.
    if points.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
        return none;
    }
    let mean = points.iter().sum::<Vector3<f64>>() / n as f64;
    let spread: Matrix3<f64> = points.iter().map(|p| (p - mean) * (p - mean).transpose()).sum::<Matrix3<f64>>()
        * ((n + 1) as f64 / (n * (n - 1)) as f64);
    let eigen = SymmetricEigen::new(spread);
    let root = eigen.eigenvectors
        * Matrix3::from_diagonal(&eigen.eigenvalues.map(|l| l.max(0.0).sqrt()))
        * eigen.eigenvectors.transpose();
    let mut out = Vec::with_capacity(27);
    for &(a, wa) in &NODES {
        for &(b, wb) in &NODES {
            for &(c, wc) in &NODES {
                let x = root * Vector3::new(a, b, c);
                out.push(Move { weight: wa * wb * wc, offset_px: [x[0], x[1]], zoom: x[2].exp() });
            }
        }
    }
    if out.iter().all(|m| m.offset_px == [0.0, 0.0] && m.zoom == 1.0) {
        return none;
    }
    out
}

/// `prediction` (a held-out camera's render, whose principal point is
/// `principal` in its pixels) averaged over `moves`.
pub fn expected_view(prediction: &Image, principal: [f64; 2], moves: &[Move]) -> Image {
    if let [only] = moves {
        if only.offset_px == [0.0, 0.0] && only.zoom == 1.0 {
            return prediction.clone();
        }
    }
    // Pixel by pixel, each summing the moves in order: the moved images
    // need not all be held, and the sum is the same on any number of threads.
    let w = prediction.width;
    let mut mean = Image::zeros(w, prediction.height);
    mean.data.par_chunks_mut(w.max(1)).enumerate().for_each(|(row, out)| {
        for (column, acc) in out.iter_mut().enumerate() {
            for m in moves {
                *acc += m.weight * moved_pixel(prediction, m.zoom, m.offset_px, principal, [column, row]);
            }
        }
    });
    mean
}

/// The expected view of a held-out `camera` whose render is `prediction`,
/// with the spread of `fitted`'s training corrections, scored against its
/// photograph `truth` under its protocol.
pub fn score(camera: &Camera, prediction: &Image, fitted: &Fit, truth: &Image) -> Score {
    let [_, _, cx, cy] = camera.intrinsics();
    let view = expected_view(prediction, [cx, cy], &moves(&fitted.offsets_px(), &fitted.zooms));
    let protocol = Protocol::for_size(camera.width, camera.height);
    protocol.score(&view, truth)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The moves' weighted mean and covariance (offsets, log zoom).
    fn moments(moves: &[Move]) -> (Vector3<f64>, Matrix3<f64>) {
        let point = |m: &Move| Vector3::new(m.offset_px[0], m.offset_px[1], m.zoom.ln());
        let mean: Vector3<f64> = moves.iter().map(|m| m.weight * point(m)).sum();
        let cov = moves.iter().map(|m| m.weight * (point(m) - mean) * (point(m) - mean).transpose()).sum();
        (mean, cov)
    }

    #[test]
    fn the_moves_have_the_held_out_cameras_spread() {
        // Four cameras' corrections: the held-out camera's covariance is their
        // sample covariance times (n + 1) / n = 5/4.
        let offsets = [[1.0, 6.0], [4.0, -18.0], [-2.0, -5.0], [-3.0, 17.0]];
        let zooms = [1.02, 0.98, 1.015, 0.985];
        let moves = moves(&offsets, &zooms);
        assert_eq!(moves.len(), 27);
        assert!((moves.iter().map(|m| m.weight).sum::<f64>() - 1.0).abs() < 1e-12);
        let (mean, cov) = moments(&moves);
        assert!(mean.norm() < 1e-9, "the moves are centred: {mean}");
        let points: Vec<Vector3<f64>> =
            (0..4).map(|i| Vector3::new(offsets[i][0], offsets[i][1], f64::ln(zooms[i]))).collect();
        let centre = points.iter().sum::<Vector3<f64>>() / 4.0;
        let sample: Matrix3<f64> =
            points.iter().map(|p| (p - centre) * (p - centre).transpose()).sum::<Matrix3<f64>>() / 3.0;
        let want = sample * 1.25;
        assert!((cov - want).norm() < 1e-9 * want.norm(), "covariance {cov} against {want}");
    }

    #[test]
    fn without_a_spread_the_expected_view_is_the_render() {
        let image = Image { width: 3, height: 2, data: vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0] };
        let cases = [
            (vec![], vec![]),
            (vec![[2.0, 1.0]], vec![1.1]),
            (vec![[1.0, 1.0]; 3], vec![1.0; 3]),
            (vec![[1.0, 1.0], [2.0, f64::NAN]], vec![1.0, 1.1]),
            (vec![[1.0, 1.0], [2.0, 3.0]], vec![1.0, 0.0]),
        ];
        for (offsets, zooms) in cases {
            let moves = moves(&offsets, &zooms);
            assert_eq!(moves.len(), 1);
            assert_eq!(expected_view(&image, [1.5, 1.0], &moves), image);
        }
    }

    /// The expected view is the weighted sum of the moved renders, added
    /// in the moves' order: the same to the bit however it is computed.
    #[test]
    fn the_expected_view_is_the_weighted_sum_of_the_moved_views() {
        let (w, h) = (13, 9);
        let image = Image { width: w, height: h, data: (0..w * h).map(|i| (i as f64 * 0.37).sin().abs()).collect() };
        let moves = moves(&[[1.0, 6.0], [4.7, -18.5], [-2.3, -4.9], [-3.5, 17.3]], &[1.02, 0.98, 1.015, 0.985]);
        let principal = [6.5, 4.0];
        let mut sum = Image::zeros(w, h);
        for m in &moves {
            let view = crate::capture::protocol::moved(&image, m.zoom, m.offset_px, principal);
            for (acc, v) in sum.data.iter_mut().zip(&view.data) {
                *acc += m.weight * v;
            }
        }
        assert_eq!(expected_view(&image, principal, &moves), sum);
    }

    #[test]
    fn the_expected_view_spreads_a_point_as_the_cameras_disagree() {
        // Cameras that disagree only vertically, by +-4 pixels: a bright
        // row is spread up and down, not sideways, and its light is kept.
        let (w, h) = (9, 41);
        let mut image = Image::zeros(w, h);
        for x in 0..w {
            image.data[20 * w + x] = 1.0;
        }
        let moves = moves(&[[0.0, 4.0], [0.0, -4.0], [0.0, 4.0], [0.0, -4.0]], &[1.0; 4]);
        let view = expected_view(&image, [4.5, 20.5], &moves);
        let column: Vec<f64> = (0..h).map(|y| view.data[y * w + 4]).collect();
        assert!((column.iter().sum::<f64>() - 1.0).abs() < 1e-9, "the light is kept: {column:?}");
        assert!((column[20] - 2.0 / 3.0).abs() < 1e-9, "the unmoved view keeps its weight: {column:?}");
        // The spread's standard deviation: sqrt(16 * 4/3 * 5/4) = 5.16 pixels.
        let mean_y: f64 = column.iter().enumerate().map(|(y, v)| y as f64 * v).sum();
        let var: f64 = column.iter().enumerate().map(|(y, v)| (y as f64 - mean_y).powi(2) * v).sum();
        assert!((mean_y - 20.0).abs() < 1e-9);
        assert!((var - 16.0 * 4.0 / 3.0 * 1.25).abs() < 0.5, "variance {var}");
        for y in 0..h {
            assert!((view.data[y * w] - view.data[y * w + 4]).abs() < 1e-9, "nothing moves sideways");
        }
    }
}
