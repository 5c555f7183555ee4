//! Hostile inputs to the library (and a few through the command line): each
//! is a one-line error naming the bad field or file, found before any work
//! (or after bounded work), never a panic, an abort, a hang, or NaN or
//! infinity in an output.
mod common;
use common::temp_dir;

use dualphoton::data::scalarflow::load_scalarflow;
use dualphoton::eval::density::density_metrics;
use dualphoton::eval::metrics::{block_rel_rmse, rel_l1, rel_rmse};
use dualphoton::eval::scenes;
use dualphoton::image::Image;
use dualphoton::io::npy;
use dualphoton::math::Vec3;
use dualphoton::prior::Prior;
use dualphoton::scene::file::{self, validate};
use dualphoton::scene::validate::{render_memory, MAX_RENDER_BYTES};
use dualphoton::scene::Scene;
use dualphoton::volume::Grid;
use std::io::Write;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Instant;

/// Asserts that `result` is one line that starts with (or names) `field`.
fn fails<T: std::fmt::Debug>(result: dualphoton::Result<T>, field: &str) -> String {
    let e = result.expect_err(&format!("{field}: not rejected")).0;
    assert!(e.contains(field), "error does not name {field}: {e}");
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.len() < 600, "error too long ({} bytes): {e}", e.len());
    e
}

/// A `.npy` (format 1.0) header claiming `shape` of float64, followed by `body`.
fn npy_header(shape: &str, body: &[u8]) -> Vec<u8> {
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
    header.push_str(&" ".repeat((64 - (10 + header.len() + 1) % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(body);
    out
}

#[test]
fn arrays_claiming_a_huge_shape_are_refused_before_allocating() {
    let start = Instant::now();
    let dir = temp_dir("huge");
    // A 4 MB .npy claiming 1024^3 float64 (8 GB).
    let path = dir.join("huge.npy");
    std::fs::write(&path, npy_header("(1024, 1024, 1024)", &vec![0; 4 << 20])).unwrap();
    let e = fails(npy::read(&path, "volume.density"), "volume.density");
    assert!(e.contains("huge.npy") && e.contains("more elements than"), "{e}");
    // A shape that fits but does not match the file's size: refused from the header and the file's length.
    let long = dir.join("long.npy");
    std::fs::write(&long, npy_header("(4,)", &vec![0; 1 << 20])).unwrap();
    let e = fails(npy::read(&long, "--images"), "--images");
    assert!(e.contains("data is 1048576 bytes, shape [4] of <f8 needs 32"), "{e}");
    // The same inside a deflated .npz: the header is read first, nothing else decompressed.
    let npz = dir.join("huge.npz");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&npz).unwrap());
    let deflated = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("data.npy", deflated).unwrap();
    zip.write_all(&npy_header("(1024, 1024, 1024, 1)", &[])).unwrap();
    for _ in 0..64 {
        zip.write_all(&vec![0u8; 1 << 20]).unwrap();
    }
    zip.finish().unwrap();
    assert!(std::fs::metadata(&npz).unwrap().len() < 4 << 20);
    let e = fails(load_scalarflow(&npz, 16), "huge.npz");
    assert!(e.contains("more elements than"), "{e}");
    // A header whose shape fits but whose data goes on (a zip bomb) is cut at the declared size.
    let npz = dir.join("long.npz");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&npz).unwrap());
    zip.start_file("data.npy", deflated).unwrap();
    zip.write_all(&npy_header("(2, 2, 2)", &vec![0u8; 32 << 20])).unwrap();
    zip.finish().unwrap();
    let e = fails(load_scalarflow(&npz, 16), "long.npz");
    assert!(e.contains("needs 64"), "{e}");
    assert!(start.elapsed().as_secs_f64() < 20.0, "took {:?}", start.elapsed());
}

#[test]
fn endless_files_and_directories_are_refused_before_reading() {
    let start = Instant::now();
    let dir = temp_dir("endless");
    for path in [Path::new("/dev/zero"), dir.as_path()] {
        let e = fails(npy::read(path, "--estimate"), "--estimate");
        assert!(e.contains("not a regular file"), "{e}");
        let e = fails(file::load(path), "scene");
        assert!(e.contains("not a regular file"), "{e}");
        let e = fails(load_scalarflow(path, 8), "ScalarFlow frame");
        assert!(e.contains("not a regular file"), "{e}");
    }
    // A scene whose density is /dev/zero.
    let scene = dir.join("scene.json");
    let text = serde_json::json!({
            "volume": {"bbox_min": [-0.5, -0.5, -0.5], "bbox_max": [0.5, 0.5, 0.5], "density": "/dev/zero",
                       "sigma_t_scale": 20.0, "albedo": 0.9, "g": 0.5, "max_order": 2},
            "lights": [{"position": [1.0, 0.5, 2.0], "intensity": 50.0}],
            "cameras": [{"position": [0.0, 0.0, 2.5], "look_at": [0.0, 0.0, 0.0], "fov_y_deg": 40.0, "width": 8, "height": 6}]
    })
    .to_string();
    std::fs::write(&scene, text).unwrap();
    let e = fails(file::load(&scene), "volume.density");
    assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
    // A prior directory whose prior.json is a directory.
    std::fs::create_dir_all(dir.join("prior/prior.json")).unwrap();
    let e = fails(Prior::load(&dir.join("prior")), "prior.json");
    assert!(e.contains("not a regular file"), "{e}");
    assert!(start.elapsed().as_secs_f64() < 5.0, "took {:?}", start.elapsed());
}

