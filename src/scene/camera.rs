//! Pinhole cameras (docs/DESIGN.md §1): image row 0 at the top, a pixel's
//! value the mean radiance over its footprint. The lens is either a vertical
//! field of view (square pixels, principal point at the centre) or general
//! intrinsics in pixels, as calibrations give them; the latter survive
//! cropping and downsampling, which move and scale the principal point.

use crate::math::{Ray, Vec3};

/// How a camera maps viewing directions to image positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lens {
    /// Vertical field of view in degrees, in (0, 180); square pixels,
    /// principal point at the image centre.
    FovY(f64),
    /// Intrinsics in pixels, `x` to the right and `y` down from the image's
    /// top-left corner.
    Pinhole {
        /// Horizontal focal length (> 0).
        fx: f64,
        /// Vertical focal length (> 0).
        fy: f64,
        /// Principal point, x.
        cx: f64,
        /// Principal point, y.
        cy: f64,
    },
}

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection (world units).
    pub position: Vec3,
    /// A point the optical axis passes through; differs from `position`.
    pub look_at: Vec3,
    /// Up hint; not parallel to the viewing direction.
    pub up: Vec3,
    /// The lens.
    pub lens: Lens,
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

    /// The intrinsics `[fx, fy, cx, cy]` in pixels, whatever the lens.
    pub fn intrinsics(&self) -> [f64; 4] {
        match self.lens {
            Lens::FovY(deg) => {
                let f = 0.5 * self.height as f64 / (deg.to_radians() * 0.5).tan();
                [f, f, 0.5 * self.width as f64, 0.5 * self.height as f64]
            }
            Lens::Pinhole { fx, fy, cx, cy } => [fx, fy, cx, cy],
        }
    }

    /// The ray through image position `(x, y)` in pixel units: `x` in
    /// `[0, width]` to the right, `y` in `[0, height]` downwards.
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let (right, up, forward) = self.basis();
        let (sx, sy) = match self.lens {
            // Kept in this form so that existing scenes render to the same bits.
            Lens::FovY(deg) => {
                let tan_half = (deg.to_radians() * 0.5).tan();
                let sx = (2.0 * x / self.width as f64 - 1.0) * tan_half * self.width as f64 / self.height as f64;
                (sx, (1.0 - 2.0 * y / self.height as f64) * tan_half)
            }
            Lens::Pinhole { fx, fy, cx, cy } => ((x - cx) / fx, (cy - y) / fy),
        };
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
        let (sx, sy) = (v.dot(&right) / depth, v.dot(&up) / depth);
        Some(match self.lens {
            Lens::FovY(deg) => {
                let tan_half = (deg.to_radians() * 0.5).tan();
                let aspect = self.width as f64 / self.height as f64;
                let (sx, sy) = (sx / (tan_half * aspect), sy / tan_half);
                ((sx + 1.0) * 0.5 * self.width as f64, (1.0 - sy) * 0.5 * self.height as f64)
            }
            Lens::Pinhole { fx, fy, cx, cy } => (cx + fx * sx, cy - fy * sy),
        })
    }

    /// The pixel `(column, row)` where `p` appears, or `None` if `p` is
    /// behind the camera or outside its image.
    pub fn pixel_of(&self, p: &Vec3) -> Option<(usize, usize)> {
        let (x, y) = self.project(p)?;
        (x >= 0.0 && y >= 0.0 && (x as usize) < self.width && (y as usize) < self.height)
            .then_some((x as usize, y as usize))
    }

    /// The same camera seeing only the `width` x `height` window whose
    /// top-left pixel is `(x0, y0)`: the principal point moves, nothing else.
    pub fn crop(&self, x0: usize, y0: usize, width: usize, height: usize) -> Camera {
        let [fx, fy, cx, cy] = self.intrinsics();
        let lens = Lens::Pinhole { fx, fy, cx: cx - x0 as f64, cy: cy - y0 as f64 };
        Camera { lens, width, height, ..self.clone() }
    }

    /// The camera whose principal point is `(dx, dy)` pixels further right
    /// and down: its image is this one's moved by `(dx, dy)`.
    pub fn shift(&self, dx: f64, dy: f64) -> Camera {
        let [fx, fy, cx, cy] = self.intrinsics();
        Camera { lens: Lens::Pinhole { fx, fy, cx: cx + dx, cy: cy + dy }, ..self.clone() }
    }

    /// The same camera with its focal lengths `k` times as long: its image
    /// magnified `k` times about the principal point.
    pub fn zoom(&self, k: f64) -> Camera {
        let [fx, fy, cx, cy] = self.intrinsics();
        Camera { lens: Lens::Pinhole { fx: fx * k, fy: fy * k, cx, cy }, ..self.clone() }
    }

    /// The same camera turned by `angle` radians about its optical axis: a
    /// point's image turns by `angle` about the principal point, from the
    /// image's right towards its bottom (exactly so where `fx == fy`).
    pub fn roll(&self, angle: f64) -> Camera {
        if angle == 0.0 {
            return self.clone();
        }
        let (right, up, _) = self.basis();
        Camera { up: up * angle.cos() - right * angle.sin(), ..self.clone() }
    }

    /// The same camera for the image averaged over `factor` x `factor`
    /// blocks (a partial block at the right or bottom edge is dropped): new
    /// pixel `(u, v)` covers old pixels `factor*u .. factor*(u+1)`, so every
    /// intrinsic divides by `factor`.
    pub fn downsample(&self, factor: usize) -> Camera {
        let [fx, fy, cx, cy] = self.intrinsics();
        let f = factor as f64;
        let lens = Lens::Pinhole { fx: fx / f, fy: fy / f, cx: cx / f, cy: cy / f };
        Camera { lens, width: self.width / factor, height: self.height / factor, ..self.clone() }
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(lens: Lens) -> Camera {
        Camera {
            position: Vec3::new(1.0, 0.5, 2.5),
            look_at: Vec3::new(0.0, 0.1, 0.0),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens,
            width: 64,
            height: 48,
        }
    }

    #[test]
    fn project_inverts_ray() {
        for lens in [Lens::FovY(40.0), Lens::Pinhole { fx: 70.0, fy: 66.0, cx: 30.5, cy: 20.0 }] {
            let c = camera(lens);
            for (x, y) in [(0.5, 0.5), (10.2, 40.7), (63.9, 1.0)] {
                let r = c.ray(x, y);
                let (px, py) = c.project(&r.at(2.0)).unwrap();
                assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "{lens:?}");
            }
            assert!(c.project(&Vec3::new(1.0, 0.5, 4.0)).is_none());
        }
    }

    #[test]
    fn a_field_of_view_is_a_centred_pinhole() {
        let fov = camera(Lens::FovY(40.0));
        let [fx, fy, cx, cy] = fov.intrinsics();
        let pinhole = camera(Lens::Pinhole { fx, fy, cx, cy });
        for (x, y) in [(0.0, 0.0), (10.2, 40.7), (64.0, 48.0)] {
            assert!((fov.ray(x, y).dir - pinhole.ray(x, y).dir).norm() < 1e-12);
        }
        // The top edge of the image is half the field of view above the axis.
        let (_, up, forward) = fov.basis();
        let top = fov.ray(32.0, 0.0).dir;
        assert!((top.dot(&up).atan2(top.dot(&forward)).to_degrees() - 20.0).abs() < 1e-9);
    }

    #[test]
    fn cropping_and_downsampling_keep_every_point_in_place() {
        let full = camera(Lens::Pinhole { fx: 70.0, fy: 66.0, cx: 30.5, cy: 20.0 });
        let p = Vec3::new(0.1, 0.2, -0.1);
        let (x, y) = full.project(&p).unwrap();
        let (xc, yc) = full.crop(8, 4, 40, 30).project(&p).unwrap();
        assert!((xc - (x - 8.0)).abs() < 1e-9 && (yc - (y - 4.0)).abs() < 1e-9);
        let half = full.downsample(2);
        assert_eq!((half.width, half.height), (32, 24));
        let (xh, yh) = half.project(&p).unwrap();
        assert!((xh - x / 2.0).abs() < 1e-9 && (yh - y / 2.0).abs() < 1e-9);
        // Zooming magnifies the image about the principal point.
        let (xz, yz) = full.zoom(1.1).project(&p).unwrap();
        assert!((xz - (30.5 + 1.1 * (x - 30.5))).abs() < 1e-9 && (yz - (20.0 + 1.1 * (y - 20.0))).abs() < 1e-9);
    }

    #[test]
    fn rolling_turns_every_point_about_the_principal_point() {
        let c = camera(Lens::Pinhole { fx: 70.0, fy: 70.0, cx: 30.5, cy: 20.0 });
        let angle = 0.2;
        let turned = c.roll(angle);
        assert_eq!(c.roll(0.0), c);
        for p in [Vec3::new(0.1, 0.2, -0.1), Vec3::new(-0.3, -0.1, 0.2)] {
            let ((x, y), (xt, yt)) = (c.project(&p).unwrap(), turned.project(&p).unwrap());
            let (u, v) = (x - 30.5, y - 20.0);
            // Towards the bottom: (1, 0) turns to (cos, sin).
            let (ut, vt) = (u * angle.cos() - v * angle.sin(), u * angle.sin() + v * angle.cos());
            assert!((xt - 30.5 - ut).abs() < 1e-9 && (yt - 20.0 - vt).abs() < 1e-9, "{p:?}");
        }
        // The optical axis stays.
        assert!((turned.basis().2 - c.basis().2).norm() < 1e-12);
    }
}
