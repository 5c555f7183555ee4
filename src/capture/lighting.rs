//! The lighting of a fit, and the cameras' gains: the candidate lights and
//! the ambient term (the medium's emission). A frame's images are linear in
//! every light's intensity, in the emission and in each camera's gain, so
//! for a given density these follow exactly from one render per light and
//! one of the emission alone (non-negative least squares). The lights'
//! places are not linear: a Levenberg-Marquardt step with the Jacobian of
//! [`super::lights`] (dual lanes), kept only if the renderer agrees.

use super::align::geometric_mean;
use super::lights::{flatten, single_image, step, Gathers};
use crate::error::Result;
use crate::image::Image;
use crate::math::{frame, Vec3};
use crate::render::render_photon;
use crate::scene::{Light, Scene};

/// The candidate lights: far from the box (four times its half-diagonal
/// from its centre), six around it 20 degrees above its centre (every 60
/// degrees of azimuth about the up axis +y, starting at +x) plus one above
/// and one below. Their intensities are fitted (most end at 0): a fixed
/// basis able to express a few studio lights in unknown places. With
/// `radius_deg` > 0 each is a disc facing the box's centre, of that
/// angular radius seen from it, as studio softboxes are: [`disc_points`]
/// point lights in turn, sharing its intensity. 0: points.
pub fn candidate_lights(lo: &Vec3, hi: &Vec3, radius_deg: f64) -> Vec<Light> {
    let centre = (lo + hi) / 2.0;
    let distance = 2.0 * (hi - lo).norm();
    let mut dirs: Vec<Vec3> = (0..6).map(|k| direction(k as f64 * 60.0, 20.0)).collect();
    dirs.push(Vec3::new(0.0, 1.0, 0.0));
    dirs.push(Vec3::new(0.0, -1.0, 0.0));
    dirs.into_iter()
        .flat_map(|d| {
            let radius = distance * radius_deg.to_radians().tan();
            disc(&(centre + d * distance), &d, radius, disc_points(radius_deg))
        })
        .map(|position| Light { position, intensity: 0.0 })
        .collect()
}

/// How many point lights sample a candidate of angular radius
/// `radius_deg`: its centre and a ring of six, or the point alone at 0.
pub fn disc_points(radius_deg: f64) -> usize {
    if radius_deg > 0.0 {
        7
    } else {
        1
    }
}

/// `n` points (1 or 7) standing for a disc of `radius` about `centre`,
/// perpendicular to `normal`: its centre, then six on the ring through the
/// centroid of the outer six sevenths of its area (an equal-area split).
fn disc(centre: &Vec3, normal: &Vec3, radius: f64, n: usize) -> Vec<Vec3> {
    if n == 1 {
        return vec![*centre];
    }
    let (a, b) = frame(normal);
    let inner = 1.0 / 7f64.sqrt();
    let ring = radius * (2.0 / 3.0) * (1.0 - inner.powi(3)) / (1.0 - inner.powi(2));
    std::iter::once(*centre)
        .chain((0..6).map(|k| {
            let t = k as f64 * std::f64::consts::PI / 3.0;
            centre + (a * t.cos() + b * t.sin()) * ring
        }))
        .collect()
}

/// The unit direction at `azimuth` degrees about the up axis +y (0 at +x,
/// 90 at +z) and `elevation` degrees above the horizontal: where the
/// candidates, and a made capture's lights, are placed.
pub fn direction(azimuth: f64, elevation: f64) -> Vec3 {
    let (az, el) = (azimuth.to_radians(), elevation.to_radians());
    Vec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin())
}

/// One render per light of `scene` (intensity 1, no emission) and one of
/// the emission alone, the `b`-th from seed `seed + b`. A light is `per`
/// consecutive point lights of `scene` (a disc's), each at 1 / `per`.
fn unit_renders(scene: &Scene, per: usize, seed: u64) -> Vec<Vec<Image>> {
    let lights = scene.lights.len() / per;
    (0..=lights)
        .map(|b| {
            let mut one = scene.clone();
            one.render.seed = seed.wrapping_add(b as u64);
            one.medium.emission = if b == lights { 1.0 } else { 0.0 };
            let share = 1.0 / per as f64;
            one.lights
                .iter_mut()
                .enumerate()
                .for_each(|(m, light)| light.intensity = if m / per == b { share } else { 0.0 });
            render_photon(&one).images
        })
        .collect()
}

