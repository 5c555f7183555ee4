//! How one plume differs from another beyond its seed: the knobs of the
//! simulation a training set of many plumes varies (sources, buoyancy,
//! drafts, turbulence, lean, how far the plume has risen), the training
//! distribution they are drawn from, the plumes deliberately outside it,
//! and the partition of seeds between training and test.
//!
//! [`Variation::default`] is the built-in plume's simulation: `plume(res,
//! seed)` and `plume_with(res, seed, &Variation::default())` are the same
//! grid, bit for bit.

use crate::rng::{Purpose, Rng};
use serde::{Deserialize, Serialize};

/// Stream index (under `Purpose::Scene`) of a seed's drawn variation.
const STREAM: u64 = 0x9A41_0000;

/// Seeds of the training plumes: `TRAIN_SEEDS.start + i` for plume `i`.
/// Disjoint from [`TEST_SEEDS`], [`OOD_SEEDS`] and the Table 1 plume (seed 0).
pub const TRAIN_SEEDS: std::ops::Range<u64> = 1_000..1_000_000;

/// Seeds of the test plumes drawn from the training distribution.
pub const TEST_SEEDS: std::ops::Range<u64> = 100..200;

/// Seeds of the plumes outside the training distribution.
pub const OOD_SEEDS: std::ops::Range<u64> = 200..300;

/// Seeds a prior may hold out from its own training set to choose its
/// settings (never a test plume).
pub const VALIDATION_SEEDS: std::ops::Range<u64> = 300..400;

/// A source ball of smoke at the bottom of the box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Source {
    /// Centre, world units (the box is `[-0.5, 0.5]`).
    pub x: f64,
    /// Centre, world units.
    pub z: f64,
    /// Radius in simulation cells (1/48 of the box).
    pub radius: f64,
}

/// The knobs of one plume's simulation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Variation {
    /// The inflows (1 to 3).
    pub sources: Vec<Source>,
    /// Upward acceleration per unit density (cells / time^2).
    pub buoyancy: f64,
    /// Vorticity confinement: how turbulent the plume is.
    pub confinement: f64,
    /// Speed of the random, slowly changing horizontal draft (cells / time).
    pub draft: f64,
    /// Amplitude of the initial random air motion (cells / time).
    pub stir: f64,
    /// Steady horizontal wind (x, z; cells / time): the plume's lean.
    pub lean: [f64; 2],
    /// World height (top of the box at 0.5) the head of the plume has
    /// reached when it is captured.
    pub head: f64,
    /// Steps simulated after the head has reached `head` (0: captured
    /// mid-rise; more: the plume runs into the top of the box).
    pub overrun: usize,
    /// Simulation cells across x and z (the box is 48 high); at most 46, so
    /// that the simulated box stays inside the unit box.
    pub width: usize,
}

impl Default for Variation {
    /// The built-in plume: one source of radius 2.5 cells at the bottom
    /// centre, captured when its head is 0.09 below the top.
    fn default() -> Self {
        Variation {
            sources: vec![Source { x: 0.0, z: 0.0, radius: 2.5 }],
            buoyancy: 0.06,
            confinement: 0.2,
            draft: 1.2,
            stir: 0.3,
            lean: [0.0, 0.0],
            head: 0.41,
            overrun: 0,
            width: 31,
        }
    }
}

impl Variation {
    /// The variation of training or test plume `seed`, drawn from the
    /// training distribution: 1 source (70 %) or 2, each within 0.12 of the
    /// centre with a radius of 1.8-3.5 cells; buoyancy 0.04-0.09;
    /// confinement 0.08-0.35; draft 0.4-1.8; stir 0.1-0.5; a lean of up to
    /// 0.5 cells per unit time in any direction; the head anywhere from
    /// 0.05 below the middle to 0.09 below the top; 39 cells across.
    /// The built-in plume's knobs ([`Variation::default`]) lie inside these ranges.
    pub fn sample(seed: u64) -> Variation {
        let mut rng = Rng::new(seed, Purpose::Scene, STREAM);
        let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
        let n = if u(0.0, 1.0) < 0.7 { 1 } else { 2 };
        let sources = (0..n).map(|_| Source { x: u(-0.12, 0.12), z: u(-0.12, 0.12), radius: u(1.8, 3.5) }).collect();
        let (buoyancy, confinement, draft, stir) = (u(0.04, 0.09), u(0.08, 0.35), u(0.4, 1.8), u(0.1, 0.5));
        let (speed, angle) = (u(0.0, 0.5), u(0.0, std::f64::consts::TAU));
        let head = u(-0.05, 0.41);
        Variation {
            sources,
            buoyancy,
            confinement,
            draft,
            stir,
            lean: [speed * angle.cos(), speed * angle.sin()],
            head,
            overrun: 0,
            width: 39,
        }
    }

