//! Single scattering by deterministic quadrature: an independent check of
//! both renderers (the photon mapper and the path tracer).
//!
//! A pixel's single-scattered radiance is
//! `∫ T(cam, x) albedo sigma_t(x) Σ_l p_HG(w_l · (-d)) I_l T(x, l) / |x - l|^2 dt`
//! along the camera ray `x = cam + t d`, averaged over the pixel's footprint.
//! Nothing here is shared with the renderers: the phase function is written
//! out again, rays are integrated by Simpson's rule instead of being sampled
//! or marched, and the transmittance is whatever the caller passes (exact
//! for a homogeneous box, or the midpoint rule on the trilinear density).

use crate::math::{intersect_box, Ray, Vec3};
use crate::scene::{Camera, Scene};
use std::f64::consts::PI;

/// The Henyey-Greenstein phase function, written out from its definition
/// (independent of `volume::phase`): `mu` is the cosine between the
/// propagation directions before and after scattering.
pub fn p_hg(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Length of the segment `a -> b` inside the box `[lo, hi]`.
pub fn length_in_box(a: &Vec3, b: &Vec3, lo: &Vec3, hi: &Vec3) -> f64 {
    let r = (b - a).norm();
    match intersect_box(&Ray { origin: *a, dir: (b - a) / r }, lo, hi) {
        Some((t0, t1)) => (t1.min(r) - t0).max(0.0),
        None => 0.0,
    }
}

/// Exact transmittance between two points of a homogeneous medium of
/// extinction `sigma_t` filling `scene`'s box (and nothing outside it).
pub fn homogeneous_transmittance(scene: &Scene, sigma_t: f64) -> impl Fn(&Vec3, &Vec3) -> f64 + '_ {
    move |a, b| (-sigma_t * length_in_box(a, b, &scene.density.lo, &scene.density.hi)).exp()
}

/// Transmittance of `scene`'s trilinear density by the midpoint rule with
/// `k` steps on the part of the segment inside the box.
pub fn midpoint_transmittance(scene: &Scene, k: usize) -> impl Fn(&Vec3, &Vec3) -> f64 + '_ {
    move |a, b| {
        let (lo, hi) = (&scene.density.lo, &scene.density.hi);
        let d = b - a;
        let len = d.norm();
        let Some((t0, t1)) = intersect_box(&Ray { origin: *a, dir: d / len }, lo, hi) else { return 1.0 };
        let t1 = t1.min(len);
        let h = (t1 - t0) / k as f64;
        let tau: f64 = (0..k).map(|i| scene.density.at(&(a + d / len * (t0 + (i as f64 + 0.5) * h)))).sum::<f64>()
            * h
            * scene.medium.sigma_t_scale;
        (-tau).exp()
    }
}

/// Resolution of a pixel's quadrature.
#[derive(Clone, Copy, Debug)]
pub struct Resolution {
    /// Rays per footprint edge (`sub x sub` midpoints over the pixel).
    pub sub: usize,
    /// Simpson intervals along each ray (even).
    pub steps: usize,
}

/// Single-scattered radiance into pixel `(px, py)` of `cam`, from every
/// light of `scene`; `tr(a, b)` is the transmittance between two points.
pub fn single_scattering(
    scene: &Scene,
    cam: &Camera,
    (px, py): (usize, usize),
    res: Resolution,
    tr: &dyn Fn(&Vec3, &Vec3) -> f64,
) -> f64 {
    let (lo, hi) = (&scene.density.lo, &scene.density.hi);
    let m = &scene.medium;
    let sub = res.sub as f64;
    let mut total = 0.0;
    for a in 0..res.sub {
        for b in 0..res.sub {
            let ray = cam.ray(px as f64 + (a as f64 + 0.5) / sub, py as f64 + (b as f64 + 0.5) / sub);
            let Some((t0, t1)) = intersect_box(&ray, lo, hi) else { continue };
            let f = |t: f64| {
                let x = ray.at(t);
                let rho: f64 = scene.density.at(&x);
                let ls: f64 = scene
                    .lights
                    .iter()
                    .map(|l| {
                        let w_l = (x - l.position).normalize(); // light -> x
                        let r2 = (x - l.position).norm_squared();
                        p_hg(m.g, w_l.dot(&-ray.dir)) * l.intensity * tr(&x, &l.position) / r2
                    })
                    .sum();
                tr(&ray.origin, &x) * m.albedo * m.sigma_t_scale * rho * ls
            };
            let h = (t1 - t0) / res.steps as f64;
            let mut sum = f(t0) + f(t1);
            for i in 1..res.steps {
                sum += f(t0 + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            total += sum * h / 3.0;
        }
    }
    total / (sub * sub)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scenes::{homogeneous, look_at_origin, medium, scene};
    use crate::scene::Light;

    #[test]
    fn phase_integrates_to_one() {
        for g in [-0.5, 0.0, 0.7] {
            let n = 100_000;
            let sum: f64 = (0..n).map(|i| p_hg(g, -1.0 + 2.0 * (i as f64 + 0.5) / n as f64)).sum();
            assert!((sum * 2.0 / n as f64 * 2.0 * PI - 1.0).abs() < 1e-6, "g = {g}");
        }
    }

    #[test]
    fn both_transmittances_agree_on_a_homogeneous_box() {
        let s = scene(homogeneous(4, 0.05), medium(0.9, 0.0, 1), vec![], vec![]);
        let (a, b) = (Vec3::new(-1.0, 0.2, 0.1), Vec3::new(0.3, -0.1, -0.2));
        let exact = homogeneous_transmittance(&s, 1.0)(&a, &b);
        assert!((midpoint_transmittance(&s, 100)(&a, &b) - exact).abs() < 1e-12);
        assert!(exact < 1.0 && exact > 0.0);
    }

    #[test]
    fn empty_medium_scatters_nothing() {
        let cam = look_at_origin(Vec3::new(0.0, 0.0, 3.0), 2, 30.0);
        let light = Light { position: Vec3::new(1.0, 1.0, 1.0), intensity: 1.0 };
        let s = scene(homogeneous(4, 0.0), medium(0.9, 0.0, 1), vec![light], vec![cam.clone()]);
        let res = Resolution { sub: 2, steps: 10 };
        assert_eq!(single_scattering(&s, &cam, (0, 1), res, &midpoint_transmittance(&s, 10)), 0.0);
    }
}
