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
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Directions {
    /// Independent standard normal entries; `g = (1/K) Σ (∇L·v) v`.
    Gaussian,
    /// K random orthonormal directions (Gram-Schmidt of Gaussians); `g = (n/K) Σ (∇L·q) q`.
    Orthonormal,
}

/// K random directions over `n` parameters and the factor that makes
/// `factor * Σ (∇L·v) v` unbiased. Orthonormal: at most `n` directions can
/// be; any beyond the first `n` stay Gaussian.
pub fn random_directions<const K: usize>(n: usize, kind: Directions, rng: &mut Rng) -> ([Vec<f64>; K], f64) {
    let dirs: [Vec<f64>; K] = std::array::from_fn(|_| rng.normals(n));
    match kind {
        Directions::Gaussian => (dirs, 1.0 / K as f64),
        Directions::Orthonormal => {
            let m = K.min(n);
            let mut first = Vec::from(dirs);
            let rest = first.split_off(m);
            let mut basis = orthonormalize(first);
            // A direction that vanished (probability zero) contributes nothing.
            basis.resize(m, vec![0.0; n]);
            let mut all = basis.into_iter().chain(rest);
            (std::array::from_fn(|_| all.next().unwrap_or_default()), n as f64 / K as f64)
        }
    }
}

/// Modified Gram-Schmidt, in order: each vector loses its components along
/// the basis kept so far, then is normalised; one whose remainder has zero
/// or non-finite length is dropped. Returns the orthonormal basis.
///
/// ```
/// use dualphoton::grad::forward::orthonormalize;
/// let q = orthonormalize(vec![vec![2.0, 0.0], vec![3.0, 0.0], vec![1.0, 1.0]]);
/// // The second vector is parallel to the first: dropped.
/// assert_eq!(q, vec![vec![1.0, 0.0], vec![0.0, 1.0]]);
/// ```
pub fn orthonormalize(vectors: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(vectors.len());
    for mut v in vectors {
        for b in &basis {
            let dot: f64 = v.iter().zip(b).map(|(a, c)| a * c).sum();
            v.iter_mut().zip(b).for_each(|(a, c)| *a -= dot * c);
        }
        let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm > 0.0 && norm.is_finite() {
            v.iter_mut().for_each(|a| *a /= norm);
            basis.push(v);
        }
    }
    basis
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

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    #[test]
    fn orthonormal_directions_are_orthonormal_up_to_n_of_them() {
        let (dirs, factor) = random_directions::<4>(3, Directions::Orthonormal, &mut Rng::from_seed(2));
        assert_eq!(factor, 0.75);
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot(&dirs[i], &dirs[j]) - want).abs() < 1e-12);
            }
        }
        // The fourth cannot be orthogonal to the other three: it stays the Gaussian draw.
        let mut rng = Rng::from_seed(2);
        let drawn: Vec<Vec<f64>> = (0..4).map(|_| (0..3).map(|_| rng.normal()).collect()).collect();
        assert_eq!(dirs[3], drawn[3]);
    }
}
