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
//! The grid's cells are the density voxels, coarsened where the radius is
//! so large that a photon would touch more than about 5^3 nodes.

use super::photons::Photon;
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
}

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
        let nodes = Grid::new(
            density.lo,
            density.hi,
            shape,
            vec![0.0; shape.iter().product()],
        );
        SplatGeometry { nodes, radius }
    }

    /// The node index range (inclusive) along axis `a` (0 = x) within the radius of `x`.
    fn range(&self, x: &Vec3, a: usize) -> (usize, usize) {
        let n = self.nodes.shape[2 - a];
        let cell = (self.nodes.hi[a] - self.nodes.lo[a]) / n as f64;
        let lo = ((x[a] - self.radius - self.nodes.lo[a]) / cell - 0.5)
            .ceil()
            .max(0.0) as usize;
        let hi = (((x[a] + self.radius - self.nodes.lo[a]) / cell - 0.5)
            .floor()
            .max(-1.0)
            + 1.0) as usize;
        (lo.min(n), hi.min(n))
    }

    /// Calls `deposit(flat_index, weight)` for the nodes a photon at `x` reaches,
    /// restricted to z-planes `k_range`; weights over all planes sum to 1.
    fn for_each_weight(
        &self,
        x: &Vec3,
        norm: f64,
        k_range: (usize, usize),
        mut deposit: impl FnMut(usize, f64),
    ) {
        if norm == 0.0 {
            // No node within the radius: the trilinear hat keeps the photon's power.
            if let Some(s) = self.nodes.stencil(x) {
                for c in 0..8 {
                    let k = s.index[c] / (self.nodes.shape[1] * self.nodes.shape[2]);
                    if k >= k_range.0 && k < k_range.1 {
                        deposit(s.index[c], s.weight[c]);
                    }
                }
            }
            return;
        }
        let r2 = self.radius * self.radius;
        let (i0, i1) = self.range(x, 0);
        let (j0, j1) = self.range(x, 1);
        let (k0, k1) = self.range(x, 2);
        for k in k0.max(k_range.0)..k1.min(k_range.1) {
            for j in j0..j1 {
                for i in i0..i1 {
                    let d2 = (self.nodes.voxel_center(k, j, i) - x).norm_squared();
                    if d2 < r2 {
                        deposit(self.nodes.index(k, j, i), (1.0 - d2 / r2) / norm);
                    }
                }
            }
        }
    }

    /// Sum of the unnormalised kernel weights of a photon at `x` (0: no node in reach).
    fn kernel_sum(&self, x: &Vec3) -> f64 {
        let mut sum = 0.0;
        let r2 = self.radius * self.radius;
        let (i0, i1) = self.range(x, 0);
        let (j0, j1) = self.range(x, 1);
        let (k0, k1) = self.range(x, 2);
        for k in k0..k1 {
            for j in j0..j1 {
                for i in i0..i1 {
                    let d2 = (self.nodes.voxel_center(k, j, i) - x).norm_squared();
                    if d2 < r2 {
                        sum += 1.0 - d2 / r2;
                    }
                }
            }
        }
        sum
    }

    /// Per-photon normalisers (parallel, in photon order).
    pub fn normalisers(&self, photons: &[Photon]) -> Vec<f64> {
        photons
            .par_iter()
            .map(|p| self.kernel_sum(&p.pos))
            .collect()
    }

    /// For each camera position, the in-scattered radiance per unit length
    /// `albedo * sum_p p_HG * power * K` towards that camera, on the nodes.
    /// Deterministic: every node sums its photons in photon order.
    pub fn estimate(
        &self,
        photons: &[Photon],
        norms: &[f64],
        cameras: &[Vec3],
        albedo: f64,
        g: f64,
    ) -> Vec<Grid<f64>> {
        let [nz, ny, nx] = self.nodes.shape;
        let cell_volume = (self.nodes.hi - self.nodes.lo).product() / (nx * ny * nz) as f64;
        let chunk = 4usize;
        let n_chunks = nz.div_ceil(chunk);
        let plane = ny * nx;
        let slabs: Vec<Vec<f64>> = (0..cameras.len() * n_chunks)
            .into_par_iter()
            .map(|task| {
                let (cam, c) = (task / n_chunks, task % n_chunks);
                let k_range = (c * chunk, ((c + 1) * chunk).min(nz));
                let mut slab = vec![0.0; (k_range.1 - k_range.0) * plane];
                for (p, &norm) in photons.iter().zip(norms) {
                    let (k0, k1) = self.range(&p.pos, 2);
                    let reach = if norm == 0.0 {
                        (k0.saturating_sub(1), k1 + 1)
                    } else {
                        (k0, k1)
                    };
                    if reach.1 <= k_range.0 || reach.0 >= k_range.1 {
                        continue;
                    }
                    let to_cam = cameras[cam] - p.pos;
                    let dist = to_cam.norm();
                    if dist == 0.0 {
                        continue;
                    }
                    let value =
                        albedo * hg_eval(g, p.dir.dot(&(to_cam / dist))) * p.power / cell_volume;
                    self.for_each_weight(&p.pos, norm, k_range, |idx, w| {
                        slab[idx - k_range.0 * plane] += w * value
                    });
                }
                slab
            })
            .collect();
        slabs
            .chunks(n_chunks)
            .map(|cam_slabs| {
                let data: Vec<f64> = cam_slabs.iter().flatten().copied().collect();
                Grid::new(self.nodes.lo, self.nodes.hi, self.nodes.shape, data)
            })
            .collect()
    }
}
