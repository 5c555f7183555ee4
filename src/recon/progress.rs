//! Progress of a reconstruction: the log row just measured, the time so far
//! and an ETA that knows coarse-to-fine training. The first share of the
//! updates runs at half resolution, several times cheaper than the rest, so
//! "time so far / updates so far" promises far too little; [`Eta`] keeps the
//! seconds per update of each level apart and, until a full-resolution
//! update has been timed, predicts its cost from the coarse one times the
//! measured ratio of one primal render at each level ([`fine_over_coarse`]).

use super::level::Level;
use super::problem::Problem;
use super::train::{LogRow, TrainSettings};
use crate::model::Model;
use crate::render::frozen::Frozen;
use std::fmt;
use std::time::Instant;

/// What a reconstruction reports after each log row.
pub struct Progress<'a> {
    /// The row just measured (before its update).
    pub row: &'a LogRow,
    /// Which part of the reconstruction the row belongs to.
    pub part: Part,
    /// Seconds since the reconstruction started (hull and model included).
    pub elapsed_s: f64,
    /// Predicted seconds of training left (this update and the later ones);
    /// `None` until one update has been timed.
    pub eta_s: Option<f64>,
}

/// The part of a reconstruction a log row belongs to, with its own count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Part {
    /// Training, of `total` updates.
    Training {
        /// Training updates asked for.
        total: usize,
    },
    /// The refinement, of `total` updates, numbered in the log from `first`.
    Refinement {
        /// The log's number of the first refinement update (the training updates made).
        first: usize,
        /// Refinement updates asked for.
        total: usize,
    },
}

impl fmt::Display for Progress<'_> {
    /// `training 12/250  loss ..  held-out ..  eps ..  30 s, ETA 160 s`
    /// (`refinement 3/400 ...` after training); the held-out loss and the
    /// density error only where they are known.
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let r = self.row;
        match self.part {
            Part::Training { total } => write!(f, "training {}/{total}", r.iteration + 1)?,
            Part::Refinement { first, total } => {
                write!(f, "refinement {}/{total}", r.iteration + 1 - first.min(r.iteration))?
            }
        }
        write!(f, "  loss {:.4e}", r.train_loss)?;
        if r.held_out_loss != 0.0 {
            write!(f, "  held-out {:.4e}", r.held_out_loss)?;
        }
        if r.density_rel_l1.is_finite() {
            write!(f, "  eps {:.3}", r.density_rel_l1)?;
        }
        match self.eta_s {
            Some(eta) => write!(f, "  {:.0} s, ETA {eta:.0} s", self.elapsed_s),
            None => write!(f, "  {:.0} s, ETA ?", self.elapsed_s),
        }
    }
}

/// How many times longer one full-resolution primal render (photons and
/// camera rays, as an update starts with) takes than a half-resolution one,
/// timed once each at `model`'s density. The renders have their own seed:
/// training's random draws and results are untouched. `None` if the problem
/// has no half level. Clamped to [1, 16]: the half level has a quarter of
/// the pixels and half the steps per ray, so the true ratio is below 8;
/// the clamp only guards against a timer hiccup on a tiny problem.
pub fn fine_over_coarse(problem: &Problem, model: &Model, settings: &TrainSettings) -> Option<f64> {
    let coarse = Level::half(problem, &model.mask)?;
    let fine = Level::full(problem, &model.mask);
    let decoded = model.density(&problem.scene.density);
    let time = |level: &Level| {
        let start = Instant::now();
        let scene = level.scene_at(&decoded, settings.photons, settings.spp, settings.seed);
        let frozen = Frozen::new(&scene, Some(&level.support));
        std::hint::black_box(&frozen.images);
        start.elapsed().as_secs_f64()
    };
    let t_coarse = time(&coarse);
    let t_fine = time(&fine);
    Some((t_fine / t_coarse.max(1e-9)).clamp(1.0, 16.0))
}

/// What an update is, for its cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// A training update at half resolution.
    Coarse,
    /// A training update at full resolution.
    Fine,
    /// A per-voxel refinement update ([`super::refine`]).
    Refine,
}

/// Predicts the seconds of training left from the updates timed so far.
#[derive(Clone, Debug)]
pub struct Eta {
    /// Training updates, then refinement updates.
    train: usize,
    refine: usize,
    coarse_updates: usize,
    fine_over_coarse: f64,
    time_budget: Option<f64>,
    /// Seconds and count of the timed updates of each [`Phase`].
    timed: [(f64, usize); 3],
    /// Seconds and phase of the previous row.
    last: Option<(f64, Phase)>,
}

