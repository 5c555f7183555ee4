//! Pinhole cameras (docs/DESIGN.md §1): vertical field of view, square pixels,
//! image row 0 at the top, a pixel's value the mean radiance over its footprint.

use crate::math::{Ray, Vec3};

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection (world units).
    pub position: Vec3,
    /// A point the optical axis passes through; differs from `position`.
    pub look_at: Vec3,
    /// Up hint; not parallel to the viewing direction.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f64,
    /// Image width in pixels (> 0).
    pub width: usize,
    /// Image height in pixels (> 0).
    pub height: usize,
}

impl Camera {
    /// The orthonormal camera basis `(right, up, forward)`.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.look_at - self.position).normalize();
        let right = forward.cross(&self.up).normalize();
        let up = right.cross(&forward);
        (right, up, forward)
    }

    /// The ray through image position `(x, y)` in pixel units: `x` in
    /// `[0, width]` to the right, `y` in `[0, height]` downwards.
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let (right, up, forward) = self.basis();
        let tan_half = (self.fov_y_deg.to_radians() * 0.5).tan();
        let sx = (2.0 * x / self.width as f64 - 1.0) * tan_half * self.width as f64 / self.height as f64;
        let sy = (1.0 - 2.0 * y / self.height as f64) * tan_half;
        Ray { origin: self.position, dir: (forward + right * sx + up * sy).normalize() }
    }

    /// Image position `(x, y)` in pixel units (as [`ray`](Self::ray) takes
    /// them) where `p` appears, or `None` if `p` is not in front of the camera.
    pub fn project(&self, p: &Vec3) -> Option<(f64, f64)> {
        let (right, up, forward) = self.basis();
        let v = p - self.position;
        let depth = v.dot(&forward);
        if depth <= 0.0 {
            return None;
        }
        let tan_half = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = self.width as f64 / self.height as f64;
        let sx = v.dot(&right) / depth / (tan_half * aspect);
        let sy = v.dot(&up) / depth / tan_half;
        Some(((sx + 1.0) * 0.5 * self.width as f64, (1.0 - sy) * 0.5 * self.height as f64))
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_ray() {
        let c = Camera {
            position: Vec3::new(1.0, 0.5, 2.5),
            look_at: Vec3::new(0.0, 0.1, 0.0),
            up: Vec3::new(0.0, 1.0, 0.0),
            fov_y_deg: 40.0,
            width: 64,
            height: 48,
        };
        for (x, y) in [(0.5, 0.5), (10.2, 40.7), (63.9, 1.0)] {
            let r = c.ray(x, y);
            let (px, py) = c.project(&r.at(2.0)).unwrap();
            assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9);
        }
        assert!(c.project(&Vec3::new(1.0, 0.5, 4.0)).is_none());
    }
}