/// Sets the lights' intensities and the emission of `scene` to their
/// non-negative least-squares fit to `targets`: the image is linear in
/// them, so one render per light (intensity 1, no emission) and one of the
/// emission alone give it exactly. A light is `per` consecutive point
/// lights of `scene` ([`candidate_lights`]' discs). Returns those renders.
pub(super) fn fit_lights(
    scene: &mut Scene,
    targets: &[Image],
    ambient: bool,
    per: usize,
    renders: &mut u64,
) -> Result<Vec<Vec<Image>>> {
    let seed = scene.render.seed.wrapping_add(*renders);
    *renders += (scene.lights.len() / per) as u64 + 1;
    let basis = unit_renders(scene, per, seed);
    let weights = light_weights(&basis, targets, ambient);
    if weights.iter().all(|&w| w == 0.0) {
        // Nothing rendered (the density has gone to 0 where the images are
        // black): the last intensities stay, so the density can grow back.
        return Ok(basis);
    }
    set_weights(scene, &weights, per);
    Ok(basis)
}

/// The lights' intensities, then the emission; each light's shared by
/// its `per` point lights.
fn set_weights(scene: &mut Scene, weights: &[f64], per: usize) {
    for (m, light) in scene.lights.iter_mut().enumerate() {
        light.intensity = weights[m / per] / per as f64;
    }
    scene.medium.emission = *weights.last().unwrap();
}

/// The lights' intensities, then the emission, of `scene`: the weights of
/// its unit renders, a light being `per` point lights.
pub(super) fn weights_of(scene: &Scene, per: usize) -> Vec<f64> {
    let mut weights = vec![0.0; scene.lights.len() / per];
    scene.lights.iter().enumerate().for_each(|(m, l)| weights[m / per] += l.intensity);
    weights.push(scene.medium.emission);
    weights
}

/// Camera `c`'s render: `basis` (unit renders) weighted by `weights`.
fn weighted(basis: &[Vec<Image>], weights: &[f64], c: usize) -> Vec<f64> {
    let mut sum = vec![0.0; basis[0][c].data.len()];
    for (b, w) in basis.iter().zip(weights) {
        sum.iter_mut().zip(&b[c].data).for_each(|(s, v)| *s += w * v);
    }
    sum
}

/// `sum_b weights_b basis_b` minus `targets`, all cameras' pixels in order.
fn residual(basis: &[Vec<Image>], weights: &[f64], targets: &[Image]) -> Vec<f64> {
    (0..targets.len())
        .flat_map(|c| {
            weighted(basis, weights, c).into_iter().zip(&targets[c].data).map(|(r, t)| r - t).collect::<Vec<_>>()
        })
        .collect()
}

/// Multiplies every camera's gain by the least-squares scale of its render
/// (`basis` weighted by `weights`: the lights' intensities, then the
/// emission) onto its target (its photograph over its gain, censored),
/// then divides all by their geometric mean, which the lights absorb: the
/// render's level is the lights', the gains say only how the cameras differ.
pub(super) fn fit_gains(gains: &mut [f64], weights: &[f64], basis: &[Vec<Image>], targets: &[Image]) {
    let fitted: Vec<f64> = (0..gains.len())
        .map(|c| {
            let render = weighted(basis, weights, c);
            let rr: f64 = render.iter().map(|r| r * r).sum();
            let rt: f64 = render.iter().zip(&targets[c].data).map(|(r, t)| r * t).sum();
            if rr > 0.0 && rt > 0.0 {
                gains[c] * rt / rr
            } else {
                gains[c]
            }
        })
        .collect();
    let mean = geometric_mean(&fitted);
    gains.iter_mut().zip(&fitted).for_each(|(g, f)| *g = f / mean);
}

