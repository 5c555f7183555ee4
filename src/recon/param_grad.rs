//! Gradients of the image loss with respect to the model's parameters (the
//! latent `z` and the decoder weights `w`): forward mode through decoder and
//! renderer, or reverse mode through the renderer followed by the decoder's
//! own vector-Jacobian product. [`super::estimator`] chooses among them.

use super::level::Level;
use crate::ad::dual::with_tangents;
use crate::error::Result;
use crate::grad::forward::{directional, orthonormalize, random_directions, Directions};
use crate::grad::lanes_for;
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::model::Model;
use crate::render::frozen::Frozen;
use crate::rng::Rng;
use crate::volume::Grid;
use num_dual::DualSVec64;
use rayon::prelude::*;

/// `(dL/dz, dL/dw)` by reverse mode on `subset` (exact for the full set, unbiased otherwise).
pub fn reverse(level: &Level, model: &Model, frozen: &Frozen, subset: Subset) -> (Vec<f64>, Vec<f64>) {
    let g = reverse_gradient(frozen, &level.targets, subset).grad;
    let g = level.pull_back(g, model.decoder_shape());
    model.decoder.backward(&model.z, &model.w, &model.mask, &g)
}

/// Exact `dL/dz` from all latent coordinates, at most `lanes` per forward
/// pass ([`lanes_for`]: a 64-d latent takes one pass of 64 lanes).
pub fn latent_exact(level: &Level, model: &Model, frozen: &Frozen, lanes: usize) -> Result<Vec<f64>> {
    fn pass<const K: usize>(level: &Level, model: &Model, frozen: &Frozen) -> Vec<f64> {
        let n = model.z.len();
        let mut grad = Vec::with_capacity(n);
        for first in (0..n).step_by(K) {
            let z: Vec<DualSVec64<K>> = (0..n)
                .map(|i| {
                    if i >= first && i < first + K {
                        let mut e = [0.0; K];
                        e[i - first] = 1.0;
                        with_tangents(model.z[i], e)
                    } else {
                        DualSVec64::from_re(model.z[i])
                    }
                })
                .collect();
            let density = tangent_grid(level, model, model.decoder.forward_fixed_weights(&z, &model.w, &model.mask));
            let (_, d) = directional(frozen, &density, &level.targets);
            grad.extend_from_slice(&d[..K.min(n - first)]);
        }
        grad
    }
    let lanes = lanes_for(model.z.len(), lanes)?;
    Ok(crate::with_lanes!(lanes, pass(level, model, frozen)))
}

/// An unbiased `dL/dz` from `k` random directions in one forward pass
/// (`k` one of the lane counts).
pub fn latent_random(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    k: usize,
    kind: Directions,
    rng: &mut Rng,
) -> Result<Vec<f64>> {
    fn pass<const K: usize>(
        level: &Level,
        model: &Model,
        frozen: &Frozen,
        kind: Directions,
        rng: &mut Rng,
    ) -> Vec<f64> {
        let n = model.z.len();
        let (dirs, factor) = random_directions::<K>(n, kind, rng);
        let z: Vec<DualSVec64<K>> =
            (0..n).map(|i| with_tangents(model.z[i], std::array::from_fn(|k| dirs[k][i]))).collect();
        let density = tangent_grid(level, model, model.decoder.forward_fixed_weights(&z, &model.w, &model.mask));
        let (_, d) = directional(frozen, &density, &level.targets);
        (0..n).map(|i| factor * (0..K).map(|k| d[k] * dirs[k][i]).sum::<f64>()).collect()
    }
    Ok(crate::with_lanes!(k, pass(level, model, frozen, kind, rng)))
}

/// A random-direction estimate of `dL/dw` from `k` directions (any k),
/// unbiased for both kinds; `lanes` directions per forward pass.
pub fn weights_random(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    k: usize,
    kind: Directions,
    lanes: usize,
    rng: &mut Rng,
) -> Result<Vec<f64>> {
    let n = model.w.len();
    let k = k.min(n);
    if k == 0 {
        return Ok(vec![0.0; n]);
    }
    let (dirs, factor) = directions(n, k, kind, rng);
    let d = weight_derivatives(level, model, frozen, &dirs, lanes)?;
    Ok(combine(&dirs, &d, factor))
}

/// The projection of `dL/dw` onto a guessed direction and `k - 1` random
/// ones ([`guided_basis`]), from exact forward-mode directional
/// derivatives: biased, but always a descent direction.
pub fn weights_guided(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    k: usize,
    lanes: usize,
    rng: &mut Rng,
) -> Result<Vec<f64>> {
    let n = model.w.len();
    if k.min(n) == 0 {
        return Ok(vec![0.0; n]);
    }
    let basis = guided_basis(level, model, frozen, k, rng);
    let d = weight_derivatives(level, model, frozen, &basis, lanes)?;
    Ok(combine(&basis, &d, 1.0))
}

