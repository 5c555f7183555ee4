//! The training loop (issue 4): a 64-d latent and a small decoder produce
//! the density inside the visual hull; Adam minimises the image MSE of the
//! training cameras. Each update re-traces the photons with a fresh seed
//! (detached sampling at the current density), so the noise averages out
//! over iterations.
//!
//! Gradients per estimator:
//! - `fwd-full` (default): the latent's gradient is exact, from 64
//!   coordinate directions through decoder and renderer in chunks of K dual
//!   lanes; the decoder weights get `weight_directions` directional
//!   derivatives per update ([`WeightDirections`]).
//! - `fwd-rand`: K random directions for the latent and for the weights.
//! - `rev-full` / `rev-sub`: reverse mode through the renderer (the paper's
//!   approximate learning for `rev-sub`), then the decoder's own
//!   vector-Jacobian product: exact (or unbiased) for latent and weights.

use crate::ad::dual::with_tangents;
use crate::error::Result;
use crate::grad::forward::{directional, random_directions, Directions};
use crate::grad::loss::mse;
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::grad::Estimator;
use crate::model::Decoder;
use crate::optim::adam::Adam;
use crate::render::frozen::Frozen;
use crate::render::Image;
use crate::rng::{Purpose, Rng};
use crate::scene::Scene;
use crate::volume::Grid;
use num_dual::DualSVec64;
use std::time::Instant;

/// How the decoder weights get their directional derivatives in forward mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightDirections {
    /// Exact partial derivatives of a block of weights, cycling through all of them.
    Coordinates,
    /// Random orthonormal directions; the step uses the projection of the
    /// gradient onto their span (scaled to be unbiased: `n/K Σ (g·q) q`).
    Orthonormal,
}

/// Everything a training run is set up with.
#[derive(Clone, Debug)]
pub struct TrainSettings {
    /// Adam updates.
    pub iterations: usize,
    /// Gradient estimator.
    pub estimator: Estimator,
    /// Dual lanes per forward pass (1, 2, 4, 8 or 16).
    pub lanes: usize,
    /// Directions for the decoder weights per update (forward estimators; 0 freezes the weights).
    pub weight_directions: usize,
    /// How those directions are chosen.
    pub weight_mode: WeightDirections,
    /// Adam step for the latent.
    pub lr_latent: f64,
    /// Adam step for the decoder weights.
    pub lr_weights: f64,
    /// Photons per update (the images of the targets may use more).
    pub photons: u64,
    /// Camera samples per pixel per update.
    pub spp: u32,
    /// `rev-sub`: pixels and photon paths differentiated per update.
    pub subset_pixels: usize,
    /// `rev-sub`: photon paths differentiated per update.
    pub subset_paths: usize,
    /// Seed of everything random in training.
    pub seed: u64,
}

impl Default for TrainSettings {
    fn default() -> Self {
        TrainSettings {
            iterations: 250,
            estimator: Estimator::FwdFull,
            lanes: 8,
            weight_directions: 16,
            weight_mode: WeightDirections::Orthonormal,
            lr_latent: 0.05,
            lr_weights: 0.01,
            photons: 100_000,
            spp: 2,
            subset_pixels: 1000,
            subset_paths: 5000,
            seed: 0,
        }
    }
}

/// The parameters being learned.
#[derive(Clone, Debug)]
pub struct Model {
    /// The decoder architecture.
    pub decoder: Decoder,
    /// Latent code.
    pub z: Vec<f64>,
    /// Decoder weights.
    pub w: Vec<f64>,
    /// Voxels that may hold smoke (the visual hull).
    pub mask: Vec<bool>,
}

impl Model {
    /// The density grid on `like`'s geometry.
    pub fn density(&self, like: &Grid<f64>) -> Grid<f64> {
        Grid::new(like.lo, like.hi, like.shape, self.decoder.forward(&self.z, &self.w, &self.mask))
    }
}

