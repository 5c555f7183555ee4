//! The training loop: a 64-d latent and a small decoder produce
//! the density inside the visual hull; Adam minimises the image MSE of the
//! training cameras. Each update re-traces the photons with a fresh seed
//! (detached sampling at the current density), so the noise averages out
//! over iterations.
//!
//! Gradients per estimator ([`super::estimator`] computes them):
//! - `fwd-full` (default): the latent's gradient is exact, from 64
//!   coordinate directions through decoder and renderer in chunks of K dual
//!   lanes; the decoder weights get `weight_directions` directional
//!   derivatives per update ([`super::estimator::WeightDirections`]).
//! - `fwd-rand`: K random directions for the latent and for the weights.
//! - `rev-full` / `rev-sub`: reverse mode through the renderer (the paper's
//!   approximate learning for `rev-sub`), then the decoder's own
//!   vector-Jacobian product: exact (or unbiased) for latent and weights.

use super::estimator::{parameter_gradient, Entries, EstimatorSettings};
use super::level::Level;
use super::problem::Problem;
use crate::error::{Error, Result};
use crate::eval::metrics::{rel_l1, rel_rmse};
use crate::grad::loss::mse;
use crate::image::Image;
use crate::model::Model;
use crate::optim::Adam;
use crate::par;
use crate::render::frozen::Frozen;
use crate::rng::{Purpose, Rng};
use crate::volume::Grid;
use std::time::Instant;

/// Everything a training run is set up with.
#[derive(Clone, Debug)]
pub struct TrainSettings {
    /// Adam updates.
    pub iterations: usize,
    /// How each update's gradient is estimated.
    pub gradient: EstimatorSettings,
    /// Adam step for the latent.
    pub lr_latent: f64,
    /// Adam step for the decoder weights.
    pub lr_weights: f64,
    /// Photons per update (the images of the targets may use more).
    pub photons: u64,
    /// Camera samples per pixel per update.
    pub spp: u32,
    /// Seed of everything random in training.
    pub seed: u64,
    /// Share of the updates made at half resolution (grid and images pooled
    /// 2x) before the full resolution: coarse to fine, about 6x cheaper per update.
    pub coarse_fraction: f64,
    /// Stop once this many seconds have passed (at most `iterations`
    /// updates); `coarse_fraction` then applies to the time, not the updates.
    pub time_budget: Option<f64>,
    /// Learning rates fall exponentially over the full-resolution updates
    /// to this fraction of their starting values (1: constant), so that the
    /// last updates average the render noise instead of following it.
    pub lr_final: f64,
    /// Take each update's image residual from a second, independent render
    /// (another seed) rather than from the render differentiated. The
    /// squared loss of a noisy render is biased,
    /// `E[(I - T)^2] = (E[I] - T)^2 + Var I`, and its gradient on one render carries the `Var I` term; with
    /// independent residual and derivative the gradient is that of `(E[I] - T)^2`.
    /// Costs one more primal render per update.
    pub decorrelate: bool,
    /// Weight of a sparsity prior `sparsity * mean density over the hull`
    /// added to the image loss (0: none, the paper's loss). Its gradient is
    /// exact for every estimator (the decoder's vector-Jacobian product).
    pub sparsity: f64,
    /// Weight of a Gaussian penalty on the latent, `latent_penalty * s *
    /// mean_k z_k^2` with `s` the mean square of the training target pixels
    /// (so the weight is relative to the image loss): the prior of a
    /// learned decoder, whose latents are whitened (0: none).
    pub latent_penalty: f64,
    /// Weight of a penalty keeping the decoder weights near their values at
    /// the start of training, `weight_penalty * s * mean_i (w_i - w0_i)^2`
    /// (`s` as for `latent_penalty`): fine-tuning a learned prior's decoder
    /// without leaving the prior (0: none).
    pub weight_penalty: f64,
}

