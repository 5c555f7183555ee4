//! The density grid: cell-centred samples on a box, trilinear in between
//! (docs/DESIGN.md §1).
//!
//! Voxel `(k, j, i)` of the `(Z, Y, X)` array has its centre at
//! `lo + ((i+0.5)/X, (j+0.5)/Y, (k+0.5)/Z) * (hi - lo)`. Between centres the
//! value is trilinear; in the outer half-voxel shell it is clamped to the
//! edge value; outside the box it is 0.

use crate::ad::Real;
use crate::math::Vec3;
use crate::par;
use rayon::prelude::*;

/// Values on a regular grid over the box `[lo, hi]`, stored in C order of
/// shape `(nz, ny, nx)`: index `(k * ny + j) * nx + i`.
#[derive(Debug)]
pub struct Grid<T> {
    /// Lower corner of the box (world units).
    pub lo: Vec3,
    /// Upper corner of the box (world units), componentwise above `lo`.
    pub hi: Vec3,
    /// Shape `[nz, ny, nx]`, each at least 1.
    pub shape: [usize; 3],
    /// The values, C order.
    pub data: Vec<T>,
    /// Voxels per world unit along x, y, z (cached for lookups).
    to_voxel: Vec3,
}

/// The values are copied in parallel where large ([`par::cloned`]).
impl<T: Clone + Send + Sync> Clone for Grid<T> {
    fn clone(&self) -> Self {
        Grid { data: par::cloned(&self.data), ..*self }
    }
}

/// The 8 voxels (flat indices) and trilinear weights that make up the value
/// at one point. Weights are non-negative and sum to 1.
#[derive(Clone, Copy, Debug)]
pub struct Stencil {
    /// Flat voxel indices.
    pub index: [usize; 8],
    /// Trilinear weights.
    pub weight: [f64; 8],
}

impl<T: Copy> Grid<T> {
    /// A grid holding `data` (C order, `shape = [nz, ny, nx]`).
    pub fn new(lo: Vec3, hi: Vec3, shape: [usize; 3], data: Vec<T>) -> Self {
        assert_eq!(data.len(), shape.iter().product::<usize>(), "grid data does not match its shape");
        let e = hi - lo;
        let to_voxel = Vec3::new(shape[2] as f64 / e.x, shape[1] as f64 / e.y, shape[0] as f64 / e.z);
        Grid { lo, hi, shape, data, to_voxel }
    }

