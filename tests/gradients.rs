//! Derivatives of the frozen estimator, checked three ways on the same
//! frozen sample: dual lanes == per-coordinate duals, forward == reverse,
//! both == central finite differences.

use dualphoton::ad::dual::with_tangents;
use dualphoton::eval::scenes::{look_at_origin, two_light_blob};
use dualphoton::grad::forward::{coordinate_gradient, directional, random_directions, random_gradient, Directions};
use dualphoton::grad::loss::mse;
use dualphoton::grad::reverse::{reverse_gradient, Subset};
use dualphoton::image::Image;
use dualphoton::math::Vec3;
use dualphoton::render::frozen::Frozen;
use dualphoton::rng::Rng;
use dualphoton::scene::{Scene, Shadows};
use num_dual::Dual64;

/// The 10^3 two-light blob with a side camera added: two 6x6 cameras,
/// the lights' transmittance from the light-depth grids.
fn scene(max_order: u32) -> Scene {
    scene_with(max_order, Shadows::Grid)
}

/// [`scene`] with the given shadows.
fn scene_with(max_order: u32, shadows: Shadows) -> Scene {
    let mut s = two_light_blob(10, 0.6, max_order, 6);
    s.cameras.push(look_at_origin(Vec3::new(2.2, 0.3, 0.0), 6, 30.0));
    s.render.photons = 2000;
    s.render.seed = 3;
    s.render.shadows = shadows;
    s
}

/// Every way of finding the lights' transmittance; on this blob `auto`
/// marches near its dense lump and reads the grids elsewhere.
const SHADOWS: [Shadows; 3] = [Shadows::Grid, Shadows::Marched, Shadows::Auto];

/// The medium's emission added to [`scene_with`]'s (the lights kept, or
/// none: the emission-absorption image model).
fn emitting(max_order: u32, shadows: Shadows, lights: bool) -> Scene {
    let mut s = scene_with(max_order, shadows);
    s.medium.emission = 0.4;
    if !lights {
        s.lights.clear();
    }
    s
}

/// Scenes with emission: lit (single and multiple scattering), and unlit.
fn emitting_scenes() -> Vec<(String, Scene)> {
    vec![
        ("emission, order 1, Grid".into(), emitting(1, Shadows::Grid, true)),
        ("emission, order 3, Marched".into(), emitting(3, Shadows::Marched, true)),
        ("emission, no lights".into(), emitting(1, Shadows::Grid, false)),
    ]
}

/// Targets: the images of a slightly different density, so residuals are non-zero.
fn targets(scene: &Scene) -> Vec<Image> {
    let mut other = scene.clone();
    other.density.data.iter_mut().enumerate().for_each(|(i, v)| *v *= 0.8 + 0.4 * ((i * 7919) % 13) as f64 / 13.0);
    dualphoton::render::render_photon(&other).images
}

/// Voxels: the blob's centre, its dense lump, a thin edge voxel, an empty corner.
fn probe_voxels(scene: &Scene) -> Vec<(usize, &'static str)> {
    let d = &scene.density;
    let edge = (0..d.len()).filter(|&v| d.data[v] > 0.0).min_by(|&a, &b| d.data[a].total_cmp(&d.data[b])).unwrap();
    vec![
        (d.index(5, 5, 5), "centre"),
        (d.index(5, 6, 6), "lump"),
        (edge, "edge"),
        (d.index(5, 5, 0), "empty side"),
        (d.index(0, 0, 0), "corner"),
    ]
}

/// The frozen loss at `scene.density + h e_v` (decisions from the scene's density).
fn frozen_loss(frozen: &Frozen, targets: &[Image], v: usize, h: f64) -> f64 {
    let mut d = frozen.scene.density.clone();
    d.data[v] += h;
    mse(&frozen.images_with(&d, 2), targets)
}

#[test]
fn dual_derivatives_match_central_differences_of_the_frozen_estimator() {
    let plain = [1, 2, 3].into_iter().flat_map(|o| SHADOWS.map(|s| (format!("order {o}, {s:?}"), scene_with(o, s))));
    for (case, scene) in plain.chain(emitting_scenes()) {
        let targets = targets(&scene);
        let frozen = Frozen::new(&scene, None);
        for (v, name) in probe_voxels(&scene) {
            let mut d = scene.density.map(Dual64::from_re);
            d.data[v] = Dual64::new(scene.density.data[v], 1.0);
            let dual = mse(&frozen.images_with(&d, 2), &targets).eps;
            // Richardson-extrapolated central differences: error O(h^4).
            let h = 1e-3 * scene.density.data[v].max(0.01);
            let c1 = (frozen_loss(&frozen, &targets, v, h) - frozen_loss(&frozen, &targets, v, -h)) / (2.0 * h);
            let c2 = (frozen_loss(&frozen, &targets, v, h / 2.0) - frozen_loss(&frozen, &targets, v, -h / 2.0)) / h;
            let fd = (4.0 * c2 - c1) / 3.0;
            let floor = 1e-9;
            let rel = (dual - fd).abs() / fd.abs().max(floor);
            eprintln!("{case}, {name} voxel {v}: dual {dual:.6e}, fd {fd:.6e}, rel {rel:.1e}");
            assert!(rel <= 1e-5, "{case}, {name}: dual {dual:e} vs fd {fd:e} (rel {rel:e})");
        }
    }
}

