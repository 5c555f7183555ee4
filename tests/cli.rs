//! The command line: outputs and their names, and a one-line error naming
//! the field (non-zero exit, no panic) for every kind of bad input.
mod common;
use common::temp_dir;

use dualphoton::io::npy;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dualphoton(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dualphoton")).args(args).output().unwrap()
}

/// A small valid scene: an 8^3 blob, one light, two cameras of 8x6 pixels.
fn valid_scene() -> Value {
    json!({
        "volume": {"bbox_min": [-0.5, -0.5, -0.5], "bbox_max": [0.5, 0.5, 0.5], "density": "density.npy",
                   "sigma_t_scale": 20.0, "albedo": 0.9, "g": 0.5, "max_order": 2},
        "lights": [{"position": [1.0, 0.5, 2.0], "intensity": 50.0}],
        "cameras": [
            {"position": [0.0, 0.0, 2.5], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y_deg": 40.0, "width": 8, "height": 6},
            {"position": [2.5, 0.0, 0.0], "look_at": [0.0, 0.0, 0.0], "fov_y_deg": 40.0, "width": 8, "height": 6}
        ],
        "render": {"photons": 2000, "path_spp": 4}
    })
}

fn blob(n: usize) -> Vec<f64> {
    let mut v = vec![0.0; n * n * n];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = |a: usize| (a as f64 + 0.5) / n as f64 - 0.5;
                let r2 = c(i).powi(2) + c(j).powi(2) + c(k).powi(2);
                v[(k * n + j) * n + i] = (0.3 - r2).max(0.0);
            }
        }
    }
    v
}

/// Writes `scene` and a density into `dir`; returns the scene path.
fn write_scene(dir: &Path, scene: &Value, density: &[f64], shape: &[usize]) -> PathBuf {
    npy::write_f32(&dir.join("density.npy"), shape, density).unwrap();
    let path = dir.join("scene.json");
    std::fs::write(&path, serde_json::to_string_pretty(scene).unwrap()).unwrap();
    path
}