/// A gain and a black level per camera: the least-squares line `gain r +
/// black` of its photograph `p` (linear, not over its gain) on its render
/// `r` (`basis` weighted by `weights`) over the pixels the capture's
/// threshold does not hide (those where `p` > 0 or the line reaches
/// `threshold`, the hidden ones read as 0, or with `to_threshold` as the
/// threshold), the black level within `threshold` either way (beyond it
/// the processing would have shown or hidden the whole background); the
/// gains then divided by their geometric mean, which the lights absorb.
pub(super) fn fit_gains_and_blacks(
    gains: &mut [f64],
    blacks: &mut [f64],
    weights: &[f64],
    basis: &[Vec<Image>],
    photographs: &[Image],
    threshold: f64,
    to_threshold: bool,
) {
    let hidden = if to_threshold { threshold } else { 0.0 };
    let fitted: Vec<f64> = (0..gains.len())
        .map(|c| {
            let render = weighted(basis, weights, c);
            let seen: Vec<(f64, f64)> = render
                .iter()
                .zip(&photographs[c].data)
                .filter(|&(&r, &p)| p > 0.0 || gains[c] * r + blacks[c] >= threshold)
                .map(|(&r, &p)| (r, if p > 0.0 { p } else { hidden }))
                .collect();
            let n = seen.len() as f64;
            let (sr, sp) = seen.iter().fold((0.0, 0.0), |(a, b), (r, p)| (a + r, b + p));
            let (srr, srp) = seen.iter().fold((0.0, 0.0), |(a, b), (r, p)| (a + r * r, b + r * p));
            let det = n * srr - sr * sr;
            if !det.is_finite() || det <= 0.0 {
                return gains[c];
            }
            let black = ((srr * sp - sr * srp) / det).clamp(-threshold, threshold);
            let gain = (srp - black * sr) / srr;
            if gain > 0.0 && gain.is_finite() {
                blacks[c] = black;
                gain
            } else {
                gains[c]
            }
        })
        .collect();
    let mean = geometric_mean(&fitted);
    gains.iter_mut().zip(&fitted).for_each(|(g, f)| *g = f / mean);
}

/// Keeps the `keep` lights of `scene` that add most to the images (by
/// `basis`, their renders at unit intensity), then moves them by one
/// Levenberg-Marquardt step ([`super::lights`]) with `damping`, tried
/// again with more damping (up to three times) until the renderer's
/// images at the new places, intensities fitted again from renders of the
/// same seeds, agree better with `targets`. A place within the box's
/// diagonal of its centre is refused: the lights are outside the set.
/// Point lights only (each light one point of `scene`).
pub(super) fn place_lights(
    scene: &mut Scene,
    targets: &[Image],
    basis: &[Vec<Image>],
    keep: usize,
    ambient: bool,
    damping: &mut f64,
    renders: &mut u64,
) {
    if scene.lights.len() > keep {
        let share = parts(basis, &weights_of(scene, 1));
        let mut order: Vec<usize> = (0..scene.lights.len()).collect();
        order.sort_by(|&a, &b| share[b].total_cmp(&share[a]));
        let mut kept = order[..keep].to_vec();
        kept.sort_unstable();
        scene.lights = kept.iter().map(|&l| scene.lights[l].clone()).collect();
    }
    // Every image of this call from one seed: the trials differ from the
    // current places by the places alone, not by the renders' noise.
    let seed = scene.render.seed.wrapping_add(*renders);
    *renders += scene.lights.len() as u64 + 1;
    let basis = unit_renders(scene, 1, seed);
    let weights = light_weights(&basis, targets, ambient);
    if weights.iter().all(|&w| w == 0.0) {
        return;
    }
    set_weights(scene, &weights, 1);
    let error = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let r = residual(&basis, &weights, targets);
    let before = error(&r);
    let (lo, hi) = (scene.density.lo, scene.density.hi);
    let (centre, diagonal) = ((lo + hi) / 2.0, (hi - lo).norm());
    let m = &scene.medium;
    let gathers = Gathers::new(&scene.density, m.sigma_t_scale, m.albedo, &scene.cameras);
    let singles: Vec<_> = scene
        .lights
        .iter()
        .map(|l| single_image(&gathers, &scene.density, m.sigma_t_scale, m.g, &l.position))
        .collect();
    let linear: Vec<Vec<f64>> = basis.iter().map(|b| flatten(b)).collect();
    for _ in 0..3 {
        let Some(moves) = step(&r, &weights, &singles, &linear, *damping) else { break };
        let mut trial = scene.clone();
        trial.lights.iter_mut().zip(&moves).for_each(|(l, d)| l.position += d);
        if trial.lights.iter().all(|l| (l.position - centre).norm() > diagonal) {
            let trial_basis = unit_renders(&trial, 1, seed);
            let trial_weights = light_weights(&trial_basis, targets, ambient);
            if error(&residual(&trial_basis, &trial_weights, targets)) < before {
                set_weights(&mut trial, &trial_weights, 1);
                *scene = trial;
                *damping = (*damping / 3.0).max(1e-6);
                return;
            }
        }
        *damping *= 4.0;
    }
}

