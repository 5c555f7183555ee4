//! The reference path tracer against independent estimators: single
//! scattering against deterministic quadrature, order 2 against a different
//! Monte Carlo estimator with analytic transmittances; exact zeros, thread
//! independence, progress, orders that add up, the sign of the phase.

use dualphoton::eval::quadrature::{
    homogeneous_transmittance, length_in_box, midpoint_transmittance, p_hg, single_scattering, Resolution,
};
use dualphoton::eval::scenes::{homogeneous, look_at_origin, scene};
use dualphoton::math::{intersect_box, Vec3};
use dualphoton::render::path::{render_path, render_path_with_progress, PathOptions, PathRender};
use dualphoton::rng::{Purpose, Rng};
use dualphoton::scene::{Light, Medium};
use dualphoton::volume::Grid;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};

fn medium(sigma_t_scale: f64, albedo: f64, g: f64, max_order: u32) -> Medium {
    Medium { sigma_t_scale, albedo, g, max_order, emission: 0.0 }
}

fn light(x: f64, y: f64, z: f64, intensity: f64) -> Light {
    Light { position: Vec3::new(x, y, z), intensity }
}

fn opts(spp: u32, seed: u64, min_order: u32, max_order: u32) -> PathOptions {
    PathOptions { spp, seed, max_order: Some(max_order), min_order }
}

/// Mean of an image and the standard error of that mean.
fn image_mean(r: &PathRender, cam: usize) -> (f64, f64) {
    let (im, se) = (&r.radiance[cam], &r.std_err[cam]);
    let n = im.data.len() as f64;
    (im.data.iter().sum::<f64>() / n, se.data.iter().map(|s| s * s).sum::<f64>().sqrt() / n)
}

/// Pseudo-random densities in [0, 1) on an `n^3` unit box (a fixed stream).
fn noise_grid(n: usize, seed: u64) -> Grid<f64> {
    let mut rng = Rng::new(seed, Purpose::Scene, 0);
    let mut g = homogeneous(n, 0.0);
    g.data.iter_mut().for_each(|v| *v = rng.uniform());
    g
}

fn assert_close(what: &str, mc: f64, se: f64, reference: f64, se_ref: f64) {
    let tol = 3.0 * (se * se + se_ref * se_ref).sqrt() + 0.005 * reference.abs();
    eprintln!(
        "{what}: path {mc:.6e} +- {se:.2e}, reference {reference:.6e} +- {se_ref:.2e}, rel diff {:.4}",
        (mc - reference) / reference
    );
    assert!((mc - reference).abs() <= tol, "{what}: {mc} vs {reference}, tolerance {tol}");
}

#[test]
fn single_scattering_matches_quadrature_homogeneous() {
    let (rho, scale) = (0.05, 20.0); // sigma_t = 1
    let cam = look_at_origin(Vec3::new(0.0, 0.0, 3.0), 8, 20.0);
    let lights = vec![light(1.5, 1.0, 0.5, 10.0), light(-0.3, -2.0, -1.0, 5.0)];
    let s = scene(homogeneous(4, rho), medium(scale, 0.8, 0.5, 1), lights, vec![cam.clone()]);
    let r = render_path(&s, &opts(8192, 1, 1, 1));
    let tr = homogeneous_transmittance(&s, rho * scale);
    let (px, py) = (3, 4);
    let q = single_scattering(&s, &cam, (px, py), Resolution { sub: 8, steps: 400 }, &tr);
    let i = py * 8 + px;
    assert_close("pixel (3, 4)", r.radiance[0].data[i], r.std_err[0].data[i], q, 0.0);
    let coarse = Resolution { sub: 4, steps: 200 };
    let q_mean = (0..64).map(|i| single_scattering(&s, &cam, (i % 8, i / 8), coarse, &tr)).sum::<f64>() / 64.0;
    let (m, se) = image_mean(&r, 0);
    assert_close("image mean", m, se, q_mean, 0.0);
}

