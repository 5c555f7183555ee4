//! The lights' places, fitted. A studio light's position is unknown; what
//! it changes in a photograph is which side of the plume is bright (the
//! phase function's angle to each camera), how the light falls off across
//! the plume, and where the plume shadows itself. The single-scattered
//! image of one light of unit intensity is computed here with the light's
//! position in three dual lanes, so its Jacobian with respect to the
//! position is exact: the geometric terms (angle, distance) and the optical
//! depth to the light, marched along rays whose direction carries the lanes
//! through the density's trilinear interpolation.
//!
//! Positions then move by Levenberg-Marquardt steps on the training
//! images, jointly with the intensities and the emission (which enter the
//! image linearly), and a step is kept only if the renderer's own images at
//! the new places, with intensities fitted again, agree better with the
//! photographs. Higher orders of scattering move with their light in the
//! renderer's images, but their share of the Jacobian is left out (their
//! change with a light's place is smoother and smaller than single
//! scattering's): the step is exact for single scattering, a model for the rest.

use crate::ad::dual::{lane, with_tangents};
use crate::image::Image;
use crate::math::{intersect_box, Ray, Vec3};
use crate::scene::Camera;
use crate::volume::Grid;
use nalgebra::{DMatrix, DVector};
use num_dual::{DualNum, DualSVec64};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Three dual lanes: a light's x, y and z.
type D3 = DualSVec64<3>;

/// Depth-grid nodes every this many voxels of the density along each axis.
const CELL: usize = 2;

/// Camera-ray transmittance below which nothing further along is gathered.
const T_MIN: f64 = 1e-4;

/// One point where a camera ray gathers light scattered once.
#[derive(Clone, Debug)]
struct Gather {
    /// Where.
    x: Vec3,
    /// Towards the camera.
    w_out: Vec3,
    /// Transmittance to the camera times the step's scattering probability
    /// (`1 - exp(-sigma_t h)` times the albedo).
    weight: f64,
}

/// Every camera pixel's gather points over a fixed density: a ray through
/// the pixel's centre, marched in fixed steps, a point at each step's middle.
pub struct Gathers {
    /// Per pixel of all cameras (in scene order, rows first), its points.
    pixels: Vec<Vec<Gather>>,
}

impl Gathers {
    /// The gather points of `cameras` through `density` (extinction
    /// `scale * density`, single-scattering `albedo`), steps of half the
    /// smallest voxel edge.
    pub fn new(density: &Grid<f64>, scale: f64, albedo: f64, cameras: &[Camera]) -> Self {
        let step = half_voxel(density);
        let rays: Vec<Ray> = cameras
            .iter()
            .flat_map(|c| (0..c.pixels()).map(move |p| c.ray((p % c.width) as f64 + 0.5, (p / c.width) as f64 + 0.5)))
            .collect();
        let pixels = rays
            .par_iter()
            .with_min_len(64)
            .map(|ray| {
                let mut points = Vec::new();
                let Some((t0, t1)) = intersect_box(ray, &density.lo, &density.hi) else { return points };
                let mut transmittance = 1.0;
                let n = ((t1 - t0) / step).ceil() as usize;
                let h = (t1 - t0) / n.max(1) as f64;
                for m in 0..n {
                    let x = ray.at(t0 + (m as f64 + 0.5) * h);
                    let sigma = density.at(&x) * scale;
                    if sigma <= 0.0 {
                        continue;
                    }
                    let absorbed = -(-sigma * h).exp_m1();
                    points.push(Gather { x, w_out: -ray.dir, weight: transmittance * absorbed * albedo });
                    transmittance *= 1.0 - absorbed;
                    if transmittance < T_MIN {
                        break;
                    }
                }
                points
            })
            .collect();
        Gathers { pixels }
    }
}

/// Half the smallest voxel edge of `grid`.
fn half_voxel(grid: &Grid<f64>) -> f64 {
    let v = grid.voxel_size();
    0.5 * v.x.min(v.y).min(v.z)
}