/// An orthonormal basis of weight space directions, at most `k` of them:
/// a guess first, then `k - 1` Gaussian ones (drawn in blocks of 16),
/// orthonormalised in that order, dropping any that vanish. The guess is
/// the decoder's vector-Jacobian product of the image residuals
/// back-projected along the camera rays (attenuated, not differentiated
/// through the renderer): cheap, and far better aligned with the gradient
/// than a random direction in 31,000 dimensions.
pub fn guided_basis(level: &Level, model: &Model, frozen: &Frozen, k: usize, rng: &mut Rng) -> Vec<Vec<f64>> {
    let n = model.w.len();
    let k = k.min(n);
    if k == 0 {
        return vec![];
    }
    let g_rho = level.pull_back(back_projection(level, frozen), model.decoder_shape());
    let (_, guess) = model.decoder.backward(&model.z, &model.w, &model.mask, &g_rho);
    let mut dirs = vec![guess];
    if k > 1 {
        dirs.extend(directions(n, k - 1, Directions::Gaussian, rng).0);
    }
    orthonormalize(dirs)
}

/// The decoder's output `decoded` with K tangents, as the level's grid for the renderer.
fn tangent_grid<const K: usize>(level: &Level, model: &Model, decoded: Vec<DualSVec64<K>>) -> Grid<DualSVec64<K>> {
    let d = &level.scene.density;
    level.grid(Grid::new(d.lo, d.hi, model.decoder_shape(), decoded))
}

/// Directional derivatives of the loss along weight-space directions `dirs`,
/// at most `lanes` per forward pass.
fn weight_derivatives(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    dirs: &[Vec<f64>],
    lanes: usize,
) -> Result<Vec<f64>> {
    fn pass<const K: usize>(level: &Level, model: &Model, frozen: &Frozen, dirs: &[Vec<f64>]) -> Vec<f64> {
        let z: Vec<DualSVec64<K>> = model.z.iter().map(|&v| DualSVec64::from_re(v)).collect();
        let mut out = vec![];
        for chunk in dirs.chunks(K) {
            let w: Vec<DualSVec64<K>> = (0..model.w.len())
                .into_par_iter()
                .map(|i| with_tangents(model.w[i], std::array::from_fn(|k| chunk.get(k).map_or(0.0, |d| d[i]))))
                .collect();
            let density = tangent_grid(level, model, model.decoder.forward(&z, &w, &model.mask));
            let (_, d) = directional(frozen, &density, &level.targets);
            out.extend_from_slice(&d[..chunk.len()]);
        }
        out
    }
    let lanes = lanes_for(dirs.len(), lanes)?;
    Ok(crate::with_lanes!(lanes, pass(level, model, frozen, dirs)))
}

/// `factor * Σ_k d_k dirs_k`: a gradient estimate from directional derivatives.
fn combine(dirs: &[Vec<f64>], d: &[f64], factor: f64) -> Vec<f64> {
    let mut g = vec![0.0; dirs.first().map_or(0, |v| v.len())];
    for (dk, dir) in d.iter().zip(dirs) {
        g.iter_mut().zip(dir).for_each(|(a, b)| *a += factor * dk * b);
    }
    g
}

/// K random directions over `n` coordinates (any K) and the unbiasing factor.
fn directions(n: usize, k: usize, kind: Directions, rng: &mut Rng) -> (Vec<Vec<f64>>, f64) {
    let dirs = match kind {
        // The draws of whole blocks of 16, as below, without drawing the unused ones.
        Directions::Gaussian => {
            let dirs = (0..k).map(|_| rng.normals(n)).collect();
            rng.skip_normals((k.div_ceil(16) * 16 - k) * n);
            dirs
        }
        Directions::Orthonormal => {
            let mut dirs = vec![];
            for _ in 0..k.div_ceil(16) {
                dirs.extend(random_directions::<16>(n, kind, rng).0);
            }
            dirs.truncate(k);
            dirs
        }
    };
    // Orthonormal blocks of 16 are independent of each other; E[q q^T] = I/n for each, so n/K stays unbiased.
    let factor = match kind {
        Directions::Gaussian => 1.0 / k as f64,
        Directions::Orthonormal => n as f64 / k as f64,
    };
    (dirs, factor)
}

