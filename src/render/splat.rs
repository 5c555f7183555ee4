//! Volumetric photon density estimation (Jensen & Christensen 1998) towards
//! each camera, on a grid: every stored photon spreads
//! `albedo * p_HG(w_photon . w_camera) * power` over the grid nodes within
//! the kernel radius with Epanechnikov weights `1 - d^2/r^2`, normalised per
//! photon so each photon deposits exactly its power (no energy lost to the
//! discretisation, however small or large the radius). Ray-march samples
//! read the grid trilinearly: the estimate at a sample is then a kernel
//! density estimate with kernel (Epanechnikov ∘ trilinear hat), computed
//! once per photon instead of once per sample and neighbour.
//!
//! The kernel weights do not depend on the camera and are computed once
//! ([`Kernel`]); each camera then only scales and adds them. The node grid
//! is the density's voxel centres, coarsened where the radius is so large
//! that a photon would touch more than about 5^3 nodes. Only the nodes some
//! photon deposits on hold a value ([`Estimate`]): at 128^3 they are a
//! tenth of the grid, and in dual numbers a dense grid per camera would
//! cost gigabytes.

use super::photons::Photon;
use crate::ad::Real;
use crate::math::Vec3;
use crate::par;
use crate::volume::phase::hg_eval;
use crate::volume::Grid;
use rayon::prelude::*;

/// Where the estimate lives: the node grid and the kernel radius.
#[derive(Clone, Debug)]
pub struct SplatGeometry {
    /// A zero grid whose geometry the estimates use.
    pub nodes: Grid<f64>,
    /// Per node, its slot among the nodes photons deposit on ([`NO_SLOT`]
    /// where none does); set by [`SplatGeometry::kernel`].
    slots: Grid<u32>,
    /// Number of slots.
    used: usize,
    /// Kernel radius (world units, > 0).
    pub radius: f64,
    /// Node spacing along x, y, z.
    cell: Vec3,
}

/// The normalised kernel weights of every photon: photon `p` deposits
/// `weights[n]` of its value on node `nodes[n]` for `n` in `start[p]..start[p+1]`.
#[derive(Clone, Debug, Default)]
pub struct Kernel {
    /// Offsets into `nodes` and `weights`, one more than there are photons.
    pub start: Vec<usize>,
    /// Flat node indices.
    pub nodes: Vec<u32>,
    /// Weights; those of one photon sum to 1 / (node cell volume).
    pub weights: Vec<f32>,
}

impl Kernel {
    /// Photon `p`'s deposits: (flat node index, weight) pairs.
    pub fn deposits(&self, p: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let range = self.start[p]..self.start[p + 1];
        self.nodes[range.clone()].iter().zip(&self.weights[range]).map(|(&n, &w)| (n as usize, w as f64))
    }
}

/// The phase function of light scattered at `photon` towards a camera at
/// `camera`: `p_HG(g, w_photon . w_to_camera)`, the only part of a photon's
/// contribution that depends on the camera. `None` where the photon sits
/// exactly at the camera (no direction, and no contribution).
pub fn phase_towards(photon: &Photon, camera: &Vec3, g: f64) -> Option<f64> {
    let to_cam = camera - photon.pos;
    let dist = to_cam.norm();
    (dist != 0.0).then(|| hg_eval(g, photon.dir.dot(&(to_cam / dist))))
}

/// z-planes per parallel task of the estimate.
const SLAB: usize = 4;

impl SplatGeometry {
    /// Nodes at the density's voxel centres, coarsened to cells of at least `radius / 2.5`.
    pub fn new(density: &Grid<f64>, radius: f64) -> Self {
        let extent = density.hi - density.lo;
        let voxel = density.voxel_size();
        let axis = |a: usize| {
            let cell = voxel[a].max(radius / 2.5);
            ((extent[a] / cell).round() as usize).clamp(1, density.shape[2 - a])
        };
        let shape = [axis(2), axis(1), axis(0)];
        let len = shape.iter().product();
        let nodes = Grid::new(density.lo, density.hi, shape, par::filled(len, 0.0));
        let slots = Grid::new(density.lo, density.hi, shape, par::filled(len, NO_SLOT));
        let cell = nodes.voxel_size();
        SplatGeometry { nodes, slots, used: 0, radius, cell }
    }