/// `grid` at a point whose coordinates carry dual lanes, trilinear as
/// [`Grid::at`] (the edge value in the outer half-voxel shell, 0 outside):
/// the lanes carry the density's gradient.
fn density_at(grid: &Grid<f64>, p: &[D3; 3]) -> D3 {
    let re = Vec3::new(p[0].re, p[1].re, p[2].re);
    if !grid.contains(&re) {
        return D3::from_re(0.0);
    }
    let mut lo_i = [0usize; 3];
    let mut frac = [D3::from_re(0.0), D3::from_re(0.0), D3::from_re(0.0)];
    for a in 0..3 {
        let n = grid.shape[2 - a];
        let u = (p[a] - grid.lo[a]) * (n as f64 / (grid.hi[a] - grid.lo[a])) - 0.5;
        let u = if u.re < 0.0 {
            D3::from_re(0.0)
        } else if u.re > (n - 1) as f64 {
            D3::from_re((n - 1) as f64)
        } else {
            u
        };
        let i0 = (u.re as usize).min(n.saturating_sub(2));
        lo_i[a] = i0;
        frac[a] = if n > 1 { u - i0 as f64 } else { D3::from_re(0.0) };
    }
    let mut sum = D3::from_re(0.0);
    for c in 0..8 {
        let bits = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        let mut weight = D3::from_re(1.0);
        let mut at = [0usize; 3];
        for a in 0..3 {
            let n = grid.shape[2 - a];
            // On a one-voxel axis the upper corner's fraction is 0: it adds nothing.
            at[a] = lo_i[a] + bits[a].min(n - 1);
            weight *= if bits[a] == 1 { frac[a] } else { -frac[a] + 1.0 };
        }
        sum += weight * grid.data[grid.index(at[2], at[1], at[0])];
    }
    sum
}

/// The optical depth from every node of a grid over `density`'s box (a
/// node every [`CELL`] voxels) to a light at `light`, marched in fixed
/// steps of half a voxel from the node to the box's face or the light.
/// Step placement is the primal's; the samples' positions carry the lanes.
fn depth_grid(density: &Grid<f64>, scale: f64, light: &[D3; 3]) -> Grid<D3> {
    let shape = density.shape.map(|n| n.div_ceil(CELL));
    let nodes = Grid::new(density.lo, density.hi, shape, vec![0.0; shape.iter().product()]);
    let step = half_voxel(density);
    let data = (0..nodes.len())
        .into_par_iter()
        .with_min_len(16)
        .map(|v| {
            let (k, j, i) = (v / (shape[1] * shape[2]), v / shape[2] % shape[1], v % shape[2]);
            let from = nodes.voxel_center(k, j, i);
            let to = [light[0] - from.x, light[1] - from.y, light[2] - from.z];
            let dist = (to[0] * to[0] + to[1] * to[1] + to[2] * to[2]).sqrt();
            if dist.re == 0.0 {
                return D3::from_re(0.0);
            }
            let dir = to.map(|c| c / dist);
            let ray = Ray { origin: from, dir: Vec3::new(dir[0].re, dir[1].re, dir[2].re) };
            let end = intersect_box(&ray, &density.lo, &density.hi).map_or(0.0, |(_, t1)| t1).min(dist.re);
            let mut depth = D3::from_re(0.0);
            let mut t = 0.5 * step;
            while t < end {
                let p = [dir[0] * t + from.x, dir[1] * t + from.y, dir[2] * t + from.z];
                depth += density_at(density, &p);
                t += step;
            }
            depth * (step * scale)
        })
        .collect();
    Grid::new(density.lo, density.hi, shape, data)
}

/// The Henyey-Greenstein phase function at `mu` (dual).
fn hg(g: f64, mu: D3) -> D3 {
    let denom = mu * (-2.0 * g) + (1.0 + g * g);
    (denom * denom.sqrt()).recip() * ((1.0 - g * g) / (4.0 * PI))
}

/// Every pixel of the gathers' cameras lit by one light of unit intensity
/// at `position`, scattered once: `sum_points weight * p_HG(mu) *
/// exp(-depth) / r^2`, with the position's x, y, z in the three lanes.
pub fn single_image(gathers: &Gathers, density: &Grid<f64>, scale: f64, g: f64, position: &Vec3) -> Vec<D3> {
    let light = [
        with_tangents(position.x, [1.0, 0.0, 0.0]),
        with_tangents(position.y, [0.0, 1.0, 0.0]),
        with_tangents(position.z, [0.0, 0.0, 1.0]),
    ];
    let depth = depth_grid(density, scale, &light);
    gathers
        .pixels
        .par_iter()
        .with_min_len(64)
        .map(|points| {
            let mut sum = D3::from_re(0.0);
            for p in points {
                let to = [light[0] - p.x.x, light[1] - p.x.y, light[2] - p.x.z];
                let r2 = to[0] * to[0] + to[1] * to[1] + to[2] * to[2];
                if r2.re == 0.0 {
                    continue;
                }
                let r = r2.sqrt();
                // Propagation from the light through x towards the camera: mu = (-to / r) . w_out.
                let mu = -(to[0] * p.w_out.x + to[1] * p.w_out.y + to[2] * p.w_out.z) / r;
                let transmittance = (-depth.at(&p.x)).exp();
                sum += hg(g, mu) * transmittance / r2 * p.weight;
            }
            sum
        })
        .collect()
}

