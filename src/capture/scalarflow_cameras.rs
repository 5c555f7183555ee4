//! Focal lengths from ScalarFlow's own calibration.
//!
//! ScalarFlow's cameras were calibrated per pixel; the GlobTrans code
//! (Franz et al., CVPR 2021) summarises that calibration in
//! `scalaFlow_cameras.json`: per camera its `position`, `fov_vertical`
//! (degrees, over the image's height) and more, in ScalarFlow's frame, which
//! is the PINF/HyFluid clip's frame with z negated. The clip's `info.json`
//! gives each camera a horizontal field of view instead, over the image's
//! shorter side; two of its five cameras share one value. On the settings
//! study's frames, square-pixel focal lengths from the vertical fields of
//! view fit the training cameras closer and give an unseen camera the
//! magnification its photograph asks for, while ScalarFlow's camera
//! orientations do neither; so only the focal lengths are taken, the poses
//! stay the capture's. They are an option, not the default: with them two
//! of four cameras held out in turn scored lower, and so they did when only
//! the held-out camera took the file's correction ([`held_out_zoom`]): a
//! magnification about the principal point also moves the smoke, against
//! the camera's own vertical offset (docs/studies/real_settings.md).

use super::align::geometric_mean;
use super::Capture;
use crate::bail;
use crate::error::{show, Error, Result};
use crate::io::npy;
use crate::math::Vec3;
use crate::scene::fields::{parse_json, Fields};
use crate::scene::Lens;
use std::path::Path;

/// Largest camera file read: 1 MiB.
const MAX_BYTES: u64 = 1 << 20;

/// Largest distance between a capture camera and its match, as a fraction
/// of the distance between the capture's two closest cameras.
const MATCH_TOLERANCE: f64 = 0.01;

/// Gives every camera of `capture` the focal length (square pixels) that
/// the vertical field of view of its camera in the file at `path` implies
/// over its image height; principal points and poses stay. A capture
/// camera matches the file's camera at its position (z negated). Errors
/// name the file: unreadable, a camera without `position` or with a
/// field of view outside (0, 180) degrees, a capture camera without match.
pub fn refocus(capture: &mut Capture, path: &Path) -> Result<()> {
    let focal = focal_lengths(capture, path)?;
    for (view, f) in capture.views.iter_mut().zip(focal) {
        let [_, _, cx, cy] = view.camera.intrinsics();
        view.camera.lens = Lens::Pinhole { fx: f, fy: f, cx, cy };
    }
    Ok(())
}

/// The factor by which the file at `path` says camera `held_out`'s focal
/// lengths are off, in the scale of a rig of the `training` cameras: its
/// focal length in the file over its vertical one in `capture`, divided by
/// the geometric mean of that ratio over `training` (whose own corrections
/// the rig fits from their photographs, with geometric mean 1). The
/// held-out camera's photograph is never looked at. Errors as [`refocus`].
pub fn held_out_zoom(capture: &Capture, path: &Path, training: &[usize], held_out: usize) -> Result<f64> {
    let focal = focal_lengths(capture, path)?;
    let ratio = |v: usize| focal[v] / capture.views[v].camera.intrinsics()[1];
    if training.is_empty() {
        bail!("{}: no training camera to scale the held-out camera against", show(path));
    }
    let ratios: Vec<f64> = training.iter().map(|&v| ratio(v)).collect();
    Ok(ratio(held_out) / geometric_mean(&ratios))
}

/// Per camera of `capture`, the focal length (square pixels) the file at
/// `path` gives it (see [`refocus`]).
fn focal_lengths(capture: &Capture, path: &Path) -> Result<Vec<f64>> {
    let shown = show(path);
    let cameras = read(path).map_err(|e| Error(format!("{shown}: {e}")))?;
    let tolerance = MATCH_TOLERANCE * closest_pair(capture);
    let mut focal = Vec::new();
    for view in &capture.views {
        let at = view.camera.position;
        let found = cameras.iter().find(|(_, position, _)| (position - at).norm() <= tolerance);
        let Some((name, _, fov)) = found else {
            bail!("{shown}: no camera at {}'s position ({:.4}, {:.4}, {:.4}, z negated)", view.name, at.x, at.y, -at.z);
        };
        let Some(fov) = fov else {
            bail!("{shown}: camera {name} has no fov_vertical");
        };
        focal.push(0.5 * view.camera.height as f64 / (0.5 * fov.to_radians()).tan());
    }
    Ok(focal)
}

