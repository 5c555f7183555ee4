//! Per-camera image warps: how far a photograph must move, and how much it
//! must be magnified, to agree with the render of the current fit. A
//! calibration that misplaces a camera by a small rotation moves its whole
//! image by nearly the same amount (ScalarFlow's nozzle rim lands up to
//! about 40 full-resolution pixels apart between cameras), one that
//! misjudges its focal length magnifies it about the principal point; a
//! fit through such views smears the density. The warp is found by
//! Gauss-Newton on `sum_p (P(c + k (p - c) + d) - R(p))^2`, with `P` the
//! photograph sampled bilinearly, `c` the principal point, `d` the offset
//! and `k = 1 + zoom`, all carried in three dual lanes: the Jacobian is
//! exact. Moving the camera's principal point by `d` and multiplying its
//! focal lengths by `k` then moves its render onto the photograph
//! ([`Corrections`], the form a capture's rig hands a fit).

use crate::ad::dual::{lane, with_tangents};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::scene::Camera;
use nalgebra::{Matrix3, Vector3};
use num_dual::DualNum;

/// Gauss-Newton iterations per call.
const ITERATIONS: usize = 8;

/// Largest move of any pixel in one iteration (pixels): the bilinear
/// photograph is a good model of itself only within about a pixel.
const MAX_STEP: f64 = 1.0;

/// A photograph's warp onto a render: sample it at `c + (1 + zoom) (p - c)
/// + offset` for pixel `p`, `c` the principal point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Warp {
    /// Pixels, right and down.
    pub offset: [f64; 2],
    /// Relative magnification: the camera's focal lengths become `1 + zoom` times theirs.
    pub zoom: f64,
}

/// The photograph `photo` at `(x, y)` (pixel units, pixel centres at
/// half-integers), bilinear, 0 outside; in plain numbers or dual lanes.
pub fn sample<D: DualNum<Primitive = f64> + Copy>(photo: &Image, x: D, y: D) -> D {
    let (u, v) = (x - 0.5, y - 0.5);
    let (i0, j0) = (u.re().floor(), v.re().floor());
    let (fx, fy) = (u - i0, v - j0);
    let at = |i: f64, j: f64| -> f64 {
        if i < 0.0 || j < 0.0 || i >= photo.width as f64 || j >= photo.height as f64 {
            0.0
        } else {
            photo.data[j as usize * photo.width + i as usize]
        }
    };
    let one = D::from(1.0);
    (one - fx) * (one - fy) * at(i0, j0)
        + fx * (one - fy) * at(i0 + 1.0, j0)
        + (one - fx) * fy * at(i0, j0 + 1.0)
        + fx * fy * at(i0 + 1.0, j0 + 1.0)
}

/// The squared error `sum_p (P(c + k (p - c) + d) - R(p))^2` and its
/// gradient and Gauss-Newton matrix in `w = [d_x, d_y, zoom]`; without
/// `zoom`, `k` is 1 and its lane 0.
fn gauss_newton(
    rendered: &Image,
    photo: &Image,
    centre: [f64; 2],
    w: [f64; 3],
    zoom: bool,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let dx = with_tangents(w[0], [1.0, 0.0, 0.0]);
    let dy = with_tangents(w[1], [0.0, 1.0, 0.0]);
    let k = with_tangents(1.0 + w[2], [0.0, 0.0, 1.0]);
    let (mut err, mut g, mut h) = (0.0, Vector3::zeros(), Matrix3::zeros());
    for y in 0..rendered.height {
        for x in 0..rendered.width {
            let r = rendered.data[y * rendered.width + x];
            // Without the zoom, the offset alone, rounded as it always was.
            let (px, py) = if !zoom {
                (dx + (x as f64 + 0.5), dy + (y as f64 + 0.5))
            } else {
                (k * (x as f64 + 0.5 - centre[0]) + dx + centre[0], k * (y as f64 + 0.5 - centre[1]) + dy + centre[1])
            };
            let p = sample(photo, px, py);
            let res = p.re - r;
            let j = Vector3::new(lane(&p, 0), lane(&p, 1), lane(&p, 2));
            err += res * res;
            g += 2.0 * res * j;
            h += 2.0 * j * j.transpose();
        }
    }
    (err, g, h)
}

