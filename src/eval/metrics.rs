//! Error metrics: of images (relative RMSE, also over block means with a
//! reference's own Monte Carlo noise subtracted) and of densities over the
//! hull voxels (mean and max, relative L1 error, Pearson r).

use crate::image::Image;

/// What a terminal line or a table shows for an undefined score (a
/// relative error against a black image, a PSNR of an exact one).
pub const UNDEFINED: &str = "undefined";

/// `v` times `scale` to `decimals` places, then `unit`; [`UNDEFINED`] for `None`.
pub fn show_score(v: Option<f64>, scale: f64, decimals: usize, unit: &str) -> String {
    v.map_or_else(|| UNDEFINED.to_string(), |v| format!("{:.*}{unit}", decimals, scale * v))
}

/// Sums over all camera pairs: (sum of squared block differences, sum of
/// reference block noise variances, sum of squared reference blocks, blocks).
fn block_sums(ours: &[Image], reference: &[Image], std_err: Option<&[Image]>, b: usize) -> (f64, f64, f64, usize) {
    let (mut diff2, mut noise, mut ref2, mut count) = (0.0, 0.0, 0.0, 0);
    for (c, (o, r)) in ours.iter().zip(reference).enumerate() {
        let (ob, rb) = (o.block_means(b), r.block_means(b));
        if let Some(se) = std_err {
            let var =
                Image { width: se[c].width, height: se[c].height, data: se[c].data.iter().map(|s| s * s).collect() };
            // Variance of a block mean of independent pixels: sum of variances / (b^2)^2.
            noise += var.block_means(b).iter().sum::<f64>() / (b * b) as f64;
        }
        diff2 += ob.iter().zip(&rb).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
        ref2 += rb.iter().map(|y| y * y).sum::<f64>();
        count += rb.len();
    }
    (diff2, noise, ref2, count)
}

/// `sqrt(mean((ours_b - ref_b)^2) - mean(var_b)) / sqrt(mean(ref_b^2))` over
/// `b x b` block means of all cameras, where `var_b` is the reference's
/// noise variance of each block mean (from its standard-error images; none
/// subtracted if `std_err` is `None`). 0 if the difference is below the
/// noise; `None` against an all-black reference (a relative error is
/// undefined there, and writers leave its cell empty).
pub fn block_rel_rmse(ours: &[Image], reference: &[Image], std_err: Option<&[Image]>, b: usize) -> Option<f64> {
    let (diff2, noise, ref2, n) = block_sums(ours, reference, std_err, b);
    if ref2 == 0.0 || n == 0 {
        return None;
    }
    Some(((diff2 - noise).max(0.0) / n as f64).sqrt() / (ref2 / n as f64).sqrt())
}

/// The reference's own noise on the same scale: `sqrt(mean(var_b)) / sqrt(mean(ref_b^2))`.
pub fn reference_noise(reference: &[Image], std_err: &[Image], b: usize) -> f64 {
    let (_, noise, ref2, n) = block_sums(reference, reference, Some(std_err), b);
    if ref2 == 0.0 {
        return 0.0;
    }
    (noise / n as f64).sqrt() / (ref2 / n as f64).sqrt()
}

/// Relative difference of the summed radiance of all images.
pub fn rel_mean_diff(ours: &[Image], reference: &[Image]) -> f64 {
    let sum = |v: &[Image]| v.iter().map(|i| i.data.iter().sum::<f64>()).sum::<f64>();
    let r = sum(reference);
    if r == 0.0 {
        0.0
    } else {
        (sum(ours) - r) / r
    }
}

/// Relative RMSE of `ours` against `reference`; `None` when the reference
/// is all zero (the relative error is undefined there).
///
/// ```
/// use dualphoton::eval::metrics::rel_rmse;
/// assert_eq!(rel_rmse(&[2.0, 0.0], &[1.0, 0.0]), Some(1.0));
/// assert_eq!(rel_rmse(&[2.0], &[0.0]), None);
/// ```
pub fn rel_rmse(ours: &[f64], reference: &[f64]) -> Option<f64> {
    let num: f64 = ours.iter().zip(reference).map(|(a, b)| (a - b).powi(2)).sum();
    let den: f64 = reference.iter().map(|b| b * b).sum();
    (den > 0.0).then(|| (num / den).sqrt())
}

/// Relative L1 error `|a - b|_1 / |b|_1` over the masked voxels; `None`
/// when `b` is zero over them (the relative error is undefined there).
pub fn rel_l1(a: &[f64], b: &[f64], mask: &[bool]) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..a.len() {
        if mask[i] {
            num += (a[i] - b[i]).abs();
            den += b[i].abs();
        }
    }
    (den > 0.0).then(|| num / den)
}

/// Density statistics over the hull voxels.
#[derive(Clone, Copy, Debug)]
pub struct HullStats {
    /// Mean density.
    pub mean: f64,
    /// Largest density.
    pub max: f64,
}

/// Mean and max of `d` over the `mask` voxels.
pub fn hull_stats(d: &[f64], mask: &[bool]) -> HullStats {
    let v: Vec<f64> = d.iter().zip(mask).filter(|(_, &m)| m).map(|(x, _)| *x).collect();
    HullStats { mean: v.iter().sum::<f64>() / v.len().max(1) as f64, max: v.iter().fold(0.0, |a: f64, &b| a.max(b)) }
}

/// Means over the 2x2x2 blocks of a cubic `res`^3 grid `d` (C order), in C
/// order over the `(res/2)^3` blocks (an odd last layer is left out): the
/// density at the scale a few views of `res` pixels can resolve.
///
/// ```
/// let d: Vec<f64> = (0..64).map(|v| v as f64).collect();
/// let b = dualphoton::eval::metrics::block_means(&d, 4);
/// assert_eq!(b.len(), 8);
/// assert_eq!(b[0], (0.0 + 1.0 + 4.0 + 5.0 + 16.0 + 17.0 + 20.0 + 21.0) / 8.0);
/// ```
pub fn block_means(d: &[f64], res: usize) -> Vec<f64> {
    let h = res / 2;
    let mut out = vec![0.0; h * h * h];
    for (b, o) in out.iter_mut().enumerate() {
        let (k, j, i) = (b / (h * h), (b / h) % h, b % h);
        let mut s = 0.0;
        for c in 0..8 {
            let (z, y, x) = (2 * k + c / 4, 2 * j + (c / 2) % 2, 2 * i + c % 2);
            s += d[(z * res + y) * res + x];
        }
        *o = s / 8.0;
    }
    out
}

/// The 2x2x2 blocks of a `res`^3 `mask` (as [`block_means`]) at least half inside it.
pub fn block_mask(mask: &[bool], res: usize) -> Vec<bool> {
    let m: Vec<f64> = mask.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
    block_means(&m, res).iter().map(|&f| f >= 0.5).collect()
}

/// Pearson correlation of `a` and `b` over the `mask` voxels.
pub fn pearson(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    let idx: Vec<usize> = (0..a.len()).filter(|&i| mask[i]).collect();
    let n = idx.len().max(1) as f64;
    let (ma, mb) = (idx.iter().map(|&i| a[i]).sum::<f64>() / n, idx.iter().map(|&i| b[i]).sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for &i in &idx {
        sab += (a[i] - ma) * (b[i] - mb);
        saa += (a[i] - ma).powi(2);
        sbb += (b[i] - mb).powi(2);
    }
    if saa == 0.0 || sbb == 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}
