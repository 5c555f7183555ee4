//! The two ways the project reconstructs, with the settings the main job,
//! `dualphoton fit` and the prior's evaluation share:
//! - the paper's method: a decoder trained from scratch on the one scene
//!   (latent and weights), then the per-voxel refinement;
//! - the learned prior: only the 64-d latent of a pretrained decoder is
//!   fitted, by exact forward-mode gradients over its 64 coordinates, under
//!   a Gaussian penalty, then (optionally) the same per-voxel refinement.

use super::estimator::{Estimator, EstimatorSettings, WeightDirections};
use super::reconstruct::ReconstructSettings;
use super::refine::RefineSettings;
use super::train::TrainSettings;
use crate::error::{Error, Result};
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
    /// With a prior: the refinement also fits one global density factor (see --refine-global;
    /// `--prior-refine-global false`: none).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub prior_refine_global: bool,
    /// With a prior: the refinement also adds a non-negative density to every hull voxel (see
    /// --refine-additive; `--prior-refine-additive false`: factors only).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub prior_refine_additive: bool,
    /// With a prior: the refinement returns the mean density over this last fraction of its updates
    /// (see --refine-average; 0: the last update's).
    #[arg(long, default_value_t = 0.0)]
    pub prior_refine_average: f64,
    /// With a prior: the refinement's steps fall exponentially to this fraction (see --refine-lr-final;
    /// 1: constant, the prior's default until its validation says otherwise).
    #[arg(long, default_value_t = 1.0)]
    pub prior_refine_lr_final: f64,
    /// With a prior: the refinement's block edges (see --refine-blocks). 4 and 8 help on every plume
    /// measured, most outside the training set (`docs/prior_studies.md`, "Block terms"); `--prior-refine-blocks 0`: none.
    #[arg(long, value_delimiter = ',', default_values_t = [4, 8])]
    pub prior_refine_blocks: Vec<usize>,
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
            prior_refine_global: true,
            prior_refine_additive: true,
            prior_refine_average: 0.0,
            prior_refine_lr_final: 1.0,
            prior_refine_blocks: vec![4, 8],
            prior_estimator: Estimator::FwdFull,
        }
    }
}

/// Fine-tuning a learned prior's decoder weights after its latent fit (a
/// study: `prior_eval --methods prior_tune`; not part of the default fit).
#[derive(clap::Args, Clone, Debug, PartialEq, Serialize)]
pub struct PriorTuneArgs {
    /// Updates of latent and weights after the latent fit (guided forward-mode directions for the weights).
    #[arg(long, default_value_t = 40)]
    pub prior_tune: usize,
    /// Adam step of the weights while fine-tuning.
    #[arg(long, default_value_t = 3e-4)]
    pub prior_tune_lr: f64,
    /// Weight of the penalty mean((w - w_prior)^2), relative to the images' mean square.
    #[arg(long, default_value_t = 100.0)]
    pub prior_tune_penalty: f64,
    /// Forward-mode directions for the weights per update.
    #[arg(long, default_value_t = 8)]
    pub prior_tune_directions: usize,
}

impl Default for PriorTuneArgs {
    fn default() -> Self {
        PriorTuneArgs { prior_tune: 40, prior_tune_lr: 3e-4, prior_tune_penalty: 100.0, prior_tune_directions: 8 }
    }
}

/// Seed offset of the fine-tuning updates' renders (other noise than the latent fit's).
const TUNE_SEED: u64 = 0x7475_6e65;

/// The training that fine-tunes a learned prior after its latent fit by
/// `fit`: latent and weights at full resolution, the weights by `tune`'s
/// guided directions under a penalty that keeps them near the prior.
pub fn prior_tuning(fit: &PriorFitArgs, tune: &PriorTuneArgs, r: UpdateRenders) -> TrainSettings {
    TrainSettings {
        iterations: tune.prior_tune,
        gradient: EstimatorSettings {
            estimator: fit.prior_estimator,
            weight_directions: tune.prior_tune_directions,
            weight_mode: WeightDirections::Guided,
            ..EstimatorSettings::default()
        },
        lr_latent: fit.prior_lr,
        lr_weights: tune.prior_tune_lr,
        coarse_fraction: 0.0,
        latent_penalty: fit.prior_penalty,
        weight_penalty: tune.prior_tune_penalty,
        ..training(UpdateRenders { seed: r.seed ^ TUNE_SEED, ..r })
    }
}

/// What every update renders with, for both methods (command-line options
/// of every program that reconstructs; the seed is the program's own).
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Serialize)]
pub struct UpdateRenders {
    /// Photons per update.
    #[arg(long, default_value_t = 50_000)]
    pub photons: u64,
    /// Camera samples per pixel per update.
    #[arg(long, default_value_t = 2)]
    pub spp: u32,
    /// Take each update's image residual from a second, independent render: removes the squared loss's
    /// noise bias at one more primal render per update (`--decorrelate false`: the paper's loss as it is).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub decorrelate: bool,
    /// Seed of the renders (and the paper decoder's initial values): set by the program.
    #[arg(skip)]
    #[serde(skip)]
    pub seed: u64,
}

