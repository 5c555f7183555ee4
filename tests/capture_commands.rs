//! The capture commands end to end on captures made here: the field's
//! protocol, the rig's choice of image model, `experiment_real`, `fit
//! --capture` and `made_capture`. The test that encodes videos needs
//! `ffmpeg` and says that it skips when it is not installed.

mod common;

use common::capture::{looking_at_origin, write_png, write_video};
use common::temp_dir;
use dualphoton::capture::{calibration, frames, observe, protocol::Protocol, settings::FitSettings};
use dualphoton::io::npy;
use serde_json::{json, Value};
use std::path::Path;

/// The fit settings of the command tests, as a JSON object's fields: a
/// coarse grid and short fits (the commands' plumbing is tested here, not
/// the defaults' fit), the rig without its probe fit under multiple
/// scattering (a test of its own).
const SMALL: &str = r#""rig_lit_share": null, "resolution": 16, "updates": [10, 20], "photons": 4000"#;

#[test]
fn the_protocol_scores_black_as_its_share_of_the_crop() {
    // A 1080x1920 truth that is 0.5 on 50 of the crop's 495 half-resolution columns, black elsewhere.
    let mut truth = dualphoton::image::Image::zeros(1080, 1920);
    for y in 180..1920 {
        for x in 90..190 {
            truth.data[y * 1080 + x] = 0.5;
        }
    }
    let black = dualphoton::image::Image::zeros(1080, 1920);
    let s = Protocol::for_size(1080, 1920).score(&black, &truth);
    assert!((s.psnr.unwrap() - -10.0 * (50.0 / 495.0 * 0.25f64).log10()).abs() < 1e-9, "{s:?}");
    assert_eq!(s.rel_rmse, Some(1.0));
}

/// Encodes `frames` flat grey frames of `code` as `dir/name.mp4` (64x48, H.264).
fn flat_video(dir: &Path, name: &str, frames: u16, code: u16) {
    write_video(dir, name, frames, (64, 48), |_, _, _| code);
}

