//! Per-camera image offsets: how far a photograph must move to agree with
//! the render of the current fit. A calibration that misplaces a camera by
//! a small rotation moves its whole image by nearly the same amount
//! (ScalarFlow's nozzle rim lands up to about 40 full-resolution pixels
//! apart between cameras), and a fit through such views smears the density.
//! The offset is found by Gauss-Newton on `sum_p (P(p + d) - R(p))^2` with
//! `P` the photograph sampled bilinearly and `d` carried in two dual lanes:
//! the Jacobian is exact. Moving the camera's principal point by `d` then
//! moves its render onto the photograph.

use crate::ad::dual::{lane, with_tangents};
use crate::image::Image;
use num_dual::DualSVec64;

/// Two dual lanes: the offset's x and y.
type D2 = DualSVec64<2>;

/// Gauss-Newton iterations per call.
const ITERATIONS: usize = 8;

/// Largest step of one iteration (pixels): the bilinear photograph is a
/// good model of itself only within about a pixel.
const MAX_STEP: f64 = 1.0;

/// The photograph `photo` at `(x, y)` (pixel units, pixel centres at
/// half-integers), bilinear, 0 outside.
fn sample(photo: &Image, x: D2, y: D2) -> D2 {
    let (u, v) = (x - 0.5, y - 0.5);
    let (i0, j0) = (u.re.floor(), v.re.floor());
    let (fx, fy) = (u - i0, v - j0);
    let at = |i: f64, j: f64| -> f64 {
        if i < 0.0 || j < 0.0 || i >= photo.width as f64 || j >= photo.height as f64 {
            0.0
        } else {
            photo.data[j as usize * photo.width + i as usize]
        }
    };
    let one = D2::from_re(1.0);
    (one - fx) * (one - fy) * at(i0, j0)
        + fx * (one - fy) * at(i0 + 1.0, j0)
        + (one - fx) * fy * at(i0, j0 + 1.0)
        + fx * fy * at(i0 + 1.0, j0 + 1.0)
}

/// The squared error `sum_p (P(p + d) - R(p))^2` and its gradient and
/// Gauss-Newton matrix at offset `d`.
fn gauss_newton(rendered: &Image, photo: &Image, d: [f64; 2]) -> (f64, [f64; 2], [[f64; 2]; 2]) {
    let dx = with_tangents(d[0], [1.0, 0.0]);
    let dy = with_tangents(d[1], [0.0, 1.0]);
    let (mut err, mut g, mut h) = (0.0, [0.0; 2], [[0.0; 2]; 2]);
    for y in 0..rendered.height {
        for x in 0..rendered.width {
            let r = rendered.data[y * rendered.width + x];
            let p = sample(photo, dx + (x as f64 + 0.5), dy + (y as f64 + 0.5));
            let res = p.re - r;
            let j = [lane(&p, 0), lane(&p, 1)];
            err += res * res;
            for a in 0..2 {
                g[a] += 2.0 * res * j[a];
                for b in 0..2 {
                    h[a][b] += 2.0 * j[a] * j[b];
                }
            }
        }
    }
    (err, g, h)
}

/// The offset `d` (pixels) that moves `photo` onto `rendered`, starting at
/// `start`: `photo(p + d)` best matches `rendered(p)`. Each iteration is a
/// Gauss-Newton step, shortened to [`MAX_STEP`] and halved until the error falls.
pub fn offset(rendered: &Image, photo: &Image, start: [f64; 2]) -> [f64; 2] {
    let mut d = start;
    for _ in 0..ITERATIONS {
        let (err, g, h) = gauss_newton(rendered, photo, d);
        let det = h[0][0] * h[1][1] - h[0][1] * h[1][0];
        if !(det > 0.0 && det.is_finite()) {
            break;
        }
        let mut step = [-(h[1][1] * g[0] - h[0][1] * g[1]) / det, -(h[0][0] * g[1] - h[1][0] * g[0]) / det];
        let len = step[0].hypot(step[1]);
        if len > MAX_STEP {
            step = [step[0] * MAX_STEP / len, step[1] * MAX_STEP / len];
        }
        let mut moved = false;
        for _ in 0..6 {
            let trial = [d[0] + step[0], d[1] + step[1]];
            if gauss_newton(rendered, photo, trial).0 < err {
                d = trial;
                moved = true;
                break;
            }
            step = [step[0] * 0.5, step[1] * 0.5];
        }
        if !moved {
            break;
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth blob centred at `(cx, cy)`.
    fn blob(w: usize, h: usize, cx: f64, cy: f64) -> Image {
        let data = (0..w * h)
            .map(|p| {
                let (x, y) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
                (-((x - cx).powi(2) + (y - cy).powi(2)) / 18.0).exp()
            })
            .collect();
        Image { width: w, height: h, data }
    }

    #[test]
    fn a_moved_blob_is_found_where_it_was_moved() {
        let rendered = blob(40, 30, 20.0, 15.0);
        let photo = blob(40, 30, 22.3, 13.6);
        let d = offset(&rendered, &photo, [0.0, 0.0]);
        // Bilinear sampling of the photograph limits the match to a few hundredths of a pixel.
        assert!((d[0] - 2.3).abs() < 0.05 && (d[1] + 1.4).abs() < 0.05, "{d:?}");
    }

    #[test]
    fn the_dual_gradient_matches_finite_differences() {
        let rendered = blob(24, 20, 11.0, 9.0);
        let photo = blob(24, 20, 12.2, 8.1);
        let d = [0.37, -0.21];
        let (_, g, _) = gauss_newton(&rendered, &photo, d);
        for a in 0..2 {
            let h = 1e-6;
            let (mut up, mut down) = (d, d);
            up[a] += h;
            down[a] -= h;
            let fd = (gauss_newton(&rendered, &photo, up).0 - gauss_newton(&rendered, &photo, down).0) / (2.0 * h);
            assert!((fd - g[a]).abs() < 1e-6 * fd.abs().max(1e-6), "lane {a}: {} vs {fd}", g[a]);
        }
    }
}
