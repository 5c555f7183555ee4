//! Where `auto` shadows do not trust the light-depth grids: near voxels
//! whose optical depth across one node spacing exceeds
//! [`GRID_MAX_DEPTH`](crate::scene::GRID_MAX_DEPTH). Interpolating the
//! depth across such a voxel misses the transmittance by a fifth or more;
//! camera-ray samples whose interpolation can span one march their shadow
//! rays instead, and every other sample reads the grids. The cost then
//! follows the number of thick voxels, instead of a whole render switching
//! to marched shadow rays when a single voxel passes the limit. Decided on
//! the sampling density once per render, like the marching steps.

use crate::math::Vec3;
use crate::volume::Grid;

/// The voxels near a thick voxel, on the density's grid.
#[derive(Clone, Debug)]
pub struct ThickVoxels {
    lo: Vec3,
    /// Voxels per world unit, per axis (x, y, z).
    to_voxel: Vec3,
    /// The density's shape (z, y, x).
    shape: [usize; 3],
    /// Per voxel: a thick voxel lies within `cell` voxels along every axis.
    near: Vec<bool>,
    /// Number of thick voxels.
    count: usize,
}

impl ThickVoxels {
    /// The thick voxels of `density` (extinction `scale` per unit density)
    /// for light-depth nodes every `cell` voxels; `None` if there are none.
    pub fn new(density: &Grid<f64>, scale: f64, cell: usize) -> Option<Self> {
        let limit = crate::scene::grid_density_limit(density, scale, cell.max(1));
        let count = density.data.iter().filter(|&&v| v > limit).count();
        if count == 0 {
            return None;
        }
        // A sample's trilinear stencil spans at most `cell` voxels each way:
        // widen the thick voxels by that much, one axis at a time.
        let mut near: Vec<bool> = density.data.iter().map(|&v| v > limit).collect();
        let [nz, ny, nx] = density.shape;
        for (stride, n) in [(1, nx), (nx, ny), (nx * ny, nz)] {
            let from = near.clone();
            for (v, out) in near.iter_mut().enumerate() {
                let c = v / stride % n;
                let (a, b) = (c.saturating_sub(cell), (c + cell).min(n - 1));
                *out = (a..=b).any(|d| from[v - c * stride + d * stride]);
            }
        }
        let size = density.voxel_size();
        let to_voxel = Vec3::new(1.0 / size.x, 1.0 / size.y, 1.0 / size.z);
        Some(ThickVoxels { lo: density.lo, to_voxel, shape: density.shape, near, count })
    }

    /// Whether a sample at `p` may read the grids across a thick voxel.
    #[inline]
    pub fn near(&self, p: &Vec3) -> bool {
        let mut index = [0usize; 3];
        for a in 0..3 {
            let u = (p[a] - self.lo[a]) * self.to_voxel[a];
            let n = self.shape[2 - a];
            if !(0.0..=n as f64).contains(&u) {
                return false;
            }
            index[a] = (u as usize).min(n - 1);
        }
        self.near[(index[2] * self.shape[1] + index[1]) * self.shape[2] + index[0]]
    }

    /// Number of thick voxels.
    pub fn count(&self) -> usize {
        self.count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, thick: &[(usize, usize, usize)]) -> Grid<f64> {
        let mut g = Grid::new(Vec3::zeros(), Vec3::from_element(n as f64), [n; 3], vec![0.5; n * n * n]);
        for &(k, j, i) in thick {
            let v = g.index(k, j, i);
            g.data[v] = 3.0;
        }
        g
    }

    /// Thin media have none; a thick voxel marks the voxels within `cell`
    /// of it along every axis, and only those.
    #[test]
    fn marks_the_voxels_within_a_node_spacing() {
        assert!(ThickVoxels::new(&grid(8, &[]), 1.0, 1).is_none());
        // 0.5 per voxel: thick across 3 voxels, not across 1.
        assert!(ThickVoxels::new(&grid(8, &[]), 1.0, 3).is_some_and(|t| t.count() == 512));
        for cell in [1, 2] {
            let t = ThickVoxels::new(&grid(8, &[(4, 2, 6)]), 1.0, cell).unwrap();
            assert_eq!(t.count(), 1);
            for k in 0..8usize {
                for j in 0..8usize {
                    for i in 0..8usize {
                        let want = k.abs_diff(4) <= cell && j.abs_diff(2) <= cell && i.abs_diff(6) <= cell;
                        let p = Vec3::new(i as f64 + 0.3, j as f64 + 0.7, k as f64 + 0.5);
                        assert_eq!(t.near(&p), want, "cell {cell}, voxel ({k}, {j}, {i})");
                    }
                }
            }
            assert!(!t.near(&Vec3::new(6.5, 2.5, -0.1)), "outside the box");
        }
    }
}