#[test]
fn single_scattering_matches_quadrature_heterogeneous() {
    // Random trilinear density on a 10^3 grid, zero for x > 0.05 (voxels
    // i >= 5): blocks of 4 give a loose majorant, an empty block column
    // that clips the occupied box, the clamped outer shell, ratio tracking.
    let n = 10;
    let mut density = noise_grid(n, 3);
    for (v, idx) in density.data.iter_mut().zip(0..) {
        if idx % n >= 5 {
            *v = 0.0;
        }
    }
    let cam = look_at_origin(Vec3::new(0.4, 0.9, 2.8), 1, 2.0);
    let s = scene(density, medium(3.0, 0.9, 0.7, 1), vec![light(2.0, 0.3, -1.5, 20.0)], vec![cam.clone()]);
    let r = render_path(&s, &opts(40_000, 2, 1, 1));
    let q = single_scattering(&s, &cam, (0, 0), Resolution { sub: 4, steps: 200 }, &midpoint_transmittance(&s, 300));
    assert_close("heterogeneous pixel", r.radiance[0].data[0], r.std_err[0].data[0], q, 0.0);
}

#[test]
fn double_scattering_matches_independent_estimator() {
    // Order 2 in a homogeneous box against a different estimator: the
    // first vertex uniform on the camera segment, the second uniform in
    // direction and in distance to the box wall, analytic transmittances.
    let (rho, scale, albedo, g) = (0.1, 20.0, 0.9, 0.6); // sigma_t = 2
    let cam = look_at_origin(Vec3::new(0.5, 0.2, 2.5), 8, 25.0);
    let l = light(2.0, 1.0, -1.0, 30.0);
    let s = scene(homogeneous(4, rho), medium(scale, albedo, g, 3), vec![l.clone()], vec![cam.clone()]);
    let r = render_path(&s, &opts(4096, 5, 2, 2));
    let (m, se) = image_mean(&r, 0);

    let (lo, hi) = (s.density.lo, s.density.hi);
    let (sigma_t, sigma_s) = (rho * scale, albedo * rho * scale);
    let mut rng = Rng::new(9, Purpose::Scene, 1);
    let (n, mut sum, mut sum2) = (1_600_000, 0.0, 0.0);
    for _ in 0..n {
        let ray = cam.ray(rng.uniform() * 8.0, rng.uniform() * 8.0);
        let mut v = 0.0;
        if let Some((t0, t1)) = intersect_box(&ray, &lo, &hi) {
            let t = t0 + rng.uniform() * (t1 - t0);
            let x = ray.at(t);
            let z = 1.0 - 2.0 * rng.uniform();
            let phi = 2.0 * PI * rng.uniform();
            let rxy = (1.0 - z * z).sqrt();
            let w = Vec3::new(rxy * phi.cos(), rxy * phi.sin(), z); // uniform, pdf 1 / (4 pi)
            let (_, s_exit) = intersect_box(&dualphoton::math::Ray { origin: x, dir: w }, &lo, &hi).unwrap();
            let dist = rng.uniform() * s_exit; // pdf 1 / s_exit; dy = dist^2 d(dist) dw cancels 1 / dist^2
            let y = x + w * dist;
            let w_l = (y - l.position).normalize();
            let light_in = l.intensity * (-sigma_t * length_in_box(&y, &l.position, &lo, &hi)).exp()
                / (y - l.position).norm_squared();
            v = (t1 - t0)
                * (-sigma_t * (t - t0)).exp()
                * sigma_s
                * p_hg(g, (-w).dot(&-ray.dir))
                * 4.0
                * PI
                * s_exit
                * (-sigma_t * dist).exp()
                * sigma_s
                * p_hg(g, w_l.dot(&-w))
                * light_in;
        }
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n as f64;
    let se_ref = ((sum2 / n as f64 - mean * mean) / (n - 1) as f64).sqrt();
    assert_close("order-2 image mean", m, se, mean, se_ref);
}

#[test]
fn zero_density_is_exactly_black() {
    let cams =
        vec![look_at_origin(Vec3::new(0.0, 0.0, 3.0), 8, 40.0), look_at_origin(Vec3::new(0.0, 0.0, 0.2), 4, 90.0)];
    let s = scene(homogeneous(4, 0.0), medium(20.0, 0.9, 0.9, 3), vec![light(0.0, 0.0, 0.0, 100.0)], cams);
    let r = render_path(&s, &opts(16, 0, 1, 3));
    assert_eq!(r.samples, (64 + 16) * 16);
    for im in r.radiance.iter().chain(&r.std_err) {
        assert!(im.data.iter().all(|&v| v == 0.0));
    }
}

#[test]
fn bit_identical_for_any_thread_count() {
    let cams =
        vec![look_at_origin(Vec3::new(0.0, 0.0, 2.5), 8, 30.0), look_at_origin(Vec3::new(2.0, 0.5, 1.0), 6, 35.0)];
    let lights = vec![light(1.0, 2.0, 2.0, 50.0), light(-2.0, 0.0, 0.0, 20.0)];
    let s = scene(noise_grid(6, 4), medium(10.0, 0.9, 0.8, 3), lights, cams);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render_path(&s, &opts(8, 11, 1, 3)))
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.radiance, b.radiance);
    assert_eq!(a.std_err, b.std_err);
    assert!(a.radiance[1].data.iter().any(|&v| v > 0.0));
}

