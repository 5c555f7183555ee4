//! Forward mode: `num-dual`'s dual numbers as [`Real`]. `Dual64` carries one
//! directional derivative, `DualSVec64<K>` carries K at once; a constant
//! `DualSVec64` holds no tangent at all (`Derivative(None)`) and costs about
//! as much as an `f64`, which is how work on paths no parameter reaches is
//! left out.

use super::Real;
use num_dual::{Dual64, DualNum, DualSVec64};

impl<const K: usize> Real for DualSVec64<K> {
    #[inline]
    fn cst(x: f64) -> Self {
        DualSVec64::from_re(x)
    }
    #[inline]
    fn re(&self) -> f64 {
        self.re
    }
    #[inline]
    fn exp(self) -> Self {
        DualNum::exp(&self)
    }
    #[inline]
    fn exp_m1(self) -> Self {
        DualNum::exp_m1(&self)
    }
    #[inline]
    fn is_exact_zero(&self) -> bool {
        self.re == 0.0 && self.eps.0.as_ref().is_none_or(|e| e.iter().all(|v| *v == 0.0))
    }
}

impl Real for Dual64 {
    #[inline]
    fn cst(x: f64) -> Self {
        Dual64::from_re(x)
    }
    #[inline]
    fn re(&self) -> f64 {
        self.re
    }
    #[inline]
    fn exp(self) -> Self {
        DualNum::exp(&self)
    }
    #[inline]
    fn exp_m1(self) -> Self {
        DualNum::exp_m1(&self)
    }
    #[inline]
    fn is_exact_zero(&self) -> bool {
        self.re == 0.0 && self.eps == 0.0
    }
}

/// Tangent `k` of a vector dual (0 for a constant).
#[inline]
pub fn lane<const K: usize>(x: &DualSVec64<K>, k: usize) -> f64 {
    x.eps.0.as_ref().map_or(0.0, |e| e[k])
}

/// A vector dual with value `re` and tangents `eps`.
pub fn with_tangents<const K: usize>(re: f64, eps: [f64; K]) -> DualSVec64<K> {
    DualSVec64::new(re, num_dual::Derivative::some(nalgebra::SVector::from(eps)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vector_lanes_match_single_duals() {
        let x = with_tangents::<3>(0.7, [1.0, 0.0, -2.0]);
        let y = (-(x * 3.0)).exp() * x + x.one_minus_exp_over(0.5);
        for (k, t) in [1.0, 0.0, -2.0].into_iter().enumerate() {
            let d = Dual64::new(0.7, t);
            let e = (-(d * 3.0)).exp() * d + d.one_minus_exp_over(0.5);
            assert_eq!(lane(&y, k).to_bits(), e.eps.to_bits());
            assert_eq!(y.re.to_bits(), e.re.to_bits());
        }
    }

    #[test]
    fn constants_carry_no_tangent() {
        let c = DualSVec64::<8>::cst(2.0) * 3.0 + 1.0;
        assert!(c.eps.0.is_none());
        assert!(DualSVec64::<8>::cst(0.0).is_exact_zero());
    }
}