impl Eta {
    /// An ETA for `train` training updates, the first `coarse_updates` at
    /// half resolution, a full-resolution update costing about
    /// `fine_over_coarse` half-resolution ones until one has been timed,
    /// then `refine` refinement updates (predicted at a full-resolution
    /// update's cost until one has been timed); with a `time_budget`
    /// (seconds) training stops there at the latest.
    pub fn new(
        train: usize,
        coarse_updates: usize,
        refine: usize,
        fine_over_coarse: f64,
        time_budget: Option<f64>,
    ) -> Eta {
        Eta { train, refine, coarse_updates, fine_over_coarse, time_budget, timed: [(0.0, 0); 3], last: None }
    }

    /// Takes log row `iteration` (refinement rows count on after training's),
    /// measured `wall_s` seconds in before an update of `phase`, and returns
    /// the predicted seconds left: this update and the later ones.
    pub fn observe(&mut self, iteration: usize, wall_s: f64, phase: Phase) -> Option<f64> {
        if let Some((t, was)) = self.last {
            let slot = &mut self.timed[was as usize];
            slot.0 += (wall_s - t).max(0.0);
            slot.1 += 1;
        }
        self.last = Some((wall_s, phase));
        let left_in = |from: usize, to: usize| to.saturating_sub(from.max(iteration));
        let coarse = self.coarse_updates.min(self.train);
        let counts = [left_in(0, coarse), left_in(coarse, self.train), left_in(self.train, self.train + self.refine)];
        let mean = |(s, n): (f64, usize)| (n > 0).then(|| s / n as f64);
        let [c, f, r] = self.timed.map(mean);
        let cost_fine = f.or(c.map(|c| c * self.fine_over_coarse));
        let costs = [c.or(f.map(|f| f / self.fine_over_coarse)), cost_fine, r.or(cost_fine)];
        let need = |n: usize, cost: Option<f64>| if n == 0 { Some(0.0) } else { cost.map(|c| c * n as f64) };
        let eta = (0..3).try_fold(0.0, |sum, p| need(counts[p], costs[p]).map(|x| sum + x));
        match self.time_budget {
            Some(budget) => {
                let left = (budget - wall_s).max(0.0);
                Some(eta.map_or(left, |e| e.min(left)))
            }
            None => eta,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_eta_counts_the_dearer_full_resolution_updates() {
        // 10 updates, 8 at half resolution costing 1 s, full ones predicted at 6 s.
        let mut eta = Eta::new(10, 8, 0, 6.0, None);
        assert_eq!(eta.observe(0, 0.0, Phase::Coarse), None);
        let after_one = eta.observe(1, 1.0, Phase::Coarse).unwrap();
        assert!((after_one - (7.0 + 2.0 * 6.0)).abs() < 1e-12, "{after_one}");
        for it in 2..8 {
            eta.observe(it, it as f64, Phase::Coarse);
        }
        // The first full update is still predicted, then measured (here 5 s).
        assert!((eta.observe(8, 8.0, Phase::Fine).unwrap() - 12.0).abs() < 1e-12);
        assert!((eta.observe(9, 13.0, Phase::Fine).unwrap() - 5.0).abs() < 1e-12);
    }

    #[test]
    fn without_a_half_level_every_update_costs_the_same() {
        let mut eta = Eta::new(4, 0, 0, 6.0, None);
        eta.observe(0, 0.0, Phase::Fine);
        assert!((eta.observe(1, 2.0, Phase::Fine).unwrap() - 6.0).abs() < 1e-12);
    }

    #[test]
    fn a_time_budget_caps_the_eta() {
        let mut eta = Eta::new(100, 0, 0, 1.0, Some(10.0));
        assert_eq!(eta.observe(0, 0.0, Phase::Fine), Some(10.0));
        assert!((eta.observe(1, 4.0, Phase::Fine).unwrap() - 6.0).abs() < 1e-12);
    }

    #[test]
    fn refinement_updates_are_timed_on_their_own() {
        // 2 full updates of 4 s, then 3 refinement updates of 1 s.
        let mut eta = Eta::new(2, 0, 3, 6.0, None);
        eta.observe(0, 0.0, Phase::Fine);
        // Refinement predicted at a full update's cost until timed.
        assert!((eta.observe(1, 4.0, Phase::Fine).unwrap() - 16.0).abs() < 1e-12);
        assert!((eta.observe(2, 8.0, Phase::Refine).unwrap() - 12.0).abs() < 1e-12);
        assert!((eta.observe(3, 9.0, Phase::Refine).unwrap() - 2.0).abs() < 1e-12);
    }
}
