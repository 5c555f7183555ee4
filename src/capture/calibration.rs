//! Camera calibrations as NeRF-style projects write them.
//!
//! Two forms are read, told apart by their keys:
//! - **`info.json`** (PINF, HyFluid): `train_videos` and optional
//!   `test_videos`, each a list of `{file_name, frame_num, camera_angle_x,
//!   camera_hw: [H, W], transform_matrix}`; the test cameras are the
//!   held-out ones. `file_name` may also name a folder of the video's
//!   frames as images (one per frame). The smoke box is `voxel_matrix` (4x4) and `voxel_scale`,
//!   read as PINF and HyFluid read them: with the matrix's first and third
//!   columns exchanged, the box is `M (s * u)` for `u` in `[0, 1]^3`.
//! - **`transforms.json`** (NeRF, instant-ngp, nerfstudio): `frames`, a list
//!   of `{file_path, transform_matrix}`, one per camera; `file_path` names
//!   an image (a one-frame capture) or a folder of images (one per frame, in
//!   the order of the numbers in their names). Or one per camera and frame, each an image: entries with
//!   the same pose and lens are one camera (see `per_camera`).
//!   Intrinsics at the top or per camera: either
//!   `camera_angle_x` or `fl_x`, `fl_y`, `cx`, `cy`; the size `w`, `h`.
//!   No smoke box: the user gives it.
//!
//! `transform_matrix` is camera-to-world in the OpenGL convention: columns
//! right, up, backwards (the camera looks along minus the third column) and
//! the centre of projection. `camera_angle_x` is the horizontal field of view
//! in radians over the full width; square pixels, principal point at the
//! image centre. Paths are relative to the calibration file.

use super::frames::IMAGE_EXTENSIONS;
use super::{first_repeat, Capture, Frames, View};
use crate::bail;
use crate::error::{show, Error, Result};
use crate::io::npy;
use crate::math::Vec3;
use crate::scene::fields::{parse_json, Fields};
use crate::scene::{Camera, Lens};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Largest calibration file read: 64 MiB.
const MAX_BYTES: u64 = 64 << 20;

/// How far a rotation's columns may be from orthonormal.
const ROTATION_TOLERANCE: f64 = 1e-3;

/// Two cameras whose centres stand closer than this fraction of the rig's
/// width (the largest distance between two cameras' centres) ...
const NEARLY_ONE_PLACE: f64 = 0.01;

/// ... and whose optical axes are closer than this many degrees look like
/// one camera listed twice. ScalarFlow's two calibrations of its rig put
/// each camera at one place and turn it by at most 0.32 degrees; its
/// closest distinct cameras stand 25 % of the rig's width and 22 degrees
/// apart.
const NEARLY_ONE_DIRECTION_DEG: f64 = 1.0;

/// Why a fixed camera's entries must agree, for the errors and the warning.
const ONE_POSE: &str = "a fixed camera listed once per frame needs the same transform_matrix and intrinsics in \
                        each of its entries (poses registered frame by frame differ)";

/// `path` itself if it is a file, else the `info.json` (or, failing that,
/// the `transforms.json`) in the folder `path`.
pub fn locate(path: &Path) -> PathBuf {
    if path.is_dir() {
        let info = path.join("info.json");
        if info.exists() {
            info
        } else {
            path.join("transforms.json")
        }
    } else {
        path.to_path_buf()
    }
}

/// The capture whose calibration is at `path` (a file or the folder holding
/// it, see [`locate`]), with the focal lengths of ScalarFlow's camera file
/// `focal_lengths` if given ([`super::scalarflow_cameras`]) and the smoke
/// box `smoke_box` if given (the user's `--box`) in place of the
/// calibration's.
pub fn open(path: &Path, focal_lengths: Option<&Path>, smoke_box: Option<(Vec3, Vec3)>) -> Result<Capture> {
    let mut capture = load_boxed(&locate(path), smoke_box)?;
    if let Some(file) = focal_lengths {
        super::scalarflow_cameras::refocus(&mut capture, file).map_err(|e| Error(format!("--focal-lengths: {e}")))?;
    }
    Ok(capture)
}

/// The capture described by the calibration file at `path`. Errors name the
/// file and the field: unreadable, neither form, a matrix that is not a
/// rotation and translation, a field of view outside (0, pi), a frame source
/// that does not exist.
pub fn load(path: &Path) -> Result<Capture> {
    load_boxed(path, None)
}

