//! A final refinement after training: every hull voxel gets its own factor,
//! `density = decoded * exp(s)` (optionally times one global factor,
//! `exp(g + s)`, and plus a non-negative term `a` of its own), and Adam
//! fits them to the training images by reverse mode (the renderer's exact
//! `dL/d density`; no decoder in between, so nothing limits how closely
//! the images can be explained). Without the additive term, voxels where
//! the decoder gives 0 stay 0.
//!
//! It exists because the decoder, trained through a noisy renderer, fits
//! its own training images only slowly; the refinement closes the rest of
//! the gap at the cost of the smoothness the decoder provides.

use super::level::Level;
use super::problem::Problem;
use super::train::{check_finite, check_renders, log_row, LogRow};
use crate::error::{Error, Result};
use crate::grad::reverse::{reverse_gradient, Subset};
use crate::model::Model;
use crate::optim::Adam;
use crate::par;
use crate::volume::Grid;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// How the refinement runs. `Default` is the paper's method as this
/// project ships it, [`RefineSettings::prior`] the learned prior's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefineSettings {
    /// Adam updates (0: no refinement).
    pub updates: usize,
    /// Adam step of the log-factors.
    pub lr: f64,
    /// Photons per update.
    pub photons: u64,
    /// Camera samples per pixel per update.
    pub spp: u32,
    /// Take each update's residual from a second, independent render
    /// (as [`super::train::TrainSettings::decorrelate`]).
    pub decorrelate: bool,
    /// Seed of the updates' renders.
    pub seed: u64,
    /// Stop after this many seconds (at most `updates`), if given.
    pub time_budget: Option<f64>,
    /// Also fit one global log-factor `g` (its own Adam, not penalised):
    /// its gradient sums every voxel's, so it is far less noisy than any one
    /// voxel's and corrects the total mass in a few updates, where the
    /// per-voxel factors follow their noisy gradients only slowly.
    pub global: bool,
    /// Also give every hull voxel a term `a >= 0` added to its density
    /// (projected Adam, step `lr` times the mean non-zero decoded density):
    /// a decoder's ReLU output is exactly 0 in whole regions of the hull,
    /// which a factor cannot fill.
    pub additive: bool,
    /// The steps of every factor and term fall exponentially over the
    /// updates (or the time budget, if that ends the refinement first) to
    /// this fraction of their start (1: constant). Adam moves a coordinate
    /// whose gradient is only noise by a random walk of about its step per
    /// update. Alone, smaller late steps did not lessen the haze in empty
    /// voxels; with block terms, whose steps move many voxels at once,
    /// they are what keeps the last iterate's images close (the paper's
    /// method's default, 0.1).
    pub lr_final: f64,
    /// Also fit one log-factor (and, with `additive`, one additive term)
    /// per block of `b`^3 voxels for every edge `b` here (empty: none). A
    /// block's gradient sums its voxels', so it follows the images' coarse
    /// misfit far sooner than the voxels' own noisy factors do.
    pub blocks: Vec<usize>,
}

impl Default for RefineSettings {
    /// The paper's method: 400 updates with the global factor, the
    /// additive terms and blocks of 4 and 8, steps falling to 0.1.
    fn default() -> Self {
        RefineSettings {
            updates: 400,
            lr: 0.02,
            photons: 50_000,
            spp: 2,
            decorrelate: true,
            seed: 0,
            time_budget: None,
            global: true,
            additive: true,
            lr_final: 0.1,
            blocks: vec![4, 8],
        }
    }
}

impl RefineSettings {
    /// The learned prior's: 200 updates (a fit within 3 minutes on 2
    /// cores), constant steps, the same terms and blocks.
    pub fn prior() -> Self {
        RefineSettings { updates: 200, lr_final: 1.0, ..RefineSettings::default() }
    }

