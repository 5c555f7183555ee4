//! Gradients of the image loss with respect to the density voxels, from the
//! frozen estimator (docs/DESIGN.md §3): forward mode with dual numbers, reverse
//! mode with the project's tape, and the estimators built on them.
//!
//! | name       | what                                                     | cost at 64^3 (x one primal render) |
//! |------------|----------------------------------------------------------|-------------------------------------|
//! | `fwd-full` | exact; coordinate directions in chunks of K lanes        | P / K dual passes (64 dirs, K = 16: about 5) |
//! | `fwd-rand` | unbiased; K random directions in one dual pass           | 1 dual pass (about 1.6)            |
//! | `rev-sub`  | unbiased; reverse mode on random pixels and photon paths | about 0.3 at the paper's subsets   |
//! | `rev-full` | exact; reverse mode on every pixel and path              | about 3.4, under 400 MiB           |
//!
//! (`results/bench_grad/`; the primal render that freezes the estimator comes on top.)
//!
//! Derivatives with respect to voxels whose block of the sampling density is
//! empty are zero by construction (nothing is marched there); pass a
//! `support` to [`Frozen::new`](crate::render::frozen::Frozen::new) to widen it.

pub mod finite_diff;
pub mod forward;
pub mod loss;
pub mod reverse;

use crate::error::{Error, Result};
use crate::image::Image;
use crate::render::frozen::Frozen;
use crate::rng::{Purpose, Rng};
use forward::{coordinate_gradient, random_gradient, Directions};
use reverse::{reverse_gradient, Subset};
use serde::{Deserialize, Serialize};

/// A gradient estimator, by its command-line name (`fwd-full`, `fwd-rand`,
/// `rev-sub`, `rev-full`: clap and serde spell it the same way).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
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

/// Lane counts a forward pass can carry (`DualSVec64<K>`).
pub const LANES: [usize; 7] = [1, 2, 4, 8, 16, 32, 64];

/// The lane count for `directions` directions with at most `most` lanes per
/// pass: the fewest of [`LANES`] that carry them in as few passes as `most`
/// does (a pass costs about a primal render plus a share per lane, so unused
/// lanes are waste). Every lane computes the same operations whatever the
/// count, so the derivatives are the same to the bit.
pub fn lanes_for(directions: usize, most: usize) -> Result<usize> {
    if !LANES.contains(&most) {
        return Err(Error(format!("--lanes: {most} is not one of {LANES:?}")));
    }
    let passes = directions.div_ceil(most).max(1);
    let per_pass = directions.div_ceil(passes);
    Ok(LANES.into_iter().find(|&k| k >= per_pass).unwrap_or(most))
}

/// Settings of a voxel gradient.
#[derive(Clone, Debug)]
pub struct GradOptions {
    /// Which estimator.
    pub estimator: Estimator,
    /// Directions per forward pass (one of [`LANES`]).
    pub lanes: usize,
    /// `rev-sub`: pixels differentiated (the paper: 1,000).
    pub pixels: usize,
    /// `rev-sub`: photon paths differentiated (the paper: 5,000).
    pub paths: usize,
    /// `fwd-rand`: how directions are drawn.
    pub directions: Directions,
    /// Seed of the estimator's own draws (subsets, directions).
    pub seed: u64,
}

impl Default for GradOptions {
    fn default() -> Self {
        GradOptions {
            estimator: Estimator::RevFull,
            lanes: 8,
            pixels: 1000,
            paths: 5000,
            directions: Directions::Gaussian,
            seed: 0,
        }
    }
}

/// Calls `$f::<K>` with the const K equal to the runtime `$lanes`.
#[macro_export]
macro_rules! with_lanes {
    ($lanes:expr, $f:ident ( $($arg:expr),* )) => {
        match $lanes {
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            4 => $f::<4>($($arg),*),
            8 => $f::<8>($($arg),*),
            16 => $f::<16>($($arg),*),
            32 => $f::<32>($($arg),*),
            64 => $f::<64>($($arg),*),
            k => return Err($crate::error::Error(format!("--lanes: {k} is not one of {:?}", $crate::grad::LANES))),
        }
    };
}

/// `dL/drho` for every voxel (zero where no lookup reaches) by the chosen
/// estimator. `progress(done, total)` reports forward passes of `fwd-full`.
pub fn voxel_gradient(
    frozen: &Frozen,
    targets: &[Image],
    opts: &GradOptions,
    progress: &dyn Fn(usize, usize),
) -> Result<Vec<f64>> {
    let voxels = frozen.scene.density.len();
    Ok(match opts.estimator {
        Estimator::RevFull => reverse_gradient(frozen, targets, Subset::full()).grad,
        Estimator::RevSub => {
            let subset = Subset { pixels: Some(opts.pixels), paths: Some(opts.paths), seed: opts.seed };
            reverse_gradient(frozen, targets, subset).grad
        }
        Estimator::FwdFull => {
            let reach = frozen.reachable_voxels();
            let part = with_lanes!(opts.lanes, coordinate_gradient(frozen, &reach, targets, progress));
            let mut grad = vec![0.0; voxels];
            reach.iter().zip(part).for_each(|(&v, g)| grad[v] = g);
            grad
        }
        Estimator::FwdRand => {
            let reach = frozen.reachable_voxels();
            let mut rng = Rng::new(opts.seed, Purpose::Gradient, 1);
            with_lanes!(opts.lanes, random_gradient(frozen, &reach, targets, opts.directions, &mut rng))
        }
    })
}

/// `dL/drho` at the listed voxels by forward mode (coordinate directions).
pub fn forward_at(frozen: &Frozen, targets: &[Image], voxels: &[usize], lanes: usize) -> Result<Vec<f64>> {
    Ok(with_lanes!(lanes, coordinate_gradient(frozen, voxels, targets, &|_, _| {})))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn estimator_names_agree_with_clap_and_serde() {
        for e in Estimator::value_variants() {
            let clap_name = e.to_possible_value().map(|v| v.get_name().to_string());
            assert_eq!(clap_name.as_deref(), Some(e.name()));
            assert_eq!(serde_json::to_string(e).ok(), Some(format!("\"{}\"", e.name())));
        }
    }

    #[test]
    fn lanes_carry_the_directions_in_the_fewest_passes_without_waste() {
        assert_eq!(lanes_for(64, 64).unwrap(), 64);
        assert_eq!(lanes_for(64, 16).unwrap(), 16);
        assert_eq!(lanes_for(8, 64).unwrap(), 8);
        assert_eq!(lanes_for(72, 64).unwrap(), 64);
        assert_eq!(lanes_for(20, 16).unwrap(), 16);
        assert_eq!(lanes_for(3, 64).unwrap(), 4);
        assert_eq!(lanes_for(0, 4).unwrap(), 1);
        assert!(lanes_for(8, 3).is_err());
    }
}