/// Each camera of the file: its name, its position in the capture's frame
/// (z negated) and its vertical field of view in degrees, if given.
fn read(path: &Path) -> Result<Vec<(String, Vec3, Option<f64>)>> {
    let bytes = npy::read_bounded(path, MAX_BYTES).map_err(|e| Error(e.to_string()))?;
    let text = String::from_utf8(bytes).map_err(|_| Error("not UTF-8 text".into()))?;
    let root = parse_json(&text).map_err(|e| Error(format!("not valid JSON: {e}")))?;
    let Some(entries) = root.as_object() else {
        bail!("not a ScalarFlow camera file (an object of cameras, each with position and fov_vertical)");
    };
    let mut cameras = Vec::new();
    // Cameras are the objects; the other entries summarise them (`focus`, averages).
    for (name, entry) in entries.iter().filter(|(_, e)| e.is_object()) {
        let fields = Fields::lenient(entry, name)?;
        let p: [f64; 3] = fields.required("position")?;
        // GlobTrans writes null where it has no field of view.
        let fov: Option<f64> = match fields.get("fov_vertical") {
            None | Some(serde_json::Value::Null) => None,
            Some(_) => Some(fields.required("fov_vertical")?),
        };
        if p.iter().any(|x| !x.is_finite()) {
            bail!("{}: {p:?} is not a finite point", fields.name("position"));
        }
        if let Some(fov) = fov.filter(|f| !(*f > 0.0 && *f < 180.0)) {
            bail!("{}: {fov} must be a field of view in (0, 180) degrees", fields.name("fov_vertical"));
        }
        cameras.push((name.clone(), Vec3::new(p[0], p[1], -p[2]), fov));
    }
    if cameras.is_empty() {
        bail!("no cameras");
    }
    Ok(cameras)
}