/// One Levenberg-Marquardt step for the lights' positions, intensities and
/// the emission: the residual `rendered - targets` (all cameras' pixels in
/// order), per light its intensity and its images' Jacobian with respect to
/// its position (`singles`), and the columns the image is linear in (per
/// light its image at unit intensity, last the emission's). Returns the
/// positions' moves, or `None` where the system has no finite solution.
pub fn step(
    residual: &[f64],
    intensities: &[f64],
    singles: &[Vec<D3>],
    linear: &[Vec<f64>],
    damping: f64,
) -> Option<Vec<Vec3>> {
    let lights = singles.len();
    let n = 3 * lights + linear.len();
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DVector::<f64>::zeros(n);
    let mut row = vec![0.0; n];
    for (p, &r) in residual.iter().enumerate() {
        for (l, s) in singles.iter().enumerate() {
            for k in 0..3 {
                row[3 * l + k] = intensities[l] * lane(&s[p], k);
            }
        }
        for (c, column) in linear.iter().enumerate() {
            row[3 * lights + c] = column[p];
        }
        if row.iter().all(|&v| v == 0.0) {
            continue;
        }
        for i in 0..n {
            if row[i] == 0.0 {
                continue;
            }
            b[i] += row[i] * r;
            for j in 0..n {
                a[(i, j)] += row[i] * row[j];
            }
        }
    }
    for i in 0..n {
        a[(i, i)] += damping * a[(i, i)].max(1e-300);
    }
    let delta = a.cholesky()?.solve(&-b);
    if delta.iter().any(|d| !d.is_finite()) {
        return None;
    }
    Some((0..lights).map(|l| Vec3::new(delta[3 * l], delta[3 * l + 1], delta[3 * l + 2])).collect())
}

/// All cameras' pixels of `images`, in order.
pub fn flatten(images: &[Image]) -> Vec<f64> {
    images.iter().flat_map(|im| im.data.iter().copied()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Lens;

    fn blob() -> Grid<f64> {
        let (lo, hi) = (Vec3::new(-0.5, -0.6, -0.4), Vec3::new(0.5, 0.6, 0.4));
        let shape = [8, 12, 10];
        let mut grid = Grid::new(lo, hi, shape, vec![0.0; 960]);
        for k in 0..8 {
            for j in 0..12 {
                for i in 0..10 {
                    let c = grid.voxel_center(k, j, i);
                    let r2 = (c.x - 0.05).powi(2) / 0.06 + c.y.powi(2) / 0.1 + (c.z + 0.03).powi(2) / 0.04;
                    let v = grid.index(k, j, i);
                    grid.data[v] = 3.0 * (-r2 * 2.0).exp() * (1.0 - r2).max(0.0);
                }
            }
        }
        grid
    }

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(0.3, 0.2, 3.0),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: Lens::Pinhole { fx: 30.0, fy: 30.0, cx: 6.0, cy: 5.0 },
            width: 12,
            height: 10,
        }
    }

    /// The lanes are the derivative of the same estimator: central finite
    /// differences of its value, every pixel, each axis.
    #[test]
    fn the_position_lanes_match_finite_differences() {
        let density = blob();
        let gathers = Gathers::new(&density, 2.0, 0.9, &[camera()]);
        let light = Vec3::new(1.7, 1.1, -0.6);
        let image = single_image(&gathers, &density, 2.0, 0.5, &light);
        let lit = image.iter().filter(|v| v.re > 0.0).count();
        assert!(lit > 20, "only {lit} pixels see the blob");
        let h = 1e-5;
        for axis in 0..3 {
            let mut e = Vec3::zeros();
            e[axis] = h;
            let up = single_image(&gathers, &density, 2.0, 0.5, &(light + e));
            let down = single_image(&gathers, &density, 2.0, 0.5, &(light - e));
            let scale = image.iter().map(|v| lane(v, axis).abs()).fold(0.0, f64::max);
            assert!(scale > 0.0);
            for p in 0..image.len() {
                let fd = (up[p].re - down[p].re) / (2.0 * h);
                let dual = lane(&image[p], axis);
                assert!((fd - dual).abs() < 1e-5 * scale, "axis {axis}, pixel {p}: dual {dual} vs fd {fd}");
            }
        }
    }
}
