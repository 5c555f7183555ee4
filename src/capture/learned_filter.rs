//! A learned linear filter from a fitted density to the true one: each
//! voxel's true density as a weighted sum of the fitted density over the
//! (2r+1)^3 voxels around it, plus a constant, the weights found by ridge
//! regression over the voxels of fits whose truth is known (made captures).
//!
//! Why: four views leave each fit's fine detail misplaced along their
//! rays, and through one rig the misplacement has a shape of its own (the
//! rays' directions are fixed). A filter learned on plumes made through
//! the same cameras may learn to undo part of it, where a generic prior
//! (smoothness, total variation) can only remove detail.

use crate::error::{Error, Result};
use crate::volume::Grid;
use nalgebra::{DMatrix, DVector};

/// The normal equations of the ridge regression, summed over voxels.
#[derive(Clone, Debug)]
pub struct Normal {
    radius: usize,
    /// Sum of x x^T over the voxels (x: the neighbourhood, then 1).
    xtx: DMatrix<f64>,
    /// Sum of x y.
    xty: DVector<f64>,
    /// Voxels summed.
    pub voxels: usize,
}

/// The learned weights: one per neighbour (z, y, x order, each from -r to
/// r), then the constant.
#[derive(Clone, Debug, PartialEq)]
pub struct Filter {
    /// Voxels each way of the neighbourhood.
    pub radius: usize,
    /// (2 radius + 1)^3 weights, then the constant.
    pub weights: Vec<f64>,
}

/// The fitted density over the neighbourhood of voxel (k, j, i), edge voxels
/// repeated beyond the faces, then 1.
fn features(fitted: &Grid<f64>, radius: usize, k: usize, j: usize, i: usize, out: &mut Vec<f64>) {
    out.clear();
    let r = radius as isize;
    let [nz, ny, nx] = fitted.shape.map(|n| n as isize);
    for dk in -r..=r {
        let kk = (k as isize + dk).clamp(0, nz - 1) as usize;
        for dj in -r..=r {
            let jj = (j as isize + dj).clamp(0, ny - 1) as usize;
            for di in -r..=r {
                let ii = (i as isize + di).clamp(0, nx - 1) as usize;
                out.push(fitted.data[fitted.index(kk, jj, ii)]);
            }
        }
    }
    out.push(1.0);
}

impl Normal {
    /// Empty sums for neighbourhoods of `radius` voxels each way.
    pub fn new(radius: usize) -> Normal {
        let n = (2 * radius + 1).pow(3) + 1;
        Normal { radius, xtx: DMatrix::zeros(n, n), xty: DVector::zeros(n), voxels: 0 }
    }

    /// Adds every voxel where `fitted` is above 0 (inside its fit's hull),
    /// with `truth` (same grid) as the target.
    pub fn add(&mut self, fitted: &Grid<f64>, truth: &Grid<f64>) -> Result<()> {
        if fitted.shape != truth.shape {
            return Err(Error(format!("fitted grid {:?} against truth {:?}", fitted.shape, truth.shape)));
        }
        let [nz, ny, nx] = fitted.shape;
        let mut x = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let v = fitted.index(k, j, i);
                    if fitted.data[v] <= 0.0 {
                        continue;
                    }
                    features(fitted, self.radius, k, j, i, &mut x);
                    let x = DVector::from_column_slice(&x);
                    self.xtx.ger(1.0, &x, &x, 1.0);
                    self.xty.axpy(truth.data[v], &x, 1.0);
                    self.voxels += 1;
                }
            }
        }
        Ok(())
    }

    /// The weights that minimise the squared error plus `ridge` times the
    /// mean diagonal of the sums times the weights' squared norm (the
    /// constant not penalised).
    pub fn solve(&self, ridge: f64) -> Result<Filter> {
        if self.voxels == 0 {
            return Err(Error("the learned filter has no voxel to learn from".into()));
        }
        let n = self.xty.len();
        let scale = (0..n - 1).map(|d| self.xtx[(d, d)]).sum::<f64>() / (n - 1) as f64;
        let mut a = self.xtx.clone();
        for d in 0..n - 1 {
            a[(d, d)] += ridge * scale;
        }
        let weights = a
            .cholesky()
            .ok_or_else(|| Error("the learned filter's equations are singular: add ridge".into()))?
            .solve(&self.xty);
        if weights.iter().any(|w| !w.is_finite()) {
            return Err(Error("the learned filter's weights are not finite".into()));
        }
        Ok(Filter { radius: self.radius, weights: weights.iter().copied().collect() })
    }
}

impl Filter {
    /// `fitted` filtered, voxel by voxel where it is above 0, and at least
    /// 0 (0 where it is 0: outside its fit's hull).
    pub fn apply(&self, fitted: &Grid<f64>) -> Grid<f64> {
        let [nz, ny, nx] = fitted.shape;
        let mut data = vec![0.0; fitted.len()];
        let mut x = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let v = fitted.index(k, j, i);
                    if fitted.data[v] > 0.0 {
                        features(fitted, self.radius, k, j, i, &mut x);
                        data[v] = x.iter().zip(&self.weights).map(|(a, w)| a * w).sum::<f64>().max(0.0);
                    }
                }
            }
        }
        Grid::new(fitted.lo, fitted.hi, fitted.shape, data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::rng::Rng;

    fn random_grid(seed: u64) -> Grid<f64> {
        let mut rng = Rng::from_seed(seed);
        let data = (0..8 * 9 * 10).map(|_| 0.1 + rng.uniform()).collect();
        Grid::new(Vec3::zeros(), Vec3::from_element(1.0), [8, 9, 10], data)
    }

    #[test]
    fn it_learns_a_known_filter_and_applies_it() {
        // The truth: twice the voxel, minus half its upper neighbour, plus 0.3.
        let truth_of = |g: &Grid<f64>| {
            let mut t = g.clone();
            for k in 0..8 {
                for j in 0..9 {
                    for i in 0..10 {
                        let up = g.data[g.index(k, (j + 1).min(8), i)];
                        t.data[g.index(k, j, i)] = 2.0 * g.data[g.index(k, j, i)] - 0.5 * up + 0.3;
                    }
                }
            }
            t
        };
        let mut normal = Normal::new(1);
        for seed in 0..2 {
            let fitted = random_grid(seed);
            normal.add(&fitted, &truth_of(&fitted)).unwrap();
        }
        assert_eq!(normal.voxels, 2 * 720);
        let filter = normal.solve(1e-12).unwrap();
        // Neighbourhood index of (dk, dj, di): 9 (dk + 1) + 3 (dj + 1) + (di + 1).
        let expected = |n: usize| match n {
            13 => 2.0,
            16 => -0.5,
            27 => 0.3,
            _ => 0.0,
        };
        for (n, w) in filter.weights.iter().enumerate() {
            assert!((w - expected(n)).abs() < 1e-6, "weight {n}: {w}");
        }
        // Applied to a grid it never saw: the truth, clipped at 0, and 0 outside the hull.
        let mut unseen = random_grid(7);
        unseen.data[0] = 0.0;
        let filtered = filter.apply(&unseen);
        let truth = truth_of(&unseen);
        assert_eq!(filtered.data[0], 0.0);
        for v in 1..unseen.len() {
            assert!((filtered.data[v] - truth.data[v].max(0.0)).abs() < 1e-6);
        }
        // A ridge pulls the weights towards 0.
        let shrunk = normal.solve(10.0).unwrap();
        assert!(shrunk.weights[13].abs() < 2.0);
    }
}