/// The share of the lights (all `weights` but the last, the emission's) in
/// the light of the images `basis` weighted by `weights`; `None` if there
/// is none.
pub(super) fn light_share(basis: &[Vec<Image>], weights: &[f64]) -> Option<f64> {
    let parts = parts(basis, weights);
    let total: f64 = parts.iter().sum();
    (total > 0.0).then(|| parts[..parts.len() - 1].iter().sum::<f64>() / total)
}

/// Each unit render's part of the light of the images `basis` weighted by
/// `weights`: its weight times its pixels' sum over all cameras.
fn parts(basis: &[Vec<Image>], weights: &[f64]) -> Vec<f64> {
    basis.iter().zip(weights).map(|(b, w)| w * b.iter().flat_map(|im| &im.data).sum::<f64>()).collect()
}

/// The lights' intensities, then the emission, by [`nnls`] on `basis`
/// (their unit renders); without `ambient` the emission is held at 0.
fn light_weights(basis: &[Vec<Image>], targets: &[Image], ambient: bool) -> Vec<f64> {
    if ambient {
        return nnls(basis, targets);
    }
    let mut weights = nnls(&basis[..basis.len() - 1], targets);
    weights.push(0.0);
    weights
}

/// Non-negative weights `w` minimising `sum_pixels (sum_b w_b basis_b - target)^2`,
/// on the normal equations (few unknowns): cyclic coordinate descent, which
/// the real capture's fits leave at the minimum, else, where its sweeps end
/// short of it (unit renders nearly proportional to each other, as distant
/// candidates' are), Lawson and Hanson's active-set method, exact.
fn nnls(basis: &[Vec<Image>], targets: &[Image]) -> Vec<f64> {
    let n = basis.len();
    let dot = |a: &[Image], b: &[Image]| -> f64 {
        a.iter().zip(b).map(|(x, y)| x.data.iter().zip(&y.data).map(|(p, q)| p * q).sum::<f64>()).sum()
    };
    let gram: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| dot(&basis[i], &basis[j])).collect()).collect();
    let rhs: Vec<f64> = (0..n).map(|i| dot(&basis[i], targets)).collect();
    let mut w = vec![0.0; n];
    for _ in 0..2000 {
        for i in 0..n {
            if gram[i][i] <= 0.0 {
                continue;
            }
            let r: f64 = rhs[i] - (0..n).map(|j| gram[i][j] * w[j]).sum::<f64>();
            w[i] = (w[i] + r / gram[i][i]).max(0.0);
        }
    }
    if at_minimum(&gram, &rhs, &w) {
        w
    } else {
        active_set(&gram, &rhs)
    }
}

/// How far from 0 the gradient of an NNLS minimum may be, relative to the
/// largest `rhs`.
const NNLS_TOLERANCE: f64 = 1e-9;

/// True where `w` meets the conditions of a minimum of `w' gram w / 2 -
/// rhs' w` over `w >= 0`: the gradient 0 on every positive weight, and
/// pointing away from the bound on every weight at 0.
fn at_minimum(gram: &[Vec<f64>], rhs: &[f64], w: &[f64]) -> bool {
    let tolerance = NNLS_TOLERANCE * rhs.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    (0..rhs.len()).all(|i| {
        let descent = rhs[i] - (0..rhs.len()).map(|j| gram[i][j] * w[j]).sum::<f64>();
        descent.abs() <= tolerance || (w[i] == 0.0 && descent < 0.0)
    })
}