/// The warp that moves `photo` onto `rendered`, from none: `photo` sampled
/// at `c + (1 + zoom) (p - c) + offset` best matches `rendered(p)`, `c` =
/// `centre`, the camera's principal point (pixels). Without `zoom`, only
/// the offset moves. Each iteration is a Gauss-Newton step, shortened until
/// no pixel moves more than [`MAX_STEP`] and halved until the error falls.
pub fn warp(rendered: &Image, photo: &Image, centre: [f64; 2], zoom: bool) -> Warp {
    // The farthest pixel from the centre, which the zoom moves most.
    let reach = [0.0, rendered.width as f64]
        .iter()
        .flat_map(|&x| [0.0, rendered.height as f64].map(|y| (x - centre[0]).hypot(y - centre[1])))
        .fold(0.0, f64::max);
    let mut w = [0.0; 3];
    for _ in 0..ITERATIONS {
        let (err, g, h) = gauss_newton(rendered, photo, centre, w, zoom);
        let Some(step) = solve(&g, &h, zoom) else { break };
        let largest = step[0].hypot(step[1]) + step[2].abs() * reach;
        let mut step = if largest > MAX_STEP { step * MAX_STEP / largest } else { step };
        let mut moved = false;
        for _ in 0..6 {
            let trial = [w[0] + step[0], w[1] + step[1], w[2] + step[2]];
            if gauss_newton(rendered, photo, centre, trial, zoom).0 < err {
                w = trial;
                moved = true;
                break;
            }
            step *= 0.5;
        }
        if !moved {
            break;
        }
    }
    Warp { offset: [w[0], w[1]], zoom: w[2] }
}

/// Cameras' corrections found before a fit (a capture's rig, [`super::rig`]):
/// the fit starts from the corrected cameras and does not move them again.
#[derive(Clone, Debug, PartialEq)]
pub struct Corrections {
    /// Per camera, how far its principal point moves, in pixels of the
    /// capture's full resolution (right, down).
    pub offsets_px: Vec<[f64; 2]>,
    /// Per camera, the factor its focal lengths are multiplied by.
    pub zooms: Vec<f64>,
}

impl Corrections {
    /// `cameras` (at 1/`factor` of the capture's resolution, in the
    /// corrections' order) corrected, and the offsets in their pixels.
    pub fn apply(&self, cameras: &[Camera], factor: usize) -> Result<(Vec<Camera>, Vec<[f64; 2]>)> {
        if cameras.len() != self.zooms.len() || self.offsets_px.len() != self.zooms.len() {
            return Err(Error(format!("corrections for {} cameras, the fit has {}", self.zooms.len(), cameras.len())));
        }
        let f = factor as f64;
        let offsets: Vec<[f64; 2]> = self.offsets_px.iter().map(|o| [o[0] / f, o[1] / f]).collect();
        let moved = cameras.iter().zip(&self.zooms).zip(&offsets).map(|((cam, &k), o)| cam.shift(o[0], o[1]).zoom(k));
        Ok((moved.collect(), offsets))
    }
}

/// Takes out of per-camera `offsets` their mean and divides `factors`
/// (magnifications) by their geometric mean: a move or magnification that
/// every camera shares is the density's to explain, not the cameras'.
pub fn take_out_shared(offsets: &mut [[f64; 2]], factors: &mut [f64]) {
    let n = offsets.len().max(1) as f64;
    let mean = [0, 1].map(|a| offsets.iter().map(|o| o[a]).sum::<f64>() / n);
    for o in offsets.iter_mut() {
        *o = [o[0] - mean[0], o[1] - mean[1]];
    }
    let shared = geometric_mean(factors);
    for k in factors.iter_mut() {
        *k /= shared;
    }
}

/// The geometric mean of per-camera `factors` (gains, magnifications), the
/// scale every camera shares; 1 for none.
pub fn geometric_mean(factors: &[f64]) -> f64 {
    (factors.iter().map(|k| k.ln()).sum::<f64>() / factors.len().max(1) as f64).exp()
}

