//! Analytic checks of the transport pieces: phase function, transmittance,
//! single scattering of the photon mapper against an independent quadrature
//! (`dualphoton::eval::quadrature`; the path tracer's is in `path_tracer.rs`).

mod common;

use dualphoton::eval::quadrature::{homogeneous_transmittance, single_scattering, Resolution};
use dualphoton::math::{intersect_box, Ray, Vec3};
use dualphoton::render::march::Marcher;
use dualphoton::render::render_photon;
use dualphoton::rng::Rng;
use dualphoton::scene::Light;
use dualphoton::volume::phase::{hg_eval, hg_sample, hg_sample_mu};
use dualphoton::volume::Majorant;
use std::f64::consts::PI;

/// ∫ p_HG dω by the midpoint rule in y = ln(1 + g^2 - 2 g mu), where the
/// integrand is smooth even for g near ±1 (the peak in mu is 1e-6 wide there).
fn hg_normalisation(g: f64) -> f64 {
    if g == 0.0 {
        return hg_eval(0.0, 0.3) * 4.0 * PI;
    }
    let (y0, y1) = ((1.0 - g.abs()).powi(2).ln(), (1.0 + g.abs()).powi(2).ln());
    let n = 200_000;
    let h = (y1 - y0) / n as f64;
    (0..n)
        .map(|i| {
            let x = (y0 + (i as f64 + 0.5) * h).exp();
            let mu = (1.0 + g * g - x) / (2.0 * g);
            // dmu = dx / (2|g|), dx = x dy
            hg_eval(g, mu) * x / (2.0 * g.abs())
        })
        .sum::<f64>()
        * h
        * 2.0
        * PI
}

/// The HG cumulative distribution of mu, in closed form.
fn hg_cdf(g: f64, mu: f64) -> f64 {
    if g.abs() < 1e-12 {
        return (mu + 1.0) * 0.5;
    }
    (1.0 - g * g) / (2.0 * g) * ((1.0 + g * g - 2.0 * g * mu).powf(-0.5) - 1.0 / (1.0 + g))
}

#[test]
fn hg_integrates_to_one() {
    for g in [-0.999, -0.9, -0.3, 0.0, 0.5, 0.9, 0.99, 0.999] {
        let integral = hg_normalisation(g);
        assert!((integral - 1.0).abs() < 1e-6, "g = {g}: integral {integral}");
    }
}

#[test]
fn hg_eval_is_the_derivative_of_the_cdf() {
    for g in [-0.9, 0.0, 0.5, 0.9] {
        for mu in [-0.9, -0.2, 0.4, 0.95] {
            let h = 1e-6;
            let pdf = (hg_cdf(g, mu + h) - hg_cdf(g, mu - h)) / (2.0 * h) / (2.0 * PI);
            assert!((pdf - hg_eval(g, mu)).abs() < 1e-6 * pdf.max(1.0), "g = {g}, mu = {mu}");
        }
    }
}

#[test]
fn hg_sampling_matches_eval_and_mean_cosine_is_g() {
    for g in [-0.9, -0.5, 0.0, 0.3, 0.9, 0.999] {
        let mut rng = Rng::from_seed(11);
        let n = 400_000;
        let bins = 20;
        let mut hist = vec![0usize; bins];
        let mut mean = 0.0;
        for _ in 0..n {
            let mu = hg_sample_mu(g, rng.uniform());
            assert!(mu.is_finite() && (-1.0..=1.0).contains(&mu));
            mean += mu / n as f64;
            hist[(((mu + 1.0) * 0.5 * bins as f64) as usize).min(bins - 1)] += 1;
        }
        // Mean cosine: the standard error of mu is at most 1/sqrt(n).
        assert!((mean - g).abs() < 5.0 / (n as f64).sqrt(), "g = {g}: mean cosine {mean}");
        // Histogram against the distribution of p_HG (sampled pdf == eval).
        for (b, &count) in hist.iter().enumerate() {
            let (a, c) = (-1.0 + 2.0 * b as f64 / bins as f64, -1.0 + 2.0 * (b + 1) as f64 / bins as f64);
            let expected = (hg_cdf(g, c) - hg_cdf(g, a)) * n as f64;
            let sd = expected.max(1.0).sqrt();
            assert!((count as f64 - expected).abs() < 5.0 * sd + 2.0, "g = {g}, bin {b}: {count} vs {expected:.1}");
        }
    }
}

#[test]
fn hg_is_finite_near_plus_minus_one() {
    for g in [-0.9999, -0.999, 0.999, 0.9999] {
        for mu in [-1.0, -0.5, 0.0, 0.5, 1.0] {
            let p = hg_eval(g, mu);
            assert!(p.is_finite() && p >= 0.0, "g = {g}, mu = {mu}: {p}");
        }
        let w = Vec3::new(0.3, -0.4, 0.5).normalize();
        for u in [0.0, 1e-12, 0.5, 1.0 - 1e-12] {
            let d = hg_sample(g, &w, u, 0.3);
            assert!(d.iter().all(|c| c.is_finite()) && (d.norm() - 1.0).abs() < 1e-9);
        }
    }
}

#[test]
fn transmittance_through_homogeneous_slab_is_exponential() {
    let rho = 0.37;
    let grid = common::homogeneous(16, rho);
    let majorant = Majorant::build(&grid, 4);
    let marcher = Marcher::new(&grid, majorant, 0.5 / 16.0);
    for (from, to) in [
        (Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.0, 0.0, -2.0)),
        (Vec3::new(-1.0, 0.1, 0.2), Vec3::new(0.2, -0.1, 0.0)),
        (Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.3, 0.2, -0.4)),
    ] {
        let ray = Ray { origin: from, dir: (to - from).normalize() };
        let (t0, t1) = intersect_box(&ray, &grid.lo, &grid.hi).unwrap();
        let d = t1.min((to - from).norm()) - t0;
        let t: f64 = marcher.transmittance(&grid, 20.0, &from, &to, 0.37);
        let exact = (-20.0 * rho * d).exp();
        assert!((t - exact).abs() < 1e-12 * exact.max(1e-300) + 1e-15, "{t} vs {exact}");
    }
}

