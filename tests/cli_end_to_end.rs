//! `dualphoton grad` and `dualphoton judge` end to end on a tiny scene
//! (6^3 blob, two 8x8 cameras): what they write, and that it agrees with
//! the library and with finite differences.
mod common;
use common::temp_dir;

use dualphoton::eval::scenes;
use dualphoton::grad::loss::mse;
use dualphoton::grad::reverse::{reverse_gradient, Subset};
use dualphoton::image::Image;
use dualphoton::io::npy;
use dualphoton::render::frozen::Frozen;
use dualphoton::render::render_photon;
use dualphoton::scene::{file, Scene};
use std::path::Path;
use std::process::{Command, Output};

fn dualphoton(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_dualphoton")).args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

/// The tiny scene written to `dir/scene.json` and loaded back (its density
/// rounded to float32 as the commands see it).
fn tiny_scene(dir: &Path) -> Scene {
    let mut s = scenes::one_light_blob(6, 8);
    s.render.photons = 3_000;
    s.render.seed = 5;
    file::save(&s, dir, "scene").unwrap();
    file::load(&dir.join("scene.json")).unwrap()
}

/// Renders `scene` at `density` with `seed` and `photons` and writes DIR/cam0.npy, ...
fn write_images(scene: &Scene, density: &[f64], seed: u64, photons: u64, dir: &Path) -> Vec<Image> {
    std::fs::create_dir_all(dir).unwrap();
    let mut s = scene.clone();
    s.density.data = density.to_vec();
    (s.render.seed, s.render.photons, s.render.spp) = (seed, photons, 4);
    let images = render_photon(&s).images;
    for (c, image) in images.iter().enumerate() {
        npy::write_f32(&dir.join(format!("cam{c}.npy")), &[image.height, image.width], &image.data).unwrap();
    }
    // As the command reads them: float32.
    images.into_iter().map(|i| Image { data: i.data.iter().map(|&v| v as f32 as f64).collect(), ..i }).collect()
}

#[test]
fn grad_writes_the_librarys_gradient_and_its_sign_matches_finite_differences() {
    let dir = temp_dir("grad");
    let scene = tiny_scene(&dir);
    let other: Vec<f64> = scene.density.data.iter().map(|v| v * 0.7).collect();
    let targets = write_images(&scene, &other, 11, 3_000, &dir.join("targets"));
    let centre = scene.density.index(3, 3, 3);
    let out = dir.join("grad.npy");
    let run = dualphoton(&[
        "grad",
        "--scene",
        dir.join("scene.json").to_str().unwrap(),
        "--target",
        dir.join("targets").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--voxels",
        "3,3,3;2,3,2",
    ]);
    let g = npy::read(&out, "grad").unwrap();
    assert_eq!(g.shape, vec![6, 6, 6]);
    assert!(g.data.iter().all(|v| v.is_finite()));
    // The library's reverse-mode gradient of the same frozen render (rounded to float32 on writing).
    let frozen = Frozen::new(&scene, None);
    let lib = reverse_gradient(&frozen, &targets, Subset::full()).grad;
    let scale = lib.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(scale > 0.0);
    for (v, (a, b)) in g.data.iter().zip(&lib).enumerate() {
        assert!((a - b).abs() <= 1e-6 * scale, "voxel {v}: grad wrote {a}, the library gives {b}");
    }
    // The density is too bright for the targets (0.7 of it): the loss falls as the centre thins.
    let h = 1e-4;
    let loss = |dv: f64| {
        let mut d = scene.density.clone();
        d.data[centre] += dv;
        mse(&frozen.images_with(&d, 2), &targets)
    };
    let fd = (loss(h) - loss(-h)) / (2.0 * h);
    let written = g.data[centre];
    assert!(fd > 0.0 && written > 0.0, "sign: finite difference {fd}, grad {written}");
    assert!((written - fd).abs() <= 1e-3 * fd.abs() + 1e-6 * scale, "grad {written} vs finite difference {fd}");
    // The listed voxels: rev-full and forward mode printed side by side, equal.
    let stdout = String::from_utf8_lossy(&run.stdout);
    let rows: Vec<&str> = stdout.lines().filter(|l| l.starts_with('(')).collect();
    assert_eq!(rows.len(), 2, "{stdout}");
    for row in rows {
        let cols: Vec<f64> = row.split('\t').skip(1).map(|c| c.parse().unwrap()).collect();
        assert!((cols[0] - cols[1]).abs() <= 1e-9 * scale, "{row}");
    }
    assert!(stdout.lines().next().unwrap().contains("rev-full"), "{stdout}");
}

/// The data rows of a `judge` Markdown table on stdout: (camera, role, pixel / floor).
fn table(stdout: &str) -> Vec<(usize, String, String)> {
    stdout
        .lines()
        .filter(|l| l.starts_with("| ") && l.as_bytes().get(2).is_some_and(u8::is_ascii_digit))
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split('|').map(str::trim).collect();
            (cells[0].parse().unwrap(), cells[1].to_string(), cells[5].to_string())
        })
        .collect()
}

