//! Ray marching through the occupied part of the volume: fixed steps inside
//! the majorant's non-empty intervals, one jittered sample per step, the
//! density piecewise constant per step. Step placement never depends on the
//! density values (only on which blocks are empty), so the marched
//! quantities are smooth functions of the densities.

use crate::ad::Real;
use crate::math::{intersect_box, Ray, Vec3};
use crate::volume::{Grid, Majorant};

/// Optical depth beyond which marching stops: `exp(-800)` is 0 in `f64`.
const DEPTH_CUTOFF: f64 = 800.0;

/// Fractional part of the golden ratio: the additive recurrence with the best spread.
const GOLDEN: f64 = 0.618_033_988_749_894_8;

/// One ray-march step: it covers `[start, start + h]` and is represented by
/// the density at `sample`.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    /// Ray parameter where the step begins.
    pub start: f64,
    /// Step length (> 0).
    pub h: f64,
    /// Ray parameter of the step's density sample, in `[start, start + h)`.
    pub sample: f64,
}

/// What marching needs: where the medium can be non-empty and the step length.
#[derive(Clone, Debug)]
pub struct Marcher {
    /// Bounds of the density (of the sampling density, docs/DESIGN.md §3).
    pub majorant: Majorant,
    /// Box of the volume.
    pub lo: Vec3,
    /// Box of the volume.
    pub hi: Vec3,
    /// Longest step (world units).
    pub step: f64,
}

impl Marcher {
    /// A marcher over `grid`'s box with blocks from `majorant`.
    pub fn new(grid: &Grid<f64>, majorant: Majorant, step: f64) -> Self {
        Marcher { majorant, lo: grid.lo, hi: grid.hi, step }
    }

    /// Calls `visit` for every step along `ray` over `[0, t_max]` inside
    /// non-empty blocks, in order; `jitter` in [0, 1) places the sample in
    /// each step. Stops early when `visit` returns false.
    pub fn steps(&self, ray: &Ray, t_max: f64, jitter: f64, mut visit: impl FnMut(Step) -> bool) {
        let Some((t0, t1)) = intersect_box(ray, &self.lo, &self.hi) else {
            return;
        };
        let t1 = t1.min(t_max);
        if t1 <= t0 {
            return;
        }
        let mut intervals: Vec<(f64, f64)> = Vec::new();
        self.majorant.occupied_intervals(ray, t0, t1, &mut intervals);
        // Each step's offset is uniform on its own; the golden-ratio rotation
        // decorrelates successive steps so their errors average out along the ray.
        let mut offset = jitter;
        for (ta, tb) in intervals {
            let n = ((tb - ta) / self.step).ceil().max(1.0);
            let h = (tb - ta) / n;
            for m in 0..n as usize {
                let start = ta + m as f64 * h;
                if !visit(Step { start, h, sample: start + offset * h }) {
                    return;
                }
                offset += GOLDEN;
                offset -= offset.floor();
            }
        }
    }

    /// Optical depth `∫ sigma_t dt` along `ray` over `[0, t_max]` with
    /// `sigma_t = scale * density`. Stops adding once the primal exceeds
    /// `cutoff` (beyond which `exp(-depth)` is zero in `f64`).
    pub fn optical_depth<R: Real>(&self, density: &Grid<R>, scale: f64, ray: &Ray, t_max: f64, jitter: f64) -> R {
        let mut depth = R::cst(0.0);
        self.steps(ray, t_max, jitter, |s| {
            depth.add_scaled(&density.at(&ray.at(s.sample)), scale * s.h);
            depth.re() < DEPTH_CUTOFF
        });
        depth
    }

    /// Reverse mode of [`optical_depth`](Self::optical_depth): calls
    /// `add(voxel, adjoint * d depth / d rho_voxel)` for every lookup of
    /// the same march, stopping where it stops. `depth` is that march's
    /// result: below the cutoff it never stopped early, and the steps need
    /// not add up a depth of their own (half the lookups).
    #[allow(clippy::too_many_arguments)]
    pub fn optical_depth_adjoint(
        &self,
        density: &Grid<f64>,
        scale: f64,
        ray: &Ray,
        t_max: f64,
        jitter: f64,
        depth: f64,
        adjoint: f64,
        add: &mut impl FnMut(usize, f64),
    ) {
        let stops_early = depth.is_nan() || depth >= DEPTH_CUTOFF;
        let mut marched = 0.0;
        self.steps(ray, t_max, jitter, |s| {
            let x = ray.at(s.sample);
            if let Some(st) = density.stencil(&x) {
                let a = adjoint * (scale * s.h);
                for c in 0..8 {
                    add(st.index[c], a * st.weight[c]);
                }
            }
            if stops_early {
                marched += density.at(&x) * (scale * s.h);
            }
            marched < DEPTH_CUTOFF
        });
    }

    /// Transmittance from `from` to `to` in a straight line.
    pub fn transmittance<R: Real>(&self, density: &Grid<R>, scale: f64, from: &Vec3, to: &Vec3, jitter: f64) -> R {
        let d = to - from;
        let dist = d.norm();
        if dist == 0.0 {
            return R::cst(1.0);
        }
        let ray = Ray { origin: *from, dir: d / dist };
        (self.optical_depth(density, scale, &ray, dist, jitter) * -1.0).exp()
    }
}
