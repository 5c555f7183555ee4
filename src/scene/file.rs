//! The scene file: reading (then [`validate`]; every error is one line that
//! names the field: `volume.g`, `lights[0].intensity`), and writing.
//!
//! A scene is a JSON object with sections `volume` (`bbox_min`, `bbox_max`,
//! `density`: a `.npy` path relative to the scene file holding a float32 or
//! float64 array of shape (Z, Y, X), `sigma_t_scale`, `albedo`, `g`,
//! `max_order`, optional `emission`), `lights` (`position`, `intensity`), `cameras` (`position`,
//! `look_at`, optional `up`, `width`, `height`, and either `fov_y_deg` or
//! the intrinsics `fx`, `fy`, `cx`, `cy` in pixels) and an optional
//! `render` (`photons`, `kernel_radius`, `step`, `seed`, `spp`, `path_spp`,
//! `shadows`: `"auto"`, `"grid"` or `"marched"`, `shadow_cell`, `photon_step`).
//! Every field is required unless said otherwise, unknown fields are
//! errors, and numbers must be finite: JSON cannot spell NaN or infinity,
//! and `null` or a bare `NaN` in their place is reported as such.

use super::fields::{parse_json, Fields};
use super::validate::finite3;
pub use super::validate::{check_photons, validate};
use super::{Camera, Lens, Light, Medium, RenderSettings, Scene, Shadows};
use crate::bail;
use crate::error::{Error, Result};
use crate::io::npy;
use crate::math::Vec3;
use crate::volume::Grid;
use serde::Serialize;
use serde_json::Value;
use std::path::Path;

// The file's sections as written; `load` reads them field by field
// ([`Fields`]) so that every error names the field's path.

#[derive(Serialize)]
struct VolumeFile {
    bbox_min: [f64; 3],
    bbox_max: [f64; 3],
    density: String,
    sigma_t_scale: f64,
    albedo: f64,
    g: f64,
    max_order: u32,
    #[serde(skip_serializing_if = "is_zero")]
    emission: f64,
}

/// An emission of 0 is not written: scenes without one read as before.
fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

#[derive(Serialize)]
struct LightFile {
    position: [f64; 3],
    intensity: f64,
}