/// One line of the training log.
#[derive(Clone, Debug, Default)]
pub struct LogRow {
    /// Update number (0-based; the row is measured before the update).
    pub iteration: usize,
    /// Training MSE (this update's render).
    pub train_loss: f64,
    /// MSE of the held-out camera, if any.
    pub held_out_loss: f64,
    /// Relative RMSE of the held-out image.
    pub held_out_rel_rmse: f64,
    /// Relative L1 density error over the hull, if the ground truth is known.
    pub density_rel_l1: f64,
    /// Mean density over the hull.
    pub mean_density: f64,
    /// Max density over the hull.
    pub max_density: f64,
    /// Seconds since the start of training.
    pub wall_s: f64,
}

/// What the training loop needs to know about the problem.
pub struct Problem<'a> {
    /// The scene: training cameras first, then held-out ones; its density is replaced every update.
    pub scene: &'a Scene,
    /// Target images of the training cameras (the first `targets.len()` cameras).
    pub targets: &'a [Image],
    /// Target images of the remaining (held-out) cameras.
    pub held_out: &'a [Image],
    /// Ground-truth density, for the log only.
    pub truth: Option<&'a Grid<f64>>,
}

/// Relative L1 error `|a - b|_1 / |b|_1` over the masked voxels.
pub fn rel_l1(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..a.len() {
        if mask[i] {
            num += (a[i] - b[i]).abs();
            den += b[i].abs();
        }
    }
    if den == 0.0 {
        0.0
    } else {
        num / den
    }
}

/// Relative RMSE of `ours` against `reference`.
pub fn rel_rmse(ours: &[f64], reference: &[f64]) -> f64 {
    let num: f64 = ours.iter().zip(reference).map(|(a, b)| (a - b).powi(2)).sum();
    let den: f64 = reference.iter().map(|b| b * b).sum();
    if den == 0.0 {
        0.0
    } else {
        (num / den).sqrt()
    }
}

/// Trains `model` in place; `observe(row, model, images)` sees every log row
/// with the model before the update and this update's rendered images.
pub fn train(problem: &Problem, model: &mut Model, settings: &TrainSettings, observe: &mut dyn FnMut(&LogRow, &Model, &[Image])) -> Result<()> {
    let start = Instant::now();
    let mut adam_z = Adam::new(model.z.len(), settings.lr_latent);
    let mut adam_w = Adam::new(model.w.len(), settings.lr_weights);
    let support = Grid::new(
        problem.scene.density.lo,
        problem.scene.density.hi,
        problem.scene.density.shape,
        model.mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect(),
    );
    let mut rng = Rng::new(settings.seed, Purpose::Gradient, 1_000_000);
    let mut next_weight = 0usize;
    for it in 0..settings.iterations {
        let mut scene = problem.scene.clone();
        scene.density = model.density(&problem.scene.density);
        scene.render.photons = settings.photons;
        scene.render.spp = settings.spp;
        scene.render.seed = settings.seed.wrapping_mul(1_000_003).wrapping_add(it as u64);
        let frozen = Frozen::new(&scene, Some(&support));
        let row = log_row(it, problem, model, &frozen, start.elapsed().as_secs_f64());
        observe(&row, model, &frozen.images);
        let (gz, gw) = gradient(problem, model, &frozen, settings, &mut rng, &mut next_weight)?;
        adam_z.step_sparse(&mut model.z, &gz.0, &gz.1);
        adam_w.step_sparse(&mut model.w, &gw.0, &gw.1);
    }
    Ok(())
}