#[test]
fn float64_values_beyond_float32_are_refused_where_data_becomes_float32() {
    let dir = temp_dir("f64");
    let path = dir.join("big.npy");
    npy::write_f64(&path, &[2, 2, 2], &[0.1, 0.2, 1e300, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
    assert_eq!(npy::read(&path, "weights").unwrap().data[2], 1e300, "plain reads stay exact");
    let e = fails(npy::read_f32_range(&path, "--images"), "--images");
    assert!(e.contains("1e300") && e.contains("flat index 2") && e.contains("float32"), "{e}");
    // A scene's density of 1e300.
    let scene = dir.join("scene.json");
    let mut s = scenes::one_light_blob(2, 8);
    s.density.data = vec![0.1; 8];
    file::save(&s, &dir, "scene").unwrap();
    std::fs::copy(&path, dir.join("density.npy")).unwrap();
    let e = fails(file::load(&scene), "volume.density");
    assert!(e.contains("float32"), "{e}");
}

/// A valid scene: a 6^3 blob, one light, two cameras of 8x8 pixels.
fn scene() -> Scene {
    let s = scenes::one_light_blob(6, 8);
    validate(&s).unwrap();
    s
}

fn rejected(change: impl Fn(&mut Scene), field: &str) -> String {
    let mut s = scene();
    change(&mut s);
    let start = Instant::now();
    let e = fails(validate(&s), field);
    assert!(e.starts_with(field), "{e}");
    assert!(start.elapsed().as_secs_f64() < 10.0, "{field}: validation took {:?}", start.elapsed());
    e
}

#[test]
fn settings_that_would_run_for_ever_or_overflow_are_refused() {
    // Samples per pixel: 2^32 - 1 would allocate a 34 GB permutation per pixel.
    rejected(|s| s.render.spp = u32::MAX, "render.spp");
    rejected(|s| s.render.spp = 0, "render.spp");
    // One path sample has no standard error.
    let e = rejected(|s| s.render.path_spp = 1, "render.path_spp");
    assert!(e.contains("standard-error"), "{e}");
    // Marching steps far below the voxel size.
    for step in [1e-12, 1e-6] {
        rejected(|s| s.render.step = Some(step), "render.step");
        rejected(|s| s.render.photon_step = Some(step), "render.photon_step");
    }
    let mut s = scene();
    s.render.step = Some(s.density.voxel_size().min() / 64.0);
    assert_eq!(validate(&s), Ok(()), "the finest step allowed");
    // Optical depth beyond the path tracer's reach.
    let e = rejected(|s| s.medium.sigma_t_scale = 1e9, "volume.sigma_t_scale");
    assert!(e.contains("optical depth"), "{e}");
    // Light intensities whose radiance overflows float32 (or float64).
    for intensity in [1e31, 1e100, 1e300] {
        rejected(|s| s.lights[0].intensity = intensity, "lights[0].intensity");
    }
    let mut s = scene();
    s.lights[0].intensity = 1e30;
    assert_eq!(validate(&s), Ok(()));
    // A camera so far that it has no direction is blamed for its position, not its up vector.
    rejected(|s| s.cameras[0].position = Vec3::new(0.0, 0.0, 1e300), "cameras[0].position");
    rejected(|s| s.cameras[1].look_at = Vec3::new(1e300, 0.0, 0.0), "cameras[1].look_at");
    rejected(|s| s.lights[0].position = Vec3::new(0.0, -1e300, 0.0), "lights[0].position");
}

#[test]
fn a_render_that_cannot_fit_in_memory_is_refused_up_front() {
    // 10,000 small cameras on a 64^3 grid: one photon estimate per camera, 21 GB.
    let mut s = scene();
    s.density = scenes::blob(64);
    let camera = s.cameras[0].clone();
    s.cameras = vec![camera; 10_000];
    assert!(render_memory(&s) > MAX_RENDER_BYTES);
    let start = Instant::now();
    let e = fails(validate(&s), "cameras");
    assert!(e.contains("10000 cameras") && e.contains("GiB"), "{e}");
    assert!(start.elapsed().as_secs_f64() < 20.0, "took {:?}", start.elapsed());
    // Without photons (max_order 1) the same cameras need only their images.
    s.medium.max_order = 1;
    assert!(render_memory(&s) < 1 << 30);
    assert_eq!(validate(&s), Ok(()));
}

#[test]
fn prior_weights_that_decode_overflowing_densities_are_refused_on_load() {
    let dir = temp_dir("prior");
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/plume64");
    std::fs::copy(shipped.join("prior.json"), dir.join("prior.json")).unwrap();
    let n = npy::read(&shipped.join("weights.npy"), "weights").unwrap().data.len();
    let mut w = vec![0.01; n];
    w[n / 2] = 1e30;
    npy::write_f32(&dir.join("weights.npy"), &[n], &w).unwrap();
    let e = fails(Prior::load(&dir), "weights.npy");
    assert!(e.contains(&format!("weight {} is 1.000e30", n / 2)), "{e}");
    w[n / 2] = 0.5;
    npy::write_f32(&dir.join("weights.npy"), &[n], &w).unwrap();
    assert!(Prior::load(&dir).is_ok());
}

#[test]
fn relative_errors_against_zero_are_undefined_not_zero_or_infinite() {
    assert_eq!(rel_rmse(&[1.0, 2.0], &[0.0, 0.0]), None);
    assert_eq!(rel_rmse(&[0.0, 0.0], &[0.0, 0.0]), None);
    assert_eq!(rel_rmse(&[2.0, 2.0], &[1.0, 1.0]), Some(1.0));
    assert_eq!(rel_l1(&[1.0, 5.0], &[0.0, 3.0], &[true, false]), None);
    assert_eq!(rel_l1(&[1.0, 5.0], &[0.0, 4.0], &[true, true]), Some(0.5));
    let black = Image { width: 4, height: 4, data: vec![0.0; 16] };
    let lit = Image { width: 4, height: 4, data: vec![1.0; 16] };
    assert_eq!(block_rel_rmse(std::slice::from_ref(&lit), std::slice::from_ref(&black), None, 2), None);
    assert_eq!(block_rel_rmse(std::slice::from_ref(&lit), std::slice::from_ref(&lit), None, 2), Some(0.0));
    let truth = scenes::blob(8);
    let mut zero = truth.clone();
    zero.data.fill(0.0);
    let mask = vec![true; truth.len()];
    let e = fails(density_metrics(&truth, &zero, &mask), "truth");
    assert!(e.contains("undefined"), "{e}");
    assert!(density_metrics(&zero, &truth, &mask).is_ok(), "a zero estimate against a real truth is fine");
}

#[test]
fn long_paths_are_shortened_in_messages() {
    let long = format!("/tmp/{}/density.npy", "d".repeat(50_000));
    let e = fails(npy::read(Path::new(&long), "volume.density"), "volume.density");
    assert!(e.contains("...") && e.ends_with(&e[e.len() - 20..]) && e.len() < 400, "{} bytes", e.len());
    assert!(e.contains("density.npy"), "the file name (the end) is kept: {e}");
    let e = fails(load_scalarflow(Path::new(&long), 8), "ScalarFlow frame");
    assert!(e.len() < 400);
    let e = fails(Prior::load(Path::new(&long)), "prior");
    assert!(e.len() < 400);
}

fn dualphoton(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dualphoton")).args(args).output().unwrap()
}

/// The command fails at once with one line naming `field`.
fn cli_fails(args: &[&str], field: &str) {
    let start = Instant::now();
    let out = dualphoton(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !stderr.contains("panicked"), "{field}: {stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: ") && stderr.contains(field), "{field}: {stderr}");
    assert!(start.elapsed().as_secs_f64() < 10.0, "{field}: took {:?}", start.elapsed());
}

#[test]
fn the_command_line_refuses_the_same_before_rendering() {
    let dir = temp_dir("cli");
    file::save(&scene(), &dir, "scene").unwrap();
    let (scene, out) = (dir.join("scene.json"), dir.join("out"));
    let base = ["render", "--scene", scene.to_str().unwrap(), "--out", out.to_str().unwrap()];
    let with = |extra: &[&'static str]| [&base[..], extra].concat();
    cli_fails(&with(&["--spp", "4294967295"]), "render.spp");
    cli_fails(&with(&["--method", "path", "--path-spp", "1"]), "render.path_spp");
    cli_fails(&with(&["--step", "1e-12"]), "render.step");
    let zero = ["render", "--scene", "/dev/zero", "--out", out.to_str().unwrap()];
    cli_fails(&zero, "not a regular file");
    assert!(!out.join("cam0.npy").exists());
}

#[test]
fn a_grid_of_the_largest_shape_still_validates() {
    // The bounds do not refuse ordinary scenes: the 64^3 paper-sized blob with 8 cameras.
    let mut s = scene();
    s.density = Grid::new(s.density.lo, s.density.hi, [64, 64, 64], scenes::blob(64).data);
    s.cameras = (0..8).map(|_| s.cameras[0].clone()).collect();
    assert_eq!(validate(&s), Ok(()));
}