    /// The node index range `lo..hi` along axis `a` (0 = x) within the radius of `x`.
    fn range(&self, x: &Vec3, a: usize) -> (usize, usize) {
        let n = self.nodes.shape[2 - a];
        let u = |v: f64| (v - self.nodes.lo[a]) / self.cell[a] - 0.5;
        let lo = u(x[a] - self.radius).ceil().max(0.0) as usize;
        let hi = (u(x[a] + self.radius).floor().max(-1.0) + 1.0) as usize;
        (lo.min(n), hi.min(n))
    }

    /// Appends the normalised weights of a photon at `x` to `nodes`/`weights`.
    fn photon_weights(&self, x: &Vec3, nodes: &mut Vec<u32>, weights: &mut Vec<f32>) {
        let first = nodes.len();
        let r2 = self.radius * self.radius;
        let (i0, i1) = self.range(x, 0);
        let (j0, j1) = self.range(x, 1);
        let (k0, k1) = self.range(x, 2);
        let mut raw = Vec::with_capacity((i1 - i0) * (j1 - j0) * (k1 - k0));
        let centre = |k: usize, a: usize| self.nodes.lo[a] + (k as f64 + 0.5) * self.cell[a];
        for k in k0..k1 {
            let dz = centre(k, 2) - x.z;
            for j in j0..j1 {
                let dy = centre(j, 1) - x.y;
                for i in i0..i1 {
                    let dx = centre(i, 0) - x.x;
                    let d2 = dx * dx + dy * dy + dz * dz;
                    if d2 < r2 {
                        nodes.push(self.nodes.index(k, j, i) as u32);
                        raw.push(1.0 - d2 / r2);
                    }
                }
            }
        }
        let cell_volume = self.cell.product();
        let sum: f64 = raw.iter().sum();
        if sum > 0.0 {
            weights.extend(raw.iter().map(|w| (w / (sum * cell_volume)) as f32));
        } else if let Some(s) = self.nodes.stencil(x) {
            // No node within the radius: the trilinear hat keeps the photon's power.
            nodes.truncate(first);
            for c in 0..8 {
                nodes.push(s.index[c] as u32);
                weights.push((s.weight[c] / cell_volume) as f32);
            }
        }
    }

    /// Number of nodes that hold a value (slots).
    pub fn used(&self) -> usize {
        self.used
    }

    /// The slot of node `n` (flat index); only for nodes a deposit touches.
    #[inline]
    pub fn slot(&self, n: usize) -> usize {
        self.slots.data[n] as usize
    }

    /// The kernel weights of all photons (parallel, deterministic); numbers
    /// the nodes they touch, in node order.
    pub fn kernel(&mut self, photons: &[Photon]) -> Kernel {
        let kernel = self.weights(photons);
        self.slots.data.iter_mut().for_each(|s| *s = NO_SLOT);
        for &n in &kernel.nodes {
            self.slots.data[n as usize] = 0;
        }
        self.used = 0;
        for s in self.slots.data.iter_mut().filter(|s| **s != NO_SLOT) {
            *s = self.used as u32;
            self.used += 1;
        }
        kernel
    }

    fn weights(&self, photons: &[Photon]) -> Kernel {
        let parts: Vec<(Vec<usize>, Vec<u32>, Vec<f32>)> = photons
            .par_chunks(1024)
            .map(|chunk| {
                let (mut counts, mut nodes, mut weights) = (Vec::with_capacity(chunk.len()), vec![], vec![]);
                for p in chunk {
                    let before = nodes.len();
                    self.photon_weights(&p.pos, &mut nodes, &mut weights);
                    counts.push(nodes.len() - before);
                }
                (counts, nodes, weights)
            })
            .collect();
        let mut start = vec![0];
        let (mut nodes, mut weights) = (Vec::with_capacity(parts.len()), Vec::with_capacity(parts.len()));
        for (counts, n, w) in parts {
            for c in counts {
                start.push(start.last().unwrap() + c);
            }
            nodes.push(n);
            weights.push(w);
        }
        Kernel { start, nodes: par::concat(nodes), weights: par::concat(weights) }
    }