fn log_row(it: usize, problem: &Problem, model: &Model, frozen: &Frozen, wall_s: f64) -> LogRow {
    let n = problem.targets.len();
    let images: Vec<Vec<f64>> = frozen.images.iter().map(|i| i.data.clone()).collect();
    let train_loss = mse(&images[..n], problem.targets);
    let (held_out_loss, held_out_rel_rmse) = if problem.held_out.is_empty() {
        (0.0, 0.0)
    } else {
        let ours: Vec<f64> = images[n..].iter().flatten().copied().collect();
        let theirs: Vec<f64> = problem.held_out.iter().flat_map(|i| i.data.iter().copied()).collect();
        (mse(&images[n..], problem.held_out), rel_rmse(&ours, &theirs))
    };
    let d = &frozen.scene.density.data;
    let hull: Vec<f64> = d.iter().zip(&model.mask).filter(|(_, &m)| m).map(|(v, _)| *v).collect();
    LogRow {
        iteration: it,
        train_loss,
        held_out_loss,
        held_out_rel_rmse,
        density_rel_l1: problem.truth.map_or(f64::NAN, |t| rel_l1(d, &t.data, &model.mask)),
        mean_density: hull.iter().sum::<f64>() / hull.len().max(1) as f64,
        max_density: hull.iter().fold(0.0, |a: f64, &b| a.max(b)),
        wall_s,
    }
}

/// (indices, gradient) pairs for the latent and for the weights.
type Sparse = (Vec<usize>, Vec<f64>);

fn gradient(
    problem: &Problem,
    model: &Model,
    frozen: &Frozen,
    settings: &TrainSettings,
    rng: &mut Rng,
    next_weight: &mut usize,
) -> Result<(Sparse, Sparse)> {
    let all = |n: usize| (0..n).collect::<Vec<_>>();
    match settings.estimator {
        Estimator::RevFull | Estimator::RevSub => {
            let subset = if settings.estimator == Estimator::RevFull {
                Subset::full()
            } else {
                Subset { pixels: Some(settings.subset_pixels), paths: Some(settings.subset_paths), seed: rng.below(u64::MAX) }
            };
            let g = reverse_gradient(frozen, problem.targets, subset).grad;
            let (dz, dw) = model.decoder.backward(&model.z, &model.w, &model.mask, &g);
            Ok(((all(dz.len()), dz), (all(dw.len()), dw)))
        }
        Estimator::FwdFull => {
            let dz = crate::with_lanes!(settings.lanes, latent_gradient(problem, model, frozen));
            let gw = match settings.weight_mode {
                WeightDirections::Coordinates => {
                    let n = model.w.len();
                    let idx: Vec<usize> = (0..settings.weight_directions.min(n)).map(|k| (*next_weight + k) % n).collect();
                    *next_weight = (*next_weight + idx.len()) % n.max(1);
                    let dirs: Vec<Vec<f64>> = idx
                        .iter()
                        .map(|&i| {
                            let mut e = vec![0.0; n];
                            e[i] = 1.0;
                            e
                        })
                        .collect();
                    let d = weight_derivatives(problem, model, frozen, &dirs, settings.lanes)?;
                    (idx, d)
                }
                WeightDirections::Orthonormal => random_weight_gradient(problem, model, frozen, settings, Directions::Orthonormal, rng)?,
            };
            Ok(((all(dz.len()), dz), gw))
        }
        Estimator::FwdRand => {
            let dz = random_latent_gradient(problem, model, frozen, settings, rng)?;
            let gw = random_weight_gradient(problem, model, frozen, settings, Directions::Gaussian, rng)?;
            Ok(((all(dz.len()), dz), gw))
        }
    }
}

/// The decoder's output with K tangents, as a grid for the renderer.
fn tangent_grid<const K: usize>(model: &Model, like: &Grid<f64>, z: &[DualSVec64<K>], w: &[DualSVec64<K>]) -> Grid<DualSVec64<K>> {
    Grid::new(like.lo, like.hi, like.shape, model.decoder.forward(z, w, &model.mask))
}

/// Exact `dL/dz` from all latent coordinates, K per pass.
fn latent_gradient<const K: usize>(problem: &Problem, model: &Model, frozen: &Frozen) -> Vec<f64> {
    let n = model.z.len();
    let w: Vec<DualSVec64<K>> = model.w.iter().map(|&v| DualSVec64::from_re(v)).collect();
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
        let density = tangent_grid(model, &frozen.scene.density, &z, &w);
        let (_, d) = directional(frozen, &density, problem.targets);
        grad.extend_from_slice(&d[..K.min(n - first)]);
    }
    grad
}

