//! Gradients of the image loss with respect to the density voxels, from the
//! frozen estimator (DESIGN.md §3): forward mode with dual numbers, reverse
//! mode with the project's tape, and the estimators built on them.
//!
//! | name       | what                                                           | cost                        |
//! |------------|----------------------------------------------------------------|-----------------------------|
//! | `fwd-full` | exact; coordinate directions in chunks of K lanes              | P / K dual passes           |
//! | `fwd-rand` | unbiased; K random directions in one dual pass                 | 1 dual pass                 |
//! | `rev-sub`  | unbiased; reverse mode on random pixels and photon paths       | about the subset's share    |
//! | `rev-full` | exact; reverse mode on every pixel and path                    | a few primal renders        |
//!
//! Derivatives with respect to voxels whose block of the sampling density is
//! empty are zero by construction (nothing is marched there); pass a
//! `support` to [`Frozen::new`](crate::render::frozen::Frozen::new) to widen it.

pub mod forward;
pub mod loss;
pub mod reverse;

use crate::bail;
use crate::error::{Error, Result};
use std::str::FromStr;

/// A gradient estimator, by its command-line name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimator {
    /// Forward mode over every coordinate direction (exact).
    FwdFull,
    /// Forward mode over K random directions (unbiased).
    FwdRand,
    /// Reverse mode over a random subset of pixels and photon paths (unbiased).
    RevSub,
    /// Reverse mode over everything (exact).
    RevFull,
}

impl FromStr for Estimator {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "fwd-full" => Estimator::FwdFull,
            "fwd-rand" => Estimator::FwdRand,
            "rev-sub" => Estimator::RevSub,
            "rev-full" => Estimator::RevFull,
            _ => bail!("--estimator: unknown estimator {s:?} (fwd-full, fwd-rand, rev-sub, rev-full)"),
        })
    }
}

impl Estimator {
    /// The command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            Estimator::FwdFull => "fwd-full",
            Estimator::FwdRand => "fwd-rand",
            Estimator::RevSub => "rev-sub",
            Estimator::RevFull => "rev-full",
        }
    }
}