#[test]
fn vector_lanes_equal_single_duals_bit_for_bit() {
    let scene = scene(3);
    let targets = targets(&scene);
    let frozen = Frozen::new(&scene, None);
    let voxels: Vec<usize> = probe_voxels(&scene).into_iter().map(|p| p.0).take(4).collect();
    let mut d = scene.density.map(num_dual::DualSVec64::<4>::from_re);
    for (k, &v) in voxels.iter().enumerate() {
        let mut e = [0.0; 4];
        e[k] = 1.0;
        d.data[v] = with_tangents(scene.density.data[v], e);
    }
    let (loss, lanes) = directional(&frozen, &d, &targets);
    for (k, &v) in voxels.iter().enumerate() {
        let mut s = scene.density.map(Dual64::from_re);
        s.data[v] = Dual64::new(scene.density.data[v], 1.0);
        let single = mse(&frozen.images_with(&s, 2), &targets);
        assert_eq!(single.re.to_bits(), loss.to_bits(), "primal differs");
        assert!(single.eps == lanes[k], "lane {k}: {} vs {}", lanes[k], single.eps);
    }
    let primal = mse(&frozen.images_with(&scene.density, 2), &targets);
    assert_eq!(primal.to_bits(), loss.to_bits(), "f64 primal differs from the dual primal");
}

#[test]
fn forward_and_reverse_agree_on_every_voxel() {
    let plain = [1, 3].into_iter().flat_map(|o| SHADOWS.map(|s| (format!("order {o}, {s:?}"), scene_with(o, s))));
    for (case, scene) in plain.chain(emitting_scenes()) {
        let targets = targets(&scene);
        let frozen = Frozen::new(&scene, None);
        let all: Vec<usize> = (0..scene.density.len()).collect();
        let fwd = coordinate_gradient::<8>(&frozen, &all, &targets, &|_, _| {});
        let rev = reverse_gradient(&frozen, &targets, Subset::full());
        let scale = fwd.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        assert!(scale > 0.0);
        let mut worst = 0.0f64;
        for (f, r) in fwd.iter().zip(&rev.grad) {
            worst = worst.max((f - r).abs() / scale);
        }
        eprintln!("{case}: max |fwd - rev| / max |g| = {worst:.2e}, peak tape {} B", rev.peak_tape_bytes);
        assert!(worst <= 1e-9, "{case}: forward and reverse differ by {worst:e} of the largest entry");
    }
}

