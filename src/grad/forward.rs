//! Forward mode: directional derivatives of the frozen loss with
//! `DualSVec64<K>` (K directions per pass), and the gradient estimators
//! built from them: `fwd-full` (coordinate directions in chunks of K) and
//! `fwd-rand` (K random directions, an unbiased forward gradient).

use super::loss::mse;
use crate::ad::dual::{lane, with_tangents};
use crate::image::Image;
use crate::render::frozen::Frozen;
use crate::rng::Rng;
use crate::volume::Grid;
use num_dual::DualSVec64;

/// The loss and its K directional derivatives along the tangents `density`
/// carries. The targets belong to the scene's first `targets.len()` cameras;
/// cameras after them (held out) are not rendered.
pub fn directional<const K: usize>(
    frozen: &Frozen,
    density: &Grid<DualSVec64<K>>,
    targets: &[Image],
) -> (f64, [f64; K]) {
    let loss = mse(&frozen.images_with(density, targets.len()), targets);
    (loss.re, std::array::from_fn(|k| lane(&loss, k)))
}

/// The scene's density with unit tangents on `voxels` (at most K of them), constants elsewhere.
pub fn coordinate_tangents<const K: usize>(density: &Grid<f64>, voxels: &[usize]) -> Grid<DualSVec64<K>> {
    assert!(voxels.len() <= K);
    let mut g = density.map(DualSVec64::<K>::from_re);
    for (k, &v) in voxels.iter().enumerate() {
        let mut e = [0.0; K];
        e[k] = 1.0;
        g.data[v] = with_tangents(density.data[v], e);
    }
    g
}

/// `dL/drho_v` for every listed voxel, K coordinate directions per pass
/// (exact, `fwd-full`). `progress(done, total)` is called after each pass.
pub fn coordinate_gradient<const K: usize>(
    frozen: &Frozen,
    voxels: &[usize],
    targets: &[Image],
    progress: &dyn Fn(usize, usize),
) -> Vec<f64> {
    let mut grad = Vec::with_capacity(voxels.len());
    for chunk in voxels.chunks(K) {
        let density = coordinate_tangents::<K>(&frozen.scene.density, chunk);
        let (_, d) = directional(frozen, &density, targets);
        grad.extend_from_slice(&d[..chunk.len()]);
        progress(grad.len(), voxels.len());
    }
    grad
}

/// How random directions are drawn for `fwd-rand`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Directions {
    /// Independent standard normal entries; `g = (1/K) Σ (∇L·v) v`.
    Gaussian,
    /// K random orthonormal directions (Gram-Schmidt of Gaussians); `g = (n/K) Σ (∇L·q) q`.
    Orthonormal,
}

/// K random directions over `n` parameters and the factor that makes
/// `factor * Σ (∇L·v) v` unbiased.
pub fn random_directions<const K: usize>(n: usize, kind: Directions, rng: &mut Rng) -> ([Vec<f64>; K], f64) {
    let mut dirs: [Vec<f64>; K] = std::array::from_fn(|_| (0..n).map(|_| rng.normal()).collect());
    match kind {
        Directions::Gaussian => (dirs, 1.0 / K as f64),
        Directions::Orthonormal => {
            for k in 0..K.min(n) {
                for j in 0..k {
                    let dot: f64 = dirs[k].iter().zip(&dirs[j]).map(|(a, b)| a * b).sum();
                    let (head, tail) = dirs.split_at_mut(k);
                    tail[0].iter_mut().zip(&head[j]).for_each(|(a, b)| *a -= dot * b);
                }
                let norm = dirs[k].iter().map(|a| a * a).sum::<f64>().sqrt();
                dirs[k].iter_mut().for_each(|a| *a /= norm);
            }
            (dirs, n as f64 / K as f64)
        }
    }
}

/// `fwd-rand`: an unbiased estimate of `dL/drho` on the voxels `params`
/// (zero elsewhere) from K random directions in one pass.
pub fn random_gradient<const K: usize>(
    frozen: &Frozen,
    params: &[usize],
    targets: &[Image],
    kind: Directions,
    rng: &mut Rng,
) -> Vec<f64> {
    let base = &frozen.scene.density;
    let (dirs, factor) = random_directions::<K>(params.len(), kind, rng);
    let mut density = base.map(DualSVec64::<K>::from_re);
    for (i, &v) in params.iter().enumerate() {
        density.data[v] = with_tangents(base.data[v], std::array::from_fn(|k| dirs[k][i]));
    }
    let (_, d) = directional(frozen, &density, targets);
    let mut grad = vec![0.0; base.len()];
    for (i, &v) in params.iter().enumerate() {
        grad[v] = factor * (0..K).map(|k| d[k] * dirs[k][i]).sum::<f64>();
    }
    grad
}
