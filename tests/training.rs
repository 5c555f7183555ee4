//! The experiment binaries end to end at a tiny size (`--smoke`): they run,
//! write every promised file, and their numbers are finite.

use std::process::Command;

#[test]
fn experiment_table1_smoke_run_writes_everything() {
    let dir = std::env::temp_dir().join(format!("dualphoton-table1-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_experiment_table1"))
        .args(["--smoke", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in [
        "density_gt.npy",
        "density_initial.npy",
        "density_estimated.npy",
        "hull.npy",
        "scene.json",
        "log.csv",
        "manifest.json",
        "table1.csv",
        "table1.md",
        "table1.svg",
        "fig5_loss.svg",
        "fig6_camera2.png",
        "fig6_camera2.svg",
        "fig7_scatter.svg",
        "fig8_held_out.png",
        "fig8_held_out.svg",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let svg = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    let (fig6, fig8, table1) = (svg("fig6_camera2.svg"), svg("fig8_held_out.svg"), svg("table1.svg"));
    // Fig. 6: iterations 0 and 2 of the smoke run, then the target, each an embedded image with its label.
    assert_eq!(fig6.matches("<image").count(), 3, "{fig6}");
    for label in ["iteration 0", "iteration 2", "ground truth"] {
        assert!(fig6.contains(label), "fig6 lacks {label:?}");
    }
    // Fig. 8: three panels and the colour bar, titled.
    assert_eq!(fig8.matches("<image").count(), 4);
    assert!(fig8.contains("signed error") && fig8.contains("estimate"));
    for label in ["before training", "after training", "ground truth", "ours", "paper"] {
        assert!(table1.contains(label), "table1.svg lacks {label:?}");
    }
    let manifest: serde_json::Value = serde_json::from_str(&svg("manifest.json")).unwrap();
    for key in ["seed", "estimator", "weight_mode", "target_photons", "hull_voxels", "git", "wall_s", "threads"] {
        assert!(manifest.get(key).is_some(), "manifest lacks {key}");
    }
    let log = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    assert_eq!(log.lines().count(), 4, "header + 3 iterations");
    assert!(!log.contains("NaN") && !log.contains("inf"), "{log}");
    for bin in [env!("CARGO_BIN_EXE_fig5"), env!("CARGO_BIN_EXE_fig7")] {
        let out = Command::new(bin).args(["--dir", dir.to_str().unwrap()]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
}

#[test]
fn training_lowers_the_loss_with_exact_gradients() {
    // rev-full on a 16^3 plume: a few updates must lower the training loss.
    let dir = std::env::temp_dir().join(format!("dualphoton-train-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_experiment_table1"))
        .args(["--smoke", "--estimator", "rev-full", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let log = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    let losses: Vec<f64> = log.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
    assert!(losses.iter().all(|l| l.is_finite()));
}

#[test]
fn benchmarks_run_at_smoke_size() {
    for (bin, name) in [(env!("CARGO_BIN_EXE_bench_render"), "render"), (env!("CARGO_BIN_EXE_bench_grad"), "grad")] {
        let dir = std::env::temp_dir().join(format!("dualphoton-bench-{name}-{}", std::process::id()));
        let out = Command::new(bin).args(["--smoke", "--out", dir.to_str().unwrap()]).output().unwrap();
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(dir.join("summary.md").exists() && dir.join("manifest.json").exists());
    }
}

#[test]
fn stability_study_passes_every_case_at_smoke_size() {
    let dir = std::env::temp_dir().join(format!("dualphoton-stability-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_stability"))
        .args(["--smoke", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in ["report.csv", "summary.md", "fd_error.svg", "manifest.json"] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let mut report = csv::Reader::from_path(dir.join("report.csv")).unwrap();
    let header = report.headers().unwrap().clone();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
    for name in ["case", "passed", "values_finite", "derivatives_finite", "fd_rel_error", "seconds", "note"] {
        column(name);
    }
    let rows: Vec<csv::StringRecord> = report.records().map(|r| r.unwrap()).collect();
    // One row per case, each printed as one progress line.
    let stderr = String::from_utf8_lossy(&out.stderr);
    let progress = stderr.lines().filter(|l| l.starts_with("ok ") || l.starts_with("FAIL ")).count();
    assert_eq!(rows.len(), progress, "rows and progress lines differ");
    let cases: Vec<&str> = rows.iter().map(|r| &r[column("case")]).collect();
    for case in ["optical depth 1e4", "zero density", "albedo 1", "g 0.9999", "zero photons", "invalid: g = 1"] {
        assert!(cases.contains(&case), "no row for {case}");
    }
    for r in &rows {
        assert_eq!(&r[column("passed")], "true", "{} failed: {}", &r[column("case")], &r[column("note")]);
    }
}

#[test]
fn fit_writes_its_log_arrays_and_figures() {
    // A 16^3 paper scene, its images, then `fit` with the last camera held out.
    let dir = std::env::temp_dir().join(format!("dualphoton-fit-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = |p: &str| dir.join(p).to_str().unwrap().to_string();
    let (scene, images, fit) = (d("scene"), d("images"), d("fit"));
    let json = format!("{scene}/scene.json");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_dualphoton")).args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    run(&["scene", "--res", "16", "--out", &scene]);
    run(&["render", "--scene", &json, "--out", &images, "--photons", "5000"]);
    run(&["fit", "--scene", &json, "--images", &images, "--out", &fit, "--held-out", "1", "--iterations", "2"]);
    let files =
        ["log.csv", "density_estimated.npy", "hull.npy", "fig5_loss.svg", "fig6_camera2.svg", "fig8_held_out.svg"];
    for f in files {
        assert!(dir.join("fit").join(f).exists(), "{f} missing");
    }
    let log = std::fs::read_to_string(dir.join("fit/log.csv")).unwrap();
    assert_eq!(log.lines().count(), 3, "header + 2 iterations: {log}");
}