#[test]
fn the_subset_estimator_is_unbiased() {
    let scene = scene(3);
    let targets = targets(&scene);
    let frozen = Frozen::new(&scene, None);
    let full = reverse_gradient(&frozen, &targets, Subset::full()).grad;
    let seeds = 64;
    let check = |name: &str, estimates: Vec<Vec<f64>>| {
        // Compare along the full gradient and a fixed random direction: the mean of the projections within 3 SE.
        let mut rng = Rng::from_seed(99);
        let probe: Vec<f64> = (0..full.len()).map(|_| rng.normal()).collect();
        for (what, dir) in [("along g", &full), ("random", &probe)] {
            let proj: Vec<f64> = estimates.iter().map(|e| e.iter().zip(dir).map(|(a, b)| a * b).sum()).collect();
            let target: f64 = full.iter().zip(dir).map(|(a, b)| a * b).sum();
            let n = proj.len() as f64;
            let mean = proj.iter().sum::<f64>() / n;
            let se = (proj.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
            eprintln!("{name} {what}: mean {mean:.4e}, full {target:.4e}, se {se:.2e}");
            assert!((mean - target).abs() <= 3.0 * se + 1e-12 * target.abs(), "{name} ({what}) is biased");
        }
    };
    let rev_sub: Vec<Vec<f64>> = (0..seeds)
        .map(|s| reverse_gradient(&frozen, &targets, Subset { pixels: Some(20), paths: Some(300), seed: s }).grad)
        .collect();
    check("rev-sub", rev_sub);
}

/// `fwd-rand` is checked exactly, estimate by estimate: with its own K
/// directions `u_k` (the same stream replayed) it must equal
/// `(1/K) sum_k (u_k . g) u_k` for the exact gradient `g` (reverse mode),
/// to rounding. Then statistically and sharply: along `g` its mean is
/// `|g|^2` with a standard error of `|g|^2 sqrt(2 / (K seeds))` (9 % here),
/// so a zero estimator (0) or a flipped sign (-1) is many errors away.
#[test]
fn fwd_rand_is_its_directions_projection_of_the_exact_gradient() {
    let scene = scene(3);
    let targets = targets(&scene);
    let frozen = Frozen::new(&scene, None);
    let full = reverse_gradient(&frozen, &targets, Subset::full()).grad;
    let params: Vec<usize> = (0..scene.density.len()).filter(|&v| full[v] != 0.0).collect();
    let g: Vec<f64> = params.iter().map(|&v| full[v]).collect();
    let g2: f64 = g.iter().map(|x| x * x).sum();
    const K: usize = 4;
    let seeds = 64;
    let mut along = vec![];
    for s in 0..seeds {
        let estimate = random_gradient::<K>(&frozen, &params, &targets, Directions::Gaussian, &mut Rng::from_seed(s));
        let (dirs, factor) = random_directions::<K>(params.len(), Directions::Gaussian, &mut Rng::from_seed(s));
        assert_eq!(factor, 1.0 / K as f64);
        let proj: Vec<f64> = dirs.iter().map(|u| u.iter().zip(&g).map(|(a, b)| a * b).sum()).collect();
        let want: Vec<f64> =
            (0..params.len()).map(|i| factor * (0..K).map(|k| proj[k] * dirs[k][i]).sum::<f64>()).collect();
        let size = want.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        let worst = params.iter().zip(&want).fold(0.0f64, |m, (&v, w)| m.max((estimate[v] - w).abs()));
        assert!(
            size > 0.0 && worst <= 1e-9 * size,
            "seed {s}: fwd-rand is off its projection by {worst:e} of {size:e}"
        );
        assert!((0..estimate.len()).all(|v| params.contains(&v) || estimate[v] == 0.0), "non-zero off the parameters");
        along.push(estimate.iter().zip(&full).map(|(a, b)| a * b).sum::<f64>() / g2);
    }
    let n = along.len() as f64;
    let mean = along.iter().sum::<f64>() / n;
    let theory_se = (2.0 / (K as f64 * n)).sqrt();
    eprintln!("fwd-rand along g: mean {mean:.3} of |g|^2 (1 expected, standard error {theory_se:.3})");
    assert!((mean - 1.0).abs() <= 4.0 * theory_se, "fwd-rand along g: mean {mean} of |g|^2, expected 1");
}

#[test]
fn tape_primal_equals_f64_bit_for_bit() {
    for shadows in SHADOWS {
        tape_primal_matches(&scene_with(3, shadows));
    }
}

#[test]
fn kept_light_depths_are_the_bits_of_a_new_march() {
    // Reverse mode reads the grids the render kept instead of marching them again.
    for shadows in SHADOWS {
        let scene = scene_with(3, shadows);
        let frozen = Frozen::new(&scene, None);
        let bits = |d: Option<&Vec<Option<dualphoton::volume::Grid<f64>>>>| {
            d.map(|per_light| {
                per_light
                    .iter()
                    .map(|g| g.as_ref().map(|g| g.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>()))
                    .collect::<Vec<_>>()
            })
        };
        let kept = bits(frozen.primal_depths());
        assert_eq!(
            kept.is_some(),
            shadows != Shadows::Marched,
            "{shadows:?}: grids kept only where the render has them"
        );
        assert_eq!(kept, bits(frozen.light_depths(&scene.density).as_ref()), "{shadows:?}");
    }
}

fn tape_primal_matches(scene: &Scene) {
    use dualphoton::ad::tape::{self, Var};
    use dualphoton::volume::Grid;
    let frozen = Frozen::new(scene, None);
    let d = &scene.density;
    let leaves = Grid::new(d.lo, d.hi, d.shape, (0..d.len()).map(|v| Var::leaf(v as u32, d.data[v])).collect());
    let multiple = frozen.multiple_with(|p| frozen.photons[p].power, scene.cameras.len());
    let depths = frozen
        .light_depths(d)
        .map(|per_light| per_light.iter().map(|g| g.as_ref().map(|g| g.map(Var::constant))).collect::<Vec<_>>());
    let rays = frozen.camera_rays(&leaves, None, depths.as_ref());
    let ms: Option<Vec<_>> = multiple
        .as_ref()
        .map(|m| m.iter().map(|e| e.with_values(e.values.iter().map(|&v| Var::constant(v)).collect())).collect());
    for c in 0..scene.cameras.len() {
        for p in 0..scene.cameras[c].pixels() {
            tape::reset();
            let v = rays.pixel(&scene.cameras[c], frozen.first_pixel(c), p, ms.as_ref().map(|m| &m[c]));
            assert_eq!(v.value().to_bits(), frozen.images[c].data[p].to_bits(), "camera {c}, pixel {p}");
        }
    }
    tape::reset();
}
