//! The one vocabulary of gradient estimators for the model's parameters
//! (the 64-d latent and the decoder weights) and the one dispatch that turns
//! a choice into an estimate. Training takes one estimate per update; the
//! gradient-variance study compares many settings of the same dispatch.
//!
//! Random draws come from the caller's [`Rng`], always in the same order:
//! `rev-sub` draws one subset seed; `fwd-rand` draws the latent's directions,
//! then the weights'; `guided` draws its `k - 1` Gaussian directions in
//! blocks of 16. `fwd-full`'s latent draws nothing.

use super::level::Level;
use super::param_grad;
use crate::error::{Error, Result};
use crate::grad::forward::Directions;
use crate::grad::reverse::Subset;
pub use crate::grad::Estimator;
use crate::model::Model;
use crate::par;
use crate::render::frozen::Frozen;
use crate::rng::Rng;
use serde::{Deserialize, Serialize};

/// How the decoder weights get their directional derivatives under `fwd-full`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WeightDirections {
    /// Random orthonormal directions; the step uses the projection of the
    /// gradient onto their span (scaled to be unbiased: `n/K Σ (g·q) q`).
    Orthonormal,
    /// A guessed direction first, then random ones, orthonormalised; the
    /// step is the exact projection of the gradient onto their span
    /// ([`param_grad::weights_guided`]).
    Guided,
}

/// How one gradient of the parameters is estimated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatorSettings {
    /// Which estimator.
    pub estimator: Estimator,
    /// Dual lanes per forward pass, at most (1, 2, 4, ..., 64; `fwd-full`
    /// takes no more than its directions need, and at most
    /// [`LANES_ABOVE_64_CUBED`] on grids above 64^3); `fwd-rand` draws
    /// this many latent directions.
    pub lanes: usize,
    /// Differentiate the latent (forward estimators; reverse mode always gives both parts).
    pub latent: bool,
    /// `fwd-rand`: how its random directions are drawn.
    pub directions: Directions,
    /// Forward-mode directions for the decoder weights (0 leaves them out).
    pub weight_directions: usize,
    /// `fwd-full`: how those directions are chosen.
    pub weight_mode: WeightDirections,
    /// `rev-sub`: pixels differentiated.
    pub subset_pixels: usize,
    /// `rev-sub`: photon paths differentiated.
    pub subset_paths: usize,
}

impl Default for EstimatorSettings {
    fn default() -> Self {
        EstimatorSettings {
            estimator: Estimator::FwdFull,
            lanes: 64,
            latent: true,
            directions: Directions::Gaussian,
            weight_directions: 8,
            weight_mode: WeightDirections::Guided,
            subset_pixels: 1000,
            subset_paths: 5000,
        }
    }
}

/// Most forward-mode directions for the decoder weights per update (far
/// above any useful value: each costs a dual lane of every render).
pub const MAX_WEIGHT_DIRECTIONS: usize = 1024;

impl EstimatorSettings {
    /// Errors (naming the field) on settings that cannot run.
    pub fn check(&self) -> Result<()> {
        if !crate::grad::LANES.contains(&self.lanes) {
            return Err(Error(format!("train.gradient.lanes: {} is not one of {:?}", self.lanes, crate::grad::LANES)));
        }
        if self.weight_directions > MAX_WEIGHT_DIRECTIONS {
            return Err(Error(format!(
                "train.gradient.weight_directions: {} must be at most {MAX_WEIGHT_DIRECTIONS}",
                self.weight_directions
            )));
        }
        if self.subset_pixels == 0 || self.subset_paths == 0 {
            return Err(Error::new("train.gradient.subset_pixels and subset_paths: must be at least 1"));
        }
        Ok(())
    }
}

/// Some entries of a gradient: `values[i]` is the derivative with respect
/// to parameter `indices[i]`. Empty when the part was left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Entries {
    /// Parameter indices.
    pub indices: Vec<usize>,
    /// Derivatives, one per index.
    pub values: Vec<f64>,
}

impl Entries {
    /// Every entry of a dense gradient, in order.
    pub fn dense(values: Vec<f64>) -> Self {
        Entries { indices: (0..values.len()).collect(), values }
    }

    /// The dense gradient over `n` parameters (zero where no entry is given), or `None` if empty.
    pub fn to_dense(&self, n: usize) -> Option<Vec<f64>> {
        if self.indices.is_empty() {
            return None;
        }
        let mut g = vec![0.0; n];
        self.indices.iter().zip(&self.values).for_each(|(&i, &v)| g[i] = v);
        Some(g)
    }
}

/// One estimate of `(dL/dz, dL/dw)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamGradient {
    /// With respect to the latent.
    pub latent: Entries,
    /// With respect to the decoder weights.
    pub weights: Entries,
}

/// Up to 64^3 one pass of 64 lanes gives the latent's gradient soonest
/// (results/bench_grad). Above it, passes of 32 lanes keep the peak memory
/// of a 128^3 gradient at about 1.9 GB instead of 3 GB; whether 32 or 64
/// lanes is faster there has changed between machines and revisions
/// (results/bench_grad has the current numbers). The bits are the same
/// either way.
pub const WIDE_LANES_UP_TO: usize = 64 * 64 * 64;