#[derive(Serialize)]
struct CameraFile {
    position: [f64; 3],
    look_at: [f64; 3],
    up: [f64; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    fov_y_deg: Option<f64>,
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    intrinsics: Option<IntrinsicsFile>,
    width: usize,
    height: usize,
}

#[derive(Serialize)]
struct IntrinsicsFile {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

#[derive(Serialize, Default)]
struct RenderFile {
    #[serde(skip_serializing_if = "Option::is_none")]
    photons: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    kernel_radius: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    step: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    seed: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    spp: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    path_spp: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    shadows: Option<Shadows>,
    #[serde(skip_serializing_if = "Option::is_none")]
    shadow_cell: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    photon_step: Option<f64>,
}

#[derive(Serialize)]
struct SceneFile {
    volume: VolumeFile,
    lights: Vec<LightFile>,
    cameras: Vec<CameraFile>,
    render: RenderFile,
}

/// The scene file's sections from its JSON; errors name the field.
fn scene_file(root: &Value) -> Result<SceneFile> {
    let top = Fields::new(root, "", &["volume", "lights", "cameras", "render"])?;
    let known = ["bbox_min", "bbox_max", "density", "sigma_t_scale", "albedo", "g", "max_order", "emission"];
    let v = Fields::new(top.value("volume")?, "volume", &known)?;
    let volume = VolumeFile {
        bbox_min: v.required("bbox_min")?,
        bbox_max: v.required("bbox_max")?,
        density: v.required("density")?,
        sigma_t_scale: v.required("sigma_t_scale")?,
        albedo: v.required("albedo")?,
        g: v.required("g")?,
        max_order: v.required("max_order")?,
        emission: v.optional("emission")?.unwrap_or(0.0),
    };
    let lights = top
        .list("lights")?
        .into_iter()
        .map(|(path, item)| {
            let l = Fields::new(item, &path, &["position", "intensity"])?;
            Ok(LightFile { position: l.required("position")?, intensity: l.required("intensity")? })
        })
        .collect::<Result<_>>()?;
    let known = ["position", "look_at", "up", "fov_y_deg", "fx", "fy", "cx", "cy", "width", "height"];
    let cameras = top
        .list("cameras")?
        .into_iter()
        .map(|(path, item)| {
            let c = Fields::new(item, &path, &known)?;
            let intrinsics = match (c.get("fov_y_deg"), ["fx", "fy", "cx", "cy"].iter().any(|k| c.get(k).is_some())) {
                (Some(_), true) => bail!("{path}: give either fov_y_deg or fx, fy, cx, cy, not both"),
                (_, false) => None,
                (None, true) => Some(IntrinsicsFile {
                    fx: c.required("fx")?,
                    fy: c.required("fy")?,
                    cx: c.required("cx")?,
                    cy: c.required("cy")?,
                }),
            };
            Ok(CameraFile {
                position: c.required("position")?,
                look_at: c.required("look_at")?,
                up: c.optional("up")?.unwrap_or([0.0, 1.0, 0.0]),
                fov_y_deg: if intrinsics.is_some() { None } else { Some(c.required("fov_y_deg")?) },
                intrinsics,
                width: c.required("width")?,
                height: c.required("height")?,
            })
        })
        .collect::<Result<_>>()?;
    let render = match top.get("render") {
        None => RenderFile::default(),
        Some(r) => {
            let known = [
                "photons",
                "kernel_radius",
                "step",
                "seed",
                "spp",
                "path_spp",
                "shadows",
                "shadow_cell",
                "photon_step",
            ];
            let r = Fields::new(r, "render", &known)?;
            RenderFile {
                photons: r.optional_count("photons")?,
                kernel_radius: r.optional("kernel_radius")?,
                step: r.optional("step")?,
                seed: r.optional("seed")?,
                spp: r.optional("spp")?,
                path_spp: r.optional("path_spp")?,
                shadows: r.optional("shadows")?,
                shadow_cell: r.optional("shadow_cell")?,
                photon_step: r.optional("photon_step")?,
            }
        }
    };
    Ok(SceneFile { volume, lights, cameras, render })
}

/// The JSON value of `text`; a bare `NaN` or `Infinity` (not JSON, but what
/// Python's `json` writes) is read as `null`, so the error names its field.
/// Largest scene file read: 64 MiB (a scene of 10,000 cameras is about 2 MB).
pub const MAX_SCENE_BYTES: u64 = 64 << 20;

/// Reads, validates and loads a scene file and its density.
pub fn load(path: &Path) -> Result<Scene> {
    let shown = crate::error::show(path);
    let bytes = npy::read_bounded(path, MAX_SCENE_BYTES).map_err(|e| Error(format!("scene {shown}: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|_| Error(format!("scene {shown}: not UTF-8 text")))?;
    let root = parse_json(&text).map_err(|e| Error(format!("scene {shown}: not valid JSON: {e}")))?;
    let file = scene_file(&root)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let density_path = dir.join(&file.volume.density);
    let array = npy::read_f32_range(&density_path, "volume.density")?;
    let shown = crate::error::show(&density_path);
    if !array.element.is_float() {
        bail!("volume.density: {shown} has dtype {}, need float32 or float64", array.dtype);
    }
    if array.shape.len() != 3 || array.shape.contains(&0) {
        bail!("volume.density: {shown} has shape {:?}, need (Z, Y, X) with every axis > 0", array.shape);
    }
    let shape = [array.shape[0], array.shape[1], array.shape[2]];
    let lo = finite3(file.volume.bbox_min, "volume.bbox_min")?;
    let hi = finite3(file.volume.bbox_max, "volume.bbox_max")?;
    let density = Grid::new(lo, hi, shape, array.data);
    let medium = Medium {
        sigma_t_scale: file.volume.sigma_t_scale,
        albedo: file.volume.albedo,
        g: file.volume.g,
        max_order: file.volume.max_order,
        emission: file.volume.emission,
    };
    let lights = file
        .lights
        .iter()
        .enumerate()
        .map(|(n, l)| {
            Ok(Light { position: finite3(l.position, &format!("lights[{n}].position"))?, intensity: l.intensity })
        })
        .collect::<Result<Vec<_>>>()?;
    let cameras = file
        .cameras
        .iter()
        .enumerate()
        .map(|(n, c)| {
            Ok(Camera {
                position: finite3(c.position, &format!("cameras[{n}].position"))?,
                look_at: finite3(c.look_at, &format!("cameras[{n}].look_at"))?,
                up: finite3(c.up, &format!("cameras[{n}].up"))?,
                lens: match (&c.intrinsics, c.fov_y_deg) {
                    (Some(k), _) => Lens::Pinhole { fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy },
                    (None, Some(deg)) => Lens::FovY(deg),
                    (None, None) => bail!("cameras[{n}].fov_y_deg: missing (or give fx, fy, cx, cy)"),
                },
                width: c.width,
                height: c.height,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let defaults = RenderSettings::default();
    let r = &file.render;
    let render = RenderSettings {
        photons: r.photons.unwrap_or(defaults.photons),
        kernel_radius: r.kernel_radius,
        step: r.step,
        seed: r.seed.unwrap_or(defaults.seed),
        spp: r.spp.unwrap_or(defaults.spp),
        path_spp: r.path_spp.unwrap_or(defaults.path_spp),
        shadows: r.shadows.unwrap_or(defaults.shadows),
        shadow_cell: r.shadow_cell,
        photon_step: r.photon_step,
    };
    let scene = Scene { density, medium, lights, cameras, render };
    validate(&scene)?;
    Ok(scene)
}
/// Writes `scene` as `dir/name.json` with its density as `dir/density.npy` (float32).
pub fn save(scene: &Scene, dir: &Path, name: &str) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error(format!("cannot create {}: {e}", dir.display())))?;
    let d = &scene.density;
    npy::write_f32(&dir.join("density.npy"), &d.shape, &d.data)?;
    let arr = |v: &Vec3| [v.x, v.y, v.z];
    let r = &scene.render;
    let file = SceneFile {
        volume: VolumeFile {
            bbox_min: arr(&d.lo),
            bbox_max: arr(&d.hi),
            density: "density.npy".into(),
            sigma_t_scale: scene.medium.sigma_t_scale,
            albedo: scene.medium.albedo,
            g: scene.medium.g,
            max_order: scene.medium.max_order,
            emission: scene.medium.emission,
        },
        lights: scene.lights.iter().map(|l| LightFile { position: arr(&l.position), intensity: l.intensity }).collect(),
        cameras: scene
            .cameras
            .iter()
            .map(|c| CameraFile {
                position: arr(&c.position),
                look_at: arr(&c.look_at),
                up: arr(&c.up),
                fov_y_deg: match c.lens {
                    Lens::FovY(deg) => Some(deg),
                    Lens::Pinhole { .. } => None,
                },
                intrinsics: match c.lens {
                    Lens::FovY(_) => None,
                    Lens::Pinhole { fx, fy, cx, cy } => Some(IntrinsicsFile { fx, fy, cx, cy }),
                },
                width: c.width,
                height: c.height,
            })
            .collect(),
        render: RenderFile {
            photons: Some(r.photons),
            kernel_radius: r.kernel_radius,
            step: r.step,
            seed: Some(r.seed),
            spp: Some(r.spp),
            path_spp: Some(r.path_spp),
            shadows: Some(r.shadows),
            shadow_cell: r.shadow_cell,
            photon_step: r.photon_step,
        },
    };
    let text = serde_json::to_string_pretty(&file).map_err(|e| Error(e.to_string()))?;
    std::fs::write(dir.join(format!("{name}.json")), text + "\n").map_err(|e| Error(format!("cannot write scene: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scenes::homogeneous;
    use crate::scene::rig::paper_scene;

    #[test]
    fn both_lenses_survive_a_save_and_load() {
        let mut scene = paper_scene(homogeneous(4, 0.1), 8);
        scene.cameras[1] = scene.cameras[1].crop(1, 2, 6, 5);
        assert!(matches!(scene.cameras[0].lens, Lens::FovY(_)));
        assert!(matches!(scene.cameras[1].lens, Lens::Pinhole { .. }));
        let dir = std::env::temp_dir().join(format!("dualphoton_lens_{}", std::process::id()));
        save(&scene, &dir, "scene").unwrap();
        let loaded = load(&dir.join("scene.json")).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert_eq!(loaded.cameras, scene.cameras);
    }
}
