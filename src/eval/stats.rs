//! Small statistics over repeated measurements: medians of noisy timings,
//! and how a set of random gradient estimates compares with the exact
//! gradient and a reference (variance, bias, cosine, mean squared error).

/// The median of `xs` (the upper one of an even count). Every caller
/// measures at least once (its options are checked first): an empty `xs`
/// is a bug, and panics rather than return a NaN that could reach a file.
pub fn median(xs: &[f64]) -> f64 {
    assert!(!xs.is_empty(), "the median of no measurements");
    let mut v = xs.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// `a · b`.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `|a|^2`.
pub fn norm2(a: &[f64]) -> f64 {
    dot(a, a)
}

/// `|a - b|^2`.
pub fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum()
}

/// The cosine of the angle between `a` and `b`; 0 if either is zero.
pub fn cosine(a: &[f64], b: &[f64]) -> f64 {
    let d = (norm2(a) * norm2(b)).sqrt();
    if d > 0.0 {
        dot(a, b) / d
    } else {
        0.0
    }
}

/// The mean of equally long vectors (empty if there are none).
pub fn mean(xs: &[Vec<f64>]) -> Vec<f64> {
    let mut m = vec![0.0; xs.first().map_or(0, Vec::len)];
    for x in xs {
        m.iter_mut().zip(x).for_each(|(a, b)| *a += b / xs.len() as f64);
    }
    m
}

/// Unbiased total variance (trace of the covariance) of the vectors. It
/// needs two or more (`grad_variance` refuses fewer seeds before any
/// work); fewer is a bug, and panics rather than return a NaN.
pub fn total_variance(xs: &[Vec<f64>]) -> f64 {
    assert!(xs.len() >= 2, "the variance of fewer than two estimates");
    let m = mean(xs);
    xs.iter().map(|x| dist2(x, &m)).sum::<f64>() / (xs.len() - 1) as f64
}

/// How independent estimates `g_hat` of a gradient compare with a
/// reference `g_ref` (the mean of `refs`, noisy itself) and, sample by
/// sample, with the exact gradient `g` of the same frozen estimator.
/// Squared quantities are relative to `|g_ref|^2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimateStats {
    /// Parameters.
    pub n: usize,
    /// Total variance of the estimates / `|g_ref|^2`.
    pub rel_variance: f64,
    /// `|mean - g_ref| / |g_ref|`.
    pub bias: f64,
    /// The bias noise alone would give: the standard errors of the mean and of the reference.
    pub bias_floor: f64,
    /// Mean `|g_hat - g_ref|^2 / |g_ref|^2` (variance + bias^2: the fair measure for biased estimators).
    pub rel_mse: f64,
    /// Mean cosine of one estimate with `g_ref`.
    pub cosine_mean: f64,
    /// Cosine of the mean of the estimates with `g_ref`.
    pub cosine_of_mean: f64,
    /// Mean `|g_hat - g|^2 / |g|^2`: the estimator's own noise, the renderer's excluded.
    pub estimator_noise: f64,
}

impl EstimateStats {
    /// The statistics of `estimates`; `exact[i]` is the exact gradient on
    /// the samples of `estimates[i]`; `refs` are the reference's seeds.
    pub fn of(estimates: &[Vec<f64>], exact: &[Vec<f64>], refs: &[Vec<f64>]) -> Self {
        let xs = estimates;
        let g_ref = mean(refs);
        let g2 = norm2(&g_ref).max(f64::MIN_POSITIVE);
        let m = mean(xs);
        let var = total_variance(xs);
        let ref_var = if refs.len() > 1 { total_variance(refs) / refs.len() as f64 } else { 0.0 };
        let own: Vec<f64> = xs.iter().zip(exact).map(|(x, g)| dist2(x, g) / norm2(g).max(f64::MIN_POSITIVE)).collect();
        EstimateStats {
            n: g_ref.len(),
            rel_variance: var / g2,
            bias: (dist2(&m, &g_ref) / g2).sqrt(),
            bias_floor: ((var / xs.len() as f64 + ref_var) / g2).sqrt(),
            rel_mse: xs.iter().map(|x| dist2(x, &g_ref)).sum::<f64>() / xs.len() as f64 / g2,
            cosine_mean: xs.iter().map(|x| cosine(x, &g_ref)).sum::<f64>() / xs.len() as f64,
            cosine_of_mean: cosine(&m, &g_ref),
            estimator_noise: own.iter().sum::<f64>() / own.len() as f64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 3.0);
    }

    #[test]
    #[should_panic(expected = "the variance of fewer than two estimates")]
    fn the_variance_of_one_estimate_is_refused() {
        total_variance(&[vec![1.0]]);
    }

    #[test]
    #[should_panic(expected = "the median of no measurements")]
    fn the_median_of_nothing_is_refused() {
        median(&[]);
    }

    #[test]
    fn vector_statistics() {
        let xs = vec![vec![1.0, 0.0], vec![3.0, 2.0]];
        assert_eq!(mean(&xs), vec![2.0, 1.0]);
        assert_eq!(total_variance(&xs), 4.0);
        assert_eq!(dist2(&xs[0], &xs[1]), 8.0);
        assert!((cosine(&[1.0, 1.0], &[2.0, 0.0]) - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(cosine(&[0.0, 0.0], &[1.0, 0.0]), 0.0);
    }

    #[test]
    fn exact_estimates_have_no_variance_bias_or_own_noise() {
        let g = vec![vec![1.0, -2.0, 0.5]; 2];
        let s = EstimateStats::of(&g, &g, &g);
        assert_eq!((s.n, s.rel_variance, s.bias, s.rel_mse, s.estimator_noise), (3, 0.0, 0.0, 0.0, 0.0));
        assert!((s.cosine_mean - 1.0).abs() < 1e-15 && (s.cosine_of_mean - 1.0).abs() < 1e-15);
    }
}