fn expect_error(out: &Output, field: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure for {field}, got success");
    assert!(!stderr.contains("panicked"), "panic instead of an error: {stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "error must be one line: {stderr}");
    assert!(stderr.starts_with("error: ") && stderr.contains(field), "error for {field} does not name it: {stderr}");
}

/// A named change to the valid scene and the field its error must name.
type Case = (&'static str, Box<dyn Fn(&mut Value)>, &'static str);

fn render_error(name: &str, scene: Value, density: Vec<f64>, shape: &[usize], field: &str) {
    let dir = temp_dir(name);
    let path = write_scene(&dir, &scene, &density, shape);
    let out = dualphoton(&["render", "--scene", path.to_str().unwrap(), "--out", dir.join("out").to_str().unwrap()]);
    expect_error(&out, field);
}

#[test]
fn render_writes_one_npy_and_png_per_camera() {
    let dir = temp_dir("ok");
    let path = write_scene(&dir, &valid_scene(), &blob(8), &[8, 8, 8]);
    for method in ["photon", "path"] {
        let out_dir = dir.join(method);
        let out = dualphoton(&[
            "render",
            "--scene",
            path.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
            "--method",
            method,
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        for cam in ["cam0", "cam1"] {
            let image = npy::read(&out_dir.join(format!("{cam}.npy")), "test").unwrap();
            assert_eq!(image.shape, vec![6, 8]);
            assert_eq!(image.dtype, "<f4");
            assert!(image.data.iter().all(|v| v.is_finite() && *v >= 0.0) && image.data.iter().any(|v| *v > 0.0));
            assert!(out_dir.join(format!("{cam}.png")).exists());
            assert_eq!(out_dir.join(format!("{cam}_stderr.npy")).exists(), method == "path");
        }
        assert!(!out_dir.join("cam2.npy").exists());
    }
}

#[test]
fn bad_files_are_errors() {
    let dir = temp_dir("files");
    let out =
        dualphoton(&["render", "--scene", dir.join("missing.json").to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    expect_error(&out, "scene");
    std::fs::write(dir.join("bad.json"), "{ not json").unwrap();
    let out =
        dualphoton(&["render", "--scene", dir.join("bad.json").to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    expect_error(&out, "scene");
    // Missing density file.
    std::fs::write(dir.join("scene.json"), valid_scene().to_string()).unwrap();
    let out =
        dualphoton(&["render", "--scene", dir.join("scene.json").to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    expect_error(&out, "volume.density");
    // Not a .npy file.
    std::fs::write(dir.join("density.npy"), "hello").unwrap();
    let out =
        dualphoton(&["render", "--scene", dir.join("scene.json").to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    expect_error(&out, "volume.density");
    // Wrong dtype (uint8).
    npy::write_u8(&dir.join("density.npy"), &[2, 2, 2], &[1; 8]).unwrap();
    let out =
        dualphoton(&["render", "--scene", dir.join("scene.json").to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    expect_error(&out, "volume.density");
}

#[test]
fn bad_density_values_and_shapes_are_errors() {
    render_error("shape2d", valid_scene(), vec![0.1; 64], &[8, 8], "volume.density");
    render_error("shape0", valid_scene(), vec![], &[0, 8, 8], "volume.density");
    for (name, bad) in [("nan", f64::NAN), ("inf", f64::INFINITY), ("neg", -0.5)] {
        let mut d = blob(8);
        d[100] = bad;
        render_error(name, valid_scene(), d, &[8, 8, 8], "volume.density");
    }
}

#[test]
fn bad_fields_are_errors() {
    let cases: Vec<Case> = vec![
        ("g1", Box::new(|s| s["volume"]["g"] = json!(1.0)), "volume.g"),
        ("gm1", Box::new(|s| s["volume"]["g"] = json!(-1.5)), "volume.g"),
        ("albedo", Box::new(|s| s["volume"]["albedo"] = json!(1.2)), "volume.albedo"),
        ("albedo_neg", Box::new(|s| s["volume"]["albedo"] = json!(-0.1)), "volume.albedo"),
        ("order0", Box::new(|s| s["volume"]["max_order"] = json!(0)), "volume.max_order"),
        ("scale", Box::new(|s| s["volume"]["sigma_t_scale"] = json!(-1.0)), "volume.sigma_t_scale"),
        ("bbox", Box::new(|s| s["volume"]["bbox_max"] = json!([0.5, -0.5, 0.5])), "volume.bbox_max"),
        ("intensity", Box::new(|s| s["lights"][0]["intensity"] = json!(-3.0)), "lights[0].intensity"),
        ("width0", Box::new(|s| s["cameras"][1]["width"] = json!(0)), "cameras[1]"),
        ("height0", Box::new(|s| s["cameras"][0]["height"] = json!(0)), "cameras[0]"),
        ("nothing", Box::new(|s| s["cameras"][0]["look_at"] = json!([0.0, 0.0, 5.0])), "cameras[0]"),
        ("fov", Box::new(|s| s["cameras"][0]["fov_y_deg"] = json!(180.0)), "cameras[0].fov_y_deg"),
        ("up", Box::new(|s| s["cameras"][0]["up"] = json!([0.0, 0.0, 1.0])), "cameras[0].up"),
        ("fx", Box::new(|s| pinhole(&mut s["cameras"][0], -20.0)), "cameras[0].fx"),
        ("nocam", Box::new(|s| s["cameras"] = json!([])), "cameras"),
        ("typo", Box::new(|s| s["lights"][0]["intesity"] = json!(3.0)), "intesity"),
        ("missing", Box::new(|s| s["volume"].as_object_mut().unwrap().remove("g").map(|_| ()).unwrap()), "volume.g"),
        ("radius", Box::new(|s| s["render"]["kernel_radius"] = json!(0.0)), "render.kernel_radius"),
        ("shadow_cell", Box::new(|s| s["render"]["shadow_cell"] = json!(0)), "render.shadow_cell"),
        ("photon_step", Box::new(|s| s["render"]["photon_step"] = json!(-0.01)), "render.photon_step"),
    ];
    for (name, mutate, field) in cases {
        let mut scene = valid_scene();
        mutate(&mut scene);
        render_error(name, scene, blob(8), &[8, 8, 8], field);
    }
}

/// Gives the camera at `v` the intrinsics `fx = fy = f`, principal point at its centre, in place of its field of view.
fn pinhole(v: &mut Value, f: f64) {
    remove(v, "fov_y_deg");
    for (key, value) in [("fx", f), ("fy", f), ("cx", 4.0), ("cy", 3.0)] {
        v[key] = json!(value);
    }
}

/// Removes `key` from the object at `v`.
fn remove(v: &mut Value, key: &str) {
    v.as_object_mut().unwrap().remove(key).unwrap();
}

#[test]
fn file_errors_name_the_field_by_its_path() {
    let cases: Vec<Case> = vec![
        // Wrong types.
        ("type_g", Box::new(|s| s["volume"]["g"] = json!("0.5")), "volume.g"),
        ("type_intensity", Box::new(|s| s["lights"][0]["intensity"] = json!("bright")), "lights[0].intensity"),
        ("type_width", Box::new(|s| s["cameras"][1]["width"] = json!(-8)), "cameras[1].width"),
        ("type_position", Box::new(|s| s["cameras"][0]["position"] = json!([0.0, 2.5])), "cameras[0].position"),
        ("type_order", Box::new(|s| s["volume"]["max_order"] = json!(2.5)), "volume.max_order"),
        ("type_lights", Box::new(|s| s["lights"] = json!({"position": [0, 0, 0]})), "lights"),
        ("type_render", Box::new(|s| s["render"] = json!(5)), "render"),
        ("type_photons", Box::new(|s| s["render"]["photons"] = json!(-5)), "render.photons"),
        ("type_density", Box::new(|s| s["volume"]["density"] = json!(3)), "volume.density"),
        ("type_shadows", Box::new(|s| s["render"]["shadows"] = json!("soft")), "render.shadows"),
        // Missing required fields.
        ("missing_position", Box::new(|s| remove(&mut s["lights"][0], "position")), "lights[0].position"),
        ("missing_fov", Box::new(|s| remove(&mut s["cameras"][1], "fov_y_deg")), "cameras[1].fov_y_deg"),
        ("missing_lights", Box::new(|s| remove(s, "lights")), "lights"),
        (
            "missing_cy",
            Box::new(|s| {
                pinhole(&mut s["cameras"][0], 20.0);
                remove(&mut s["cameras"][0], "cy")
            }),
            "cameras[0].cy",
        ),
        ("fov_and_fx", Box::new(|s| s["cameras"][1]["fx"] = json!(20.0)), "cameras[1]: give either"),
        ("missing_density", Box::new(|s| remove(&mut s["volume"], "density")), "volume.density"),
        // Unknown fields.
        ("unknown_render", Box::new(|s| s["render"]["phtons"] = json!(10)), "render.phtons"),
        ("unknown_camera", Box::new(|s| s["cameras"][1]["fov"] = json!(40)), "cameras[1].fov"),
        ("unknown_top", Box::new(|s| s["light"] = json!([])), "light"),
        // NaN and infinity written as null.
        ("null_g", Box::new(|s| s["volume"]["g"] = Value::Null), "volume.g"),
        ("null_intensity", Box::new(|s| s["lights"][0]["intensity"] = Value::Null), "lights[0].intensity"),
        ("null_bbox", Box::new(|s| s["volume"]["bbox_min"] = json!([-0.5, null, -0.5])), "volume.bbox_min"),
        ("null_radius", Box::new(|s| s["render"]["kernel_radius"] = Value::Null), "render.kernel_radius"),
        ("null_photons", Box::new(|s| s["render"]["photons"] = Value::Null), "render.photons"),
    ];
    for (name, mutate, field) in cases {
        let mut scene = valid_scene();
        mutate(&mut scene);
        render_error(name, scene, blob(8), &[8, 8, 8], field);
    }
}

#[test]
fn bare_nan_names_its_field() {
    // Python's json.dump writes NaN and Infinity bare: not JSON, but the error should still name the field.
    for (name, from, to, field) in [
        ("nan_g", "\"g\": 0.5", "\"g\": NaN", "volume.g"),
        ("inf_intensity", "\"intensity\": 50.0", "\"intensity\": -Infinity", "lights[0].intensity"),
    ] {
        let dir = temp_dir(name);
        let path = write_scene(&dir, &valid_scene(), &blob(8), &[8, 8, 8]);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(from), "{text}");
        std::fs::write(&path, text.replace(from, to)).unwrap();
        let out =
            dualphoton(&["render", "--scene", path.to_str().unwrap(), "--out", dir.join("out").to_str().unwrap()]);
        expect_error(&out, field);
        assert!(String::from_utf8_lossy(&out.stderr).contains("finite number"));
    }
}

/// The bytes of a float64 `.npy` in the given byte and axis order, as numpy writes it.
fn npy_f8(shape: &[usize], c_order: &[f64], fortran: bool, big_endian: bool) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|s| s.to_string()).collect();
    let descr = if big_endian { ">f8" } else { "<f8" };
    let order = if fortran { "True" } else { "False" };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': ({}), }}", dims.join(", "));
    header.push_str(&" ".repeat((64 - (10 + header.len() + 1) % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    let [nz, ny, nx] = [shape[0], shape[1], shape[2]];
    let mut values = vec![];
    if fortran {
        // First axis fastest.
        for i in 0..nx {
            for j in 0..ny {
                for k in 0..nz {
                    values.push(c_order[(k * ny + j) * nx + i]);
                }
            }
        }
    } else {
        values.extend_from_slice(c_order);
    }
    for v in values {
        out.extend_from_slice(&if big_endian { v.to_be_bytes() } else { v.to_le_bytes() });
    }
    out
}

#[test]
fn density_in_any_numpy_layout_renders_the_same() {
    // A lopsided density (x, y and z differ), so a transposition would show.
    let (nz, ny, nx) = (6, 7, 8);
    let mut d = vec![0.0; nz * ny * nx];
    for (n, v) in d.iter_mut().enumerate() {
        let (k, j, i) = (n / (ny * nx), (n / nx) % ny, n % nx);
        *v = 0.05 * (1 + i + 2 * j * j + 3 * k) as f64 / 20.0;
    }
    let mut images = vec![];
    for (name, fortran, big) in
        [("c_le", false, false), ("f_le", true, false), ("c_be", false, true), ("f_be", true, true)]
    {
        let dir = temp_dir(name);
        let path = write_scene(&dir, &valid_scene(), &[0.0; 8], &[2, 2, 2]);
        std::fs::write(dir.join("density.npy"), npy_f8(&[nz, ny, nx], &d, fortran, big)).unwrap();
        let out =
            dualphoton(&["render", "--scene", path.to_str().unwrap(), "--out", dir.join("out").to_str().unwrap()]);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        images.push(std::fs::read(dir.join("out/cam0.npy")).unwrap());
    }
    assert!(images.iter().all(|im| *im == images[0]), "the layout changed the image");
    // Data that does not match the header's shape.
    let dir = temp_dir("short_npy");
    let path = write_scene(&dir, &valid_scene(), &[0.0; 8], &[2, 2, 2]);
    let mut bytes = npy_f8(&[nz, ny, nx], &d, false, false);
    bytes.truncate(bytes.len() - 8);
    std::fs::write(dir.join("density.npy"), bytes).unwrap();
    let out = dualphoton(&["render", "--scene", path.to_str().unwrap(), "--out", dir.join("out").to_str().unwrap()]);
    expect_error(&out, "volume.density");
    assert!(String::from_utf8_lossy(&out.stderr).contains("density.npy: data is"));
}

#[test]
fn photon_counts_beyond_memory_are_an_error_not_an_abort() {
    let start = std::time::Instant::now();
    for (name, photons) in [("photons_float", json!(1e15)), ("photons_int", json!(1_000_000_000_000_000u64))] {
        let mut scene = valid_scene();
        scene["render"]["photons"] = photons;
        render_error(name, scene, blob(8), &[8, 8, 8], "render.photons");
    }
    let dir = temp_dir("photons_flag");
    let path = write_scene(&dir, &valid_scene(), &blob(8), &[8, 8, 8]);
    let out = dualphoton(&[
        "render",
        "--scene",
        path.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
        "--photons",
        "1000000000000000",
    ]);
    expect_error(&out, "render.photons");
    assert!(String::from_utf8_lossy(&out.stderr).contains("in memory"));
    assert!(start.elapsed().as_secs_f64() < 10.0, "rejecting took {:?}", start.elapsed());
}

#[test]
fn zero_density_renders_black_not_nan() {
    let dir = temp_dir("zero");
    let path = write_scene(&dir, &valid_scene(), &[0.0; 512], &[8, 8, 8]);
    let out = dualphoton(&["render", "--scene", path.to_str().unwrap(), "--out", dir.join("out").to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = npy::read(&dir.join("out/cam0.npy"), "test").unwrap();
    assert!(image.data.iter().all(|v| *v == 0.0));
}

#[test]
fn scene_preset_writes_the_paper_rig() {
    let dir = temp_dir("preset");
    let out = dualphoton(&["scene", "--preset", "paper", "--res", "16", "--seed", "3", "--out", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let scene = dualphoton::scene::file::load(&dir.join("scene.json")).unwrap();
    assert_eq!(scene.cameras.len(), 5);
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(scene.density.shape, [16, 16, 16]);
    let bad = dualphoton(&["scene", "--preset", "paper", "--res", "0", "--out", dir.to_str().unwrap()]);
    expect_error(&bad, "--res");
    let bad = dualphoton(&[
        "scene",
        "--from-scalarflow",
        dir.join("nope.npz").to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
}

#[test]
fn fit_on_a_grid_the_decoder_cannot_make_is_an_error() {
    let dir = temp_dir("fit24");
    let path = write_scene(&dir, &valid_scene(), &blob(24), &[24, 24, 24]);
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for cam in 0..2 {
        npy::write_f32(&images.join(format!("cam{cam}.npy")), &[6, 8], &[1.0; 48]).unwrap();
    }
    let out = dualphoton(&[
        "fit",
        "--scene",
        path.to_str().unwrap(),
        "--images",
        images.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
        "--iterations",
        "1",
        "--prior",
        "none",
    ]);
    assert_eq!(out.status.code(), Some(1));
    // `fit` first says which model it fits, then the one-line error.
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.trim().lines().collect();
    assert_eq!(lines.len(), 2, "{stderr}");
    assert!(lines[0].starts_with("fit: the paper's per-scene decoder"), "{stderr}");
    assert!(lines[1].starts_with("error: ") && lines[1].contains("volume.density"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("4 * 2^n voxels per side") && stderr.trim_end().ends_with("got 24"), "{stderr}");
}

/// A valid 8^3 scene with an image per camera in `dir` (scene path, images directory).
fn scene_with_images(dir: &Path) -> (String, String) {
    let path = write_scene(dir, &valid_scene(), &blob(8), &[8, 8, 8]);
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for cam in 0..2 {
        npy::write_f32(&images.join(format!("cam{cam}.npy")), &[6, 8], &[0.5; 48]).unwrap();
    }
    (path.to_str().unwrap().into(), images.to_str().unwrap().into())
}

#[test]
fn fit_checks_every_option_before_any_work() {
    let dir = temp_dir("fit-options");
    let (scene, images) = scene_with_images(&dir);
    let out = dir.join("out");
    let study = |name: &str, text: &str| {
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--threads".into(), "0".into()], "--threads"),
        (vec!["--threads".into(), "100000".into()], "--threads"),
        (vec!["--spp".into(), "0".into()], "--spp"),
        (vec!["--photons".into(), "0".into()], "--photons"),
        (vec!["--time-budget=-1".into()], "--time-budget"),
        (vec!["--time-budget".into(), "NaN".into()], "--time-budget"),
        (vec!["--held-out".into(), "2".into()], "--held-out"),
        (
            vec!["--study".into(), study("unknown", r#"{"paper": {"train": {"lr_latnet": 1}}}"#)],
            "'paper.train.lr_latnet'",
        ),
        (
            vec!["--study".into(), study("type", r#"{"prior": {"refine": {"updates": "many"}}}"#)],
            "'prior.refine.updates'",
        ),
        (vec!["--study".into(), study("lanes", r#"{"paper": {"train": {"gradient": {"lanes": 3}}}}"#)], "lanes"),
        (vec!["--study".into(), study("blocks", r#"{"prior": {"refine": {"blocks": [1]}}}"#)], "prior.refine.blocks"),
        (
            vec!["--study".into(), study("coarse", r#"{"paper": {"train": {"coarse_fraction": 1.5}}}"#)],
            "coarse_fraction",
        ),
        (vec!["--study".into(), study("lr", r#"{"paper": {"train": {"lr_latent": -1}}}"#)], "lr_latent"),
        (vec!["--study".into(), study("refine_lr", r#"{"paper": {"refine": {"lr": 0}}}"#)], "refine.lr"),
        (
            vec![
                "--study".into(),
                study("directions", r#"{"paper": {"train": {"gradient": {"weight_directions": 1000000}}}}"#),
            ],
            "weight_directions",
        ),
        (vec!["--study".into(), dir.join("missing.json").to_str().unwrap().into()], "--study"),
        (vec!["--images".into(), dir.join("nowhere").to_str().unwrap().into()], "--images"),
        (vec!["--box=-1,-1,-1,1,1,1".into()], "--box"),
    ];
    for (extra, field) in cases {
        let mut args = vec!["fit", "--scene", &scene, "--out", out.to_str().unwrap(), "--prior", "none"];
        if !extra.contains(&"--images".to_string()) {
            args.extend(["--images", &images]);
        }
        args.extend(extra.iter().map(String::as_str));
        let result = dualphoton(&args);
        let stderr = String::from_utf8_lossy(&result.stderr);
        // `--images` is read after the method is announced; every other option is refused before.
        let error = stderr.lines().last().unwrap_or("").to_string();
        assert!(!result.status.success() && !stderr.contains("panicked"), "{extra:?}: {stderr}");
        assert!(error.starts_with("error: ") && error.contains(field), "{extra:?} does not name {field}: {stderr}");
        assert!(!stderr.contains("training 1/"), "{extra:?}: work started before the error: {stderr}");
        assert!(!out.join("log.csv").exists(), "{extra:?} wrote output");
    }
}

#[test]
fn judge_names_both_of_its_references_and_fit_names_images() {
    let dir = temp_dir("judge-options");
    let (scene, images) = scene_with_images(&dir);
    npy::write_f32(&dir.join("estimate.npy"), &[8, 8, 8], &blob(8)).unwrap();
    let estimate = dir.join("estimate.npy");
    let out = dualphoton(&["judge", "--scene", &scene, "--estimate", estimate.to_str().unwrap()]);
    expect_error(&out, "--truth");
    expect_error(&out, "--images");
    std::fs::remove_file(Path::new(&images).join("cam1.npy")).unwrap();
    let out = dualphoton(&["judge", "--scene", &scene, "--estimate", estimate.to_str().unwrap(), "--images", &images]);
    expect_error(&out, "--images");
    let out = dualphoton(&["judge", "--scene", &scene, "--estimate", estimate.to_str().unwrap(), "--spp", "0"]);
    assert!(!out.status.success());
}

#[test]
fn the_option_surface_is_small() {
    let options = |bin: &str, args: &[&str]| {
        let out = Command::new(bin).args(args).arg("--help").output().unwrap();
        let help = String::from_utf8_lossy(&out.stdout).into_owned();
        let n = help.lines().filter(|l| l.trim_start().starts_with("--")).count();
        (n, help)
    };
    let (fit, help) = options(env!("CARGO_BIN_EXE_dualphoton"), &["fit"]);
    // 14 for images you rendered, plus --capture, --frame, --box, --focal-lengths and --rig for a real capture.
    assert!(fit <= 19 && help.lines().count() <= 28, "fit: {fit} options\n{help}");
    // The library's defaults, computed, not copied.
    assert!(help.contains("[default: 250 (paper's method), 60 (learned prior)]"), "{help}");
    let (table1, help) = options(env!("CARGO_BIN_EXE_experiment_table1"), &[]);
    assert!(table1 <= 12, "experiment_table1: {table1} options\n{help}");
    let (prior_eval, help) = options(env!("CARGO_BIN_EXE_prior_eval"), &[]);
    assert!(prior_eval <= 16, "prior_eval: {prior_eval} options\n{help}");
}
