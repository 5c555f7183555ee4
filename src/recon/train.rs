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

use super::estimator::{parameter_gradient, EstimatorSettings};
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
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Everything a training run is set up with. `Default` is the paper's
/// method as this project ships it, [`TrainSettings::prior`] the learned prior's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    /// Take each update's image residual from a second, independent render
    /// (another seed) rather than from the render differentiated. The
    /// squared loss of a noisy render is biased,
    /// `E[(I - T)^2] = (E[I] - T)^2 + Var I`, and its gradient on one render carries the `Var I` term; with
    /// independent residual and derivative the gradient is that of `(E[I] - T)^2`.
    /// Costs one more primal render per update.
    pub decorrelate: bool,
    /// Weight of a Gaussian penalty on the latent, `latent_penalty * s *
    /// mean_k z_k^2` with `s` the mean square of the training target pixels
    /// (so the weight is relative to the image loss): the prior of a
    /// learned decoder, whose latents are whitened (0: none).
    pub latent_penalty: f64,
}

impl Default for TrainSettings {
    /// The paper's method: latent and weights (8 guided directions, the
    /// latent exact by `fwd-full`), 80 % of 250 updates at half resolution,
    /// decorrelated residuals.
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
            decorrelate: true,
            latent_penalty: 0.0,
        }
    }
}

impl TrainSettings {
    /// The latent penalty's gradient in `z_k` over `z_k`, for a latent of
    /// `len` numbers and targets whose mean square is `image_power`:
    /// `d/dz_k latent_penalty * image_power * mean_k z_k^2`.
    pub fn latent_penalty_slope(&self, image_power: f64, len: usize) -> f64 {
        2.0 * self.latent_penalty * image_power / len.max(1) as f64
    }

    /// The learned prior's fit: 60 updates of its latent alone (exact,
    /// `fwd-full`; the weights fixed), half of them at half resolution,
    /// under a latent penalty of 1e-3.
    pub fn prior() -> Self {
        TrainSettings {
            iterations: 60,
            gradient: EstimatorSettings { weight_directions: 0, ..EstimatorSettings::default() },
            lr_latent: 0.1,
            lr_weights: 0.0,
            coarse_fraction: 0.5,
            latent_penalty: 1e-3,
            ..TrainSettings::default()
        }
    }

    /// Errors (naming the field) on settings that cannot run; [`train`]
    /// checks them before its first update.
    pub fn check(&self) -> Result<()> {
        self.gradient.check()?;
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error(format!("{name}: {v} must be finite and > 0")))
            }
        };
        positive("train.lr_latent", self.lr_latent)?;
        if !(self.lr_weights.is_finite() && self.lr_weights >= 0.0) {
            return Err(Error(format!("train.lr_weights: {} must be finite and >= 0", self.lr_weights)));
        }
        if !(self.latent_penalty.is_finite() && self.latent_penalty >= 0.0) {
            return Err(Error(format!("train.latent_penalty: {} must be finite and >= 0", self.latent_penalty)));
        }
        if !(0.0..=1.0).contains(&self.coarse_fraction) {
            return Err(Error(format!("train.coarse_fraction: {} must be in 0..=1", self.coarse_fraction)));
        }
        if let Some(b) = self.time_budget {
            positive("train.time_budget", b)?;
        }
        check_renders("train", self.photons, self.spp)
    }
}

/// Errors unless `photons` and `spp` (of `part`'s updates) are at least 1 and `spp` at most [`MAX_SPP`].
pub(super) fn check_renders(part: &str, photons: u64, spp: u32) -> Result<()> {
    if photons == 0 {
        return Err(Error(format!("{part}.photons: must be at least 1")));
    }
    if spp == 0 || spp > MAX_SPP {
        return Err(Error(format!("{part}.spp: {spp} must be in 1..={MAX_SPP}")));
    }
    Ok(())
}

/// Most camera samples per pixel an update may take (far above any useful value).
pub const MAX_SPP: u32 = 4096;

/// Errors if `density` is no longer finite as the float32 its file holds
/// (a step too large sent the fit off): `what` and the update name where
/// it happened.
pub(super) fn check_finite(density: &Grid<f64>, what: &str, update: usize) -> Result<()> {
    if density.data.iter().all(|v| v.abs() <= f32::MAX as f64) {
        return Ok(());
    }
    Err(Error(format!(
        "{what}: the density is no longer finite (in float32) at update {} (a learning rate too large?)",
        update + 1
    )))
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
    settings.check()?;
    let start = Instant::now();
    let mut adam_z = Adam::new(model.z.len(), settings.lr_latent);
    let mut adam_w = Adam::new(model.w.len(), settings.lr_weights);
    let fine = Level::full(problem, &model.mask);
    let coarse = if settings.coarse_fraction > 0.0 { Level::half(problem, &model.mask) } else { None };
    let coarse_updates = coarse_updates(settings, coarse.is_some());
    let mut rng = Rng::new(settings.seed, Purpose::Gradient, 1_000_000);
    let estimator = settings.gradient;
    let target_power = crate::image::mean_square(&fine.targets);
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
        let decoded = model.density(&problem.scene.density);
        check_finite(&decoded, "training", it)?;
        let seed = settings.seed.wrapping_mul(1_000_003).wrapping_add(it as u64);
        let scene = level.scene_at(&decoded, settings.photons, settings.spp, seed);
        let (frozen, shifted) = level.freeze(&scene, &decoded, settings.decorrelate.then_some(seed ^ DECORRELATE_SEED));
        let wall_s = start.elapsed().as_secs_f64();
        // The log row is serial work: a helper thread computes it while the gradient runs.
        let (g, row) = par::alongside(
            || parameter_gradient(shifted.as_ref().unwrap_or(level), model, &frozen, &estimator, &mut rng),
            || log_row(it, problem, level, &model.mask, &decoded, &frozen, wall_s),
        );
        observe(&row, model, &frozen.images);
        let mut g = g?;
        if settings.latent_penalty > 0.0 {
            let scale = settings.latent_penalty_slope(target_power, model.z.len());
            for (&i, v) in g.latent.indices.iter().zip(&mut g.latent.values) {
                *v += scale * model.z[i];
            }
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