/// The rows of a `judge --out` CSV, as text cells.
fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(!text.contains("inf") && !text.contains("NaN"), "{text}");
    let mut lines = text.lines().map(|l| l.split(',').map(String::from).collect::<Vec<_>>());
    (lines.next().unwrap(), lines.collect())
}

#[test]
fn judge_tables_a_fit_against_the_truth_or_images_and_labels_the_held_out_camera() {
    let dir = temp_dir("judge");
    let scene = tiny_scene(&dir);
    let scene_path = dir.join("scene.json");
    let truth_path = dir.join("truth.npy");
    npy::write_f32(&truth_path, &scene.density.shape, &scene.density.data).unwrap();
    let scaled: Vec<f64> = scene.density.data.iter().map(|v| v * 1.3).collect();
    let scaled_path = dir.join("scaled.npy");
    npy::write_f32(&scaled_path, &scene.density.shape, &scaled).unwrap();
    // As judge renders: 200,000 photons, 4 samples per pixel.
    write_images(&scene, &scene.density.data, 99, 200_000, &dir.join("images"));
    std::fs::create_dir_all(dir.join("black")).unwrap();
    for c in 0..2 {
        npy::write_f32(&dir.join(format!("black/cam{c}.npy")), &[8, 8], &[0.0; 64]).unwrap();
    }
    let judge = |estimate: &Path, against: [&str; 2], csv: &str| {
        let csv = dir.join(csv);
        let out = dualphoton(&[
            "judge",
            "--scene",
            scene_path.to_str().unwrap(),
            "--estimate",
            estimate.to_str().unwrap(),
            against[0],
            against[1],
            "--held-out",
            "1",
            "--photons",
            "200000",
            "--spp",
            "4",
            "--out",
            csv.to_str().unwrap(),
        ]);
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        (table(&stdout), csv_rows(&csv), stdout)
    };
    let truth = ["--truth", truth_path.to_str().unwrap()];
    let images = dir.join("images");
    let images = ["--images", images.to_str().unwrap()];
    let ratio = |s: &str| s.parse::<f64>().unwrap();

    // Against the truth: a density scaled by 1.3 is far above the floor on both cameras.
    let (rows, (header, cells), _) = judge(&scaled_path, truth, "scaled_truth.csv");
    assert_eq!(rows.iter().map(|r| (r.0, r.1.as_str())).collect::<Vec<_>>(), [(0, "train"), (1, "held-out")]);
    assert!(rows.iter().all(|r| ratio(&r.2) > 2.0), "{rows:?}");
    assert_eq!(header[..2], ["camera", "role"]);
    assert_eq!(header.len(), 8);
    assert_eq!(cells.len(), 2);
    assert_eq!((cells[0][1].as_str(), cells[1][1].as_str()), ("train", "held-out"));
    assert!(cells.iter().flat_map(|r| &r[2..]).all(|c| c.parse::<f64>().is_ok_and(|v| v.is_finite() && v > 0.0)));
    // Against images of the truth (another seed): the truth sits near the floor, the scaled density above it.
    let (at_floor, _, _) = judge(&truth_path, images, "truth_images.csv");
    assert!(at_floor.iter().all(|r| (0.6..1.6).contains(&ratio(&r.2))), "{at_floor:?}");
    let (above, _, _) = judge(&scaled_path, images, "scaled_images.csv");
    assert!(above.iter().all(|r| ratio(&r.2) > 2.0), "{above:?}");
    // All-black images: the relative errors are undefined, said so, never inf or NaN.
    let black = dir.join("black");
    let (rows, (_, cells), stdout) = judge(&truth_path, ["--images", black.to_str().unwrap()], "black.csv");
    assert!(rows.iter().all(|r| r.2 == "undefined") && stdout.contains("all black"), "{stdout}");
    assert!(cells.iter().all(|r| r[2].is_empty()), "{cells:?}");
}
