//! Forward mode: `num-dual`'s dual numbers as [`Real`]. `Dual64` carries one
//! directional derivative, `DualSVec64<K>` carries K at once; a constant
//! `DualSVec64` holds no tangent at all (`Derivative(None)`) and costs about
//! as much as an `f64`, which is how work on paths no parameter reaches is
//! left out.

use super::Real;
use nalgebra::{Const, U1};
use num_dual::{Derivative, Dual64, DualNum, DualSVec64};

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
    /// The default's operations lane by lane, in place: `v * w` then `+=`,
    /// where a value without tangent adds nothing and the first tangent is
    /// taken as it is (num-dual's rules), so the bits are the default's.
    #[inline]
    fn weighted_sum8(values: [&Self; 8], weights: [f64; 8]) -> Self {
        let mut re = values[0].re * weights[0];
        for c in 1..8 {
            re += values[c].re * weights[c];
        }
        let mut eps = Derivative::none();
        for (v, &w) in values.iter().zip(&weights) {
            add_tangent(&mut eps, &v.eps, w);
        }
        DualSVec64::new(re, eps)
    }
    /// Lane by lane `x * w` then `+=`, by num-dual's rules for a missing tangent.
    #[inline]
    fn add_scaled(&mut self, x: &Self, w: f64) {
        self.re += x.re * w;
        add_tangent(&mut self.eps, &x.eps, w);
    }
}

/// `sum += x * w` on tangents, in place, as num-dual's `+=` of a product
/// does it: a missing `x` adds nothing, a missing `sum` becomes `x * w`.
#[inline]
fn add_tangent<const K: usize>(sum: &mut Derivative<f64, Const<K>, U1>, x: &Derivative<f64, Const<K>, U1>, w: f64) {
    let Some(e) = x.0.as_ref() else { return };
    match sum.0.as_mut() {
        None => *sum = Derivative::some(e * w),
        Some(s) => s.as_mut_slice().iter_mut().zip(e.as_slice()).for_each(|(s, x)| *s += x * w),
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

    /// The in-place trilinear sum gives the bits of the generic one, with
    /// constants (no tangent) first, between and last.
    #[test]
    fn weighted_sum_in_place_is_the_generic_sum() {
        let weights = [0.3, 0.1, 1e-9, 0.2, 0.15, 0.05, 0.7, 1.0 / 3.0];
        for constants in [0b0000_0000u8, 0b0000_0011, 0b1010_0101, 0b1000_0000, 0b1111_1111] {
            let values: Vec<DualSVec64<4>> = (0..8)
                .map(|c| match constants >> c & 1 {
                    1 => DualSVec64::from_re(0.1 * c as f64 - 0.25),
                    _ => with_tangents::<4>(1.0 / (c + 1) as f64, [c as f64, -0.0, 1e-300, 1.0 / 7.0]),
                })
                .collect();
            let refs: [&DualSVec64<4>; 8] = std::array::from_fn(|c| &values[c]);
            let got = DualSVec64::<4>::weighted_sum8(refs, weights);
            let mut want = values[0] * weights[0];
            for c in 1..8 {
                want += values[c] * weights[c];
            }
            assert_eq!(got.re.to_bits(), want.re.to_bits(), "constants {constants:08b}");
            assert_eq!(got.eps.0.is_some(), want.eps.0.is_some(), "constants {constants:08b}");
            for k in 0..4 {
                assert_eq!(lane(&got, k).to_bits(), lane(&want, k).to_bits(), "constants {constants:08b}, lane {k}");
            }
        }
    }

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
