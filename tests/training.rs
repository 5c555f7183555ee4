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
        "fig5_loss.svg",
        "fig6_camera2.png",
        "fig7_scatter.svg",
        "fig8_held_out.png",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
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
