//! The two ways the project reconstructs, each one [`Method`] (training,
//! then the per-voxel refinement), with the shipped defaults in one place:
//! - the paper's method, [`Method::paper`] (`TrainSettings::default()` and
//!   `RefineSettings::default()`): a decoder trained from scratch on the
//!   one scene (latent and weights), then the refinement;
//! - the learned prior, [`Method::prior`] (`TrainSettings::prior()` and
//!   `RefineSettings::prior()`): only the 64-d latent of a pretrained
//!   decoder is fitted, by exact forward-mode gradients over its 64
//!   coordinates, under a Gaussian penalty, then the same refinement.
//!
//! A program starts from these, applies a study file
//! ([`super::study::apply_study`]) and then its command-line options
//! ([`MethodOptions`], overrides only: no option holds a default of its own).

use super::estimator::Estimator;
use super::refine::RefineSettings;
use super::train::TrainSettings;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// One way to reconstruct: training, then the refinement.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Method {
    /// Training of latent (and weights).
    pub train: TrainSettings,
    /// The per-voxel refinement after training (`updates` 0: none).
    pub refine: RefineSettings,
}

impl Default for Method {
    /// The paper's method.
    fn default() -> Self {
        Method::paper()
    }
}

impl Method {
    /// The paper's method as this project ships it.
    pub fn paper() -> Method {
        Method { train: TrainSettings::default(), refine: RefineSettings::default() }
    }

    /// The learned prior's fit as this project ships it.
    pub fn prior() -> Method {
        Method { train: TrainSettings::prior(), refine: RefineSettings::prior() }
    }

    /// The same method with every random stream seeded by `seed` (training's
    /// and the refinement's; the model's initial values and the final
    /// renders follow training's, [`super::reconstruct::ReconstructSettings`]).
    pub fn seeded(mut self, seed: u64) -> Method {
        (self.train.seed, self.refine.seed) = (seed, seed);
        self
    }

    /// Errors (naming the field) on settings that cannot run.
    pub fn check(&self) -> Result<()> {
        self.train.check()?;
        self.refine.check()
    }
}

/// Both methods: what a study file sets (`{"paper": {...}, "prior": {...}}`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Methods {
    /// The paper's method.
    pub paper: Method,
    /// The learned prior's.
    pub prior: Method,
}

impl Default for Methods {
    fn default() -> Self {
        Methods { paper: Method::paper(), prior: Method::prior() }
    }
}

/// `--help` text of an option: what it sets and the library's default for
/// both methods (computed from [`Method::paper`] and [`Method::prior`]).
fn defaults<T: std::fmt::Display + PartialEq>(what: &str, of: impl Fn(&Method) -> T) -> String {
    let (paper, prior) = (of(&Method::paper()), of(&Method::prior()));
    if paper == prior {
        return format!("{what} [default: {paper}]");
    }
    format!("{what} [default: {paper} (paper's method), {prior} (learned prior)]")
}

/// The options of every program that reconstructs: overrides of a
/// [`Method`]'s settings, none by default.
#[derive(clap::Args, Clone, Debug, Default, PartialEq, Serialize)]
pub struct MethodOptions {
    /// Training updates.
    #[arg(long, help = defaults("Training updates", |m| m.train.iterations))]
    pub iterations: Option<usize>,
    /// Stop training after this many seconds (at most --iterations updates).
    #[arg(long, help = "Stop training after this many seconds (at most --iterations updates) [default: none]")]
    pub time_budget: Option<f64>,
    /// Refinement updates after training (0: none).
    #[arg(long, help = defaults("Refinement updates after training (0: none)", |m| m.refine.updates))]
    pub refine: Option<usize>,
    /// Photons per update (training and refinement).
    #[arg(long, help = defaults("Photons per update", |m| m.train.photons))]
    pub photons: Option<u64>,
    /// Camera samples per pixel per update.
    #[arg(long, help = defaults("Camera samples per pixel per update", |m| m.train.spp))]
    pub spp: Option<u32>,
}

impl MethodOptions {
    /// Errors (naming the option) on values no method can run with, before any work.
    pub fn check(&self) -> Result<()> {
        if self.spp == Some(0) {
            return Err(Error::new("--spp: must be at least 1"));
        }
        if self.photons == Some(0) {
            return Err(Error::new("--photons: must be at least 1"));
        }
        if let Some(b) = self.time_budget {
            if !(b.is_finite() && b > 0.0) {
                return Err(Error(format!("--time-budget: {b} must be finite and > 0")));
            }
        }
        Ok(())
    }

    /// `m` with the options given.
    pub fn apply(&self, m: &mut Method) {
        let (t, r) = (&mut m.train, &mut m.refine);
        t.iterations = self.iterations.unwrap_or(t.iterations);
        t.time_budget = self.time_budget.or(t.time_budget);
        r.updates = self.refine.unwrap_or(r.updates);
        (t.photons, r.photons) = self.photons.map_or((t.photons, r.photons), |p| (p, p));
        (t.spp, r.spp) = self.spp.map_or((t.spp, r.spp), |s| (s, s));
    }
}

/// The gradient estimator option of the experiments (both methods).
pub fn set_estimator(m: &mut Method, estimator: Option<Estimator>) {
    m.train.gradient.estimator = estimator.unwrap_or(m.train.gradient.estimator);
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, Parser};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        options: MethodOptions,
    }

    #[test]
    fn no_option_leaves_both_methods_at_the_library_defaults() {
        Cli::command().debug_assert();
        let cli = Cli::parse_from(["test"]);
        for m in [Method::paper(), Method::prior()] {
            let mut set = m.clone();
            cli.options.apply(&mut set);
            assert_eq!(set, m);
        }
    }

    #[test]
    fn options_set_training_and_refinement() {
        let cli = Cli::parse_from(["test", "--iterations", "7", "--refine", "3", "--photons", "1234", "--spp", "1"]);
        cli.options.check().unwrap();
        let mut m = Method::prior().seeded(9);
        cli.options.apply(&mut m);
        assert_eq!((m.train.iterations, m.train.photons, m.train.spp, m.train.seed), (7, 1234, 1, 9));
        assert_eq!((m.refine.updates, m.refine.photons, m.refine.spp, m.refine.seed), (3, 1234, 1, 9));
        assert!(m.train.decorrelate && m.refine.decorrelate);
        let bad = Cli::parse_from(["test", "--spp", "0"]);
        assert!(bad.options.check().unwrap_err().to_string().contains("--spp"));
    }

    #[test]
    fn help_prints_the_library_defaults() {
        let help = Cli::command().render_help().to_string();
        assert!(help.contains("[default: 250 (paper's method), 60 (learned prior)]"), "{help}");
        assert!(help.contains("[default: 400 (paper's method), 200 (learned prior)]"), "{help}");
    }
}
