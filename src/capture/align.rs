//! Per-camera image warps: how far a photograph must move, and how much it
//! must be magnified, to agree with the render of the current fit. A
//! calibration that misplaces a camera by a small rotation moves its whole
//! image by nearly the same amount (ScalarFlow's nozzle rim lands up to
//! about 40 full-resolution pixels apart between cameras), one that
//! misjudges its focal length magnifies it about the principal point; a
//! fit through such views smears the density. The warp is found by
//! Gauss-Newton on `sum_p (P(c + k Rot(roll) (p - c) + d) - R(p))^2`, with
//! `P` the photograph sampled bilinearly, `c` the principal point, `d` the
//! offset, `k = 1 + zoom` and `Rot` a rotation of the image plane (a camera
//! turned about its optical axis), all carried in four dual lanes: the
//! Jacobian is exact. Moving the camera's principal point by `d`,
//! multiplying its focal lengths by `k` and turning it by `roll` then moves
//! its render onto the photograph ([`Corrections`], the form a capture's
//! rig hands a fit).

use crate::ad::dual::{lane, with_tangents};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::scene::Camera;
use nalgebra::{DMatrix, DVector, Matrix4, Vector4};
use num_dual::DualNum;

/// Gauss-Newton iterations per call.
const ITERATIONS: usize = 8;

/// Largest move of any pixel in one iteration (pixels): the bilinear
/// photograph is a good model of itself only within about a pixel.
pub const MAX_STEP: f64 = 1.0;

/// A photograph's warp onto a render: sample it at `c + (1 + zoom)
/// Rot(roll) (p - c) + offset` for pixel `p`, `c` the principal point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Warp {
    /// Pixels, right and down.
    pub offset: [f64; 2],
    /// Relative magnification: the camera's focal lengths become `1 + zoom` times theirs.
    pub zoom: f64,
    /// Radians, from the image's right towards its bottom: the camera turned
    /// about its optical axis by [`Camera::roll`] of this angle.
    pub roll: f64,
}

/// Which of a warp's parameters besides the offset are fitted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Free {
    /// The magnification about the principal point.
    pub zoom: bool,
    /// The turn about the optical axis.
    pub roll: bool,
}