impl Default for TrainSettings {
    fn default() -> Self {
        TrainSettings {
            iterations: 250,
            gradient: EstimatorSettings::default(),
            lr_latent: 0.05,
            lr_weights: 0.01,
            photons: 50_000,
            spp: 2,
            seed: 0,
            coarse_fraction: 0.8,
            time_budget: None,
            lr_final: 1.0,
            decorrelate: false,
            sparsity: 0.0,
            latent_penalty: 0.0,
            weight_penalty: 0.0,
        }
    }
}

/// How many of the first updates [`train`] makes at half
/// resolution for a fixed number of updates, given whether the problem has a
/// half level at all ([`Level::half`]).
pub fn coarse_updates(settings: &TrainSettings, has_half: bool) -> usize {
    if !has_half || settings.coarse_fraction <= 0.0 {
        return 0;
    }
    (settings.coarse_fraction.clamp(0.0, 1.0) * settings.iterations as f64).round() as usize
}

/// Flips the seed of an update's second render ([`TrainSettings::decorrelate`]).
const DECORRELATE_SEED: u64 = 0x5EC0_0D00_0000_0000;

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

/// Trains `model` in place; `observe(row, model, images)` sees every log row
/// with the model before the update and this update's rendered images.
pub fn train(
    problem: &Problem,
    model: &mut Model,
    settings: &TrainSettings,
    observe: &mut dyn FnMut(&LogRow, &Model, &[Image]),
) -> Result<()> {
    if !(settings.lr_final.is_finite() && settings.lr_final > 0.0) {
        return Err(Error(format!("lr_final: {} must be finite and > 0", settings.lr_final)));
    }
    for (name, v) in [("latent_penalty", settings.latent_penalty), ("weight_penalty", settings.weight_penalty)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(Error(format!("{name}: {v} must be finite and >= 0")));
        }
    }
    let anchor = model.w.clone();
    let start = Instant::now();
    let mut adam_z = Adam::new(model.z.len(), settings.lr_latent);
    let mut adam_w = Adam::new(model.w.len(), settings.lr_weights);
    let fine = Level::full(problem, &model.mask);
    let coarse = if settings.coarse_fraction > 0.0 { Level::half(problem, &model.mask) } else { None };
    let coarse_updates = coarse_updates(settings, coarse.is_some());
    let mut rng = Rng::new(settings.seed, Purpose::Gradient, 1_000_000);
    let estimator = settings.gradient;
    let pixels = fine.targets.iter().map(|t| t.data.len()).sum::<usize>().max(1) as f64;
    let target_power = fine.targets.iter().flat_map(|t| &t.data).map(|v| v * v).sum::<f64>() / pixels;
    for it in 0..settings.iterations {
        let elapsed = start.elapsed().as_secs_f64();
        let coarse_now = match settings.time_budget {
            Some(budget) if elapsed >= budget => break,
            Some(budget) => elapsed < settings.coarse_fraction * budget,
            None => it < coarse_updates,
        };
        let level = match &coarse {
            Some(c) if coarse_now => c,
            _ => &fine,
        };
        let fine_progress = match settings.time_budget {
            _ if coarse_now => 0.0,
            Some(budget) => (elapsed - settings.coarse_fraction * budget) / (budget * (1.0 - settings.coarse_fraction)),
            None => {
                (it - coarse_updates.min(it)) as f64
                    / (settings.iterations - coarse_updates.min(settings.iterations)).max(1) as f64
            }
        };
        let decay = settings.lr_final.powf(fine_progress.clamp(0.0, 1.0));
        (adam_z.lr, adam_w.lr) = (settings.lr_latent * decay, settings.lr_weights * decay);
        let decoded = model.density(&problem.scene.density);
        let seed = settings.seed.wrapping_mul(1_000_003).wrapping_add(it as u64);
        let scene = level.scene_at(&decoded, settings.photons, settings.spp, seed);
        let (frozen, shifted) = level.freeze(&scene, &decoded, settings.decorrelate.then_some(seed ^ DECORRELATE_SEED));
        let wall_s = start.elapsed().as_secs_f64();
        // The log row is serial work: a helper thread computes it while the gradient runs.
        let (g, row) = par::alongside(
            || parameter_gradient(shifted.as_ref().unwrap_or(level), model, &frozen, &estimator, it, &mut rng),
            || log_row(it, problem, level, &model.mask, &decoded, &frozen, wall_s),
        );
        observe(&row, model, &frozen.images);
        let mut g = g?;
        if settings.sparsity > 0.0 {
            add_sparsity_gradient(model, settings.sparsity, &mut g.latent, &mut g.weights);
        }
        if settings.latent_penalty > 0.0 {
            let k = model.z.len().max(1) as f64;
            let scale = 2.0 * settings.latent_penalty * target_power / k;
            for (&i, v) in g.latent.indices.iter().zip(&mut g.latent.values) {
                *v += scale * model.z[i];
            }
        }
        if settings.weight_penalty > 0.0 {
            let scale = 2.0 * settings.weight_penalty * target_power / model.w.len().max(1) as f64;
            let mut dense = g.weights.to_dense(model.w.len()).unwrap_or_else(|| vec![0.0; model.w.len()]);
            dense.iter_mut().zip(model.w.iter().zip(&anchor)).for_each(|(d, (w, w0))| *d += scale * (w - w0));
            g.weights = Entries::dense(dense);
        }
        adam_z.step_sparse(&mut model.z, &g.latent.indices, &g.latent.values);
        adam_w.step_sparse(&mut model.w, &g.weights.indices, &g.weights.values);
    }
    Ok(())
}