/// The distance between the capture's two closest cameras (1 for one camera).
fn closest_pair(capture: &Capture) -> f64 {
    let positions: Vec<Vec3> = capture.views.iter().map(|v| v.camera.position).collect();
    let mut closest = f64::INFINITY;
    for (i, a) in positions.iter().enumerate() {
        for b in &positions[i + 1..] {
            closest = closest.min((a - b).norm());
        }
    }
    if closest.is_finite() {
        closest
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{Frames, View};
    use crate::scene::Camera;

    fn view(name: &str, position: Vec3) -> View {
        let lens = Lens::Pinhole { fx: 900.0, fy: 900.0, cx: 47.0, cy: 81.0 };
        let camera = Camera { position, look_at: Vec3::zeros(), up: Vec3::y(), lens, width: 100, height: 160 };
        View { name: name.into(), camera, frames: Frames::Images(vec![]), held_out: false }
    }

    fn file(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("dualphoton-scalarflow-cameras-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// A factor the file shares over every camera is the rig's scale, not an
    /// error of the held-out camera; what it gives the held-out camera beyond
    /// the training cameras' geometric mean is.
    #[test]
    fn the_held_out_zoom_is_the_files_ratio_over_the_training_cameras() {
        let at = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 0.5), Vec3::new(-1.0, 0.0, 0.5)];
        let capture = Capture { views: vec![view("a", at[0]), view("b", at[1]), view("c", at[2])], smoke_box: None };
        // The capture's cameras have focal length 900 over a height of 160 pixels.
        let fov = |f: f64| 2.0 * (80.0 / f).atan().to_degrees();
        let entry = |name: &str, p: Vec3, f: f64| {
            format!(r#""{name}": {{"position": [{}, {}, {}], "fov_vertical": {}}}"#, p.x, p.y, -p.z, fov(f))
        };
        let path = file(
            "zoom.json",
            &format!(
                "{{{}, {}, {}}}",
                entry("0", at[0], 450.0 * 0.98),
                entry("1", at[1], 450.0 / 0.98),
                entry("2", at[2], 450.0 * 1.03)
            ),
        );
        let k = held_out_zoom(&capture, &path, &[0, 1], 2).unwrap();
        assert!((k - 1.03).abs() < 1e-12, "{k}");
        let k = held_out_zoom(&capture, &path, &[1], 0).unwrap();
        assert!((k - 0.98 * 0.98).abs() < 1e-12, "{k}");
        assert!(held_out_zoom(&capture, &path, &[], 2).unwrap_err().0.contains("no training camera"));
    }

    #[test]
    fn focal_lengths_follow_the_vertical_field_of_view_of_the_camera_at_the_same_place() {
        let mut capture = Capture {
            views: vec![view("a", Vec3::new(0.0, 0.0, 1.0)), view("b", Vec3::new(1.0, 0.0, 0.5))],
            smoke_box: None,
        };
        let before = capture.clone();
        // ScalarFlow's frame negates z; the file lists the cameras in another order.
        let path = file(
            "cameras.json",
            r#"{"focus": [0.3, 0.4, 0.2], "fov_vertical_average": 40.7,
                "0": {"position": [1.0, 0.0, -0.5], "fov_vertical": 90.0, "fov_horizontal": null},
                "1": {"position": [0.0, 0.0, -1.0], "fov_vertical": 40.0}}"#,
        );
        refocus(&mut capture, &path).unwrap();
        let focal = |v: usize| capture.views[v].camera.intrinsics();
        assert!((focal(1)[0] - 80.0).abs() < 1e-9 && focal(1)[0] == focal(1)[1], "{:?}", focal(1));
        let f = 80.0 / 20f64.to_radians().tan();
        assert!((focal(0)[0] - f).abs() < 1e-9 && focal(0)[0] == focal(0)[1], "{:?}", focal(0));
        for (now, was) in capture.views.iter().zip(&before.views) {
            let [_, _, cx, cy] = now.camera.intrinsics();
            assert_eq!((cx, cy), (47.0, 81.0));
            assert_eq!(
                (now.camera.position, now.camera.look_at, now.camera.up),
                (was.camera.position, was.camera.look_at, was.camera.up)
            );
        }
        // A point on the camera's upward image edge at the field of view's half angle lands on the top row.
        let camera = &capture.views[1].camera;
        let p = camera.position + (camera.look_at - camera.position).normalize() + Vec3::y() * 45f64.to_radians().tan();
        let (_, y) = camera.project(&p).unwrap();
        assert!((y - (81.0 - 80.0)).abs() < 1e-9, "{y}");
    }

    #[test]
    fn a_camera_without_a_match_or_a_bad_field_of_view_is_an_error() {
        let capture = Capture {
            views: vec![view("a", Vec3::new(0.0, 0.0, 1.0)), view("b", Vec3::new(1.0, 0.0, 0.5))],
            smoke_box: None,
        };
        // Positions not negated: camera a is not found.
        let unnegated = file("unnegated.json", r#"{"0": {"position": [0.0, 0.0, 1.0], "fov_vertical": 40.0}}"#);
        let e = refocus(&mut capture.clone(), &unnegated).unwrap_err().0;
        assert!(e.contains("no camera at a's position"), "{e}");
        let no_fov = file(
            "no_fov.json",
            r#"{"0": {"position": [0.0, 0.0, -1.0], "fov_vertical": null}, "1": {"position": [1.0, 0.0, -0.5], "fov_vertical": 40.0}}"#,
        );
        let e = refocus(&mut capture.clone(), &no_fov).unwrap_err().0;
        assert!(e.contains("camera 0 has no fov_vertical"), "{e}");
        let wide = file("wide.json", r#"{"0": {"position": [0.0, 0.0, -1.0], "fov_vertical": 180.0}}"#);
        assert!(refocus(&mut capture.clone(), &wide).unwrap_err().0.contains("(0, 180)"));
        let list = file("list.json", "[1, 2]");
        assert!(refocus(&mut capture.clone(), &list).unwrap_err().0.contains("not a ScalarFlow camera file"));
        let summary_only = file("summary.json", r#"{"focus": [0.3, 0.4, 0.2]}"#);
        assert!(refocus(&mut capture.clone(), &summary_only).unwrap_err().0.contains("no cameras"));
    }
}