/// Directional derivatives of the loss along weight-space directions `dirs`.
fn weight_derivatives(problem: &Problem, model: &Model, frozen: &Frozen, dirs: &[Vec<f64>], lanes: usize) -> Result<Vec<f64>> {
    fn pass<const K: usize>(problem: &Problem, model: &Model, frozen: &Frozen, dirs: &[Vec<f64>]) -> Vec<f64> {
        let z: Vec<DualSVec64<K>> = model.z.iter().map(|&v| DualSVec64::from_re(v)).collect();
        let mut out = vec![];
        for chunk in dirs.chunks(K) {
            let w: Vec<DualSVec64<K>> = (0..model.w.len())
                .map(|i| with_tangents(model.w[i], std::array::from_fn(|k| chunk.get(k).map_or(0.0, |d| d[i]))))
                .collect();
            let density = tangent_grid(model, &frozen.scene.density, &z, &w);
            let (_, d) = directional(frozen, &density, problem.targets);
            out.extend_from_slice(&d[..chunk.len()]);
        }
        out
    }
    Ok(crate::with_lanes!(lanes, pass(problem, model, frozen, dirs)))
}

/// A random-direction estimate of `dL/dw` from `weight_directions` directions.
fn random_weight_gradient(problem: &Problem, model: &Model, frozen: &Frozen, settings: &TrainSettings, kind: Directions, rng: &mut Rng) -> Result<Sparse> {
    let n = model.w.len();
    let k = settings.weight_directions.min(n);
    if k == 0 {
        return Ok((vec![], vec![]));
    }
    let (dirs, factor) = directions(n, k, kind, rng);
    let d = weight_derivatives(problem, model, frozen, &dirs, settings.lanes)?;
    let mut g = vec![0.0; n];
    for (dk, dir) in d.iter().zip(&dirs) {
        g.iter_mut().zip(dir).for_each(|(a, b)| *a += factor * dk * b);
    }
    Ok(((0..n).collect(), g))
}

/// K random directions over `n` coordinates (any K) and the unbiasing factor.
fn directions(n: usize, k: usize, kind: Directions, rng: &mut Rng) -> (Vec<Vec<f64>>, f64) {
    let mut dirs = vec![];
    for _ in 0..k.div_ceil(16) {
        dirs.extend(random_directions::<16>(n, kind, rng).0);
    }
    dirs.truncate(k);
    // Orthonormal blocks of 16 are independent of each other; E[q q^T] = I/n for each, so n/K stays unbiased.
    let factor = match kind {
        Directions::Gaussian => 1.0 / k as f64,
        Directions::Orthonormal => n as f64 / k as f64,
    };
    (dirs, factor)
}

/// `fwd-rand` for the latent: K Gaussian directions.
fn random_latent_gradient(problem: &Problem, model: &Model, frozen: &Frozen, settings: &TrainSettings, rng: &mut Rng) -> Result<Vec<f64>> {
    fn pass<const K: usize>(problem: &Problem, model: &Model, frozen: &Frozen, rng: &mut Rng) -> Vec<f64> {
        let n = model.z.len();
        let (dirs, factor) = random_directions::<K>(n, Directions::Gaussian, rng);
        let z: Vec<DualSVec64<K>> = (0..n).map(|i| with_tangents(model.z[i], std::array::from_fn(|k| dirs[k][i]))).collect();
        let w: Vec<DualSVec64<K>> = model.w.iter().map(|&v| DualSVec64::from_re(v)).collect();
        let density = tangent_grid(model, &frozen.scene.density, &z, &w);
        let (_, d) = directional(frozen, &density, problem.targets);
        (0..n).map(|i| factor * (0..K).map(|k| d[k] * dirs[k][i]).sum::<f64>()).collect()
    }
    Ok(crate::with_lanes!(settings.lanes, pass(problem, model, frozen, rng)))
}
