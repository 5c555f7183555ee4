//! The number interface the renderer is written against.
//!
//! Everything that a density can change (extinction, transmittance, path
//! weights, pixel values) is computed in a type `R: Real`; everything that is
//! a sampling decision (positions, directions, distances) stays `f64`
//! (docs/DESIGN.md §3, detached sampling). `f64` implements `Real` here; the dual
//! and reverse-mode types implement it in their own modules.

pub mod dual;
pub mod tape;

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub};

/// A scalar that may carry derivatives. Narrow on purpose: only what the
/// transport code needs. Mixed arithmetic with plain `f64` never creates
/// tangent work for the plain operand.
pub trait Real:
    Copy
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign
    + MulAssign
{
    /// A constant (no derivative).
    fn cst(x: f64) -> Self;
    /// The primal value, used for sampling decisions.
    fn re(&self) -> f64;
    /// `e^self`.
    fn exp(self) -> Self;
    /// `e^self - 1`, accurate near 0.
    fn exp_m1(self) -> Self;
    /// True if the value and every derivative are exactly zero, so that
    /// work multiplied by it can be left out without changing any result.
    fn is_exact_zero(&self) -> bool;
    /// `sum_c values[c] * weights[c]`: a trilinear lookup. Types may record
    /// it as one operation (the tape does: one node with eight parents) or
    /// sum in place (wide duals: copying eight of them cost more than the sum).
    /// Every type sums in this order, so the primal is the same bits as `f64`'s.
    #[inline]
    fn weighted_sum8(values: [&Self; 8], weights: [f64; 8]) -> Self {
        let mut s = *values[0] * weights[0];
        for c in 1..8 {
            s += *values[c] * weights[c];
        }
        s
    }
    /// `self += x * w`, with the operations of that expression (wide duals
    /// do it in place, without a product to copy).
    #[inline]
    fn add_scaled(&mut self, x: &Self, w: f64) {
        *self += *x * w;
    }
    /// `(1 - e^{-self * h}) / self`: the integral of `e^{-self t}` over
    /// `t in [0, h]`. Finite for `self = 0` (value `h`) and for huge `self`.
    /// It divides `Self` by `Self`, whose primal num-dual computes as a
    /// product with the reciprocal: call it on plain values (as the renderer
    /// does) where the primal must match `f64` bit for bit.
    fn one_minus_exp_over(self, h: f64) -> Self {
        let x = self.re() * h;
        if x.abs() < 1e-4 {
            // Series h (1 - x/2 + x^2/6): avoids 0/0 and keeps the tangent
            // (-h^2/2 at zero) instead of a NaN.
            let s = self * h;
            (Self::cst(1.0) - s * 0.5 + s * s * (1.0 / 6.0)) * h
        } else {
            (Self::cst(1.0) - (self * -h).exp()) / self
        }
    }
}

impl Real for f64 {
    #[inline]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline]
    fn re(&self) -> f64 {
        *self
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn exp_m1(self) -> Self {
        f64::exp_m1(self)
    }
    #[inline]
    fn is_exact_zero(&self) -> bool {
        *self == 0.0
    }
}