    /// A grid of the same geometry holding `f` of every value.
    pub fn map<U: Copy>(&self, f: impl Fn(T) -> U) -> Grid<U> {
        Grid {
            lo: self.lo,
            hi: self.hi,
            shape: self.shape,
            data: self.data.iter().map(|&v| f(v)).collect(),
            to_voxel: self.to_voxel,
        }
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True if the grid has no voxels (never, for a validated grid).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Flat index of voxel `(k, j, i)`.
    #[inline]
    pub fn index(&self, k: usize, j: usize, i: usize) -> usize {
        (k * self.shape[1] + j) * self.shape[2] + i
    }

    /// Voxel size along x, y, z (world units).
    pub fn voxel_size(&self) -> Vec3 {
        let e = self.hi - self.lo;
        Vec3::new(e.x / self.shape[2] as f64, e.y / self.shape[1] as f64, e.z / self.shape[0] as f64)
    }

    /// World position of the centre of voxel `(k, j, i)`.
    pub fn voxel_center(&self, k: usize, j: usize, i: usize) -> Vec3 {
        let v = self.voxel_size();
        self.lo + Vec3::new((i as f64 + 0.5) * v.x, (j as f64 + 0.5) * v.y, (k as f64 + 0.5) * v.z)
    }

    /// True if `p` lies in the closed box.
    #[inline]
    pub fn contains(&self, p: &Vec3) -> bool {
        (0..3).all(|a| p[a] >= self.lo[a] && p[a] <= self.hi[a])
    }

    /// Per axis (x, y, z): lower voxel index, index step to the upper one
    /// (0 on a one-voxel axis) and the upper one's weight; `None` outside the box.
    #[inline(always)]
    fn axes(&self, p: &Vec3) -> Option<([usize; 3], [usize; 3], [f64; 3])> {
        if !self.contains(p) {
            return None;
        }
        let mut lo_i = [0usize; 3];
        let mut step = [0usize; 3];
        let mut frac = [0f64; 3];
        for a in 0..3 {
            let n = self.shape[2 - a];
            let u = (p[a] - self.lo[a]) * self.to_voxel[a] - 0.5;
            // Clamping to [0, n-1] gives the edge value in the outer half-voxel shell.
            let u = u.clamp(0.0, (n - 1) as f64);
            let i0 = (u as usize).min(n.saturating_sub(2));
            lo_i[a] = i0;
            step[a] = usize::from(n > 1);
            frac[a] = u - i0 as f64;
        }
        Some((lo_i, step, frac))
    }

    /// The voxels and weights of the trilinear value at `p`, or `None` outside the box.
    #[inline]
    pub fn stencil(&self, p: &Vec3) -> Option<Stencil> {
        let (lo_i, step, frac) = self.axes(p)?;
        let mut s = Stencil { index: [0; 8], weight: [0.0; 8] };
        for c in 0..8 {
            let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let i = lo_i[0] + bx * step[0];
            let j = lo_i[1] + by * step[1];
            let k = lo_i[2] + bz * step[2];
            let wx = if bx == 1 { frac[0] } else { 1.0 - frac[0] };
            let wy = if by == 1 { frac[1] } else { 1.0 - frac[1] };
            let wz = if bz == 1 { frac[2] } else { 1.0 - frac[2] };
            s.index[c] = self.index(k, j, i);
            s.weight[c] = wx * wy * wz;
        }
        Some(s)
    }
}

impl<T: Copy> Grid<T> {
    /// The flat indices and weights of the trilinear value at `p`, or
    /// `None` outside the box. The weights are formed the same way for every
    /// grid, so equal values give bit-identical lookups.
    #[inline(always)]
    pub fn trilinear(&self, p: &Vec3) -> Option<([usize; 8], [f64; 8])> {
        let (lo_i, step, f) = self.axes(p)?;
        let (sx, sy, sz) = (step[0], step[1] * self.shape[2], step[2] * self.shape[1] * self.shape[2]);
        let base = self.index(lo_i[2], lo_i[1], lo_i[0]);
        let (gx, gy, gz) = (1.0 - f[0], 1.0 - f[1], 1.0 - f[2]);
        let (w00, w10, w01, w11) = (gy * gz, f[1] * gz, gy * f[2], f[1] * f[2]);
        let index = [
            base,
            base + sx,
            base + sy,
            base + sy + sx,
            base + sz,
            base + sz + sx,
            base + sz + sy,
            base + sz + sy + sx,
        ];
        let weights = [gx * w00, f[0] * w00, gx * w10, f[0] * w10, gx * w01, f[0] * w01, gx * w11, f[0] * w11];
        Some((index, weights))
    }
}

impl<R: Real> Grid<R> {
    /// The trilinear value at `p` (0 outside the box).
    #[inline(always)]
    pub fn at(&self, p: &Vec3) -> R {
        let Some((index, weights)) = self.trilinear(p) else { return R::cst(0.0) };
        // Weights in f64 first: 8 products of R by f64, the cheapest form for duals.
        R::weighted_sum8(index.map(|n| &self.data[n]), weights)
    }
}

impl Grid<f64> {
    /// Largest value (0 for an all-zero grid). In parallel: every render
    /// asks for it, and the maximum does not depend on the order.
    pub fn max_value(&self) -> f64 {
        self.data
            .par_iter()
            .with_min_len(par::copy_task_len::<f64>())
            .fold(|| 0.0, |m: f64, &v| m.max(v))
            .reduce(|| 0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Grid<f64> {
        // value = i + 10 j + 100 k on a 4x3x2 (x, y, z) grid over the unit box
        let shape = [2, 3, 4];
        let mut data = vec![];
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..4 {
                    data.push((i + 10 * j + 100 * k) as f64);
                }
            }
        }
        Grid::new(Vec3::zeros(), Vec3::from_element(1.0), shape, data)
    }

    #[test]
    fn centres_reproduce_voxel_values() {
        let g = ramp();
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..4 {
                    let v = g.at(&g.voxel_center(k, j, i));
                    assert!((v - (i + 10 * j + 100 * k) as f64).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn linear_between_centres_clamped_at_edges_zero_outside() {
        let g = ramp();
        let a = g.voxel_center(0, 1, 1);
        let b = g.voxel_center(0, 1, 2);
        assert!((g.at(&((a + b) * 0.5)) - 11.5).abs() < 1e-12);
        // Outer half-voxel shell in x: clamped to the edge value.
        assert!((g.at(&Vec3::new(0.01, a.y, a.z)) - 10.0).abs() < 1e-12);
        assert_eq!(g.at(&Vec3::new(-0.01, a.y, a.z)), 0.0);
        let w: f64 = g.stencil(&Vec3::new(0.3, 0.7, 0.2)).unwrap().weight.iter().sum();
        assert!((w - 1.0).abs() < 1e-12);
    }

    #[test]
    fn single_voxel_grid_is_constant() {
        let g = Grid::new(Vec3::zeros(), Vec3::from_element(1.0), [1, 1, 1], vec![2.5]);
        assert_eq!(g.at(&Vec3::new(0.1, 0.9, 0.5)), 2.5);
    }
}
