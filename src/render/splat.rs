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
//! that a photon would touch more than about 5^3 nodes.

use super::photons::Photon;
use crate::ad::Real;
use crate::math::Vec3;
use crate::volume::phase::hg_eval;
use crate::volume::Grid;
use rayon::prelude::*;

/// Where the estimate lives: the node grid and the kernel radius.
#[derive(Clone, Debug)]
pub struct SplatGeometry {
    /// A zero grid whose geometry the estimates use.
    pub nodes: Grid<f64>,
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
        let nodes = Grid::new(density.lo, density.hi, shape, vec![0.0; shape.iter().product()]);
        let cell = nodes.voxel_size();
        SplatGeometry { nodes, radius, cell }
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

    /// The kernel weights of all photons (parallel, deterministic).
    pub fn kernel(&self, photons: &[Photon]) -> Kernel {
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
        let mut kernel = Kernel { start: vec![0], ..Default::default() };
        for (counts, nodes, weights) in parts {
            for c in counts {
                kernel.start.push(kernel.start.last().unwrap() + c);
            }
            kernel.nodes.extend(nodes);
            kernel.weights.extend(weights);
        }
        kernel
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
    ) -> Vec<Grid<f64>> {
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
    ) -> Vec<Grid<R>> {
        let [nz, ny, nx] = self.nodes.shape;
        let plane = ny * nx;
        let n_slabs = nz.div_ceil(SLAB);
        // Photons whose deposits reach each slab, in photon order.
        let mut reach: Vec<Vec<u32>> = vec![vec![]; n_slabs];
        for p in 0..photons.len() {
            let nodes = &kernel.nodes[kernel.start[p]..kernel.start[p + 1]];
            let (lo, hi) = nodes.iter().fold((usize::MAX, 0), |(lo, hi), &n| {
                let s = n as usize / plane / SLAB;
                (lo.min(s), hi.max(s))
            });
            for slab in reach.iter_mut().take(hi + 1).skip(lo) {
                slab.push(p as u32);
            }
        }
        let slabs: Vec<Vec<R>> = (0..cameras.len() * n_slabs)
            .into_par_iter()
            .map(|task| {
                let (cam, s) = (task / n_slabs, task % n_slabs);
                let first = s * SLAB * plane;
                let mut slab = vec![R::cst(0.0); ((s + 1) * SLAB).min(nz) * plane - first];
                for &p in &reach[s] {
                    let Some(phase) = phase_towards(&photons[p as usize], &cameras[cam], g) else {
                        continue;
                    };
                    let value = power(p as usize) * (albedo * phase);
                    for (n, w) in kernel.deposits(p as usize) {
                        if let Some(v) = n.checked_sub(first).and_then(|i| slab.get_mut(i)) {
                            *v += value * w;
                        }
                    }
                }
                slab
            })
            .collect();
        slabs
            .chunks(n_slabs)
            .map(|cam_slabs| {
                let data: Vec<R> = cam_slabs.iter().flatten().copied().collect();
                Grid::new(self.nodes.lo, self.nodes.hi, self.nodes.shape, data)
            })
            .collect()
    }
}