#[test]
fn single_scattering_matches_quadrature_within_one_percent() {
    for (rho, g, light_pos) in [
        (0.05, 0.9, Vec3::new(1.5, 0.3, 2.0)),
        (0.2, -0.3, Vec3::new(-2.0, 1.0, -1.0)),
        (0.02, 0.0, Vec3::new(0.0, 3.0, 0.0)),
    ] {
        let light = Light { position: light_pos, intensity: 100.0 };
        // A narrow field of view: the pixel's footprint is the central ray.
        let cam = common::camera(2.5, 0.01, 1);
        let mut scene = common::scene(
            common::homogeneous(8, rho),
            common::medium(0.9, g, 1),
            vec![light.clone()],
            vec![cam.clone()],
        );
        scene.render.spp = 64;
        let ours = render_photon(&scene).images[0].data[0];
        let tr = homogeneous_transmittance(&scene, 20.0 * rho);
        let reference = single_scattering(&scene, &cam, (0, 0), Resolution { sub: 1, steps: 20_000 }, &tr);
        assert!((ours - reference).abs() < 0.01 * reference, "rho {rho}, g {g}: {ours} vs quadrature {reference}");
    }
}

#[test]
fn emission_without_lights_is_emission_times_one_minus_transmittance() {
    // A homogeneous cube seen head-on through a narrow pixel: every ray
    // crosses the whole edge, 1 unit, so the image is e (1 - exp(-sigma_t)).
    for (rho, emission) in [(0.01, 1.0), (0.1, 0.3), (2.0, 5.0)] {
        let cam = common::camera(2.5, 0.01, 1);
        let mut medium = common::medium(0.9, 0.5, 3);
        medium.emission = emission;
        let mut scene = common::scene(common::homogeneous(8, rho), medium, vec![], vec![cam]);
        scene.render.spp = 4;
        let exact = emission * (1.0 - (-20.0 * rho).exp());
        let ours = render_photon(&scene).images[0].data[0];
        assert!((ours - exact).abs() < 1e-7 * exact, "rho {rho}: photon renderer {ours} vs {exact}");
        let opts = dualphoton::render::path::PathOptions { spp: 20_000, seed: 5, ..Default::default() };
        let path = dualphoton::render::path::render_path(&scene, &opts).radiance[0].data[0];
        // Each path adds e or 0 (a Bernoulli of mean 1 - T): 5 standard errors.
        let se = emission * (exact / emission * (1.0 - exact / emission) / 20_000.0).sqrt();
        assert!((path - exact).abs() < 5.0 * se + 1e-12, "rho {rho}: path tracer {path} vs {exact} (se {se})");
    }
}

/// `auto` shadows read the light-depth grids except near voxels too deep
/// for them (optical depth over 1 across a voxel): where every voxel is that
/// deep they are marched shadow rays, bit for bit; where none is, the grids,
/// bit for bit; on the blob, whose dense lump alone is too deep, neither,
/// and nearer the marched shadow rays than the grids are.
#[test]
fn auto_shadows_march_only_near_thick_voxels() {
    use dualphoton::eval::scenes::{homogeneous, two_light_blob};
    use dualphoton::render::thick::ThickVoxels;
    use dualphoton::scene::{Scene, Shadows};
    let images = |s: &Scene, shadows: Shadows| {
        let mut s = s.clone();
        s.render.shadows = shadows;
        render_photon(&s).images.into_iter().flat_map(|i| i.data).collect::<Vec<f64>>()
    };
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let thick = |s: &Scene| ThickVoxels::new(&s.density, s.medium.sigma_t_scale, 1).map_or(0, |t| t.count());
    // Single scattering: the only order the shadows enter.
    let blob = two_light_blob(10, 0.6, 1, 8);
    // The medium's extinction is 20 per unit density on voxels of 0.1: 2 per unit density per voxel.
    let mut everywhere = blob.clone();
    everywhere.density = homogeneous(10, 0.75);
    let mut thin = blob.clone();
    thin.density.data.iter_mut().for_each(|v| *v *= 0.5);
    assert_eq!((thick(&everywhere), thick(&thin)), (1000, 0));
    assert_eq!(bits(&images(&everywhere, Shadows::Auto)), bits(&images(&everywhere, Shadows::Marched)));
    assert_eq!(bits(&images(&thin, Shadows::Auto)), bits(&images(&thin, Shadows::Grid)));

    let lump = thick(&blob);
    assert!((1..=10).contains(&lump), "the blob's dense lump: {lump} thick voxels");
    let (auto, grid, marched) =
        (images(&blob, Shadows::Auto), images(&blob, Shadows::Grid), images(&blob, Shadows::Marched));
    let distance = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
    let (to_marched, grid_to_marched) = (distance(&auto, &marched), distance(&grid, &marched));
    eprintln!("the blob: auto {to_marched:e} from marched, the grids {grid_to_marched:e}");
    assert!(distance(&auto, &grid) > 0.0 && to_marched > 0.0, "auto is neither the grids nor marched");
    assert!(to_marched < grid_to_marched, "auto {to_marched:e} from marched, the grids {grid_to_marched:e}");
}
