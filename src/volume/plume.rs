//! Built-in smoke plume (temporary stand-in: a Gaussian column; being replaced).

use super::Grid;
use crate::math::Vec3;

/// Statistics of a density grid.
pub struct PlumeStats {
    /// Voxels > 0.
    pub occupied: usize,
    /// Mean over occupied voxels.
    pub mean_occupied: f64,
    /// Maximum.
    pub max: f64,
    /// Occupied fraction.
    pub fraction_occupied: f64,
}

/// Statistics of `grid`.
pub fn plume_stats(grid: &Grid<f64>) -> PlumeStats {
    let occ: Vec<f64> = grid.data.iter().copied().filter(|v| *v > 0.0).collect();
    let mean = if occ.is_empty() { 0.0 } else { occ.iter().sum::<f64>() / occ.len() as f64 };
    PlumeStats {
        occupied: occ.len(),
        mean_occupied: mean,
        max: grid.max_value(),
        fraction_occupied: occ.len() as f64 / grid.len() as f64,
    }
}

/// A stand-in plume.
pub fn plume(res: usize, _seed: u64) -> Grid<f64> {
    let mut g = Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [res; 3], vec![0.0; res * res * res]);
    for k in 0..res {
        for j in 0..res {
            for i in 0..res {
                let p = g.voxel_center(k, j, i);
                let v = 1.36 * (-(p.x * p.x + p.z * p.z) / (2.0 * 0.06f64.powi(2)) - (p.y + 0.1).powi(2) / 0.08).exp();
                let idx = g.index(k, j, i);
                g.data[idx] = if v < 0.01 { 0.0 } else { v };
            }
        }
    }
    g
}