#[test]
fn the_rig_is_fitted_under_multiple_scattering_only_where_the_probe_finds_the_lights_share() {
    // Two training cameras see a disc of smoke, one of them 5 pixels off: the rig has something to align.
    let dir = temp_dir("capture_rig_rule");
    for (name, dx) in [("a", 0), ("b", 5), ("test", 0)] {
        std::fs::create_dir_all(dir.join(name)).unwrap();
        for f in 0..3 {
            write_png(&dir.join(name).join(format!("{f:03}.png")), 128, 96, false, |x, y| {
                disc(x.saturating_sub(dx), y)
            });
        }
    }
    let cam = |file: &str, x: f64, z: f64| json!({"file_name": file, "frame_num": 3, "camera_angle_x": 0.6, "camera_hw": [96, 128], "transform_matrix": looking_at_origin(x, z)});
    let calib = json!({"train_videos": [cam("a", 0.0, 2.0), cam("b", 2.0, 0.0)], "test_videos": [cam("test", 1.414, 1.414)],
        "voxel_matrix": UNIT_BOX, "voxel_scale": 1.0});
    std::fs::write(dir.join("info.json"), calib.to_string()).unwrap();
    // The rig of a run with `rule` added to small settings (fits of seconds): its model, the probe's share and its cameras.
    let rig = |name: &str, rule: &str| {
        let settings = dir.join(format!("{name}.json"));
        std::fs::write(&settings, format!(r#"{{"resolution": 16, "updates": [4, 4], "photons": 2000{rule}}}"#))
            .unwrap();
        let out = dir.join(name);
        let done = std::process::Command::new(env!("CARGO_BIN_EXE_experiment_real"))
            .arg("--data")
            .arg(&dir)
            .args(["--frames", "2", "--models", "emission-absorption", "--fit-settings"])
            .arg(&settings)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
        let rig: Value = serde_json::from_str(&std::fs::read_to_string(out.join("rig.json")).unwrap()).unwrap();
        (rig["model"].clone(), rig["lit_share"].as_f64(), rig["cameras"].clone())
    };
    let (model, share, cameras) = rig("plain", r#", "rig_lit_share": null"#);
    assert_eq!((model, share), (json!("emission-absorption"), None));
    // A bound no share exceeds keeps the rig the plain one, bit for bit, with the probe's share recorded.
    let (model, share, kept) = rig("above", r#", "rig_lit_share": 1.0"#);
    assert_eq!(model, json!("emission-absorption"));
    assert!(share.is_some_and(|s| s > 0.0 && s <= 1.0), "{share:?}");
    assert_eq!(kept, cameras);
    // A bound of 0 fits it under multiple scattering: other cameras.
    let (model, lit, moved) = rig("below", r#", "rig_lit_share": 0.0"#);
    assert_eq!((model, lit), (json!("multiple"), share), "the same probe");
    assert_ne!(moved, cameras);
    // Turned cameras: written only where fitted, their mean taken out, and a column of the summary.
    assert!(cameras.as_array().unwrap().iter().all(|c| c.get("roll_deg").is_none()), "{cameras}");
    let (_, _, turned) = rig("turned", r#", "rig_lit_share": null, "roll": true"#);
    let turns: Vec<f64> = turned.as_array().unwrap().iter().map(|c| c["roll_deg"].as_f64().unwrap()).collect();
    assert!(turns.iter().sum::<f64>().abs() < 1e-9 && turns.iter().all(|t| t.abs() < 5.0), "{turns:?}");
    let summary = std::fs::read_to_string(dir.join("turned").join("summary.md")).unwrap();
    assert!(summary.contains("turn (degrees)"), "{summary}");
    // A second round, fitted from the first's corrections, moves the cameras on.
    let (_, _, again) = rig("rounds", r#", "rig_lit_share": null, "rig_rounds": 2"#);
    assert_ne!(again, cameras);
}

#[test]
fn experiment_real_scores_black_and_the_nearest_view() {
    if !frames::have_ffmpeg() {
        eprintln!("SKIPPED experiment_real_scores_black_and_the_nearest_view: ffmpeg is not installed");
        return;
    }
    let dir = temp_dir("capture_experiment");
    flat_video(&dir, "test", 3, 100);
    flat_video(&dir, "near", 3, 80);
    flat_video(&dir, "far", 3, 200);
    let cam = |file: &str, x: f64, z: f64| json!({"file_name": file, "frame_num": 3, "camera_angle_x": 0.5, "camera_hw": [48, 64], "transform_matrix": looking_at_origin(x, z)});
    let calib = json!({
        "train_videos": [cam("far.mp4", 2.0, 0.0), cam("near.mp4", 1.0, 1.732)],
        "test_videos": [cam("test.mp4", 0.0, 2.0)],
        "voxel_matrix": UNIT_BOX, "voxel_scale": 1.0,
    });
    std::fs::write(dir.join("info.json"), calib.to_string()).unwrap();
    let exe = env!("CARGO_BIN_EXE_experiment_real");
    let out = dir.join("out");
    let no_probe = dir.join("no_probe.json");
    std::fs::write(&no_probe, format!("{{{SMALL}}}")).unwrap();
    let run_models = |frames: &str, models: &str, out: &std::path::Path| {
        std::process::Command::new(exe)
            .arg("--data")
            .arg(&dir)
            .args(["--frames", frames, "--models", models, "--fit-settings"])
            .arg(&no_probe)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let run = |frames: &str| run_models(frames, "emission-absorption", &out);
    let bad = run("0,3");
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("frame 3 is out of range"), "{err}");
    let bad = run_models("0,2", "emission-absorption,fog", &out);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("'fog' is not an image model"), "{err}");
    assert!(!out.exists(), "an invalid option is refused before any output");
    // `--models none`: the baselines alone.
    let baselines_only = dir.join("baselines_only");
    let ok = run_models("0,2", "none", &baselines_only);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    assert!(baselines_only.join("baselines.csv").exists() && !baselines_only.join("fits.csv").exists());
    let ok = run("0,2");
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let csv = std::fs::read_to_string(out.join("baselines.csv")).unwrap();
    assert_eq!(std::fs::read_to_string(baselines_only.join("baselines.csv")).unwrap(), csv);
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4, "{csv}");
    for row in &rows {
        let psnr: f64 = row[2].parse().unwrap();
        // Black against 100/255: -20 log10(100/255); the nearest view (80) against it: -20 log10(20/255).
        let expected =
            if row[1] == "all black" { -20.0 * (100.0f64 / 255.0).log10() } else { -20.0 * (20.0f64 / 255.0).log10() };
        assert!((psnr - expected).abs() < 0.8, "{row:?}: expected {expected}");
        assert!(row[1] == "all black" || row[1] == "training view near as is", "{row:?}");
    }
    assert!(out.join("manifest.json").exists() && out.join("summary.md").exists());
    // The model stage: one fit per frame, its held-out score finite.
    let fits = std::fs::read_to_string(out.join("fits.csv")).unwrap();
    let rows: Vec<Vec<&str>> = fits.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2, "{fits}");
    assert!(
        rows.iter().all(|r| r[1] == "emission-absorption" && r[2].parse::<f64>().is_ok_and(f64::is_finite)),
        "{fits}"
    );
    // The training photographs' noise: constant videos have none beyond their codec's.
    assert!(fits.lines().next().unwrap().split(',').nth(5) == Some("train_noise"), "{fits}");
    assert!(rows.iter().all(|r| r[5].parse::<f64>().is_ok_and(|n| (0.0..0.01).contains(&n))), "{fits}");
    // A rerun resumes only the run its folder recorded: the same settings
    // fit nothing again, other settings are refused before any fit.
    let again = run("0,2");
    assert!(again.status.success(), "{}", String::from_utf8_lossy(&again.stderr));
    assert_eq!(std::fs::read_to_string(out.join("fits.csv")).unwrap(), fits, "the same settings refit nothing");
    let settings = dir.join("orders.json");
    std::fs::write(&settings, format!(r#"{{{SMALL}, "orders": 4}}"#)).unwrap();
    let other = std::process::Command::new(exe)
        .arg("--data")
        .arg(&dir)
        .args(["--frames", "0,1,2", "--models", "emission-absorption", "--fit-settings"])
        .arg(&settings)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(
        !other.status.success() && err.contains("other fit setting orders (3 in its settings.json, 4 here)"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    assert_eq!(std::fs::read_to_string(out.join("fits.csv")).unwrap(), fits, "a refused rerun writes no fit");
    // --box replaces the calibration's smoke box (a transforms.json has none).
    let boxed = |smoke_box: &str| {
        let run = std::process::Command::new(exe)
            .arg("--data")
            .arg(&dir)
            .args(["--frames", "0,2", "--models", "emission-absorption", "--box", smoke_box, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(!run.status.success());
        String::from_utf8_lossy(&run.stderr).into_owned()
    };
    let err = boxed("-0.25,-0.5,-0.5,0.5,0.5,0.5");
    assert!(err.contains("holds a run made with other smoke box") && err.lines().count() == 1, "{err}");
    let err = boxed("0.5,-0.5,-0.5,-0.5,0.5,0.5");
    assert!(err.contains("--box: ") && err.lines().count() == 1, "{err}");
    // Another frame with the same settings is fitted and added to the rows before it.
    let more = run("0,1,2");
    assert!(more.status.success(), "{}", String::from_utf8_lossy(&more.stderr));
    let fits_more = std::fs::read_to_string(out.join("fits.csv")).unwrap();
    assert!(fits_more.starts_with(&fits) && fits_more.lines().count() == fits.lines().count() + 1, "{fits_more}");
    assert!(fits_more.lines().last().unwrap().starts_with("1,"), "{fits_more}");
    // Each row and the rig name the revision that fitted them, and so does
    // the manifest: a run keeping rows another revision fitted names both.
    let manifest =
        || -> Value { serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap() };
    let own = manifest()["fit_revisions"][0].as_str().unwrap().to_string();
    assert!(own.starts_with(manifest()["revision"].as_str().unwrap()), "{}", manifest());
    assert_eq!((manifest()["fit_revisions"].clone(), manifest()["rig_revision"].clone()), (json!([own]), json!(own)));
    let earlier: String = fits_more.replacen(&format!(",{own}\n"), ",0123456789ab\n", 1);
    assert_ne!(earlier, fits_more, "{fits_more}");
    std::fs::write(out.join("fits.csv"), &earlier).unwrap();
    let kept = run("0,1,2");
    assert!(kept.status.success(), "{}", String::from_utf8_lossy(&kept.stderr));
    assert_eq!(std::fs::read_to_string(out.join("fits.csv")).unwrap(), earlier, "nothing fitted again");
    assert_eq!(manifest()["fit_revisions"], json!(["0123456789ab", own]), "{}", manifest());
    // A rig made on other calibration frames is not reused.
    let rig_path = out.join("rig.json");
    let rig = std::fs::read_to_string(&rig_path).unwrap();
    std::fs::write(&rig_path, rig.replacen("\"frames\": [", "\"frames\": [7, ", 1)).unwrap();
    std::fs::remove_file(out.join("fits.csv")).unwrap();
    let moved = run("0,2");
    let err = String::from_utf8_lossy(&moved.stderr);
    assert!(!moved.status.success() && err.contains("aligns other cameras or frames"), "{err}");
    // A folder holding fits without the settings they were made with is refused.
    std::fs::remove_file(out.join("settings.json")).unwrap();
    std::fs::write(&rig_path, rig).unwrap();
    let unknown = run("0,2");
    let err = String::from_utf8_lossy(&unknown.stderr);
    assert!(!unknown.status.success() && err.contains("not the settings they were made with"), "{err}");
    // The nearest view as is comes from a camera that trains, of the held-out camera's size.
    let nearest = |name: &str, calib: &Value, drop: &[&str]| {
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        for video in ["test.mp4", "near.mp4", "far.mp4", "small.mp4"].iter().filter(|v| dir.join(v).exists()) {
            std::fs::copy(dir.join(video), sub.join(video)).unwrap();
        }
        std::fs::write(sub.join("info.json"), calib.to_string()).unwrap();
        let run = std::process::Command::new(exe)
            .arg("--data")
            .arg(&sub)
            .args(["--frames", "0", "--models", "emission-absorption", "--fit-settings"])
            .arg(&no_probe)
            .args(drop)
            .arg("--out")
            .arg(sub.join("out"))
            .output()
            .unwrap();
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        std::fs::read_to_string(sub.join("out/baselines.csv")).unwrap()
    };
    let csv = nearest("dropped", &calib, &["--drop", "near"]);
    assert!(csv.contains("training view far as is") && !csv.contains("near"), "{csv}");
    write_video(&dir, "small", 3, (32, 24), |_, _, _| 80);
    let mut small = cam("small.mp4", 1.0, 1.732);
    small["camera_hw"] = json!([24, 32]);
    let mixed = json!({
        "train_videos": [cam("far.mp4", 2.0, 0.0), small],
        "test_videos": [cam("test.mp4", 0.0, 2.0)],
        "voxel_matrix": UNIT_BOX, "voxel_scale": 1.0,
    });
    let csv = nearest("mixed", &mixed, &[]);
    assert!(csv.contains("training view far as is") && !csv.contains("small"), "{csv}");
}

/// PINF's `voxel_matrix` of the box [-0.5, 0.5]^3 (with `voxel_scale` 1).
const UNIT_BOX: [[f64; 4]; 4] =
    [[1.0, 0.0, 0.0, -0.5], [0.0, 1.0, 0.0, -0.5], [0.0, 0.0, 1.0, -0.5], [0.0, 0.0, 0.0, 1.0]];

/// A ball of smoke's image: a disc of code 120 in the middle of a 128x96 frame.
fn disc(x: u32, y: u32) -> u16 {
    let (dx, dy) = (x as f64 - 63.5, y as f64 - 47.5);
    if dx * dx + dy * dy < 400.0 {
        120
    } else {
        0
    }
}

#[test]
fn fit_takes_a_capture_and_renders_its_held_out_camera() {
    let dir = temp_dir("capture_fit");
    for name in ["a", "b", "test"] {
        std::fs::create_dir_all(dir.join(name)).unwrap();
        for f in 0..2 {
            write_png(&dir.join(name).join(format!("{f:03}.png")), 128, 96, false, disc);
        }
    }
    let cam = |file: &str, x: f64, z: f64| json!({"file_name": file, "frame_num": 2, "camera_angle_x": 0.6, "camera_hw": [96, 128], "transform_matrix": looking_at_origin(x, z)});
    let calib = |a: Value| {
        json!({"train_videos": [a, cam("b", 2.0, 0.0)], "test_videos": [cam("test", 1.414, 1.414)],
            "voxel_matrix": UNIT_BOX, "voxel_scale": 1.0})
    };
    let exe = env!("CARGO_BIN_EXE_dualphoton");
    let out = dir.join("out");
    let no_probe = dir.join("no_probe.json");
    std::fs::write(&no_probe, format!("{{{SMALL}}}")).unwrap();
    let fit = |frame: &str| {
        std::process::Command::new(exe)
            .args(["fit", "--capture"])
            .arg(dir.join("info.json"))
            .args(["--frame", frame, "--study"])
            .arg(&no_probe)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    // A camera turned away from the box, and a frame the capture lacks: one-line errors, no output.
    let mut away = cam("a", 0.0, 2.0);
    away["transform_matrix"] = looking_at_origin(0.0, 2.0);
    away["transform_matrix"][0][3] = json!(5.0);
    std::fs::write(dir.join("info.json"), calib(away).to_string()).unwrap();
    let bad = fit("0");
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("camera a: the smoke box is not in its image"), "{err}");
    // A camera in the box (a box in other units), and one posed in OpenCV's convention.
    let mut inside = cam("a", 0.0, 2.0);
    inside["transform_matrix"][2][3] = json!(0.1);
    let mut opencv = cam("a", 0.0, 2.0);
    for (row, col) in (0..3).flat_map(|row| [(row, 1), (row, 2)]) {
        let flipped = -opencv["transform_matrix"][row][col].as_f64().unwrap();
        opencv["transform_matrix"][row][col] = json!(flipped);
    }
    for (a, why) in
        [(inside, "camera a: it stands inside the smoke box"), (opencv, "camera a: the smoke box is behind it")]
    {
        std::fs::write(dir.join("info.json"), calib(a).to_string()).unwrap();
        let bad = fit("0");
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(!bad.status.success() && err.contains(why) && err.lines().count() == 1, "{err}");
    }
    std::fs::write(dir.join("info.json"), calib(cam("a", 0.0, 2.0)).to_string()).unwrap();
    let bad = fit("2");
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("frame 2 is out of range"), "{err}");
    // A ScalarFlow camera file without the capture's cameras.
    let cameras = dir.join("cameras.json");
    std::fs::write(&cameras, json!({"0": {"position": [9.0, 9.0, 9.0], "fov_vertical": 40.0}}).to_string()).unwrap();
    let bad = std::process::Command::new(exe)
        .args(["fit", "--capture"])
        .arg(dir.join("info.json"))
        .arg("--focal-lengths")
        .arg(&cameras)
        .args(["--frame", "0", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("--focal-lengths") && err.contains("no camera at a's position"),
        "{err}"
    );
    // A held-out photograph lit all over (a background left in) is refused
    // as a training one is; its camera far enough to see past the box.
    let mut far = calib(cam("a", 0.0, 2.0));
    far["test_videos"][0] = cam("test", 2.828, 2.828);
    std::fs::write(dir.join("info.json"), far.to_string()).unwrap();
    write_png(&dir.join("test/001.png"), 128, 96, false, |_, _| 200);
    let bad = fit("1");
    let err = String::from_utf8_lossy(&bad.stderr);
    let refused = err.lines().any(|l| l.starts_with("error: ") && l.contains("100 % in test (frame 1)"));
    assert!(!bad.status.success() && refused, "{err}");
    write_png(&dir.join("test/001.png"), 128, 96, false, disc);
    std::fs::write(dir.join("info.json"), calib(cam("a", 0.0, 2.0)).to_string()).unwrap();
    assert!(!out.exists(), "a bad capture is refused before any output");
    let ok = fit("1");
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let held = npy::read(&out.join("held_out.npy"), "held_out.npy").unwrap();
    assert_eq!(held.shape, vec![96, 128], "held_out.npy is (H, W) at the capture's resolution");
    assert!(held.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    // The ball seen from between the training cameras is a disc again: the
    // fit puts light inside it, little outside.
    let at = |x: usize, y: usize| held.data[y * 128 + x];
    assert!(at(64, 48) > 0.2, "centre {}", at(64, 48));
    assert!(at(2, 2) < 0.05, "corner {}", at(2, 2));
    for file in ["scene.json", "density.npy", "log.csv", "fit_quality.csv", "held_out.png", "manifest.json"] {
        assert!(out.join(file).exists(), "{file} missing");
    }
    let quality = std::fs::read_to_string(out.join("fit_quality.csv")).unwrap();
    assert_eq!(quality.lines().count(), 4, "{quality}");
    assert!(quality.contains("test,held-out"), "{quality}");
    // The held-out row's oracle: the best shift includes no shift at all,
    // so it never scores below the PSNR as scored.
    let header: Vec<&str> = quality.lines().next().unwrap().split(',').collect();
    let row: Vec<&str> = quality.lines().find(|l| l.contains(",held-out,")).unwrap().split(',').collect();
    let column = |name: &str| row[header.iter().position(|h| *h == name).unwrap()].parse::<f64>().unwrap();
    assert!(column("psnr_oracle_shift_db") >= column("psnr_db"), "{quality}");
    // Aligned (a magnification, then a shift) it includes magnification 1.
    assert!(column("psnr_oracle_aligned_db") >= column("psnr_oracle_shift_db"), "{quality}");
    let tried = dualphoton::capture::protocol::ORACLE_MAGNIFICATIONS;
    assert!((tried[0]..=tried[tried.len() - 1]).contains(&column("oracle_magnification")), "{quality}");
    // Against the same photograph a smaller error is a smaller relative RMSE.
    assert!(column("rel_rmse_oracle_aligned") <= column("rel_rmse"), "{quality}");
    // The smoke itself through that error: the photograph moved back is
    // closer to it than black, and perfect exactly when nothing was moved.
    let exact = row[header.iter().position(|h| *h == "psnr_exact_smoke_db").unwrap()];
    assert!((0.0..1.0).contains(&column("rel_rmse_exact_smoke")), "{quality}");
    assert_eq!(exact.is_empty(), column("rel_rmse_exact_smoke") == 0.0, "{quality}");

    // The folder's rig taken by a later fit: not fitted again, and the fit
    // the same to the bit as with the rig fitted there.
    let again = dir.join("again");
    let with_rig = |study: &Path, rig: &Path| {
        std::process::Command::new(exe)
            .args(["fit", "--capture"])
            .arg(dir.join("info.json"))
            .args(["--frame", "1", "--study"])
            .arg(study)
            .arg("--rig")
            .arg(rig)
            .arg("--out")
            .arg(&again)
            .output()
            .unwrap()
    };
    let other = dir.join("orders.json");
    std::fs::write(&other, format!(r#"{{{SMALL}, "orders": 4}}"#)).unwrap();
    let per_frame = dir.join("per_frame.json");
    std::fs::write(&per_frame, format!(r#"{{{SMALL}, "shared_alignment": false}}"#)).unwrap();
    for (study, rig, says) in [
        (&other, &out, "other fit setting orders (3 in its settings.json, 4 here)"),
        (&no_probe, &dir, "settings.json: not found"),
        (&per_frame, &out, "no rig to reuse"),
    ] {
        let bad = with_rig(study, rig);
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(!bad.status.success() && err.contains("--rig: ") && err.contains(says), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(!again.exists(), "a refused rig is refused before any output");
    }
    let reused = with_rig(&no_probe, &out);
    let err = String::from_utf8_lossy(&reused.stderr);
    assert!(reused.status.success() && !err.contains("aligned the training cameras"), "{err}");
    for file in ["density.npy", "held_out.npy", "rig.json", "settings.json"] {
        assert_eq!(std::fs::read(again.join(file)).unwrap(), std::fs::read(out.join(file)).unwrap(), "{file}");
    }
}

#[test]
fn fit_takes_a_transforms_json_with_the_users_box_and_settings() {
    let dir = temp_dir("capture_fit_transforms");
    for name in ["a", "b"] {
        std::fs::create_dir_all(dir.join(name)).unwrap();
        write_png(&dir.join(name).join("000.png"), 128, 96, false, disc);
    }
    let calib = json!({"camera_angle_x": 0.6, "w": 128, "h": 96, "frames": [
        {"file_path": "a", "transform_matrix": looking_at_origin(0.0, 2.0)},
        {"file_path": "b", "transform_matrix": looking_at_origin(2.0, 0.0)},
    ]});
    std::fs::write(dir.join("transforms.json"), calib.to_string()).unwrap();
    let settings = dir.join("fit.json");
    let chosen = json!({"resolution": 8, "updates": [10, 10], "threshold": 0.0, "orders": 2, "seed": 3});
    std::fs::write(&settings, chosen.to_string()).unwrap();
    let out = dir.join("out");
    let fit = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_dualphoton"))
            .args(["fit", "--capture"])
            .arg(dir.join("transforms.json"))
            .args(["--frame", "0", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    let refused = |extra: &[&str], says: &str| {
        let bad = fit(extra);
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(!bad.status.success() && err.contains(says), "{extra:?}: {err}");
    };
    // A transforms.json has no smoke box: the error says how to give one.
    refused(&[], "--box");
    refused(&["--box", "0.5,-0.5,-0.5,-0.5,0.5,0.5"], "--box: ");
    refused(&["--box", "-0.5,-0.5,-0.5,0.5,0.5"], "--box: ");
    refused(
        &["--box=-0.5,-0.5,-0.5,0.5,0.5,0.5", "--box=-1,-1,-1,1,1,1"],
        "'--box <X0,Y0,Z0,X1,Y1,Z1>' cannot be used",
    );
    refused(&["--box=-0.5,-0.5,-0.5,0.5,0.5,0.5", "--study", "missing.json"], "--study: ");
    // Options of the synthetic fit mean nothing to a capture's.
    refused(&["--box=-0.5,-0.5,-0.5,0.5,0.5,0.5", "--spp", "4"], "--spp");
    // Photographs the fit refuses are refused before the output folder is made.
    let resized = json!({"camera_angle_x": 0.6, "w": 64, "h": 48, "frames": calib["frames"]});
    std::fs::write(dir.join("resized.json"), resized.to_string()).unwrap();
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_dualphoton"))
        .args(["fit", "--capture"])
        .arg(dir.join("resized.json"))
        .args(["--frame", "0", "--box=-0.5,-0.5,-0.5,0.5,0.5,0.5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("but the calibration says 64x48"), "{err}");
    assert!(!out.exists(), "a refused fit writes nothing");

    let settings = settings.to_str().unwrap();
    let ok = fit(&["--box", "-0.5,-0.5,-0.5,0.5,0.5,0.5", "--study", settings]);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let manifest: Value = serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["bbox_min"], json!([-0.5, -0.5, -0.5]), "{manifest}");
    assert_eq!((manifest["shape"].clone(), manifest["fit"]["threshold"].clone()), (json!([8, 8, 8]), json!(0.0)));
    // The file's seed stands where --seed is not given, and its orders reach the renderer.
    assert_eq!(manifest["fit"]["seed"], json!(3), "{manifest}");
    let scene: Value = serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap()).unwrap();
    assert_eq!(scene["volume"]["max_order"], json!(2), "{scene}");
    let density = npy::read(&out.join("density.npy"), "density.npy").unwrap();
    assert!(density.data.iter().all(|v| v.is_finite() && *v >= 0.0) && density.data.iter().any(|&v| v > 0.0));
    // No test camera: nothing held out to render, both cameras scored as
    // training. One frame: its cameras aligned during its fit, no rig.
    assert!(!out.join("held_out.npy").exists());
    assert_eq!(
        (manifest["fit"]["align"].clone(), manifest["fit"]["shared_alignment"].clone()),
        (json!(true), json!(false))
    );
    assert!(!out.join("rig.json").exists() && !out.join("settings.json").exists());
    let quality = std::fs::read_to_string(out.join("fit_quality.csv")).unwrap();
    assert_eq!(quality.lines().filter(|l| l.contains(",training,")).count(), 2, "{quality}");

    // experiment_real takes the same capture with the box and a camera to
    // hold out, and scores its frames (here its one); what one frame cannot
    // measure (the photographs' noise over three) is left empty, never NaN.
    let compared = dir.join("compared");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_experiment_real"))
        .arg("--data")
        .arg(dir.join("transforms.json"))
        .args(["--box=-0.5,-0.5,-0.5,0.5,0.5,0.5", "--held-out", "b"])
        .args(["--models", "emission-absorption", "--study", settings, "--out"])
        .arg(&compared)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let summary = std::fs::read_to_string(compared.join("summary.md")).unwrap();
    assert!(summary.contains("crop rows 0..48 and columns 0..64") && !summary.contains("NaN"), "{summary}");
    assert!(summary.contains("whole-image protocol") && !summary.contains("field's"), "{summary}");
    let plot = std::fs::read_to_string(compared.join("psnr_per_frame.svg")).unwrap();
    assert!(plot.contains("whole-image protocol") && !plot.contains("field"));
    assert!(summary.contains("| emission-absorption |"), "{summary}");
    // Its figures show the frames it scored, though none is ScalarFlow's figure frames.
    assert!(compared.join("held_out_views.svg").exists() && compared.join("density_slices.svg").exists());
}

/// `made_capture` writes, from a capture's cameras and box, a capture that
/// reads back with the same cameras and box and the frames asked for: smoke
/// in the middle of every view, black at its corners (the threshold), and
/// the ambient term's share and the lights' places changing the images. A
/// bad share is refused before any output.
/// A CSV file's rows after its header, each as its fields.
fn csv_rows(text: &str) -> Vec<Vec<String>> {
    csv::Reader::from_reader(text.as_bytes()).records().map(|r| r.unwrap().iter().map(String::from).collect()).collect()
}

#[test]
fn made_capture_writes_a_capture_that_reads_back() {
    let dir = temp_dir("made_capture");
    let cam = |name: &str, x: f64, z: f64| {
        let folder = dir.join(name);
        std::fs::create_dir_all(&folder).unwrap();
        // Odd sizes: the truth is rendered at half of them, each pixel repeated.
        write_png(&folder.join("0.png"), 47, 63, false, |_, _| 0);
        json!({"file_name": name, "frame_num": 1, "camera_angle_x": 0.9, "camera_hw": [63, 47], "transform_matrix": looking_at_origin(x, z)})
    };
    let calib = json!({
        "train_videos": [cam("left", 2.0, 0.0), cam("right", 0.0, 2.0)],
        "test_videos": [cam("middle", 1.414, 1.414)],
        "voxel_matrix": UNIT_BOX, "voxel_scale": [0.8, 1.0, 0.8],
    });
    std::fs::write(dir.join("info.json"), calib.to_string()).unwrap();
    let out = dir.join("made");
    let run_to = |out: &std::path::Path, shares: &str, lights: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_made_capture"))
            .arg("--like")
            .arg(&dir)
            .args(["--frames", "3", "--res", "8", "--ambient-shares", shares, "--lights", lights])
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let run = |shares: &str| run_to(&out, shares, "between");
    let bad = run("0,1.5");
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("--ambient-shares: 1.5"), "{err}");
    assert!(!out.exists(), "a bad share is refused before any output");
    let ok = run("0,1");
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let like = calibration::load(&dir.join("info.json")).unwrap();
    let mut middles = Vec::new();
    for share in ["ambient_0", "ambient_100"] {
        let made = calibration::load(&out.join(share).join("info.json")).unwrap();
        assert_eq!(made.smoke_box, like.smoke_box);
        assert_eq!(made.views.len(), 3);
        for (m, l) in made.views.iter().zip(&like.views) {
            assert_eq!((&m.name, &m.camera, m.held_out, m.frames.count()), (&l.name, &l.camera, l.held_out, 3));
            let images = frames::read(m, &[0, 1]).unwrap();
            for image in &images {
                assert_eq!((image.width, image.height), (47, 63));
                assert_eq!(image.data[0], 0.0, "{share} {}: a corner is not black", m.name);
                assert!(image.data.iter().all(|&v| v == 0.0 || v > 8.0 / 255.0), "codes up to 8 must be 0");
            }
            middles.push(images[0].data[31 * 47 + 23]);
        }
        // Smoke inside the box on black: nothing a background would leave.
        let (lo, hi) = made.grid_box().unwrap();
        let seen =
            observe::observe(&made, &[0, 1, 2], &[0, 1, 2], &FitSettings { factor: 1, ..FitSettings::default() })
                .unwrap();
        assert_eq!(observe::light_outside_box(&seen, &[0, 1, 2], &lo, &hi).unwrap(), None, "{share}");
    }
    assert!(middles.iter().all(|&v| v > 0.0), "a view's middle has no smoke: {middles:?}");
    assert_ne!(middles[..3], middles[3..], "the ambient term's share changed nothing");
    // The lights on the fit's candidates light the same smoke otherwise.
    let moved = dir.join("made_candidates");
    let ok = run_to(&moved, "0", "candidates");
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let made = calibration::load(&moved.join("ambient_0").join("info.json")).unwrap();
    let lit: Vec<f64> = made.views.iter().map(|m| frames::read(m, &[0]).unwrap()[0].data[31 * 47 + 23]).collect();
    assert!(lit.iter().all(|&v| v > 0.0), "a view's middle has no smoke: {lit:?}");
    assert_ne!(lit[..], middles[..3], "the lights' places changed nothing");
    // made_lights fits the lighting of a made capture's truth and scores its
    // held-out camera; a capture no made_capture wrote is refused.
    let made_lights = |data: &std::path::Path, args: &[&str], out: &std::path::Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_made_lights"))
            .arg("--data")
            .arg(data)
            .args(args)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let tiny = |models| ["--frames", "0", "--orders", "1", "--models", models];
    let lights_out = dir.join("lights");
    let refused = made_lights(&dir.join("left"), &tiny("single"), &lights_out);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("not a made capture"), "{err}");
    let refused = made_lights(&moved.join("ambient_0"), &tiny("multiple"), &lights_out);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("--orders 1"), "{err}");
    let refused = made_lights(&moved.join("ambient_0"), &["--blur", "1,-1"], &lights_out);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("--blur -1"), "{err}");
    assert!(!lights_out.exists(), "bad options are refused before any output");
    let ok = made_lights(&moved.join("ambient_0"), &tiny("single,emission-absorption"), &lights_out);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let truth_csv = std::fs::read_to_string(lights_out.join("lights.csv")).unwrap();
    let truth_rows: Vec<&str> = truth_csv.lines().skip(1).collect();
    assert_eq!(truth_rows.len(), 2, "{truth_csv}");
    let [single, absorption] = [truth_rows[0], truth_rows[1]];
    assert!(
        single.starts_with("0,single,1,0.0,") && absorption.starts_with("0,emission-absorption,0,0.0,"),
        "{truth_csv}"
    );
    assert!(!truth_csv.to_lowercase().contains("nan") && !truth_csv.contains("inf"), "{truth_csv}");
    // With --fitted it holds the density a fit reaches, as it is and blurred.
    let fitted_out = dir.join("fitted");
    let args = ["--frames", "0", "--models", "emission-absorption", "--fitted", "--blur", "0,1"];
    let ok = made_lights(&moved.join("ambient_0"), &args, &fitted_out);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let csv = std::fs::read_to_string(fitted_out.join("lights.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 2, "{csv}");
    assert!(rows[0].starts_with("0,emission-absorption,0,0.0,") && rows[1].starts_with("0,emission-absorption,0,1.0,"));
    // Every column but the time: the fit's density is not the truth's.
    let but_time = |row: &str| row.rsplit_once(',').unwrap().0.to_string();
    assert_ne!(but_time(rows[0]), but_time(absorption), "--fitted held the truth");
    assert!(!csv.to_lowercase().contains("nan") && !csv.contains("inf"), "{csv}");
    // temporal_mean: a frame without neighbours enough is refused before
    // any output; a frame with them gets every arm, the mean from all three.
    let temporal = |args: &[&str], out: &std::path::Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_temporal_mean"))
            .arg("--data")
            .arg(moved.join("ambient_0"))
            .args(args)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let temporal_out = dir.join("temporal");
    let refused = temporal(&["--frames", "0", "--reach", "1"], &temporal_out);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("--frames 0: needs 1 frames on each side"), "{err}");
    assert!(!temporal_out.exists(), "a frame at the clip's edge is refused before any output");
    let refused = temporal(&["--frames", "1,1", "--reach", "1"], &temporal_out);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("frame 1 is given twice"), "{err}");
    // A small grid and short fits: the rig's path, each frame's fit, the mean and the refit all run.
    let small = dir.join("small.json");
    std::fs::write(&small, r#"{"resolution": 16, "updates": [10, 10, 20]}"#).unwrap();
    let args = ["--frames", "1", "--reach", "1", "--models", "emission-absorption", "--fit-settings"];
    let ok = temporal(&[&args[..], &[small.to_str().unwrap()]].concat(), &temporal_out);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let csv = std::fs::read_to_string(temporal_out.join("temporal.csv")).unwrap();
    let rows = csv_rows(&csv);
    let arms: Vec<(&str, &str)> = rows.iter().map(|r| (r[2].as_str(), r[3].as_str())).collect();
    assert_eq!(
        arms,
        [("fit", "1"), ("alone, held", "1"), ("mean of 3, held", "0;1;2"), ("refit from mean of 3", "0;1;2")],
        "{csv}"
    );
    assert_eq!(rows[2][4].split(';').count(), 2, "a shift per neighbour: {csv}");
    // The held density's lighting, fitted again, explains the training views
    // about as its fit did.
    let rmse = |r: &[String]| r[5].parse::<f64>().unwrap();
    assert!((rmse(&rows[1]) - rmse(&rows[0])).abs() <= 0.2 * rmse(&rows[0]) + 0.05, "{csv}");
    assert!(!csv.to_lowercase().contains("nan") && !csv.contains("inf"), "{csv}");
    // learned_filter: learning from a frame it scores is refused before any
    // output; learned from frames 0 and 2, it scores frame 1 in every arm,
    // each density against the made truth.
    let learned = |args: &[&str], out: &std::path::Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_learned_filter"))
            .arg("--learn-data")
            .arg(moved.join("ambient_0"))
            .arg("--data")
            .arg(moved.join("ambient_0"))
            .args(args)
            .args(["--model", "emission-absorption", "--radius", "1", "--fit-settings", small.to_str().unwrap()])
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let filter_out = dir.join("filter");
    let refused = learned(&["--learn-frames", "0,1", "--frames", "1"], &filter_out);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("share a frame"), "{err}");
    assert!(!filter_out.exists(), "a shared frame is refused before any output");
    let ok = learned(&["--learn-frames", "0,2", "--frames", "1"], &filter_out);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let csv = std::fs::read_to_string(filter_out.join("learned_filter.csv")).unwrap();
    let rows = csv_rows(&csv);
    let arms: Vec<&str> = rows.iter().map(|r| r[1].as_str()).collect();
    assert_eq!(arms, ["fit", "fit, held", "filtered, held", "refit from filtered"], "{csv}");
    assert!(rows.iter().all(|r| r[5].parse::<f64>().is_ok_and(|e| e > 0.0)), "a density error per arm: {csv}");
    assert!(!csv.to_lowercase().contains("nan") && !csv.contains("inf"), "{csv}");
    let filter: Value =
        serde_json::from_str(&std::fs::read_to_string(filter_out.join("filter.json")).unwrap()).unwrap();
    assert_eq!(filter["weights"].as_array().unwrap().len(), 28, "27 neighbours and a constant");
}