#[test]
fn progress_reaches_total() {
    let cam = look_at_origin(Vec3::new(0.0, 0.0, 2.0), 20, 40.0);
    let s = scene(homogeneous(4, 0.1), medium(10.0, 0.9, 0.0, 2), vec![light(0.0, 2.0, 0.0, 1.0)], vec![cam]);
    let (calls, last) = (AtomicUsize::new(0), AtomicUsize::new(0));
    render_path_with_progress(&s, &opts(1, 0, 1, 2), &|done, total| {
        assert!(done <= total && total == 400);
        calls.fetch_add(1, Ordering::Relaxed);
        last.fetch_max(done, Ordering::Relaxed);
    });
    assert!(calls.into_inner() > 1);
    assert_eq!(last.into_inner(), 400);
}

#[test]
fn orders_isolate_and_add_up() {
    let cam = look_at_origin(Vec3::new(0.0, 0.5, 2.5), 8, 30.0);
    let s = scene(noise_grid(6, 7), medium(8.0, 0.95, 0.5, 3), vec![light(1.5, 1.5, 1.0, 40.0)], vec![cam]);
    let (one, two, both) = (
        render_path(&s, &opts(1024, 1, 1, 1)),
        render_path(&s, &opts(1024, 2, 2, 2)),
        render_path(&s, &opts(1024, 3, 1, 2)),
    );
    let ((m1, s1), (m2, s2), (m12, s12)) = (image_mean(&one, 0), image_mean(&two, 0), image_mean(&both, 0));
    assert!(m2 > 0.05 * m1, "order 2 should matter here: {m2} vs {m1}");
    assert_close("order 1 + order 2 vs max_order 2", m1 + m2, (s1 * s1 + s2 * s2).sqrt(), m12, s12);
}

#[test]
fn forward_scattering_sign() {
    // g = 0.9, thin medium: a light behind the medium shining into the
    // camera must be far brighter than the same light beside the camera,
    // for single scattering (NEE sign) and for order 2 alone (sign of the
    // sampled continuation).
    let cam = look_at_origin(Vec3::new(0.0, 0.0, 3.0), 8, 20.0);
    let render = |l: Light, order: u32| {
        let s = scene(homogeneous(4, 0.01), medium(20.0, 0.9, 0.9, 2), vec![l], vec![cam.clone()]);
        image_mean(&render_path(&s, &opts(64, 0, order, order)), 0).0
    };
    for order in [1, 2] {
        let behind = render(light(0.0, 0.0, -3.0, 10.0), order);
        let beside = render(light(0.3, 0.0, 3.0, 10.0), order);
        eprintln!("order {order}: behind {behind:.3e}, camera side {beside:.3e}");
        assert!(behind > 20.0 * beside, "order {order}: behind {behind} vs camera side {beside}");
    }
}