/// The Gauss-Newton step `-h^-1 g`; without `zoom`, in the offset alone
/// (the zoom's step 0). `None` where `h` is singular.
fn solve(g: &Vector3<f64>, h: &Matrix3<f64>, zoom: bool) -> Option<Vector3<f64>> {
    let step = if zoom {
        -h.cholesky()?.solve(g)
    } else {
        let det = h[(0, 0)] * h[(1, 1)] - h[(0, 1)] * h[(1, 0)];
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        let x = -(h[(1, 1)] * g[0] - h[(0, 1)] * g[1]) / det;
        let y = -(h[(0, 0)] * g[1] - h[(1, 0)] * g[0]) / det;
        Vector3::new(x, y, 0.0)
    };
    step.iter().all(|s| s.is_finite()).then_some(step)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::scene::Lens;

    #[test]
    fn corrections_move_each_camera_in_the_working_resolutions_pixels() {
        let base = Camera {
            position: Vec3::new(0.0, 0.0, 2.0),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: Lens::Pinhole { fx: 50.0, fy: 50.0, cx: 32.0, cy: 24.0 },
            width: 64,
            height: 48,
        };
        let fixed = Corrections { offsets_px: vec![[16.0, -8.0], [0.0; 2]], zooms: vec![1.05, 1.0] };
        let (moved, offsets) = fixed.apply(&[base.clone(), base.clone()], 8).unwrap();
        assert_eq!(offsets, vec![[2.0, -1.0], [0.0, 0.0]]);
        let ([fx, fy, cx, cy], [fx0, fy0, cx0, cy0]) = (moved[0].intrinsics(), base.intrinsics());
        assert!((cx - cx0 - 2.0).abs() < 1e-12 && (cy - cy0 + 1.0).abs() < 1e-12);
        assert!((fx / fx0 - 1.05).abs() < 1e-12 && (fy / fy0 - 1.05).abs() < 1e-12);
        assert_eq!(moved[1], base);
        assert!(fixed.apply(&[base], 8).is_err(), "corrections of two cameras do not fit one");
    }

    /// A smooth blob centred at `(cx, cy)`.
    fn blob(w: usize, h: usize, cx: f64, cy: f64) -> Image {
        sized_blob(w, h, cx, cy, 1.0)
    }

    /// A smooth blob centred at `(cx, cy)`, `size` times as wide as [`blob`].
    fn sized_blob(w: usize, h: usize, cx: f64, cy: f64, size: f64) -> Image {
        let data = (0..w * h)
            .map(|p| {
                let (x, y) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
                (-((x - cx).powi(2) + (y - cy).powi(2)) / (18.0 * size * size)).exp()
            })
            .collect();
        Image { width: w, height: h, data }
    }

    #[test]
    fn a_moved_blob_is_found_where_it_was_moved() {
        let rendered = blob(40, 30, 20.0, 15.0);
        let photo = blob(40, 30, 22.3, 13.6);
        let w = warp(&rendered, &photo, [20.0, 15.0], false);
        // Bilinear sampling of the photograph limits the match to a few hundredths of a pixel.
        let d = w.offset;
        assert!((d[0] - 2.3).abs() < 0.05 && (d[1] + 1.4).abs() < 0.05 && w.zoom == 0.0, "{w:?}");
    }

    #[test]
    fn a_magnified_photograph_is_found_magnified() {
        // Two blobs about the principal point (20, 15), the photograph's magnified 4 %
        // and moved: the zoom finds the magnification the offset alone cannot.
        let pair = |k: f64, d: [f64; 2]| {
            let one = |side: f64| sized_blob(40, 30, 20.0 + side * 8.0 * k + d[0], 15.0 + d[1], k);
            let (a, b) = (one(-1.0), one(1.0));
            Image { data: a.data.iter().zip(&b.data).map(|(x, y)| x + y).collect(), ..a }
        };
        let (rendered, photo) = (pair(1.0, [0.0, 0.0]), pair(1.04, [0.6, -0.4]));
        let w = warp(&rendered, &photo, [20.0, 15.0], true);
        assert!(
            (w.zoom - 0.04).abs() < 0.003 && (w.offset[0] - 0.6).abs() < 0.05 && (w.offset[1] + 0.4).abs() < 0.05,
            "{w:?}"
        );
        let fixed = warp(&rendered, &photo, [20.0, 15.0], false);
        assert_eq!(fixed.zoom, 0.0);
    }

    #[test]
    fn the_dual_gradient_matches_finite_differences() {
        let rendered = blob(24, 20, 11.0, 9.0);
        let photo = blob(24, 20, 12.2, 8.1);
        let (w, c) = ([0.37, -0.21, 0.03], [12.5, 10.0]);
        let (_, g, _) = gauss_newton(&rendered, &photo, c, w, true);
        for a in 0..3 {
            let h = 1e-6;
            let (mut up, mut down) = (w, w);
            up[a] += h;
            down[a] -= h;
            let fd = (gauss_newton(&rendered, &photo, c, up, true).0
                - gauss_newton(&rendered, &photo, c, down, true).0)
                / (2.0 * h);
            assert!((fd - g[a]).abs() < 1e-6 * fd.abs().max(1e-6), "lane {a}: {} vs {fd}", g[a]);
        }
    }
}