impl Default for UpdateRenders {
    fn default() -> Self {
        UpdateRenders { photons: 50_000, spp: 2, decorrelate: true, seed: 0 }
    }
}

/// How the paper's method trains its per-scene decoder and refines
/// (command-line options of every program that reconstructs).
#[derive(clap::Args, Clone, Debug, PartialEq, Serialize)]
pub struct PaperFitArgs {
    /// Adam updates.
    #[arg(long, default_value_t = 250)]
    pub iterations: usize,
    /// Gradient estimator: fwd-full (default), fwd-rand, rev-sub (the paper's approximate learning), rev-full.
    #[arg(long, value_enum, default_value = "fwd-full")]
    pub estimator: Estimator,
    /// Dual lanes per forward pass, at most (1, 2, 4, ..., 64; grids above 64^3 use at most 32): one pass of
    /// 64 lanes gives the latent's exact gradient at 64^3 to the same bits as four of 16, in 0.6x the time
    /// (results/bench_grad).
    #[arg(long, default_value_t = 64)]
    pub lanes: usize,
    /// Forward-mode directions for the decoder weights per update.
    #[arg(long, default_value_t = 8)]
    pub weight_directions: usize,
    /// How weight directions are chosen: orthonormal, guided or coordinates.
    #[arg(long, value_enum, default_value = "guided")]
    pub weight_mode: WeightDirections,
    /// Adam step of the latent.
    #[arg(long, default_value_t = 0.05)]
    pub lr_latent: f64,
    /// Adam step of the decoder weights.
    #[arg(long, default_value_t = 0.01)]
    pub lr_weights: f64,
    /// Learning rates fall exponentially over the full-resolution updates to this fraction (1: constant).
    #[arg(long, default_value_t = 1.0)]
    pub lr_final: f64,
    /// Share of the updates made at half resolution (coarse to fine).
    #[arg(long, default_value_t = 0.8)]
    pub coarse_fraction: f64,
    /// Weight of a sparsity prior (times the mean hull density) added to the image loss; 0 = the paper's loss.
    #[arg(long, default_value_t = 0.0)]
    pub sparsity: f64,
    /// Stop training after this many seconds (at most --iterations updates; --coarse-fraction then
    /// shares the time). Default: none.
    #[arg(long)]
    pub time_budget: Option<f64>,
    /// Per-voxel refinement updates after training (0: none): each hull voxel's density times its own factor,
    /// fitted by reverse mode.
    #[arg(long, default_value_t = 400)]
    pub refine: usize,
    /// Adam step of the refinement's log-factors.
    #[arg(long, default_value_t = 0.02)]
    pub refine_lr: f64,
    /// Penalty on the mean squared log-factor of the refinement.
    #[arg(long, default_value_t = 0.0)]
    pub refine_penalty: f64,
    /// Stop the refinement after this many seconds (at most --refine updates). Default: none.
    #[arg(long)]
    pub refine_budget: Option<f64>,
    /// The refinement also fits one global density factor beside the per-voxel ones: its gradient sums
    /// every voxel's, so it corrects the total mass within a few updates (`--refine-global false`: none).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub refine_global: bool,
    /// The refinement also adds a non-negative density of its own to every hull voxel, so that it can fill
    /// regions where the decoder gives exactly 0 (a factor cannot); `--refine-additive false`: factors only.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub refine_additive: bool,
    /// The refinement returns the mean density over this last fraction of its updates, which carries less
    /// of each update's render noise than the last one (0: the last update's density).
    #[arg(long, default_value_t = 0.0)]
    pub refine_average: f64,
    /// The refinement's steps fall exponentially over its updates (or its time budget) to this fraction
    /// (1: constant). With
    /// the block terms, 0.1 takes a validation plume's 4x4-block image misfit from 2.3-3.0 % to 1.4-2.2 %.
    #[arg(long, default_value_t = 0.1)]
    pub refine_lr_final: f64,
    /// The refinement's additive terms' step, relative to --refine-lr times the mean non-zero decoded density.
    #[arg(long, default_value_t = 1.0)]
    pub refine_additive_lr: f64,
    /// The refinement also fits one factor (and additive term) per block of B^3 voxels for every B given:
    /// a block's gradient sums its voxels', so it corrects the coarse misfit sooner (0: none).
    #[arg(long, value_delimiter = ',', default_values_t = [4, 8])]
    pub refine_blocks: Vec<usize>,
}