    /// Errors (naming the field) on settings that cannot run; [`refine`]
    /// checks them before its first update.
    pub fn check(&self) -> Result<()> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error(format!("refine.lr: {} must be finite and > 0", self.lr)));
        }
        if !(self.lr_final.is_finite() && self.lr_final > 0.0 && self.lr_final <= 1.0) {
            return Err(Error(format!("refine.lr_final: {} must be in (0, 1]", self.lr_final)));
        }
        if let Some(b) = self.time_budget.filter(|b| !(b.is_finite() && *b > 0.0)) {
            return Err(Error(format!("refine.time_budget: {b} must be finite and > 0")));
        }
        if self.blocks.iter().any(|&b| b < 2) {
            return Err(Error(format!("refine.blocks: edges {:?} must be at least 2 voxels", self.blocks)));
        }
        check_renders("refine", self.photons, self.spp)
    }
}

/// Refines `model`'s density on `problem`'s training images; `first` numbers
/// the first update (after training's), `observe` sees every log row. Returns the refined density.
pub fn refine(
    problem: &Problem,
    model: &Model,
    settings: &RefineSettings,
    first: usize,
    observe: &mut dyn FnMut(&LogRow),
) -> Result<Grid<f64>> {
    refine_density(problem, &model.density(&problem.scene.density), &model.mask, settings, first, observe)
}

/// [`refine`] from any density `base` (on the scene's grid, 0 outside
/// `mask`), within the hull `mask`: how a start that came from elsewhere
/// (a study's oracle) fares under the same refinement.
pub fn refine_density(
    problem: &Problem,
    base: &Grid<f64>,
    mask: &[bool],
    settings: &RefineSettings,
    first: usize,
    observe: &mut dyn FnMut(&LogRow),
) -> Result<Grid<f64>> {
    settings.check()?;
    if base.shape != problem.scene.density.shape || mask.len() != base.data.len() {
        return Err(Error(format!(
            "refine: start grid {:?} and mask of {} voxels must match the scene's grid {:?}",
            base.shape,
            mask.len(),
            problem.scene.density.shape
        )));
    }
    let start = Instant::now();
    let level = Level::full(problem, mask);
    let hull: Vec<usize> =
        (0..base.data.len()).filter(|&i| mask[i] && (settings.additive || base.data[i] > 0.0)).collect();
    let nonzero: Vec<f64> = hull.iter().map(|&i| base.data[i]).filter(|&v| v > 0.0).collect();
    let mean_nonzero = nonzero.iter().sum::<f64>() / nonzero.len().max(1) as f64;
    let lr_a = settings.lr * mean_nonzero;
    // Field 0 is the voxels' own terms, then one field per block edge.
    let mut fields = vec![Field::new((0..hull.len()).collect(), settings.lr, lr_a)];
    fields.extend(settings.blocks.iter().map(|&b| Field::new(block_of(base.shape, &hull, b), settings.lr, lr_a)));
    let (mut g, mut adam_g) = ([0.0], Adam::new(1, settings.lr));
    // Each voxel's place in `hull` (`usize::MAX`: outside it).
    let mut slot = vec![usize::MAX; base.data.len()];
    hull.iter().enumerate().for_each(|(j, &i)| slot[i] = j);
    // In parallel over the voxels, each voxel's terms added in field order.
    let density_of = |fields: &[Field], g: f64| {
        let (log, additive): (Vec<f64>, Vec<f64>) = (0..hull.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|j| fields.iter().fold((g, 0.0), |(log, add), f| (log + f.s[f.of[j]], add + f.a[f.of[j]])))
            .unzip();
        let data = base
            .data
            .par_iter()
            .with_min_len(4096)
            .zip(&slot)
            .map(|(&d, &j)| if j == usize::MAX { d } else { d * log[j].exp() + additive[j] })
            .collect();
        (Grid::new(base.lo, base.hi, base.shape, data), additive)
    };
    for u in 0..settings.updates {
        if settings.time_budget.is_some_and(|b| start.elapsed().as_secs_f64() >= b) {
            break;
        }
        // Progress towards whichever ends the refinement first: its last update or its time budget.
        let by_updates = u as f64 / (settings.updates - 1).max(1) as f64;
        let progress = settings.time_budget.map_or(by_updates, |b| by_updates.max(start.elapsed().as_secs_f64() / b));
        let decay = settings.lr_final.powf(progress.min(1.0));
        adam_g.lr = settings.lr * decay;
        fields.iter_mut().for_each(|f| (f.adam_s.lr, f.adam_a.lr) = (settings.lr * decay, lr_a * decay));
        let (density, additive) = density_of(&fields, g[0]);
        check_finite(&density, "refinement", u)?;
        let seed = settings.seed.wrapping_mul(1_000_003).wrapping_add((first + u) as u64) ^ REFINE_SEED;
        let scene = level.scene_at(&density, settings.photons, settings.spp, seed);
        let (frozen, shifted) = level.freeze(&scene, &density, settings.decorrelate.then_some(seed ^ 1));
        let wall_s = start.elapsed().as_secs_f64();
        let targets = &shifted.as_ref().unwrap_or(&level).targets;
        // The log row is serial work: a helper thread computes it while the gradient runs.
        let (reverse, row) = par::alongside(
            || reverse_gradient(&frozen, targets, Subset::full()),
            || log_row(first + u, problem, &level, mask, &density, &frozen, wall_s),
        );
        observe(&row);
        let grad = reverse.grad;
        // d density / d (any log-factor) = the multiplicative part, density - additive.
        let image_part: Vec<f64> =
            hull.iter().zip(&additive).map(|(&i, add)| grad[i] * (density.data[i] - add)).collect();
        let voxel_grad: Vec<f64> = hull.iter().map(|&i| grad[i]).collect();
        if settings.global {
            adam_g.step(&mut g, &[image_part.iter().sum::<f64>()]);
        }
        for f in fields.iter_mut() {
            if settings.additive {
                let ga = f.sum_over(&voxel_grad);
                f.adam_a.step(&mut f.a, &ga);
                f.a.iter_mut().for_each(|a| *a = a.max(0.0));
            }
            let gs = f.sum_over(&image_part);
            f.adam_s.step(&mut f.s, &gs);
        }
    }
    let last = density_of(&fields, g[0]).0;
    check_finite(&last, "refinement", settings.updates.saturating_sub(1))?;
    Ok(last)
}

