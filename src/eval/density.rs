//! How close an estimated density is to the truth, voxel by voxel and at
//! the scale the views can resolve (means over 2x2x2 blocks), with the
//! ceiling no method can pass: the truth against itself blurred by a
//! Gaussian of one voxel (its voxel-scale detail is random and no view
//! resolves it).

use super::metrics::{block_mask, block_means, pearson, rel_l1};
use crate::error::{Error, Result};
use crate::volume::Grid;
use serde::Serialize;

/// The density measures of one estimate.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DensityMetrics {
    /// Hull voxels the voxel measures are taken over.
    pub hull_voxels: usize,
    /// Pearson r over the hull voxels.
    pub pearson_r: f64,
    /// Relative L1 error over the hull voxels.
    pub rel_l1_epsilon: f64,
    /// Pearson r over the 2x2x2 blocks at least half inside the hull.
    pub block_pearson_r: f64,
    /// Relative L1 error over those blocks.
    pub block_rel_l1_epsilon: f64,
    /// Relative error of the total mass (signed); over one hull it is also
    /// the relative error of the mean density.
    pub mass_error: f64,
    /// Relative error of the largest voxel density (signed).
    pub max_error: f64,
    /// Relative error of the largest block density (signed).
    pub block_max_error: f64,
    /// The ceiling: r of the truth against the truth blurred by one voxel, over the hull voxels.
    pub blur_ceiling_r: f64,
    /// The truth's largest voxel density after that blur.
    pub blurred_truth_max: f64,
    /// Fraction of the truth's mass over the hull in voxels the estimate
    /// leaves at exactly 0 (a decoder's ReLU output is 0 in whole regions;
    /// a refinement by factors alone cannot fill them).
    pub empty_truth_mass: f64,
    /// Fraction of the estimate's mass over the hull in voxels where the
    /// truth is exactly 0: a haze the training views cannot rule out (the
    /// images then look too bright around the plume and too dim at its core).
    pub haze_mass: f64,
}

/// Measures `estimate` against `truth` (both cubic grids of one shape)
/// over the hull `mask`. A truth that is zero over the hull is an error:
/// relative errors against it are undefined.
pub fn density_metrics(estimate: &Grid<f64>, truth: &Grid<f64>, mask: &[bool]) -> Result<DensityMetrics> {
    let undefined = || Error::new("truth: zero over every hull voxel: relative density errors are undefined");
    let res = truth.shape[0];
    let (e, t) = (&estimate.data, &truth.data);
    let in_hull = |d: &[f64]| d.iter().zip(mask).filter(|(_, &m)| m).map(|(v, _)| *v).collect::<Vec<f64>>();
    let (eh, th) = (in_hull(e), in_hull(t));
    let sum = |v: &[f64]| v.iter().sum::<f64>();
    let max = |v: &[f64]| v.iter().fold(0.0f64, |a, &b| a.max(b));
    let rel = |a: f64, b: f64| if b != 0.0 { (a - b) / b } else { 0.0 };
    let (eb, tb, mb) = (block_means(e, res), block_means(t, res), block_mask(mask, res));
    let in_blocks = |d: &[f64]| d.iter().zip(&mb).filter(|(_, &m)| m).map(|(v, _)| *v).collect::<Vec<f64>>();
    let blurred = crate::volume::blur::gaussian_blur(truth, 1.0);
    Ok(DensityMetrics {
        hull_voxels: eh.len(),
        pearson_r: pearson(t, e, mask),
        rel_l1_epsilon: rel_l1(e, t, mask).ok_or_else(undefined)?,
        block_pearson_r: pearson(&tb, &eb, &mb),
        block_rel_l1_epsilon: rel_l1(&eb, &tb, &mb).ok_or_else(undefined)?,
        mass_error: rel(sum(&eh), sum(&th)),
        max_error: rel(max(&eh), max(&th)),
        block_max_error: rel(max(&in_blocks(&eb)), max(&in_blocks(&tb))),
        blur_ceiling_r: pearson(t, &blurred.data, mask),
        blurred_truth_max: max(&in_hull(&blurred.data)),
        empty_truth_mass: share_where(&th, &eh),
        haze_mass: share_where(&eh, &th),
    })
}

/// The fraction of `of`'s sum held where `zero` is exactly 0 (0 if `of` sums to 0).
fn share_where(of: &[f64], zero: &[f64]) -> f64 {
    let total: f64 = of.iter().sum();
    let held: f64 = of.iter().zip(zero).filter(|(_, &z)| z == 0.0).map(|(&v, _)| v).sum();
    if total > 0.0 {
        held / total
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scenes::blob;

    #[test]
    fn the_truth_scores_perfectly_and_a_scaled_estimate_only_in_scale() {
        let t = blob(16);
        let mask = vec![true; t.len()];
        let m = density_metrics(&t, &t, &mask).unwrap();
        assert!((m.pearson_r - 1.0).abs() < 1e-12 && m.rel_l1_epsilon == 0.0 && m.mass_error == 0.0);
        assert!((m.block_pearson_r - 1.0).abs() < 1e-12 && m.block_max_error == 0.0);
        assert!(m.blur_ceiling_r > 0.9 && m.blur_ceiling_r < 1.0, "{m:?}");
        assert_eq!(m.empty_truth_mass, 0.0);
        let mut e = t.clone();
        e.data.iter_mut().for_each(|v| *v *= 1.1);
        let m = density_metrics(&e, &t, &mask).unwrap();
        assert!((m.pearson_r - 1.0).abs() < 1e-12 && (m.mass_error - 0.1).abs() < 1e-12);
        assert!((m.max_error - 0.1).abs() < 1e-12 && (m.block_rel_l1_epsilon - 0.1).abs() < 1e-12);
        // An estimate empty in half the voxels misses the truth's mass there.
        let mut e = t.clone();
        e.data.iter_mut().step_by(2).for_each(|v| *v = 0.0);
        let missing: f64 = t.data.iter().step_by(2).sum::<f64>() / t.data.iter().sum::<f64>();
        assert!((density_metrics(&e, &t, &mask).unwrap().empty_truth_mass - missing).abs() < 1e-12);
        assert_eq!(density_metrics(&e, &t, &mask).unwrap().haze_mass, 0.0);
        // And the other way round: a haze where the truth is empty.
        let m = density_metrics(&t, &e, &mask).unwrap();
        assert!((m.haze_mass - missing).abs() < 1e-12 && m.empty_truth_mass == 0.0, "{m:?}");
    }
}