impl Default for PaperFitArgs {
    fn default() -> Self {
        PaperFitArgs {
            iterations: 250,
            estimator: Estimator::FwdFull,
            lanes: 64,
            weight_directions: 8,
            weight_mode: WeightDirections::Guided,
            lr_latent: 0.05,
            lr_weights: 0.01,
            lr_final: 1.0,
            coarse_fraction: 0.8,
            sparsity: 0.0,
            time_budget: None,
            refine: 400,
            refine_lr: 0.02,
            refine_penalty: 0.0,
            refine_budget: None,
            refine_global: true,
            refine_additive: true,
            refine_average: 0.0,
            refine_lr_final: 0.1,
            refine_additive_lr: 1.0,
            refine_blocks: vec![4, 8],
        }
    }
}

/// The paper's method by `fit`: `fit.iterations` updates (by default 80 %
/// at half resolution) of latent (`fwd-full`, exact) and weights (8 guided
/// directions), then `fit.refine` refinement updates, rendering with `r`;
/// final renders with `final_photons` and `final_spp`. Errors on settings
/// that cannot run.
pub fn paper_method(
    fit: &PaperFitArgs,
    r: UpdateRenders,
    final_photons: u64,
    final_spp: u32,
) -> Result<ReconstructSettings> {
    if !(0.0..=1.0).contains(&fit.coarse_fraction) {
        return Err(Error(format!("--coarse-fraction: {} must be in 0..=1", fit.coarse_fraction)));
    }
    let train = TrainSettings {
        iterations: fit.iterations,
        gradient: EstimatorSettings {
            estimator: fit.estimator,
            lanes: fit.lanes,
            weight_directions: fit.weight_directions,
            weight_mode: fit.weight_mode,
            ..EstimatorSettings::default()
        },
        lr_latent: fit.lr_latent,
        lr_weights: fit.lr_weights,
        lr_final: fit.lr_final,
        coarse_fraction: fit.coarse_fraction,
        sparsity: fit.sparsity,
        time_budget: fit.time_budget,
        ..training(r)
    };
    let mut s = ReconstructSettings::paper(train, final_photons, final_spp);
    s.refine = RefineSettings {
        lr: fit.refine_lr,
        penalty: fit.refine_penalty,
        time_budget: fit.refine_budget,
        global: fit.refine_global,
        additive: fit.refine_additive,
        average: fit.refine_average,
        lr_final: fit.refine_lr_final,
        additive_lr: fit.refine_additive_lr,
        blocks: block_edges(&fit.refine_blocks),
        ..refinement(fit.refine, r)
    };
    Ok(s)
}

/// Block edges from the command line, where an edge of 0 asks for none.
fn block_edges(edges: &[usize]) -> Vec<usize> {
    edges.iter().copied().filter(|&b| b != 0).collect()
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
    s.refine = RefineSettings {
        global: fit.prior_refine_global,
        additive: fit.prior_refine_additive,
        average: fit.prior_refine_average,
        lr_final: fit.prior_refine_lr_final,
        blocks: block_edges(&fit.prior_refine_blocks),
        ..refinement(fit.prior_refine, r)
    };
    s.prior = Some(prior);
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, Parser};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        paper: PaperFitArgs,
        #[command(flatten)]
        prior: PriorFitArgs,
        #[command(flatten)]
        renders: UpdateRenders,
        #[command(flatten)]
        tune: PriorTuneArgs,
    }

    #[test]
    fn the_defaults_are_the_command_line_defaults() {
        Cli::command().debug_assert();
        let cli = Cli::parse_from(["test"]);
        assert_eq!(cli.paper, PaperFitArgs::default());
        assert_eq!(cli.prior, PriorFitArgs::default());
        assert_eq!(cli.renders, UpdateRenders::default());
        assert_eq!(cli.tune, PriorTuneArgs::default());
    }

    #[test]
    fn a_block_edge_of_zero_asks_for_no_block_terms() {
        let cli = Cli::parse_from(["test", "--prior-refine-blocks", "0", "--refine-blocks", "2,0"]);
        assert_eq!(block_edges(&cli.prior.prior_refine_blocks), Vec::<usize>::new());
        assert_eq!(block_edges(&cli.paper.refine_blocks), vec![2]);
    }

    #[test]
    fn the_paper_method_takes_every_option_and_refuses_a_bad_schedule() {
        let fit = PaperFitArgs { iterations: 7, lanes: 4, refine: 3, refine_lr: 0.5, ..PaperFitArgs::default() };
        let r = UpdateRenders { photons: 1234, seed: 9, ..UpdateRenders::default() };
        let s = paper_method(&fit, r, 10, 1).unwrap();
        assert_eq!((s.train.iterations, s.train.gradient.lanes, s.train.photons, s.train.seed), (7, 4, 1234, 9));
        assert_eq!((s.refine.updates, s.refine.lr, s.refine.photons, s.refine.seed), (3, 0.5, 1234, 9));
        assert!(s.train.decorrelate && s.refine.decorrelate);
        let bad = PaperFitArgs { coarse_fraction: 1.5, ..PaperFitArgs::default() };
        let e = paper_method(&bad, r, 10, 1).unwrap_err().to_string();
        assert!(e.contains("--coarse-fraction"), "{e}");
    }
}
