//! The photon-mapping renderer against the unbiased path tracer on the same
//! small heterogeneous scenes, order by order.
//!
//! Tolerances: an order's image mean must agree within 3 standard errors
//! (path tracer and the spread of 8 photon seeds combined) plus a bias
//! allowance: 1 % for ray-march quadrature at order 1; 4 % at orders >= 2
//! for the blur of the photon estimate (kernel of one voxel plus the
//! trilinear hat of the node grid), which shifts power from dense, strongly
//! attenuated parts to thin ones. Measured on this 16^3 blob: +2.5 % ± 0.5 %
//! at order 2 (g = 0.5), and +0.9 % ± 0.5 % on the same blob at 32^3: the
//! bias scales with the voxel size. 4x4-block means must agree to a
//! relative RMSE, both renderers' noise subtracted, of 6 % (g = 0.5) and
//! 12 % (g = 0.9, whose photon estimate is heavy-tailed: a photon heading
//! for the camera weighs p_HG ≈ 15 against ≈ 0.02 for back-scatter).

use dualphoton::eval::scenes::two_light_blob;
use dualphoton::image::Image;
use dualphoton::render::path::{render_path, PathOptions};
use dualphoton::render::render_photon;
use dualphoton::scene::Scene;

/// The 16^3 two-light blob, one 16x16 camera.
fn scene(g: f64, max_order: u32, seed: u64) -> Scene {
    let mut s = two_light_blob(16, g, max_order, 16);
    s.render.photons = 100_000;
    // One voxel: the blur bias at this coarse 16^3 grid is then about 1 % on image means.
    s.render.kernel_radius = Some(0.0625);
    s.render.spp = 8;
    s.render.seed = seed;
    s
}

/// Photon-mapped image of order `n` alone: same seed, so orders below `n` are identical and cancel.
fn photon_order(g: f64, n: u32, seed: u64) -> Image {
    let hi = render_photon(&scene(g, n, seed)).images.remove(0);
    if n == 1 {
        return hi;
    }
    let lo = render_photon(&scene(g, n - 1, seed)).images.remove(0);
    Image { width: hi.width, height: hi.height, data: hi.data.iter().zip(&lo.data).map(|(a, b)| a - b).collect() }
}

struct Reference {
    radiance: Image,
    std_err: Image,
}

fn path_order(g: f64, n: u32, spp: u32) -> Reference {
    let opts = PathOptions { spp, seed: 9, max_order: Some(n), min_order: n };
    let mut r = render_path(&scene(g, n, 0), &opts);
    Reference { radiance: r.radiance.remove(0), std_err: r.std_err.remove(0) }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Photon seeds per comparison: their spread measures our own noise.
const SEEDS: u64 = 8;

/// (relative difference of image means, the standard error of that
/// difference, block relative RMSE with both renderers' noise removed).
fn compare(ours: &[Image], reference: &Reference) -> (f64, f64, f64) {
    let n = ours.len() as f64;
    let m_ref = mean(&reference.radiance.data);
    let se_ref = reference.std_err.data.iter().map(|s| s * s).sum::<f64>().sqrt() / reference.std_err.data.len() as f64;
    let means: Vec<f64> = ours.iter().map(|o| mean(&o.data)).collect();
    let m_ours = mean(&means);
    let var_ours = means.iter().map(|m| (m - m_ours).powi(2)).sum::<f64>() / (n - 1.0) / n;
    let blocks: Vec<Vec<f64>> = ours.iter().map(|o| o.block_means(4)).collect();
    let a: Vec<f64> = (0..blocks[0].len()).map(|i| blocks.iter().map(|b| b[i]).sum::<f64>() / n).collect();
    // Variance of the seed-averaged block means, from the spread over seeds.
    let noise_ours =
        (0..a.len()).map(|i| blocks.iter().map(|b| (b[i] - a[i]).powi(2)).sum::<f64>() / (n - 1.0) / n).sum::<f64>()
            / a.len() as f64;
    let b = reference.radiance.block_means(4);
    let var = Image { data: reference.std_err.data.iter().map(|s| s * s).collect(), ..reference.std_err.clone() };
    let noise_ref = mean(&var.block_means(4)) / 16.0;
    let mse = a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64;
    let rms_ref = (b.iter().map(|y| y * y).sum::<f64>() / b.len() as f64).sqrt();
    let se = (se_ref * se_ref + var_ours).sqrt() / m_ref;
    ((m_ours - m_ref) / m_ref, se, (mse - noise_ref - noise_ours).max(0.0).sqrt() / rms_ref)
}

fn check(g: f64, n: u32, spp: u32, bias: f64, block_tol: f64) {
    let ours: Vec<Image> = (1..=SEEDS).map(|seed| photon_order(g, n, seed)).collect();
    let reference = path_order(g, n, spp);
    let (rel, se, block) = compare(&ours, &reference);
    eprintln!("g {g} order {n}: mean rel diff {:+.4} (se {:.4}), block rel RMSE {:.4}", rel, se, block);
    assert!(rel.abs() < 3.0 * se + bias, "g {g}, order {n}: image means differ by {rel:+.4} (se {se:.4})");
    assert!(block < block_tol, "g {g}, order {n}: block relative RMSE {block:.4}");
}

#[test]
fn order_one_matches_the_path_tracer() {
    check(0.5, 1, 512, 0.01, 0.03);
    check(0.9, 1, 512, 0.01, 0.03);
}

#[test]
fn order_two_matches_the_path_tracer() {
    check(0.5, 2, 8192, 0.04, 0.06);
    check(0.9, 2, 8192, 0.04, 0.12);
}

#[test]
fn order_three_matches_the_path_tracer() {
    check(0.5, 3, 8192, 0.04, 0.06);
    check(0.9, 3, 8192, 0.04, 0.12);
}