/// One field of refinement terms: a log-factor `s` and an additive term `a`
/// per cell, with `of[j]` the cell of hull voxel `j` (its own, or its block's).
struct Field {
    of: Vec<usize>,
    s: Vec<f64>,
    a: Vec<f64>,
    adam_s: Adam,
    adam_a: Adam,
}

impl Field {
    fn new(of: Vec<usize>, lr: f64, lr_a: f64) -> Self {
        let cells = of.iter().max().map_or(0, |&k| k + 1);
        Field {
            of,
            s: vec![0.0; cells],
            a: vec![0.0; cells],
            adam_s: Adam::new(cells, lr),
            adam_a: Adam::new(cells, lr_a),
        }
    }

    /// Per cell, the sum of `per_voxel` over its hull voxels.
    fn sum_over(&self, per_voxel: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.s.len()];
        self.of.iter().zip(per_voxel).for_each(|(&k, v)| out[k] += v);
        out
    }
}

/// For every voxel of `hull` (indices into a grid of `shape`), its block of
/// `edge`^3 voxels, numbered densely over the blocks the hull touches.
fn block_of(shape: [usize; 3], hull: &[usize], edge: usize) -> Vec<usize> {
    let per_axis = shape.map(|n| n.div_ceil(edge));
    let mut dense = std::collections::HashMap::new();
    hull.iter()
        .map(|&i| {
            let (k, j, x) = (i / (shape[1] * shape[2]), (i / shape[2]) % shape[1], i % shape[2]);
            let block = ((k / edge) * per_axis[1] + j / edge) * per_axis[2] + x / edge;
            let next = dense.len();
            *dense.entry(block).or_insert(next)
        })
        .collect()
}

/// Sets the refinement's render seeds apart from training's.
const REFINE_SEED: u64 = 0x0EF1_4E00_0000_0000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_numbered_densely_over_the_hull() {
        // A 4^3 grid in blocks of 2: the hull's first voxel opens block 0,
        // voxels of one block share its number, and a block the hull misses
        // gets none.
        let hull = [0, 1, 5, 2, 63, 21];
        assert_eq!(block_of([4, 4, 4], &hull, 2), vec![0, 0, 0, 1, 2, 0]);
        // A grid edge that the block edge does not divide: the last block is partial.
        assert_eq!(block_of([1, 1, 5], &[0, 3, 4], 4), vec![0, 0, 1]);
    }
}