impl Free {
    /// Indices of the fitted parameters in `[d_x, d_y, zoom, roll]`.
    fn indices(self) -> Vec<usize> {
        [(0, true), (1, true), (2, self.zoom), (3, self.roll)].iter().filter(|p| p.1).map(|p| p.0).collect()
    }
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

/// The squared error `sum_p (P(c + k Rot(roll) (p - c) + d) - R(p))^2` and
/// its gradient and Gauss-Newton matrix in `w = [d_x, d_y, zoom, roll]`;
/// a parameter `free` leaves out stays as `w` has it (0: `k` 1, no turn).
fn gauss_newton(
    rendered: &Image,
    photo: &Image,
    centre: [f64; 2],
    w: [f64; 4],
    free: Free,
) -> (f64, Vector4<f64>, Matrix4<f64>) {
    let dx = with_tangents(w[0], [1.0, 0.0, 0.0, 0.0]);
    let dy = with_tangents(w[1], [0.0, 1.0, 0.0, 0.0]);
    let k = with_tangents(1.0 + w[2], [0.0, 0.0, 1.0, 0.0]);
    let roll = with_tangents(w[3], [0.0, 0.0, 0.0, 1.0]);
    let (cos, sin) = (roll.cos() * k, roll.sin() * k);
    let (mut err, mut g, mut h) = (0.0, Vector4::zeros(), Matrix4::zeros());
    for y in 0..rendered.height {
        for x in 0..rendered.width {
            let r = rendered.data[y * rendered.width + x];
            let (u, v) = (x as f64 + 0.5 - centre[0], y as f64 + 0.5 - centre[1]);
            // The offset alone, or with the zoom, rounded as they always were.
            let (px, py) = match free {
                Free { zoom: false, roll: false } => (dx + (x as f64 + 0.5), dy + (y as f64 + 0.5)),
                Free { roll: false, .. } => (k * u + dx + centre[0], k * v + dy + centre[1]),
                _ => (cos * u - sin * v + dx + centre[0], sin * u + cos * v + dy + centre[1]),
            };
            let p = sample(photo, px, py);
            let res = p.re - r;
            let j = Vector4::new(lane(&p, 0), lane(&p, 1), lane(&p, 2), lane(&p, 3));
            err += res * res;
            g += 2.0 * res * j;
            h += 2.0 * j * j.transpose();
        }
    }
    (err, g, h)
}

/// The warp that moves `photo` onto `rendered`, from none: `photo` sampled
/// at `c + (1 + zoom) Rot(roll) (p - c) + offset` best matches
/// `rendered(p)`, `c` = `centre`, the camera's principal point (pixels).
/// The offset always moves, the zoom and roll where `free` says. Each
/// iteration is a Gauss-Newton step, shortened until no pixel moves more
/// than [`MAX_STEP`] and halved until the error falls.
pub fn warp(rendered: &Image, photo: &Image, centre: [f64; 2], free: Free) -> Warp {
    // The farthest pixel from the centre, which the zoom moves most.
    let reach = [0.0, rendered.width as f64]
        .iter()
        .flat_map(|&x| [0.0, rendered.height as f64].map(|y| (x - centre[0]).hypot(y - centre[1])))
        .fold(0.0, f64::max);
    let mut w = [0.0; 4];
    for _ in 0..ITERATIONS {
        let (err, g, h) = gauss_newton(rendered, photo, centre, w, free);
        let Some(step) = solve(&g, &h, free) else { break };
        let largest = step[0].hypot(step[1]) + (step[2].abs() + step[3].abs()) * reach;
        let mut step = if largest > MAX_STEP { step * MAX_STEP / largest } else { step };
        let mut moved = false;
        for _ in 0..6 {
            let trial = [w[0] + step[0], w[1] + step[1], w[2] + step[2], w[3] + step[3]];
            if gauss_newton(rendered, photo, centre, trial, free).0 < err {
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
    Warp { offset: [w[0], w[1]], zoom: w[2], roll: w[3] }
}

/// Cameras' corrections found before a fit (a capture's rig, [`super::rig`]):
/// the fit starts from the corrected cameras and does not move them again,
/// and holds their gains where its settings say so
/// ([`super::settings::FitSettings::rig_gains`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Corrections {
    /// Per camera, how far its principal point moves, in pixels of the
    /// capture's full resolution (right, down).
    pub offsets_px: Vec<[f64; 2]>,
    /// Per camera, the factor its focal lengths are multiplied by.
    pub zooms: Vec<f64>,
    /// Per camera, the angle it is turned by about its optical axis
    /// ([`Camera::roll`], radians).
    pub rolls: Vec<f64>,
    /// Per camera, its gain (their geometric mean 1), where known.
    pub gains: Option<Vec<f64>>,
}

impl Corrections {
    /// `cameras` (at 1/`factor` of the capture's resolution, in the
    /// corrections' order) corrected, and the offsets in their pixels.
    pub fn apply(&self, cameras: &[Camera], factor: usize) -> Result<(Vec<Camera>, Vec<[f64; 2]>)> {
        let n = self.zooms.len();
        let gains = self.gains.as_ref().map_or(n, Vec::len);
        if cameras.len() != n || self.offsets_px.len() != n || self.rolls.len() != n || gains != n {
            return Err(Error(format!("corrections for {} cameras, the fit has {}", self.zooms.len(), cameras.len())));
        }
        let f = factor as f64;
        let offsets: Vec<[f64; 2]> = self.offsets_px.iter().map(|o| [o[0] / f, o[1] / f]).collect();
        let moved = cameras
            .iter()
            .zip(&self.zooms)
            .zip(&self.rolls)
            .zip(&offsets)
            .map(|(((cam, &k), &roll), o)| cam.shift(o[0], o[1]).zoom(k).roll(roll));
        Ok((moved.collect(), offsets))
    }
}

/// Takes out of per-camera `offsets` and `rolls` their means and divides
/// `factors` (magnifications) by their geometric mean: a move, turn or
/// magnification that every camera shares is the density's to explain,
/// not the cameras'.
pub fn take_out_shared(offsets: &mut [[f64; 2]], factors: &mut [f64], rolls: &mut [f64]) {
    let n = offsets.len().max(1) as f64;
    let mean = [0, 1].map(|a| offsets.iter().map(|o| o[a]).sum::<f64>() / n);
    for o in offsets.iter_mut() {
        *o = [o[0] - mean[0], o[1] - mean[1]];
    }
    let shared = geometric_mean(factors);
    for k in factors.iter_mut() {
        *k /= shared;
    }
    let turn = rolls.iter().sum::<f64>() / rolls.len().max(1) as f64;
    for r in rolls.iter_mut() {
        *r -= turn;
    }
}

/// The geometric mean of per-camera `factors` (gains, magnifications), the
/// scale every camera shares; 1 for none.
pub fn geometric_mean(factors: &[f64]) -> f64 {
    (factors.iter().map(|k| k.ln()).sum::<f64>() / factors.len().max(1) as f64).exp()
}

/// The Gauss-Newton step `-h^-1 g` in the parameters `free` fits (the
/// others' steps 0). `None` where `h` is singular.
fn solve(g: &Vector4<f64>, h: &Matrix4<f64>, free: Free) -> Option<Vector4<f64>> {
    let mut step = Vector4::zeros();
    let at = free.indices();
    if at.len() == 2 {
        // The offset alone, solved as it always was.
        let det = h[(0, 0)] * h[(1, 1)] - h[(0, 1)] * h[(1, 0)];
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        step[0] = -(h[(1, 1)] * g[0] - h[(0, 1)] * g[1]) / det;
        step[1] = -(h[(0, 0)] * g[1] - h[(1, 0)] * g[0]) / det;
    } else {
        let sub_h = DMatrix::from_fn(at.len(), at.len(), |i, j| h[(at[i], at[j])]);
        let sub_g = DVector::from_fn(at.len(), |i, _| g[at[i]]);
        let sub = -sub_h.cholesky()?.solve(&sub_g);
        for (i, &a) in at.iter().enumerate() {
            step[a] = sub[i];
        }
    }
    step.iter().all(|s| s.is_finite()).then_some(step)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::scene::Lens;

    /// A `width` x `height` camera at `distance` on the z axis looking at
    /// the origin, focal length `f` pixels, the principal point at the centre.
    fn on_the_z_axis(distance: f64, f: f64, width: usize, height: usize) -> Camera {
        let (cx, cy) = (width as f64 / 2.0, height as f64 / 2.0);
        Camera {
            position: Vec3::new(0.0, 0.0, distance),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: Lens::Pinhole { fx: f, fy: f, cx, cy },
            width,
            height,
        }
    }

    #[test]
    fn corrections_move_each_camera_in_the_working_resolutions_pixels() {
        let base = on_the_z_axis(2.0, 50.0, 64, 48);
        let fixed = Corrections {
            offsets_px: vec![[16.0, -8.0], [0.0; 2]],
            zooms: vec![1.05, 1.0],
            rolls: vec![0.0; 2],
            gains: None,
        };
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

    /// The sum of a 40 x 30 image's blobs at `(cx, cy)`, each `size` times as wide as [`blob`].
    fn blobs(at: &[(f64, f64, f64)]) -> Image {
        let mut sum = sized_blob(40, 30, at[0].0, at[0].1, at[0].2);
        for &(cx, cy, size) in &at[1..] {
            let more = sized_blob(40, 30, cx, cy, size);
            sum.data.iter_mut().zip(&more.data).for_each(|(s, m)| *s += m);
        }
        sum
    }

    #[test]
    fn a_moved_blob_is_found_where_it_was_moved() {
        let rendered = blob(40, 30, 20.0, 15.0);
        let photo = blob(40, 30, 22.3, 13.6);
        let w = warp(&rendered, &photo, [20.0, 15.0], Free::default());
        // Bilinear sampling of the photograph limits the match to a few hundredths of a pixel.
        let d = w.offset;
        assert!((d[0] - 2.3).abs() < 0.05 && (d[1] + 1.4).abs() < 0.05 && w.zoom == 0.0, "{w:?}");
    }

    #[test]
    fn a_magnified_photograph_is_found_magnified() {
        // Two blobs about the principal point (20, 15), the photograph's magnified 4 %
        // and moved: the zoom finds the magnification the offset alone cannot.
        let pair = |k: f64, d: [f64; 2]| blobs(&[-1.0, 1.0].map(|side| (20.0 + side * 8.0 * k + d[0], 15.0 + d[1], k)));
        let (rendered, photo) = (pair(1.0, [0.0, 0.0]), pair(1.04, [0.6, -0.4]));
        let w = warp(&rendered, &photo, [20.0, 15.0], Free { zoom: true, roll: false });
        assert!(
            (w.zoom - 0.04).abs() < 0.003 && (w.offset[0] - 0.6).abs() < 0.05 && (w.offset[1] + 0.4).abs() < 0.05,
            "{w:?}"
        );
        let fixed = warp(&rendered, &photo, [20.0, 15.0], Free::default());
        assert_eq!(fixed.zoom, 0.0);
    }

    #[test]
    fn a_turned_photograph_is_found_turned() {
        // Two blobs on a line through the principal point (20, 15), the
        // photograph's turned by 3 degrees about it (towards the bottom) and
        // moved: the roll finds the turn, the offset and zoom alone cannot.
        let turn = 3f64.to_radians();
        let pair = |a: f64, d: [f64; 2]| {
            blobs(
                &[-1.0, 1.0]
                    .map(|side| (20.0 + side * 10.0 * a.cos() + d[0], 15.0 + side * 10.0 * a.sin() + d[1], 0.7)),
            )
        };
        let (rendered, photo) = (pair(0.0, [0.0, 0.0]), pair(turn, [0.3, -0.2]));
        let w = warp(&rendered, &photo, [20.0, 15.0], Free { zoom: true, roll: true });
        assert!(
            (w.roll - turn).abs() < 0.1f64.to_radians() && w.zoom.abs() < 0.003 && (w.offset[0] - 0.3).abs() < 0.05,
            "{w:?}"
        );
        let unturned = warp(&rendered, &photo, [20.0, 15.0], Free { zoom: true, roll: false });
        assert_eq!(unturned.roll, 0.0);
    }

    #[test]
    fn the_roll_found_is_the_turn_of_the_camera_that_took_the_photograph() {
        // Blobs where two points appear to a camera, and to the same camera
        // turned about its optical axis: the warp's roll is the camera's turn.
        let camera = on_the_z_axis(3.0, 60.0, 40, 30);
        let seen = |cam: &Camera| {
            blobs(&[Vec3::new(-0.5, 0.3, 0.0), Vec3::new(0.5, -0.1, 0.0)].map(|p| {
                let (x, y) = cam.project(&p).unwrap();
                (x, y, 0.7)
            }))
        };
        let turn = 0.05;
        let w = warp(&seen(&camera), &seen(&camera.roll(turn)), [20.0, 15.0], Free { zoom: true, roll: true });
        assert!((w.roll - turn).abs() < 0.003 && w.offset[0].abs() < 0.05 && w.offset[1].abs() < 0.05, "{w:?}");
    }

    #[test]
    fn a_turn_every_camera_shares_is_taken_out() {
        let (mut offsets, mut factors, mut rolls) = (vec![[1.0, 2.0], [3.0, -2.0]], vec![1.1, 1.1], vec![0.01, 0.03]);
        take_out_shared(&mut offsets, &mut factors, &mut rolls);
        assert_eq!(offsets, vec![[-1.0, 2.0], [1.0, -2.0]]);
        assert!(
            factors.iter().all(|k| (k - 1.0).abs() < 1e-12)
                && (rolls[0] + 0.01).abs() < 1e-12
                && (rolls[1] - 0.01).abs() < 1e-12
        );
    }

    #[test]
    fn the_dual_gradient_matches_finite_differences() {
        let rendered = blob(24, 20, 11.0, 9.0);
        let photo = blob(24, 20, 12.2, 8.1);
        let (w, c) = ([0.37, -0.21, 0.03, 0.02], [12.5, 10.0]);
        let free = Free { zoom: true, roll: true };
        let (_, g, _) = gauss_newton(&rendered, &photo, c, w, free);
        for a in 0..4 {
            let h = 1e-6;
            let (mut up, mut down) = (w, w);
            up[a] += h;
            down[a] -= h;
            let fd = (gauss_newton(&rendered, &photo, c, up, free).0
                - gauss_newton(&rendered, &photo, c, down, free).0)
                / (2.0 * h);
            assert!((fd - g[a]).abs() < 1e-6 * fd.abs().max(1e-6), "lane {a}: {} vs {fd}", g[a]);
        }
    }
}