/// Most lanes per forward pass on grids above [`WIDE_LANES_UP_TO`] voxels.
pub const LANES_ABOVE_64_CUBED: usize = 32;

/// The gradient of `level`'s image loss with respect to `model`'s latent
/// and weights on the frozen estimator, by `settings`; `rng` supplies every
/// random draw.
pub fn parameter_gradient(
    level: &Level,
    model: &Model,
    frozen: &Frozen,
    settings: &EstimatorSettings,
    rng: &mut Rng,
) -> Result<ParamGradient> {
    let s = settings;
    let k = s.weight_directions;
    let lanes = s.lanes;
    let dense = |g: Result<Vec<f64>>| g.map(Entries::dense);
    let (latent, weights) = match s.estimator {
        Estimator::RevFull | Estimator::RevSub => {
            let subset = match s.estimator {
                Estimator::RevSub => {
                    Subset { pixels: Some(s.subset_pixels), paths: Some(s.subset_paths), seed: rng.below(u64::MAX) }
                }
                _ => Subset::full(),
            };
            let (dz, dw) = param_grad::reverse(level, model, frozen, subset);
            (Entries::dense(dz), Entries::dense(dw))
        }
        Estimator::FwdFull => {
            let voxels: usize = model.decoder_shape().iter().product();
            let lanes = if voxels > WIDE_LANES_UP_TO { lanes.min(LANES_ABOVE_64_CUBED) } else { lanes };
            let latent_pass = || {
                if s.latent {
                    dense(param_grad::latent_exact(level, model, frozen, lanes))
                } else {
                    Ok(Entries::default())
                }
            };
            let mut weights_pass = || match (k, s.weight_mode) {
                (0, _) => Ok(Entries::default()),
                (_, WeightDirections::Orthonormal) => {
                    dense(param_grad::weights_random(level, model, frozen, k, Directions::Orthonormal, lanes, rng))
                }
                (_, WeightDirections::Guided) => dense(param_grad::weights_guided(level, model, frozen, k, lanes, rng)),
            };
            // The two are independent: side by side, the weights' serial parts (the guided
            // basis) overlap the latent's work. Above 64^3 the weights' dual grids outgrow
            // what a helper thread's allocator keeps (page faults cost more than the overlap saves).
            let (latent, weights) = if voxels <= WIDE_LANES_UP_TO {
                par::alongside(latent_pass, weights_pass)
            } else {
                (latent_pass(), weights_pass())
            };
            (latent?, weights?)
        }
        Estimator::FwdRand => {
            let latent = if s.latent {
                dense(param_grad::latent_random(level, model, frozen, lanes, s.directions, rng))?
            } else {
                Entries::default()
            };
            let weights = match k {
                0 => Entries::default(),
                _ => dense(param_grad::weights_random(level, model, frozen, k, s.directions, lanes, rng))?,
            };
            (latent, weights)
        }
    };
    Ok(ParamGradient { latent, weights })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recon::param_grad::tests::tiny;

    #[test]
    fn exact_forward_and_reverse_agree_and_the_latent_can_be_left_out() {
        let (level, model, scene) = tiny();
        let frozen = Frozen::new(&scene, Some(&level.support));
        let mut rng = Rng::from_seed(0);
        let rev = EstimatorSettings { estimator: Estimator::RevFull, ..EstimatorSettings::default() };
        let exact = parameter_gradient(&level, &model, &frozen, &rev, &mut rng).unwrap();
        let fwd = EstimatorSettings { lanes: 4, weight_directions: 4, ..EstimatorSettings::default() };
        let g = parameter_gradient(&level, &model, &frozen, &fwd, &mut rng).unwrap();
        // The latent's forward gradient is exact: it matches reverse mode up to rounding.
        let scale = exact.latent.values.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale > 0.0);
        assert!(g.latent.values.iter().zip(&exact.latent.values).all(|(x, y)| (x - y).abs() <= 1e-8 * scale));
        assert_eq!(g.weights.values.len(), model.w.len());
        // Leaving the latent out leaves it empty.
        let weights_only = EstimatorSettings { latent: false, ..fwd };
        let g = parameter_gradient(&level, &model, &frozen, &weights_only, &mut rng).unwrap();
        assert!(g.latent.indices.is_empty() && g.latent.to_dense(64).is_none());
        assert_eq!(g.weights.values.len(), model.w.len());
    }

    #[test]
    fn bad_settings_are_named() {
        let e = EstimatorSettings { lanes: 3, ..EstimatorSettings::default() }.check().unwrap_err().to_string();
        assert!(e.contains("lanes"), "{e}");
        let huge = EstimatorSettings { weight_directions: 1_000_000, ..EstimatorSettings::default() };
        assert!(huge.check().unwrap_err().to_string().contains("weight_directions"));
    }
}