/// The image residuals of the training cameras back-projected onto the
/// level's voxels along the pixel-centre rays, attenuated by the camera
/// transmittance: a guess of `dL/drho` that needs no renderer derivative.
fn back_projection(level: &Level, frozen: &Frozen) -> Vec<f64> {
    let d = &level.scene.density;
    let scale = level.scene.medium.sigma_t_scale;
    let marcher = frozen.marcher();
    let mut g = vec![0.0; d.len()];
    for (c, target) in level.targets.iter().enumerate() {
        let cam = &level.scene.cameras[c];
        for p in 0..cam.pixels() {
            let r = frozen.images[c].data[p] - target.data[p];
            if r == 0.0 {
                continue;
            }
            let ray = cam.ray((p % cam.width) as f64 + 0.5, (p / cam.width) as f64 + 0.5);
            let mut t = 1.0;
            marcher.steps(&ray, f64::INFINITY, 0.5, |s| {
                let x = ray.at(s.sample);
                if let Some(st) = d.stencil(&x) {
                    for k in 0..8 {
                        g[st.index[k]] += r * t * s.h * st.weight[k];
                    }
                }
                t *= (-d.at(&x) * scale * s.h).exp();
                t > 1e-6
            });
        }
    }
    g
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::eval::stats::{dot, norm2};
    use crate::recon::problem::{paper_problem, Problem};
    use crate::recon::reconstruct::initial_model;
    use crate::scene::{rig, Scene};

    /// A tiny paper problem (8^3): its level, the initial model, and a
    /// scene at the model's density for the estimator to freeze.
    pub(crate) fn tiny() -> (Level, Model, Scene) {
        let p = paper_problem(8, 0, 5_000, 0);
        let (targets, held_out) = p.images.split_at(rig::HELD_OUT_CAMERA);
        let problem = Problem { scene: &p.scene, targets, held_out, truth: None };
        let model = initial_model(&p.scene, targets, 0).unwrap();
        let level = Level::full(&problem, &model.mask);
        let scene = level.scene_at(&model.density(&p.scene.density), 5_000, 1, 3);
        (level, model, scene)
    }

    /// One pass of 64 lanes gives the latent's gradient that four passes of
    /// 16 and eight of 8 do, to the bit: every lane computes the same.
    #[test]
    fn the_latent_gradient_is_the_same_to_the_bit_for_any_lane_count() {
        let (level, model, scene) = tiny();
        let frozen = Frozen::new(&scene, Some(&level.support));
        let bits = |lanes| -> Vec<u64> {
            latent_exact(&level, &model, &frozen, lanes).unwrap().iter().map(|g| g.to_bits()).collect()
        };
        let wide = bits(64);
        assert!(wide.iter().any(|&b| f64::from_bits(b) != 0.0));
        assert_eq!(bits(16), wide);
        assert_eq!(bits(8), wide);
        let dirs: Vec<Vec<f64>> =
            (0..5).map(|k| (0..model.w.len()).map(|i| ((i * 7 + k * 3) % 11) as f64 - 5.0).collect()).collect();
        let along = |lanes| -> Vec<u64> {
            weight_derivatives(&level, &model, &frozen, &dirs, lanes).unwrap().iter().map(|g| g.to_bits()).collect()
        };
        assert_eq!(along(2), along(64));
    }

    /// On a tiny paper problem, the guided estimate is the orthogonal
    /// projection of the exact gradient (reverse mode on the same frozen
    /// estimator) onto the span of the guess and the random directions, so
    /// it is a descent direction.
    #[test]
    fn guided_estimate_is_the_projection_of_the_gradient_onto_its_directions() {
        let (level, model, scene) = tiny();
        let frozen = Frozen::new(&scene, Some(&level.support));
        let (_, g) = reverse(&level, &model, &frozen, Subset::full());
        let k = 6;
        let basis = guided_basis(&level, &model, &frozen, k, &mut Rng::from_seed(5));
        let g_hat = weights_guided(&level, &model, &frozen, k, 4, &mut Rng::from_seed(5)).unwrap();

        // An orthonormal basis of k directions.
        assert_eq!(basis.len(), k);
        for (i, a) in basis.iter().enumerate() {
            for (j, b) in basis.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot(a, b) - want).abs() < 1e-12, "q{i} . q{j} = {}", dot(a, b));
            }
        }
        // The exact projection: sum_k (g . q_k) q_k; its residual is orthogonal to the span.
        let coeffs: Vec<f64> = basis.iter().map(|q| dot(q, &g)).collect();
        let proj = combine(&basis, &coeffs, 1.0);
        let residual: Vec<f64> = g.iter().zip(&proj).map(|(a, b)| a - b).collect();
        basis.iter().for_each(|q| assert!(dot(q, &residual).abs() < 1e-9 * norm2(&g).sqrt()));
        let err = g_hat.iter().zip(&proj).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        assert!(err <= 1e-8 * norm2(&proj).sqrt(), "|g_hat - proj| = {err:e}, |proj| = {:e}", norm2(&proj).sqrt());
        // A descent direction: g_hat . g = |proj|^2 >= 0, and the guess carries most of it.
        assert!(dot(&g_hat, &g) >= 0.0);
        assert!(coeffs[0].powi(2) > coeffs[1..].iter().map(|c| c * c).sum::<f64>(), "{coeffs:?}");
    }
}