/// The log row of update `it`: the losses of `frozen`'s images at `level`,
/// the density `decoded` against the truth over the hull `mask`.
pub(super) fn log_row(
    it: usize,
    problem: &Problem,
    level: &Level,
    mask: &[bool],
    decoded: &Grid<f64>,
    frozen: &Frozen,
    wall_s: f64,
) -> LogRow {
    let n = level.targets.len();
    let images: Vec<Vec<f64>> = frozen.images.iter().map(|i| i.data.clone()).collect();
    let train_loss = mse(&images[..n], &level.targets);
    let (held_out_loss, held_out_rel_rmse) = if level.held_out.is_empty() {
        (0.0, 0.0)
    } else {
        let ours: Vec<f64> = images[n..].iter().flatten().copied().collect();
        let theirs: Vec<f64> = level.held_out.iter().flat_map(|i| i.data.iter().copied()).collect();
        (mse(&images[n..], &level.held_out), rel_rmse(&ours, &theirs).unwrap_or(f64::NAN))
    };
    let d = &decoded.data;
    let hull: Vec<f64> = d.iter().zip(mask).filter(|(_, &m)| m).map(|(v, _)| *v).collect();
    LogRow {
        iteration: it,
        train_loss,
        held_out_loss,
        held_out_rel_rmse,
        density_rel_l1: problem.truth.and_then(|t| rel_l1(d, &t.data, mask)).unwrap_or(f64::NAN),
        mean_density: hull.iter().sum::<f64>() / hull.len().max(1) as f64,
        max_density: hull.iter().fold(0.0, |a: f64, &b| a.max(b)),
        wall_s,
    }
}

/// Adds the gradient of `sparsity * mean(density over the hull)` to both
/// sparse gradients (made dense where they were not).
fn add_sparsity_gradient(model: &Model, sparsity: f64, gz: &mut Entries, gw: &mut Entries) {
    let hull = model.mask.iter().filter(|&&m| m).count().max(1) as f64;
    let seed: Vec<f64> = model.mask.iter().map(|&m| if m { sparsity / hull } else { 0.0 }).collect();
    let (dz, dw) = model.decoder.backward(&model.z, &model.w, &model.mask, &seed);
    for (g, d) in [(gz, dz), (gw, dw)] {
        let mut dense = d;
        for (&i, &v) in g.indices.iter().zip(&g.values) {
            dense[i] += v;
        }
        *g = Entries::dense(dense);
    }
}