/// [`load`] with the smoke box `given` in place of the calibration's, whose
/// `voxel_matrix` is then not read: a box the user gives replaces one the
/// file gets wrong.
pub fn load_boxed(path: &Path, given: Option<(Vec3, Vec3)>) -> Result<Capture> {
    let shown = show(path);
    let bytes = npy::read_bounded(path, MAX_BYTES).map_err(|e| Error(format!("calibration {shown}: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|_| Error(format!("calibration {shown}: not UTF-8 text")))?;
    let root = parse_json(&text).map_err(|e| Error(format!("calibration {shown}: not valid JSON: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let top = Fields::lenient(&root, "")?;
    let capture = if top.get("train_videos").is_some() {
        info_json(&top, dir, given.is_none())
    } else if top.get("frames").is_some() {
        transforms_json(&top, dir)
    } else {
        Err(Error("neither train_videos (an info.json) nor frames (a transforms.json) is there".into()))
    };
    let mut capture = capture.and_then(same_frame_counts).map_err(|e| Error(format!("calibration {shown}: {e}")))?;
    if capture.views.is_empty() {
        bail!("calibration {shown}: no cameras");
    }
    capture.smoke_box = given.or(capture.smoke_box);
    if let Some(warning) = nearly_one_camera(&capture.views) {
        eprintln!("warning: calibration {shown}: {warning}");
    }
    Ok(capture)
}

/// The capture of an `info.json`, its smoke box read where `with_box`.
fn info_json(top: &Fields, dir: &Path, with_box: bool) -> Result<Capture> {
    let mut found = Vec::new();
    for (key, held_out) in [("train_videos", false), ("test_videos", true)] {
        if key == "test_videos" && top.get(key).is_none() {
            continue;
        }
        for (path, item) in top.list(key)? {
            let v = Fields::lenient(item, &path)?;
            let file: String = v.required("file_name")?;
            let count: usize = v.required("frame_num")?;
            if count == 0 {
                bail!("{}: 0; a video has at least one frame", v.name("frame_num"));
            }
            let [height, width]: [usize; 2] = v.required("camera_hw")?;
            let angle: f64 = v.required("camera_angle_x")?;
            let lens = lens_from_angle(angle, width, height, &v.name("camera_angle_x"))?;
            let camera = posed(&v, lens, width, height)?;
            let video = existing(dir, &file, &v.name("file_name"))?;
            // A folder of frames extracted from the video stands in for it.
            let frames = if video.is_dir() {
                let frames = frame_source(&video, &v.name("file_name"))?;
                if frames.count() != count {
                    bail!(
                        "{}: {} holds {} images, frame_num says {count}",
                        v.name("file_name"),
                        show(&video),
                        frames.count()
                    );
                }
                frames
            } else {
                Frames::Video { path: video.clone(), count }
            };
            found.push((file, camera, frames, held_out));
        }
    }
    let views = named(found)?;
    let smoke_box = match (top.get("voxel_matrix"), top.get("voxel_scale")) {
        (Some(_), Some(_)) if with_box => {
            Some(smoke_box(&top.required::<Vec<[f64; 4]>>("voxel_matrix")?, &top.required("voxel_scale")?)?)
        }
        _ => None,
    };
    Ok(Capture { views, smoke_box })
}

fn transforms_json(top: &Fields, dir: &Path) -> Result<Capture> {
    let mut found = Vec::new();
    for (path, item) in top.list("frames")? {
        let f = Fields::lenient(item, &path)?;
        let file: String = f.required("file_path")?;
        let source = existing_image(dir, &file, &f.name("file_path"))?;
        let frames = frame_source(&source, &f.name("file_path"))?;
        // A size as instant-ngp writes it (`"w": 1920.0`) is a count too.
        let size = |key: &str| -> Result<Option<u64>> {
            Ok(match f.optional_count(key)? {
                Some(n) => Some(n),
                None => top.optional_count(key)?,
            })
        };
        let (width, height) = match (size("w")?, size("h")?) {
            (Some(w), Some(h)) => (usize::try_from(w).unwrap_or(usize::MAX), usize::try_from(h).unwrap_or(usize::MAX)),
            _ => first_image_size(&frames)
                .map_err(|e| Error(format!("{path}: give w and h (the image size in pixels): {e}")))?,
        };
        let lens = transforms_lens(&f, top, &path, width, height)?;
        pinhole(&f, top, &path)?;
        let camera = posed(&f, lens, width, height)?;
        let time: Option<f64> = f.optional("time")?;
        found.push(Entry { path, file, camera, frames, time });
    }
    Ok(Capture { views: named(per_camera(found)?)?, smoke_box: None })
}

/// One entry of a `transforms.json`'s `frames`.
struct Entry {
    /// Where it is in the file (`frames[3]`), for errors.
    path: String,
    /// Its `file_path`.
    file: String,
    camera: Camera,
    frames: Frames,
    /// Its `time`, if given (D-NeRF's field).
    time: Option<f64>,
}

/// The cameras of a `transforms.json`'s entries. Each entry is a camera,
/// unless entries share one: a file may list each camera once per frame
/// (an entry per image, as nerfstudio lists images). Entries with the same
/// `transform_matrix` and intrinsics are then one camera, its frames in the
/// order of their `time` where every entry gives one, else in file order,
/// each camera named by its images' folder (`cam0/000060.png` is `cam0`)
/// or, where the cameras' images share one, `camera0`, `camera1`, ... in
/// file order. Errors: such an entry naming a folder, cameras with
/// different numbers of frames or different times, and cameras that are
/// each listed once at different times (one camera moving with the smoke,
/// as D-NeRF's monocular scenes: no two views of one instant).
fn per_camera(entries: Vec<Entry>) -> Result<Vec<(String, Camera, Frames, bool)>> {
    let mut groups: Vec<Vec<Entry>> = Vec::new();
    for entry in entries {
        match groups.iter_mut().find(|g| g[0].camera == entry.camera) {
            Some(group) => group.push(entry),
            None => groups.push(vec![entry]),
        }
    }
    let Some(repeated) = groups.iter().find(|g| g.len() > 1) else {
        let timed: Vec<&Entry> = groups.iter().flatten().filter(|e| e.time.is_some()).collect();
        if let Some(other) = timed.iter().find(|e| e.time != timed[0].time) {
            bail!(
                "the cameras of {} and {} see different times ({} and {}): dualphoton fits cameras that see the \
                 same instant, so a camera moving with the smoke (a monocular capture) cannot be fitted, and \
                 {ONE_POSE}",
                timed[0].path,
                other.path,
                timed[0].time.unwrap_or_default(),
                other.time.unwrap_or_default()
            );
        }
        return Ok(groups.into_iter().flatten().map(|e| (e.file, e.camera, e.frames, false)).collect());
    };
    let single_image = |e: &Entry| matches!(&e.frames, Frames::Images(i) if i.len() == 1);
    if let Some(e) = groups.iter().flatten().find(|e| !single_image(e)) {
        bail!(
            "{}: names a folder of frames, but this file lists cameras once per frame ({} has the camera of {}: \
             the same transform_matrix and intrinsics): give each entry one image, or list each camera once \
             with a folder",
            e.path,
            repeated[1].path,
            repeated[0].path
        );
    }
    let timed = groups.iter().flatten().all(|e| e.time.is_some());
    if timed {
        for group in &mut groups {
            group.sort_by(|a, b| a.time.partial_cmp(&b.time).unwrap_or(std::cmp::Ordering::Equal));
        }
    }
    let first = &groups[0];
    for group in &groups[1..] {
        if group.len() != first.len() {
            bail!(
                "the camera of {} is listed for {} frames, the camera of {} for {}: every camera needs an image \
                 of every frame, and {ONE_POSE}",
                first[0].path,
                first.len(),
                group[0].path,
                group.len()
            );
        }
        if let Some((a, b)) = first.iter().zip(group).find(|(a, b)| timed && a.time != b.time) {
            bail!(
                "{}: time {} has no match in the camera of {} (its frame at that place is time {}): every camera \
                 needs an image of every frame",
                b.path,
                b.time.unwrap_or_default(),
                a.path,
                a.time.unwrap_or_default()
            );
        }
    }
    let folder = |g: &[Entry]| {
        let parents: Vec<_> = g.iter().map(|e| Path::new(&e.file).parent().map(Path::to_path_buf)).collect();
        parents.iter().all(|p| *p == parents[0]).then(|| parents[0].clone()).flatten()
    };
    let folders: Option<Vec<PathBuf>> = groups.iter().map(|g| folder(g)).collect();
    let distinct = |f: &Vec<PathBuf>| first_repeat(f).is_none() && f.iter().all(|p| !p.as_os_str().is_empty());
    let names: Vec<String> = match folders.filter(distinct) {
        Some(folders) => folders.iter().map(|f| f.to_string_lossy().into_owned()).collect(),
        None => (0..groups.len()).map(|k| format!("camera{k}")).collect(),
    };
    Ok(groups
        .into_iter()
        .zip(names)
        .map(|(group, name)| {
            let camera = group[0].camera.clone();
            let images = group.into_iter().flat_map(|e| match e.frames {
                Frames::Images(paths) => paths,
                Frames::Video { .. } => Vec::new(),
            });
            (name, camera, Frames::Images(images.collect()), false)
        })
        .collect())
}

/// A warning where two of `views`' cameras stand at nearly one place and
/// look nearly one way ([`NEARLY_ONE_PLACE`], [`NEARLY_ONE_DIRECTION_DEG`]):
/// most likely one fixed camera whose images were registered one by one
/// and listed without a `time`, which reads as several cameras of one
/// instant. Not an error: two cameras may stand side by side.
fn nearly_one_camera(views: &[View]) -> Option<String> {
    let centre = |v: &View| v.camera.position;
    let width =
        views.iter().flat_map(|a| views.iter().map(move |b| (centre(a) - centre(b)).norm())).fold(0.0, f64::max);
    if width == 0.0 {
        return None;
    }
    let mut pairs = Vec::new();
    for (i, a) in views.iter().enumerate() {
        for b in &views[i + 1..] {
            let apart = (centre(a) - centre(b)).norm() / width;
            let turned = a.camera.basis().2.angle(&b.camera.basis().2).to_degrees();
            if apart < NEARLY_ONE_PLACE && turned < NEARLY_ONE_DIRECTION_DEG {
                pairs.push((a, b, apart, turned));
            }
        }
    }
    let &(a, b, apart, turned) = pairs.first()?;
    let others = match pairs.len() - 1 {
        0 => String::new(),
        1 => ", as does one other pair".into(),
        n => format!(", as do {n} other pairs"),
    };
    Some(format!(
        "the cameras {} and {} stand {:.2} % of the rig's width apart and look {turned:.2} degrees apart{others}: \
         they are read as two cameras seeing one instant; if they are one camera, {ONE_POSE}",
        a.name,
        b.name,
        100.0 * apart
    ))
}

/// The lens models of a `transforms.json` (nerfstudio's `camera_model`)
/// that are a pinhole when their distortion coefficients are 0.
const PINHOLE_MODELS: [&str; 3] = ["PINHOLE", "SIMPLE_PINHOLE", "OPENCV"];

/// The distortion coefficients a `transforms.json` may give (OpenCV's).
const DISTORTION: [&str; 6] = ["k1", "k2", "k3", "k4", "p1", "p2"];

/// Errors unless camera `path`'s lens (its own fields, else the top's) is a
/// pinhole: a camera is rendered as one, so a fisheye or a distorted lens
/// would put every ray of its photographs in the wrong place, unnoticed.
fn pinhole(camera: &Fields, top: &Fields, path: &str) -> Result<()> {
    let undistort = "dualphoton models pinhole cameras: undistort the images first (e.g. COLMAP's \
                     image_undistorter) and give their pinhole intrinsics";
    if let Some(model) = inherited::<String>(camera, top, "camera_model")? {
        if !PINHOLE_MODELS.contains(&model.as_str()) {
            bail!("{path}: camera_model {model}: {undistort}");
        }
    }
    for key in DISTORTION {
        match inherited::<f64>(camera, top, key)? {
            Some(k) if k != 0.0 => bail!("{path}: lens distortion {key} = {k}: {undistort}"),
            _ => {}
        }
    }
    Ok(())
}

/// A square-pixel lens with horizontal field of view `angle` (radians) over
/// `width`, principal point at the image centre.
fn lens_from_angle(angle: f64, width: usize, height: usize, field: &str) -> Result<Lens> {
    if width == 0 || height == 0 {
        bail!("{field}: the image size {width}x{height} is empty");
    }
    let f = focal_from_angle(angle, width, field)?;
    Ok(Lens::Pinhole { fx: f, fy: f, cx: 0.5 * width as f64, cy: 0.5 * height as f64 })
}

/// The focal length in pixels of a field of view `angle` (radians) over `pixels`.
fn focal_from_angle(angle: f64, pixels: usize, field: &str) -> Result<f64> {
    if !(angle > 0.0 && angle < std::f64::consts::PI) {
        bail!("{field}: {angle} must be a field of view in (0, pi) radians");
    }
    Ok(0.5 * pixels as f64 / (0.5 * angle).tan())
}

/// The lens of camera `path` of a `transforms.json`, read as nerfstudio
/// reads it: the camera's own focal length if it gives `fl_x` or
/// `camera_angle_x`, else the top's (a camera's own field of view is never
/// overridden by a shared focal length); `fl_x` before `camera_angle_x`;
/// `fl_y` (or `camera_angle_y` over the height) from the same place, else
/// square pixels; `cx` and `cy` (the camera's, else the top's), else the
/// image centre. Errors: a focal length that is not positive, a principal
/// point that is not finite.
fn transforms_lens(camera: &Fields, top: &Fields, path: &str, width: usize, height: usize) -> Result<Lens> {
    let own = camera.get("fl_x").is_some() || camera.get("camera_angle_x").is_some();
    let level = if own { camera } else { top };
    let focal = |key: &str, angle_key: &str, pixels: usize| -> Result<Option<f64>> {
        match (level.optional::<f64>(key)?, level.optional::<f64>(angle_key)?) {
            (Some(f), _) => Ok(Some(f)),
            (None, Some(angle)) => focal_from_angle(angle, pixels, &level.name(angle_key)).map(Some),
            (None, None) => Ok(None),
        }
    };
    let Some(fx) = focal("fl_x", "camera_angle_x", width)? else {
        bail!("{path}: no intrinsics: give camera_angle_x or fl_x (here or at the top)")
    };
    let fy = focal("fl_y", "camera_angle_y", height)?.unwrap_or(fx);
    let cx = inherited(camera, top, "cx")?.unwrap_or(0.5 * width as f64);
    let cy = inherited(camera, top, "cy")?.unwrap_or(0.5 * height as f64);
    for (key, value, focal_length) in [("fl_x", fx, true), ("fl_y", fy, true), ("cx", cx, false), ("cy", cy, false)] {
        let place = if focal_length { level.name(key) } else { format!("{path}.{key}") };
        crate::scene::validate::pixels(value, focal_length, &place)?;
    }
    Ok(Lens::Pinhole { fx, fy, cx, cy })
}

/// A camera's own value of `key`, else the one at the top (per-camera
/// intrinsics override the shared ones).
fn inherited<T: serde::de::DeserializeOwned>(camera: &Fields, top: &Fields, key: &str) -> Result<Option<T>> {
    Ok(camera.optional(key)?.or(top.optional(key)?))
}

/// The camera posed by the `transform_matrix` of `fields`.
fn posed(fields: &Fields, lens: Lens, width: usize, height: usize) -> Result<Camera> {
    let matrix: Vec<[f64; 4]> = fields.required("transform_matrix")?;
    camera_from_matrix(&matrix, lens, width, height, &fields.name("transform_matrix"))
}

/// The camera whose camera-to-world matrix (OpenGL convention) is `m`.
fn camera_from_matrix(m: &[[f64; 4]], lens: Lens, width: usize, height: usize, field: &str) -> Result<Camera> {
    let rows = match m.len() {
        3 | 4 => m,
        n => bail!("{field}: {n} rows; a 4x4 (or 3x4) camera-to-world matrix has 4 (or 3)"),
    };
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        bail!("{field}: holds a value that is not a finite number");
    }
    if rows.len() == 4 && rows[3] != [0.0, 0.0, 0.0, 1.0] {
        bail!("{field}: the last row is {:?}, not [0, 0, 0, 1]", rows[3]);
    }
    let column = |c: usize| Vec3::new(rows[0][c], rows[1][c], rows[2][c]);
    let (right, up, back, position) = (column(0), column(1), column(2), column(3));
    let orthonormal = [right, up, back].iter().all(|c| (c.norm() - 1.0).abs() < ROTATION_TOLERANCE)
        && right.dot(&up).abs() < ROTATION_TOLERANCE
        && right.dot(&back).abs() < ROTATION_TOLERANCE
        && up.dot(&back).abs() < ROTATION_TOLERANCE;
    if !orthonormal || right.cross(&up).dot(&back) < 0.0 {
        bail!("{field}: the first three columns are not a rotation (orthonormal, right-handed)");
    }
    Ok(Camera { position, look_at: position - back, up, lens, width, height })
}

/// The world box of a PINF `voxel_matrix` and `voxel_scale` (one number or three).
fn smoke_box(matrix: &[[f64; 4]], scale: &Value) -> Result<(Vec3, Vec3)> {
    let s: [f64; 3] = match scale {
        Value::Number(n) => [n.as_f64().unwrap_or(f64::NAN); 3],
        _ => serde_json::from_value(scale.clone()).map_err(|e| Error(format!("voxel_scale: {e}")))?,
    };
    if s.iter().any(|x| !(x.is_finite() && *x > 0.0)) || matrix.len() < 3 {
        bail!("voxel_scale: {s:?} must be positive sizes, voxel_matrix a 4x4 matrix");
    }
    // PINF and HyFluid exchange the first and third columns before use.
    let axis = |c: usize| Vec3::new(matrix[0][c], matrix[1][c], matrix[2][c]);
    let (ax, ay, az, origin) = (axis(2) * s[0], axis(1) * s[1], axis(0) * s[2], axis(3));
    if [ax, ay, az].iter().any(|a| !(a.norm() > 0.0 && a.norm().is_finite())) {
        bail!("voxel_matrix: a column of its first three is zero: the smoke box would be flat; give --box");
    }
    let mut lo = Vec3::from_element(f64::INFINITY);
    let mut hi = Vec3::from_element(f64::NEG_INFINITY);
    for corner in 0..8 {
        let bit = |b: usize| ((corner >> b) & 1) as f64;
        let p = origin + ax * bit(0) + ay * bit(1) + az * bit(2);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    // The grid is axis-aligned: a box turned against the world axes would
    // span more than its own volume (its edges' lengths, which a matrix
    // that also scales makes other than `s`).
    let volume = |v: Vec3| v.x * v.y * v.z;
    let (spanned, given) = (volume(hi - lo), 1.01 * ax.norm() * ay.norm() * az.norm());
    if spanned.partial_cmp(&given).is_none_or(|o| o.is_gt()) {
        bail!("voxel_matrix: the smoke box is turned against the world axes, the grid is not: remove it, give --box");
    }
    Ok((lo, hi))
}

/// `dir/name`, which must exist.
fn existing(dir: &Path, name: &str, field: &str) -> Result<PathBuf> {
    let path = dir.join(name);
    if !path.exists() {
        bail!("{field}: {} does not exist", show(&path));
    }
    Ok(path)
}

/// `dir/name`, or where that does not exist and `name` has no extension
/// (as the NeRF synthetic scenes' `file_path`s have none), the first of
/// `name.png`, `.jpg`, `.jpeg` and `.npy` that does.
fn existing_image(dir: &Path, name: &str, field: &str) -> Result<PathBuf> {
    let path = dir.join(name);
    if path.exists() || path.extension().is_some() {
        return existing(dir, name, field);
    }
    let found = IMAGE_EXTENSIONS.iter().map(|e| path.with_extension(e)).find(|p| p.is_file());
    found.ok_or_else(|| {
        Error(format!("{field}: {} does not exist, with or without .png, .jpg, .jpeg or .npy", show(&path)))
    })
}

/// A video, an image, or a folder of images (one per frame, in
/// [`frame_order`]).
fn frame_source(path: &Path, field: &str) -> Result<Frames> {
    if path.is_dir() {
        let mut images: Vec<PathBuf> = std::fs::read_dir(path)
            .map_err(|e| Error(format!("{field}: cannot list {}: {e}", show(path))))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| super::frames::is_image(p))
            .collect();
        images.sort_by(|a, b| frame_order(a).cmp(&frame_order(b)).then_with(|| a.cmp(b)));
        if images.is_empty() {
            bail!("{field}: {} holds no PNG, JPEG or .npy images", show(path));
        }
        return Ok(Frames::Images(images));
    }
    if super::frames::is_image(path) {
        return Ok(Frames::Images(vec![path.to_path_buf()]));
    }
    bail!("{field}: {} is neither a folder of images nor an image; for a video, use an info.json", show(path))
}

/// A frame file's place in its folder: its name's runs of digits compared
/// as numbers and the rest as text, so that `frame2.png` comes before
/// `frame10.png`, as `ffmpeg -i clip.mp4 frame%d.png` numbers them.
fn frame_order(path: &Path) -> Vec<(String, u128)> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let mut key: Vec<(String, u128)> = Vec::new();
    let mut rest = name.as_str();
    while !rest.is_empty() {
        let text_len = rest.find(|c: char| c.is_ascii_digit()).unwrap_or(rest.len());
        let (text, after) = rest.split_at(text_len);
        let digits_len = after.find(|c: char| !c.is_ascii_digit()).unwrap_or(after.len());
        let (digits, after) = after.split_at(digits_len);
        // Past 38 digits the number saturates; the full path breaks the tie.
        let number = digits.bytes().fold(0u128, |n, d| n.saturating_mul(10).saturating_add(u128::from(d - b'0')));
        key.push((text.to_string(), number));
        rest = after;
    }
    key
}

/// The size of the first image of `frames`, read from its header.
fn first_image_size(frames: &Frames) -> Result<(usize, usize)> {
    match frames {
        Frames::Images(paths) if !paths.is_empty() => super::frames::image_size(&paths[0]),
        _ => bail!("no image to read it from"),
    }
}

/// `capture`, unless its cameras have different numbers of frames: frame
/// `n` of one camera must show the instant frame `n` of every other does,
/// and with a frame missing in one camera's folder every later frame would
/// be paired with another instant's.
fn same_frame_counts(capture: Capture) -> Result<Capture> {
    let counts: Vec<usize> = capture.views.iter().map(|v| v.frames.count()).collect();
    if let Some(k) = counts.iter().position(|&c| c != counts[0]) {
        let (a, b) = (&capture.views[0].name, &capture.views[k].name);
        bail!(
            "camera {a} has {} frames, camera {b} {}: every camera needs an image of every frame, in the same order",
            counts[0],
            counts[k]
        );
    }
    Ok(capture)
}

/// The views of the cameras `found` (the path of its frames, the camera,
/// its frames, whether it is held out), each named by [`camera_names`].
fn named(found: Vec<(String, Camera, Frames, bool)>) -> Result<Vec<View>> {
    let names = camera_names(&found.iter().map(|(path, ..)| path.as_str()).collect::<Vec<_>>())?;
    let views = found.into_iter().zip(names);
    Ok(views.map(|((_, camera, frames, held_out), name)| View { name, camera, frames, held_out }).collect())
}

/// The cameras' names from the paths of their frames as the calibration
/// gives them: the file or folder name without its extension (`train02`),
/// or, where two cameras would share one (`cam0/000060.png`,
/// `cam1/000060.png`), the path without its extension, so that
/// `experiment_real --held-out` and `--drop` name one camera each. Names
/// that still repeat are an error.
fn camera_names(paths: &[&str]) -> Result<Vec<String>> {
    let stem = |p: &str| Path::new(p).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let bare = |p: &str| Path::new(p).with_extension("").to_string_lossy().trim_end_matches('/').to_string();
    let stems: Vec<String> = paths.iter().map(|p| stem(p)).collect();
    let names = if first_repeat(&stems).is_none() { stems } else { paths.iter().map(|p| bare(p)).collect() };
    if let Some((j, i)) = first_repeat(&names) {
        bail!("cameras {j} and {i} (in file order) would both be named {}: give each its own frames", names[i]);
    }
    Ok(names)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_in_a_folder_go_by_the_numbers_in_their_names() {
        let mut names: Vec<PathBuf> = ["f10.png", "f9.png", "f1.png", "f100.png", "f2.png", "f02.png", "g0.png"]
            .iter()
            .map(PathBuf::from)
            .collect();
        names.sort_by(|a, b| frame_order(a).cmp(&frame_order(b)).then_with(|| a.cmp(b)));
        let order: Vec<&str> = names.iter().map(|p| p.to_str().unwrap()).collect();
        assert_eq!(order, ["f1.png", "f02.png", "f2.png", "f9.png", "f10.png", "f100.png", "g0.png"]);
        let zero_padded = ["cam/000009.png", "cam/000010.png"].map(PathBuf::from);
        assert!(frame_order(&zero_padded[0]) < frame_order(&zero_padded[1]));
    }

    #[test]
    fn an_opengl_matrix_looks_down_its_minus_z() {
        let lens = Lens::Pinhole { fx: 100.0, fy: 100.0, cx: 50.0, cy: 40.0 };
        // Camera at (0, 0, 3) looking at the origin: the identity rotation.
        let m = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 3.0], [0.0, 0.0, 0.0, 1.0]];
        let c = camera_from_matrix(&m, lens, 100, 80, "m").unwrap();
        let (x, y) = c.project(&Vec3::zeros()).unwrap();
        assert!((x - 50.0).abs() < 1e-12 && (y - 40.0).abs() < 1e-12);
        // A point up and to the right lands up (smaller y) and to the right.
        let (x, y) = c.project(&Vec3::new(0.3, 0.3, 0.0)).unwrap();
        assert!((x - 60.0).abs() < 1e-9 && (y - 30.0).abs() < 1e-9);
        let mut mirrored = m;
        mirrored[0][0] = -1.0;
        assert!(camera_from_matrix(&mirrored, lens, 100, 80, "m").unwrap_err().0.contains("right-handed"));
        let mut sheared = m;
        sheared[0][1] = 0.2;
        assert!(camera_from_matrix(&sheared, lens, 100, 80, "m").is_err());
    }

    #[test]
    fn the_pinf_box_is_turned_by_the_matrix() {
        // ScalarFlow's: a quarter turn about y and an offset.
        let m = [[0.0, 0.0, 1.0, 0.1], [0.0, 1.0, 0.0, -0.05], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        let (lo, hi) = smoke_box(&m, &serde_json::json!([0.4, 0.7, 0.5])).unwrap();
        // Exchanged columns: x gets 0.4 along +x, y 0.7, z 0.5 along -z.
        assert!((lo - Vec3::new(0.1, -0.05, -0.5)).norm() < 1e-12, "{lo:?}");
        assert!((hi - Vec3::new(0.5, 0.65, 0.0)).norm() < 1e-12, "{hi:?}");
        let c = std::f64::consts::FRAC_1_SQRT_2;
        let turned = [[c, 0.0, c, 0.0], [0.0, 1.0, 0.0, 0.0], [-c, 0.0, c, 0.0], [0.0, 0.0, 0.0, 1.0]];
        assert!(smoke_box(&turned, &serde_json::json!(0.5)).unwrap_err().0.contains("turned"));
        // A matrix that scales as well as places: axis-aligned, the box its columns span.
        let scaled = [[2.0, 0.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 2.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        let (lo, hi) = smoke_box(&scaled, &serde_json::json!(0.5)).unwrap();
        assert_eq!((lo, hi), (Vec3::zeros(), Vec3::from_element(1.0)));
        let flat = [[0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        assert!(smoke_box(&flat, &serde_json::json!(0.5)).unwrap_err().0.contains("flat"));
    }

    #[test]
    fn cameras_at_nearly_one_place_looking_one_way_are_warned_of() {
        let lens = Lens::Pinhole { fx: 100.0, fy: 100.0, cx: 50.0, cy: 40.0 };
        let view = |name: &str, x: f64, look_x: f64| View {
            name: name.into(),
            camera: Camera {
                position: Vec3::new(x, 0.0, 2.0),
                look_at: Vec3::new(look_x, 0.0, 0.0),
                up: Vec3::y(),
                lens,
                width: 100,
                height: 80,
            },
            frames: Frames::Images(Vec::new()),
            held_out: false,
        };
        // A rig 2 wide: a camera moved by 0.5 % of it, still looking at the origin, reads as one camera listed twice.
        let rig = [view("a", -1.0, 0.0), view("b", 1.0, 0.0), view("a1", -0.99, 0.0)];
        let warning = nearly_one_camera(&rig).unwrap();
        assert!(
            warning.contains("the cameras a and a1 stand 0.50 % of the rig's width apart and look 0.23 degrees"),
            "{warning}"
        );
        assert!(!warning.contains("other pairs") && warning.contains("the same transform_matrix"), "{warning}");
        let twice = [view("a", -1.0, 0.0), view("b", 1.0, 0.0), view("a1", -0.99, 0.0), view("b1", 0.99, 0.0)];
        assert!(nearly_one_camera(&twice).unwrap().contains("apart, as does one other pair: they are read"));
        // Moved by 2 % of the rig, or turned by 2 degrees: two cameras.
        assert!(nearly_one_camera(&[view("a", -1.0, 0.0), view("b", 1.0, 0.0), view("c", -0.96, 0.0)]).is_none());
        let turned = 2.0 * 2.0_f64.to_radians().tan();
        assert!(nearly_one_camera(&[view("a", -1.0, 0.0), view("b", 1.0, 0.0), view("c", -1.0, turned)]).is_none());
        assert!(nearly_one_camera(&[view("a", 0.0, 0.0), view("b", 0.0, 1.0)]).is_none());
    }

    #[test]
    fn a_horizontal_angle_spans_the_width() {
        let Lens::Pinhole { fx, fy, cx, cy } = lens_from_angle(0.5, 1080, 1920, "a").unwrap() else { panic!() };
        assert!((2.0 * (0.5 * 1080.0 / fx).atan() - 0.5).abs() < 1e-12);
        assert_eq!((fx, cx, cy), (fy, 540.0, 960.0));
        assert!(lens_from_angle(3.2, 10, 10, "a").is_err() && lens_from_angle(0.0, 10, 10, "a").is_err());
    }
}