    /// For each camera position, the in-scattered radiance per unit length
    /// `albedo * sum_p p_HG * power * K` towards that camera, on the nodes.
    /// Deterministic: every node sums its photons in photon order.
    pub fn estimate(
        &self,
        photons: &[Photon],
        kernel: &Kernel,
        cameras: &[Vec3],
        albedo: f64,
        g: f64,
    ) -> Vec<Estimate<'_, f64>> {
        self.estimate_with(photons, |p| photons[p].power, kernel, cameras, albedo, g)
    }

    /// [`estimate`](Self::estimate) with photon `p`'s power given by `power(p)`
    /// (a function of the density in the frozen estimator).
    pub fn estimate_with<R: Real>(
        &self,
        photons: &[Photon],
        power: impl Fn(usize) -> R + Sync,
        kernel: &Kernel,
        cameras: &[Vec3],
        albedo: f64,
        g: f64,
    ) -> Vec<Estimate<'_, R>> {
        let [nz, ny, nx] = self.nodes.shape;
        let plane = ny * nx;
        let n_slabs = nz.div_ceil(SLAB);
        // Photons whose deposits reach each slab, in photon order.
        let slab_range: Vec<(usize, usize)> = (0..photons.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|p| {
                let nodes = &kernel.nodes[kernel.start[p]..kernel.start[p + 1]];
                nodes.iter().fold((usize::MAX, 0), |(lo, hi), &n| {
                    let s = n as usize / plane / SLAB;
                    (lo.min(s), hi.max(s))
                })
            })
            .collect();
        let reach: Vec<Vec<u32>> = (0..n_slabs)
            .into_par_iter()
            .with_max_len(1)
            .map(|s| {
                let reaches = |p: &usize| slab_range[*p].0 <= s && s <= slab_range[*p].1;
                (0..photons.len()).filter(reaches).map(|p| p as u32).collect()
            })
            .collect();
        // The slots of slab s are first_slot[s]..first_slot[s + 1] (slots follow node order).
        let mut first_slot = vec![0usize; n_slabs + 1];
        for (n, &slot) in self.slots.data.iter().enumerate() {
            if slot != NO_SLOT {
                first_slot[n / plane / SLAB + 1] += 1;
            }
        }
        for s in 0..n_slabs {
            first_slot[s + 1] += first_slot[s];
        }
        // Per camera, every photon's phase towards it, once (a photon reaches one slab or more).
        let phases: Vec<Vec<Option<f64>>> = cameras
            .par_iter()
            .map(|camera| photons.par_iter().with_min_len(1024).map(|p| phase_towards(p, camera, g)).collect())
            .collect();
        // One task per slab: the photons crowd into some of them (see `crate::par`).
        let slabs: Vec<Vec<R>> = (0..cameras.len() * n_slabs)
            .into_par_iter()
            .with_max_len(1)
            .map(|task| {
                let (cam, s) = (task / n_slabs, task % n_slabs);
                let (first, last) = (s * SLAB * plane, ((s + 1) * SLAB).min(nz) * plane);
                let mut slab = vec![R::cst(0.0); first_slot[s + 1] - first_slot[s]];
                for &p in &reach[s] {
                    let Some(phase) = phases[cam][p as usize] else {
                        continue;
                    };
                    let value = power(p as usize) * (albedo * phase);
                    for (n, w) in kernel.deposits(p as usize) {
                        if (first..last).contains(&n) {
                            slab[self.slot(n) - first_slot[s]].add_scaled(&value, w);
                        }
                    }
                }
                slab
            })
            .collect();
        let mut slabs = slabs.into_iter();
        (0..cameras.len())
            .map(|_| Estimate { slots: &self.slots, values: par::concat(slabs.by_ref().take(n_slabs).collect()) })
            .collect()
    }
}

/// Slot of a node no photon deposits on.
pub const NO_SLOT: u32 = u32::MAX;

/// A photon estimate towards one camera: values on the nodes photons
/// deposit on, 0 on every other node, trilinear in between.
#[derive(Clone, Debug)]
pub struct Estimate<'a, R> {
    /// Per node, its slot in `values` ([`NO_SLOT`]: the value is 0).
    pub slots: &'a Grid<u32>,
    /// One value per slot.
    pub values: Vec<R>,
}

impl<R: Real> Estimate<'_, R> {
    /// The trilinear value at `p` (0 outside the box).
    #[inline]
    pub fn at(&self, p: &Vec3) -> R {
        let Some((index, weights)) = self.slots.trilinear(p) else { return R::cst(0.0) };
        let zero = R::cst(0.0);
        let value = |n: usize| match self.slots.data[n] {
            NO_SLOT => &zero,
            slot => &self.values[slot as usize],
        };
        R::weighted_sum8(index.map(value), weights)
    }

    /// The same estimate with other values on the same slots.
    pub fn with_values<S>(&self, values: Vec<S>) -> Estimate<'_, S> {
        assert_eq!(values.len(), self.values.len(), "one value per slot");
        Estimate { slots: self.slots, values }
    }
}