/// Lawson and Hanson's active-set NNLS on the normal equations `gram w =
/// rhs`: the weights free to move grow one at a time, each time the one
/// whose descent is steepest, and a step that would make a free weight
/// negative stops at 0 and fixes it there.
fn active_set(gram: &[Vec<f64>], rhs: &[f64]) -> Vec<f64> {
    let n = rhs.len();
    let tolerance = NNLS_TOLERANCE * rhs.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    let mut w = vec![0.0; n];
    let mut free = vec![false; n];
    // Each free set is tried at most once; 3n + 10 rounds is Lawson and Hanson's bound in practice.
    for _ in 0..3 * n + 10 {
        let descent = |w: &[f64], i: usize| rhs[i] - (0..n).map(|j| gram[i][j] * w[j]).sum::<f64>();
        let steepest = (0..n).filter(|&i| !free[i]).map(|i| (i, descent(&w, i))).filter(|&(_, d)| d > tolerance);
        let Some((j, _)) = steepest.max_by(|a, b| a.1.total_cmp(&b.1)) else { break };
        free[j] = true;
        while free.iter().any(|&f| f) {
            let z = solve_free(gram, rhs, &free);
            if (0..n).all(|i| !free[i] || z[i] > 0.0) {
                w = z;
                break;
            }
            // The longest step towards z that keeps every weight >= 0; the
            // weight it stops at leaves the free set, so the loop ends.
            let ratio = |i: usize| if w[i] > z[i] { w[i] / (w[i] - z[i]) } else { 0.0 };
            let blocking = (0..n).filter(|&i| free[i] && z[i] <= 0.0).map(|i| (i, ratio(i)));
            let Some((stop, step)) = blocking.min_by(|a, b| a.1.total_cmp(&b.1)) else { break };
            for i in 0..n {
                w[i] += step * (z[i] - w[i]);
                if free[i] && (i == stop || w[i] <= 0.0) {
                    (free[i], w[i]) = (false, 0.0);
                }
            }
        }
    }
    w
}

