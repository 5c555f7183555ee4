//! The two ways the project reconstructs, with the settings the main job,
//! `dualphoton fit` and the prior's evaluation share:
//! - the paper's method: a decoder trained from scratch on the one scene
//!   (latent and weights), then the per-voxel refinement;
//! - the learned prior: only the 64-d latent of a pretrained decoder is
//!   fitted, by exact forward-mode gradients over its 64 coordinates, under
//!   a Gaussian penalty, then (optionally) the same per-voxel refinement.

use super::estimator::{Estimator, EstimatorSettings};
use super::reconstruct::ReconstructSettings;
use super::refine::RefineSettings;
use super::train::TrainSettings;
use crate::prior::Prior;
use serde::Serialize;

/// How the latent of a learned prior is fitted (command-line options of
/// every program that reconstructs).
#[derive(clap::Args, Clone, Debug, PartialEq, Serialize)]
pub struct PriorFitArgs {
    /// With a prior: Adam updates of its latent.
    #[arg(long, default_value_t = 60)]
    pub prior_updates: usize,
    /// With a prior: Adam step of the (whitened) latent.
    #[arg(long, default_value_t = 0.1)]
    pub prior_lr: f64,
    /// With a prior: weight of the latent penalty mean(u^2), relative to the images' mean square.
    #[arg(long, default_value_t = 1e-3)]
    pub prior_penalty: f64,
    /// With a prior: share of the latent updates at half resolution.
    #[arg(long, default_value_t = 0.5)]
    pub prior_coarse_fraction: f64,
    /// With a prior: per-voxel refinement updates after the latent fit (0: none). 200 keeps a fit
    /// within 3 minutes on 2 cores (validation plume val0: 100 updates 122 s, 300 updates 235 s).
    #[arg(long, default_value_t = 200)]
    pub prior_refine: usize,
    /// With a prior: the latent's gradient estimator (fwd-full: exact, 64 directions; rev-full: exact, reverse mode).
    #[arg(long, value_enum, default_value = "fwd-full")]
    pub prior_estimator: Estimator,
}

impl Default for PriorFitArgs {
    fn default() -> Self {
        PriorFitArgs {
            prior_updates: 60,
            prior_lr: 0.1,
            prior_penalty: 1e-3,
            prior_coarse_fraction: 0.5,
            prior_refine: 200,
            prior_estimator: Estimator::FwdFull,
        }
    }
}

/// What every update renders with, for both methods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpdateRenders {
    /// Photons per update.
    pub photons: u64,
    /// Camera samples per pixel per update.
    pub spp: u32,
    /// Residual from an independent second render ([`TrainSettings::decorrelate`]).
    pub decorrelate: bool,
    /// Seed of the renders (and the paper decoder's initial values).
    pub seed: u64,
}

impl Default for UpdateRenders {
    fn default() -> Self {
        UpdateRenders { photons: 50_000, spp: 2, decorrelate: true, seed: 0 }
    }
}

/// The paper's method as the main job runs it by default: 250 updates
/// (80 % at half resolution) of latent (`fwd-full`, exact) and weights (8
/// guided directions), then 400 refinement updates; final renders with
/// `final_photons` and `final_spp`.
pub fn paper_method(r: UpdateRenders, final_photons: u64, final_spp: u32) -> ReconstructSettings {
    let mut s = ReconstructSettings::paper(training(r), final_photons, final_spp);
    s.refine = refinement(400, r);
    s
}

/// The default training, rendering with `r`.
fn training(r: UpdateRenders) -> TrainSettings {
    TrainSettings {
        decorrelate: r.decorrelate,
        photons: r.photons,
        spp: r.spp,
        seed: r.seed,
        ..TrainSettings::default()
    }
}

/// `updates` refinement updates rendering with `r`.
fn refinement(updates: usize, r: UpdateRenders) -> RefineSettings {
    RefineSettings {
        updates,
        photons: r.photons,
        spp: r.spp,
        decorrelate: r.decorrelate,
        seed: r.seed,
        ..RefineSettings::default()
    }
}

/// The learned prior's fit: the latent of `prior` by `fit`, the weights
/// fixed, then `fit.prior_refine` refinement updates.
pub fn prior_method(
    prior: Prior,
    fit: &PriorFitArgs,
    r: UpdateRenders,
    final_photons: u64,
    final_spp: u32,
) -> ReconstructSettings {
    let train = TrainSettings {
        iterations: fit.prior_updates,
        gradient: EstimatorSettings {
            estimator: fit.prior_estimator,
            weight_directions: 0,
            ..EstimatorSettings::default()
        },
        lr_latent: fit.prior_lr,
        lr_weights: 0.0,
        coarse_fraction: fit.prior_coarse_fraction,
        latent_penalty: fit.prior_penalty,
        ..training(r)
    };
    let mut s = ReconstructSettings::paper(train, final_photons, final_spp);
    s.refine = refinement(fit.prior_refine, r);
    s.prior = Some(prior);
    s
}
