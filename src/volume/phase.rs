//! The Henyey-Greenstein phase function, in propagation directions:
//! `mu = w_in . w_out`, `g > 0` scatters forward.

use crate::math::{direction_around, Vec3};
use std::f64::consts::PI;

/// `p_HG(mu) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^{3/2})`, per steradian.
/// Finite for every `|g| < 1`: the base is at least `(1 - |g|)^2 > 0`.
#[inline]
pub fn hg_eval(g: f64, mu: f64) -> f64 {
    let denom = 1.0 + g * g - 2.0 * g * mu.clamp(-1.0, 1.0);
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

/// The cosine `mu` distributed as `p_HG`, from a uniform `u` in [0, 1).
#[inline]
pub fn hg_sample_mu(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-3 {
        // The closed form below loses all precision as g -> 0; HG is isotropic there.
        return (1.0 - 2.0 * u).clamp(-1.0, 1.0);
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// A new propagation direction after scattering `w_in`, distributed as
/// `p_HG(w_in . w_out)`; its pdf is `hg_eval(g, w_in . w_out)`.
#[inline]
pub fn hg_sample(g: f64, w_in: &Vec3, u1: f64, u2: f64) -> Vec3 {
    direction_around(w_in, hg_sample_mu(g, u1), 2.0 * PI * u2)
}