/// The least-squares weights with those not `free` held at 0 (a singular
/// system, renders exactly proportional, by its least-norm solution).
fn solve_free(gram: &[Vec<f64>], rhs: &[f64], free: &[bool]) -> Vec<f64> {
    let index: Vec<usize> = (0..rhs.len()).filter(|&i| free[i]).collect();
    let k = index.len();
    let a = nalgebra::DMatrix::from_fn(k, k, |r, c| gram[index[r]][index[c]]);
    let b = nalgebra::DVector::from_fn(k, |r, _| rhs[index[r]]);
    let svd = a.svd(true, true);
    let largest = svd.singular_values.iter().fold(0.0f64, |m, &v| m.max(v));
    let z = svd.solve(&b, 1e-12 * largest).unwrap_or_else(|_| nalgebra::DVector::zeros(k));
    let mut w = vec![0.0; rhs.len()];
    index.iter().zip(z.iter()).for_each(|(&i, &v)| w[i] = v);
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Camera, Medium, RenderSettings};
    use crate::volume::Grid;

    #[test]
    fn the_light_share_weighs_each_unit_render_by_its_intensity() {
        let im = |v: Vec<f64>| vec![Image { width: v.len(), height: 1, data: v }];
        // Two lights (light 1 and 2 units at intensity 1), then the emission (6 units at 1).
        let basis = vec![im(vec![1.0, 0.0]), im(vec![0.5, 1.5]), im(vec![3.0, 3.0])];
        let share = light_share(&basis, &[1.0, 1.0, 0.5]).unwrap();
        assert!((share - 3.0 / 6.0).abs() < 1e-12, "{share}");
        assert_eq!(light_share(&basis, &[0.0, 0.0, 2.0]), Some(0.0));
        assert_eq!(light_share(&basis, &[0.0, 0.0, 0.0]), None);
    }

    #[test]
    fn nnls_recovers_non_negative_weights_and_clips_negative_ones() {
        let im = |v: Vec<f64>| vec![Image { width: v.len(), height: 1, data: v }];
        let basis = vec![im(vec![1.0, 0.0, 1.0]), im(vec![0.0, 1.0, 1.0]), im(vec![1.0, 1.0, 0.0])];
        // target = 2 b0 + 0.5 b1: exact.
        let w = nnls(&basis, &im(vec![2.0, 0.5, 2.5]));
        assert!((w[0] - 2.0).abs() < 1e-9 && (w[1] - 0.5).abs() < 1e-9 && w[2].abs() < 1e-9, "{w:?}");
        // target = b0 - b1 needs a negative weight: the fit keeps b1 at 0.
        let w = nnls(&basis, &im(vec![1.0, -1.0, 0.0]));
        assert!(w.iter().all(|&x| x >= 0.0) && w[1] == 0.0, "{w:?}");
    }

    /// Unit renders nearly proportional to each other (distant candidates,
    /// shading differing by 1-5 %): coordinate descent's sweeps end near
    /// the minimum's value but far from its weights; the fit returns the
    /// exact minimum, checked against its conditions and the known weights.
    #[test]
    fn nnls_finds_the_minimum_where_the_renders_are_nearly_proportional() {
        let pixels = 64;
        let shape = |k: usize, p: usize| {
            let x = p as f64 / pixels as f64;
            1.0 + 0.03 * ((k + 1) as f64 * 2.0 * x + k as f64).sin()
        };
        let im = |v: Vec<f64>| vec![Image { width: v.len(), height: 1, data: v }];
        let basis: Vec<Vec<Image>> = (0..9).map(|k| im((0..pixels).map(|p| shape(k, p)).collect())).collect();
        let truth = [0.0, 0.15, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0];
        let target = im((0..pixels).map(|p| (0..9).map(|k| truth[k] * shape(k, p)).sum()).collect());
        let w = nnls(&basis, &target);
        assert!(w.iter().zip(&truth).all(|(a, b)| (a - b).abs() < 1e-6), "{w:?}");
        let dot = |a: &[Image], b: &[Image]| a[0].data.iter().zip(&b[0].data).map(|(p, q)| p * q).sum::<f64>();
        let gram: Vec<Vec<f64>> = (0..9).map(|i| (0..9).map(|j| dot(&basis[i], &basis[j])).collect()).collect();
        let rhs: Vec<f64> = (0..9).map(|i| dot(&basis[i], &target)).collect();
        assert!(at_minimum(&gram, &rhs, &w), "{w:?}");
        // A minimum on the bound: the same target less most of the emission.
        let bound = im((0..pixels).map(|p| target[0].data[p] - 0.9 * shape(8, p) - 0.2).collect());
        let rhs: Vec<f64> = (0..9).map(|i| dot(&basis[i], &bound)).collect();
        let w = nnls(&basis, &bound);
        assert!(w.iter().all(|&x| x >= 0.0) && at_minimum(&gram, &rhs, &w), "{w:?}");
    }

    /// Two cameras whose photographs are their renders times 1.2 and 0.8
    /// get gains in that ratio, of geometric mean 1.
    #[test]
    fn gains_recover_how_the_cameras_differ() {
        let im = |v: Vec<f64>| Image { width: v.len(), height: 1, data: v };
        let basis =
            vec![vec![im(vec![0.1, 0.3, 0.0]), im(vec![0.2, 0.0, 0.1])], vec![im(vec![0.05; 3]), im(vec![0.02; 3])]];
        let weights = [2.0, 1.5];
        let render =
            |c: usize| -> Vec<f64> { (0..3).map(|p| 2.0 * basis[0][c].data[p] + 1.5 * basis[1][c].data[p]).collect() };
        let photographs =
            vec![im(render(0).iter().map(|v| 1.2 * v).collect()), im(render(1).iter().map(|v| 0.8 * v).collect())];
        let mut gains = vec![1.0; 2];
        fit_gains(&mut gains, &weights, &basis, &photographs);
        let mean = (0.96f64).sqrt();
        assert!((gains[0] - 1.2 / mean).abs() < 1e-12 && (gains[1] - 0.8 / mean).abs() < 1e-12, "{gains:?}");
    }

    /// Photographs that are their renders times 1.2 and 0.8 plus 0.01 and
    /// minus 0.01, 0 where that falls below the threshold 0.03 (as the
    /// capture's processing sets them), give those gains' ratio and black
    /// levels; an offset beyond the threshold is held at it.
    #[test]
    fn a_black_level_is_fitted_beside_each_gain() {
        let im = |v: Vec<f64>| Image { width: v.len(), height: 1, data: v };
        let render = [vec![0.0, 0.01, 0.05, 0.1, 0.2, 0.4], vec![0.0, 0.02, 0.04, 0.08, 0.3, 0.5]];
        let basis = vec![render.iter().map(|r| im(r.clone())).collect::<Vec<_>>()];
        let process = |r: &[f64], gain: f64, black: f64| {
            im(r.iter().map(|v| if gain * v + black < 0.03 { 0.0 } else { gain * v + black }).collect())
        };
        let photographs = vec![process(&render[0], 1.2, 0.01), process(&render[1], 0.8, -0.01)];
        let (mut gains, mut blacks) = (vec![1.0; 2], vec![0.0; 2]);
        for _ in 0..3 {
            fit_gains_and_blacks(&mut gains, &mut blacks, &[1.0], &basis, &photographs, 0.03, false);
        }
        assert!((gains[0] / gains[1] - 1.5).abs() < 1e-9, "{gains:?}");
        assert!((blacks[0] - 0.01).abs() < 1e-9 && (blacks[1] + 0.01).abs() < 1e-9, "{blacks:?}");
        let photographs = vec![process(&render[0], 1.0, 0.1), process(&render[1], 1.0, 0.1)];
        let (mut gains, mut blacks) = (vec![1.0; 2], vec![0.0; 2]);
        fit_gains_and_blacks(&mut gains, &mut blacks, &[1.0], &basis, &photographs, 0.03, false);
        assert_eq!(blacks, vec![0.03; 2]);
    }

    /// A pixel the photograph hides (0) where the line reaches the
    /// threshold enters the black level's line as 0, or with `to_threshold`
    /// as the threshold: the least-squares line through those points.
    #[test]
    fn a_hidden_pixel_enters_the_black_level_as_0_or_the_threshold() {
        let im = |v: Vec<f64>| Image { width: v.len(), height: 1, data: v };
        let render = [0.05, 0.1, 0.2, 0.4];
        let basis = vec![vec![im(render.to_vec())]];
        let photographs = vec![im(vec![0.0, 0.1, 0.21, 0.4])];
        let line = |hidden: f64| {
            let p = [hidden, 0.1, 0.21, 0.4];
            let (sr, sp): (f64, f64) = (render.iter().sum(), p.iter().sum());
            let srr: f64 = render.iter().map(|r| r * r).sum();
            let srp: f64 = render.iter().zip(&p).map(|(r, p)| r * p).sum();
            (srr * sp - sr * srp) / (4.0 * srr - sr * sr)
        };
        for (to_threshold, hidden) in [(false, 0.0), (true, 0.03)] {
            let (mut gains, mut blacks) = (vec![1.0], vec![0.0]);
            fit_gains_and_blacks(&mut gains, &mut blacks, &[1.0], &basis, &photographs, 0.03, to_threshold);
            assert!((blacks[0] - line(hidden)).abs() < 1e-12, "{to_threshold}: {blacks:?}, {}", line(hidden));
        }
        assert!(line(0.03) - line(0.0) > 0.01, "the two lines must differ for the test to tell them apart");
    }

    /// A lopsided ball of smoke seen by three cameras, lit by `lights`
    /// (single scattering, no photons: the renders' noise is small).
    fn ball_scene(lights: Vec<Light>) -> Scene {
        use crate::scene::Lens;
        let (lo, hi) = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let mut density = Grid::new(lo, hi, [10, 10, 10], vec![0.0; 1000]);
        for k in 0..10 {
            for j in 0..10 {
                for i in 0..10 {
                    let c = density.voxel_center(k, j, i);
                    let v = density.index(k, j, i);
                    density.data[v] = 4.0 * (1.0 - (c.norm() / 0.45).powi(2)).max(0.0) * (1.0 + c.x);
                }
            }
        }
        let camera = |x: f64, z: f64| Camera {
            position: Vec3::new(x, 0.1, z),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: Lens::Pinhole { fx: 60.0, fy: 60.0, cx: 12.0, cy: 12.0 },
            width: 24,
            height: 24,
        };
        Scene {
            density,
            medium: Medium { sigma_t_scale: 1.0, albedo: 1.0, g: 0.6, max_order: 1, emission: 0.0 },
            lights,
            cameras: vec![camera(0.0, 3.0), camera(3.0, 0.0), camera(-2.1, 2.1)],
            render: RenderSettings { photons: 0, spp: 4, ..RenderSettings::default() },
        }
    }

    /// A light put 25 degrees away from where it lit the target images
    /// (and too weak) is moved back towards its place.
    #[test]
    fn a_misplaced_light_moves_back_towards_its_place() {
        let place = Vec3::new(2.5, 1.0, 1.0);
        let mut scene = ball_scene(vec![Light { position: place, intensity: 5.0 }]);
        let targets = render_photon(&scene).images;
        let turn = 25f64.to_radians();
        let start = Vec3::new(
            place.x * turn.cos() - place.z * turn.sin(),
            place.y,
            place.x * turn.sin() + place.z * turn.cos(),
        );
        scene.lights[0] = Light { position: start, intensity: 2.0 };
        let (mut damping, mut renders) = (1e-3, 0);
        for _ in 0..12 {
            let basis = fit_lights(&mut scene, &targets, true, 1, &mut renders).unwrap();
            place_lights(&mut scene, &targets, &basis, 1, true, &mut damping, &mut renders);
        }
        let angle = |p: &Vec3| p.normalize().dot(&place.normalize()).clamp(-1.0, 1.0).acos().to_degrees();
        let now = angle(&scene.lights[0].position);
        assert!(now < 2.0, "the light is {now:.1} degrees from its place (it started 25 degrees away)");
    }

    /// Each disc is seven points about its candidate's place, in the plane
    /// facing the box's centre, within its angular radius of that place.
    #[test]
    fn a_disc_candidate_is_seven_points_about_the_point_candidate() {
        let (lo, hi) = (Vec3::new(-0.3, 0.0, -0.2), Vec3::new(0.3, 1.0, 0.2));
        let centre = (lo + hi) / 2.0;
        let points = candidate_lights(&lo, &hi, 0.0);
        let discs = candidate_lights(&lo, &hi, 15.0);
        assert_eq!(discs.len(), 7 * points.len());
        for (p, disc) in points.iter().zip(discs.chunks(7)) {
            let mean = disc.iter().map(|l| l.position).sum::<Vec3>() / 7.0;
            assert!((mean - p.position).norm() < 1e-9 * p.position.norm(), "{mean:?} {:?}", p.position);
            let axis = (p.position - centre).normalize();
            for l in &disc[1..] {
                let off = l.position - p.position;
                assert!(off.dot(&axis).abs() < 1e-9, "not in the disc's plane");
                let angle = (l.position - centre).normalize().dot(&axis).acos().to_degrees();
                assert!(angle > 5.0 && angle < 15.0, "{angle} degrees");
            }
        }
    }

    /// A disc's intensity is shared by its points, and the fit recovers the
    /// discs' intensities from images they lit.
    #[test]
    fn disc_lights_are_fitted_as_one_light_each() {
        let (lo, hi) = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
        let mut truth = ball_scene(candidate_lights(&lo, &hi, 20.0));
        let mut weights = vec![0.0; 9];
        (weights[0], weights[3], weights[6]) = (2.0, 1.0, 0.0);
        set_weights(&mut truth, &weights, 7);
        assert!(truth.lights[..7].iter().all(|l| (l.intensity - 2.0 / 7.0).abs() < 1e-15));
        let back = weights_of(&truth, 7);
        assert!(back.iter().zip(&weights).all(|(b, w)| (b - w).abs() < 1e-12), "{back:?}");
        let targets = render_photon(&truth).images;
        let mut scene = truth.clone();
        set_weights(&mut scene, &[0.5; 9], 7);
        let basis = fit_lights(&mut scene, &targets, true, 7, &mut 1).unwrap();
        assert_eq!(basis.len(), 9);
        let fitted = weights_of(&scene, 7);
        assert!((fitted[0] / 2.0 - 1.0).abs() < 0.05 && (fitted[3] - 1.0).abs() < 0.05, "{fitted:?}");
        assert!(fitted.iter().enumerate().filter(|(b, _)| ![0, 3].contains(b)).all(|(_, w)| *w < 0.05), "{fitted:?}");
    }
}
