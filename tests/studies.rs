//! The study binaries end to end at a tiny size (`--smoke`):
//! they run, write every promised file, and their numbers make sense.

use dualphoton::data::plume::plume;
use dualphoton::render::frozen::Frozen;
use dualphoton::render::splat::phase_towards;
use dualphoton::scene::rig;
use std::path::{Path, PathBuf};
use std::process::Command;

fn run(bin: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dualphoton-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(bin).args(["--smoke", "--out", dir.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    dir
}

/// Rows of a CSV file as (header, rows of fields).
fn csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>());
    (lines.next().unwrap(), lines.collect())
}

#[test]
fn grad_variance_smoke_run_measures_every_estimator() {
    let dir = run(env!("CARGO_BIN_EXE_grad_variance"), "grad-variance");
    for f in ["variance.csv", "summary.md", "manifest.json", "variance_vs_time_latent_midway.svg", "theory_check.svg"] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let (head, rows) = csv(&dir.join("variance.csv"));
    let col = |name: &str| head.iter().position(|h| h == name).unwrap();
    for name in ["rev-full", "rev-sub", "fwd-full", "fwd-rand gaussian K=1", "fwd-rand orthonormal K=16", "fwd-guided"]
    {
        assert!(rows.iter().any(|r| r[col("method")].starts_with(name)), "{name} missing");
    }
    for r in &rows {
        for c in ["rel_variance", "bias", "cosine_mean", "seconds", "efficiency"] {
            let v: f64 = r[col(c)].parse().unwrap();
            assert!(v.is_finite(), "{c} of {} is {v}", r[col("method")]);
        }
        // fwd-full and rev-full differentiate the same frozen estimator exactly.
        if r[col("method")] == "fwd-full" {
            let own: f64 = r[col("estimator_noise")].parse().unwrap();
            assert!(own < 1e-12, "fwd-full differs from rev-full: {own}");
        }
    }
}

#[test]
fn error_vs_time_smoke_run_writes_everything() {
    let dir = run(env!("CARGO_BIN_EXE_error_vs_time"), "error-vs-time");
    for f in [
        "reconstruction.csv",
        "reconstruction_final.csv",
        "renderer.csv",
        "reconstruction_epsilon.svg",
        "reconstruction_held_out.svg",
        "renderer_error_vs_time.svg",
        "summary.md",
        "manifest.json",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let (_, finals) = csv(&dir.join("reconstruction_final.csv"));
    assert_eq!(finals.len(), 4, "one row per estimator");
    let (_, log) = csv(&dir.join("reconstruction.csv"));
    for estimator in ["fwd-full", "fwd-rand", "rev-sub", "rev-full"] {
        for phase in ["train", "refine"] {
            assert!(log.iter().any(|r| r[0] == estimator && r[2] == phase), "{estimator}: no {phase} update logged");
        }
    }
    assert!(log.iter().all(|r| r[3..].iter().all(|v| v.parse::<f64>().unwrap().is_finite())));
    let (_, renders) = csv(&dir.join("renderer.csv"));
    assert!(renders.iter().all(|r| r[5].parse::<f64>().unwrap().is_finite()));
}

#[test]
fn photon_diagnostics_smoke_run_compares_every_order() {
    let dir = run(env!("CARGO_BIN_EXE_photon_diagnostics"), "photon-diagnostics");
    let (_, orders) = csv(&dir.join("orders.csv"));
    assert_eq!(orders.len(), 3, "orders 1-3");
    assert!(orders.iter().all(|r| r.iter().all(|v| v.parse::<f64>().unwrap().is_finite())));
    // The tails recounted here from the smoke run's photon map (16^3, 20,000 photons, seed 0), by
    // partition instead of a sort: a wrong camera, order, share or total would not match.
    let (header, tails) = csv(&dir.join("tails.csv"));
    assert_eq!(header, ["order", "photons", "top_0_1_percent", "top_1_percent", "top_10_percent"]);
    let mut scene = rig::paper_training_scene(plume(16, 0), 16);
    (scene.render.photons, scene.render.seed) = (20_000, 0);
    let frozen = Frozen::new(&scene, None);
    let camera = scene.cameras[2].position;
    assert_eq!(tails.len(), scene.medium.max_order as usize - 1, "orders 2 and up");
    for (r, order) in tails.iter().zip(2u8..) {
        assert_eq!(r[0], order.to_string());
        let mut weights: Vec<f64> = frozen
            .photons
            .iter()
            .filter(|p| p.order == order)
            .filter_map(|p| Some(phase_towards(p, &camera, scene.medium.g)? * p.power))
            .collect();
        assert_eq!(r[1], weights.len().to_string(), "order {order}: photons seen by camera 2");
        let total: f64 = weights.iter().sum();
        for (cell, fraction) in r[2..].iter().zip([0.001, 0.01, 0.1]) {
            let k = ((weights.len() as f64 * fraction) as usize).clamp(1, weights.len());
            let n = weights.len();
            let (_, kth, top) = weights.select_nth_unstable_by(n - k, |a, b| a.total_cmp(b));
            let share = (top.iter().sum::<f64>() + *kth) / total;
            let written: f64 = cell.parse().unwrap();
            assert!((written - share).abs() <= 1e-9 * share, "order {order}, top {fraction}: {written} vs {share}");
        }
    }
}

#[test]
fn decoder_capacity_smoke_run_fits_the_truth() {
    let dir = run(env!("CARGO_BIN_EXE_decoder_capacity"), "decoder-capacity");
    let (head, rows) = csv(&dir.join("capacity.csv"));
    let eps = head.iter().position(|h| h == "rel_l1_epsilon").unwrap();
    let (first, last): (f64, f64) = (rows[0][eps].parse().unwrap(), rows.last().unwrap()[eps].parse().unwrap());
    assert!(last < first, "fitting the truth directly must lower the error: {first} -> {last}");
}