    /// Checks the knobs; the error names the first bad one.
    pub fn validate(&self) -> crate::error::Result<()> {
        use crate::bail;
        if self.sources.is_empty() || self.sources.len() > 3 {
            bail!("variation.sources: {} sources (need 1 to 3)", self.sources.len());
        }
        if !(8..=46).contains(&self.width) {
            bail!("variation.width: {} cells (need 8 to 46)", self.width);
        }
        let half = self.width as f64 / 48.0 / 2.0;
        for (i, s) in self.sources.iter().enumerate() {
            let inside = s.x.abs() < half && s.z.abs() < half;
            if !(inside && s.radius.is_finite() && s.radius > 0.5 && s.radius < 8.0) {
                bail!("variation.sources[{i}]: centre ({}, {}) must lie within {half:.3} of the axis and the radius {} in (0.5, 8) cells", s.x, s.z, s.radius);
            }
        }
        let knobs = [
            ("buoyancy", self.buoyancy),
            ("confinement", self.confinement),
            ("draft", self.draft),
            ("stir", self.stir),
            ("lean", self.lean[0].hypot(self.lean[1])),
        ];
        for (name, v) in knobs {
            if !(v.is_finite() && (0.0..=5.0).contains(&v)) {
                bail!("variation.{name}: {v} (need a finite value in [0, 5])");
            }
        }
        if !(self.head.is_finite() && (-0.3..=0.45).contains(&self.head)) {
            bail!("variation.head: {} (need -0.3 to 0.45)", self.head);
        }
        if self.overrun > 100 {
            bail!("variation.overrun: {} steps (at most 100)", self.overrun);
        }
        Ok(())
    }
}

/// A plume deliberately outside the training distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unusual {
    /// Three sources spread over the floor.
    ThreeSources,
    /// Still air: no draft, no stir, no lean.
    NoDrafts,
    /// Three times the training distribution's strongest turbulence.
    StrongTurbulence,
    /// Run on after reaching the top, so that the box cuts the plume off.
    CutOff,
    /// A training-distribution plume blurred by a Gaussian of 3 voxels (at 64^3): thick and smooth.
    Smooth,
}

impl Unusual {
    /// Every case, in the evaluation's order.
    pub const ALL: [Unusual; 5] =
        [Unusual::ThreeSources, Unusual::NoDrafts, Unusual::StrongTurbulence, Unusual::CutOff, Unusual::Smooth];

    /// Short name (file names, tables).
    pub fn name(self) -> &'static str {
        match self {
            Unusual::ThreeSources => "three_sources",
            Unusual::NoDrafts => "no_drafts",
            Unusual::StrongTurbulence => "strong_turbulence",
            Unusual::CutOff => "cut_off",
            Unusual::Smooth => "smooth",
        }
    }

    /// The case's seed (in [`OOD_SEEDS`]).
    pub fn seed(self) -> u64 {
        OOD_SEEDS.start + Unusual::ALL.iter().position(|&u| u == self).unwrap_or(0) as u64
    }

    /// The case's simulation knobs: the drawn variation of its seed, changed
    /// where the case says. `Smooth` keeps them (its blur comes after sampling).
    pub fn variation(self) -> Variation {
        let mut v = Variation::sample(self.seed());
        match self {
            Unusual::ThreeSources => {
                v.sources = vec![
                    Source { x: -0.2, z: -0.1, radius: 2.5 },
                    Source { x: 0.15, z: -0.15, radius: 2.0 },
                    Source { x: 0.0, z: 0.2, radius: 3.0 },
                ];
                v.head = v.head.max(0.3);
            }
            Unusual::NoDrafts => {
                v.draft = 0.0;
                v.stir = 0.0;
                v.lean = [0.0, 0.0];
            }
            Unusual::StrongTurbulence => {
                v.confinement = 1.05;
                v.draft = 1.8;
            }
            Unusual::CutOff => {
                v.head = 0.41;
                v.overrun = 25;
            }
            Unusual::Smooth => {}
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_variations_are_valid_reproducible_and_varied() {
        let a: Vec<Variation> = (0..50).map(|i| Variation::sample(TRAIN_SEEDS.start + i)).collect();
        assert_eq!(a[3], Variation::sample(TRAIN_SEEDS.start + 3));
        a.iter().for_each(|v| v.validate().unwrap());
        assert!(a.iter().any(|v| v.sources.len() == 2) && a.iter().any(|v| v.sources.len() == 1));
        Variation::default().validate().unwrap();
        Unusual::ALL.iter().for_each(|u| u.variation().validate().unwrap());
    }

    #[test]
    fn seed_ranges_are_disjoint_and_miss_the_table1_plume() {
        let ranges = [TRAIN_SEEDS, TEST_SEEDS, OOD_SEEDS, VALIDATION_SEEDS];
        for (i, a) in ranges.iter().enumerate() {
            assert!(!a.contains(&0));
            for b in &ranges[i + 1..] {
                assert!(a.end <= b.start || b.end <= a.start, "{a:?} {b:?}");
            }
        }
    }

    #[test]
    fn bad_knobs_are_named() {
        let mut v = Variation::default();
        v.sources.clear();
        assert!(v.validate().unwrap_err().0.contains("variation.sources"));
        let v = Variation { width: 60, ..Variation::default() };
        assert!(v.validate().unwrap_err().0.contains("variation.width"));
        let v = Variation { draft: f64::NAN, ..Variation::default() };
        assert!(v.validate().unwrap_err().0.contains("variation.draft"));
    }
}
