//! Small geometry: the vector type, orthonormal frames and warps of explicit
//! uniform numbers onto directions. All plain `f64`: geometry is never
//! differentiated (docs/DESIGN.md §3).

use nalgebra::Vector3;
use std::f64::consts::PI;

/// A point or direction in world space (right-handed, y up).
pub type Vec3 = Vector3<f64>;

/// An orthonormal basis `(s, t)` completing the unit vector `n` (Duff et al. 2017).
pub fn frame(n: &Vec3) -> (Vec3, Vec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (s, t)
}

/// The direction with cosine `cos_theta` to the unit axis `n` and azimuth `phi`.
pub fn direction_around(n: &Vec3, cos_theta: f64, phi: f64) -> Vec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (s, t) = frame(n);
    (s * (sin_theta * phi.cos()) + t * (sin_theta * phi.sin()) + n * cos_theta).normalize()
}

/// Solid angle (sr) of a cone whose half-angle has cosine `cos_max`.
pub fn cone_solid_angle(cos_max: f64) -> f64 {
    2.0 * PI * (1.0 - cos_max)
}

/// A ray `origin + t * dir`, `dir` of unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Unit direction of travel.
    pub dir: Vec3,
}

impl Ray {
    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f64) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// True if `p` lies in the closed axis-aligned box `lo..hi` (a grid tests
/// its own box with `Grid::contains`, the same test on its lookups' path).
#[inline]
pub fn inside_box(p: &Vec3, lo: &Vec3, hi: &Vec3) -> bool {
    (0..3).all(|a| lo[a] <= p[a] && p[a] <= hi[a])
}

/// The parameter interval `[t0, t1]` (with `t0 >= 0`) where `ray` is inside
/// the axis-aligned box, or `None` if it misses.
pub fn intersect_box(ray: &Ray, lo: &Vec3, hi: &Vec3) -> Option<(f64, f64)> {
    let mut t0: f64 = 0.0;
    let mut t1 = f64::INFINITY;
    for a in 0..3 {
        let inv = 1.0 / ray.dir[a];
        let (mut ta, mut tb) = ((lo[a] - ray.origin[a]) * inv, (hi[a] - ray.origin[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        // NaN (0 * inf on a slab face) compares false and leaves the interval as is.
        if ta > t0 {
            t0 = ta;
        }
        if tb < t1 {
            t1 = tb;
        }
    }
    (t0 < t1).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 2.0, -3.0).normalize()] {
            let (s, t) = frame(&n);
            assert!((s.norm() - 1.0).abs() < 1e-12 && (t.norm() - 1.0).abs() < 1e-12);
            assert!(s.dot(&t).abs() < 1e-12 && s.dot(&n).abs() < 1e-12 && t.dot(&n).abs() < 1e-12);
        }
    }

    #[test]
    fn box_intersection() {
        let ray = Ray { origin: Vec3::new(0.0, 0.0, 5.0), dir: Vec3::new(0.0, 0.0, -1.0) };
        let (t0, t1) = intersect_box(&ray, &Vec3::from_element(-0.5), &Vec3::from_element(0.5)).unwrap();
        assert!((t0 - 4.5).abs() < 1e-12 && (t1 - 5.5).abs() < 1e-12);
        let miss = Ray { origin: Vec3::new(2.0, 0.0, 5.0), dir: Vec3::new(0.0, 0.0, -1.0) };
        assert!(intersect_box(&miss, &Vec3::from_element(-0.5), &Vec3::from_element(0.5)).is_none());
    }

    #[test]
    fn the_box_is_closed_and_nan_is_outside() {
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 1.0, 3.0));
        assert!(
            inside_box(&lo, &lo, &hi) && inside_box(&hi, &lo, &hi) && inside_box(&Vec3::new(0.0, 0.5, 2.5), &lo, &hi)
        );
        for outside in [Vec3::new(0.0, 0.5, 3.0001), Vec3::new(-1.0001, 0.5, 2.5), Vec3::new(0.0, f64::NAN, 2.5)] {
            assert!(!inside_box(&outside, &lo, &hi), "{outside:?}");
        }
    }
}
