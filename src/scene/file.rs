//! The scene file (JSON, docs/DESIGN.md §1): parsing, validation with errors that
//! name the field, and writing.

use super::{Camera, Light, Medium, RenderSettings, Scene};
use crate::bail;
use crate::error::{Error, Result};
use crate::io::npy;
use crate::math::{intersect_box, Vec3};
use crate::volume::Grid;
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct VolumeFile {
    bbox_min: [f64; 3],
    bbox_max: [f64; 3],
    density: String,
    sigma_t_scale: f64,
    albedo: f64,
    g: f64,
    max_order: u32,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightFile {
    position: [f64; 3],
    intensity: f64,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    position: [f64; 3],
    look_at: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
    fov_y_deg: f64,
    width: usize,
    height: usize,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
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
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    volume: VolumeFile,
    lights: Vec<LightFile>,
    cameras: Vec<CameraFile>,
    #[serde(default)]
    render: RenderFile,
}

fn vec3(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

fn finite3(v: [f64; 3], field: &str) -> Result<Vec3> {
    if v.iter().any(|x| !x.is_finite()) {
        bail!("{field}: {v:?} is not finite");
    }
    Ok(vec3(v))
}

/// Reads, validates and loads a scene file and its density.
pub fn load(path: &Path) -> Result<Scene> {
    let text =
        std::fs::read_to_string(path).map_err(|e| Error(format!("scene: cannot read {}: {e}", path.display())))?;
    let file: SceneFile = serde_json::from_str(&text).map_err(|e| Error(format!("scene {}: {e}", path.display())))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let density_path = dir.join(&file.volume.density);
    let array = npy::read(&density_path, "volume.density")?;
    if array.dtype != "<f4" && array.dtype != "<f8" {
        bail!("volume.density: {} has dtype {}, need float32 or float64", density_path.display(), array.dtype);
    }
    if array.shape.len() != 3 || array.shape.iter().any(|&n| n == 0) {
        bail!(
            "volume.density: {} has shape {:?}, need (Z, Y, X) with every axis > 0",
            density_path.display(),
            array.shape
        );
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
                fov_y_deg: c.fov_y_deg,
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
    };
    let scene = Scene { density, medium, lights, cameras, render };
    validate(&scene)?;
    Ok(scene)
}

/// Checks every field of a scene; the error names the first bad one.
pub fn validate(scene: &Scene) -> Result<()> {
    let d = &scene.density;
    // `load` checks these while parsing; a scene built in code must pass the same checks.
    finite3(d.lo.into(), "volume.bbox_min")?;
    finite3(d.hi.into(), "volume.bbox_max")?;
    if d.shape.contains(&0) {
        bail!("volume.density: shape {:?} (Z, Y, X) is empty; every axis must be > 0", d.shape);
    }
    if (0..3).any(|a| !(d.hi[a] > d.lo[a])) {
        bail!("volume.bbox_max: {:?} must exceed bbox_min {:?} on every axis", d.hi.as_slice(), d.lo.as_slice());
    }
    if let Some(n) = d.data.iter().position(|v| !v.is_finite() || *v < 0.0) {
        let (k, j, i) = (n / (d.shape[1] * d.shape[2]), (n / d.shape[2]) % d.shape[1], n % d.shape[2]);
        bail!(
            "volume.density: value {} at voxel (k, j, i) = ({k}, {j}, {i}); densities must be finite and >= 0",
            d.data[n]
        );
    }
    let m = &scene.medium;
    if !(m.sigma_t_scale.is_finite() && m.sigma_t_scale >= 0.0) {
        bail!("volume.sigma_t_scale: {} must be finite and >= 0", m.sigma_t_scale);
    }
    if !(0.0..=1.0).contains(&m.albedo) {
        bail!("volume.albedo: {} must be in [0, 1]", m.albedo);
    }
    if !(m.g.abs() < 1.0) {
        bail!("volume.g: {} must be in (-1, 1)", m.g);
    }
    if m.max_order == 0 || m.max_order > 64 {
        bail!("volume.max_order: {} must be in 1..=64", m.max_order);
    }
    for (n, l) in scene.lights.iter().enumerate() {
        finite3(l.position.into(), &format!("lights[{n}].position"))?;
        if !(l.intensity.is_finite() && l.intensity >= 0.0) {
            bail!("lights[{n}].intensity: {} must be finite and >= 0", l.intensity);
        }
    }
    if scene.cameras.is_empty() {
        bail!("cameras: the scene has no camera");
    }
    for (n, c) in scene.cameras.iter().enumerate() {
        validate_camera(c, d, n)?;
    }
    let r = &scene.render;
    if let Some(k) = r.kernel_radius {
        if !(k.is_finite() && k > 0.0) {
            bail!("render.kernel_radius: {k} must be finite and > 0");
        }
    }
    if let Some(s) = r.step {
        if !(s.is_finite() && s > 0.0) {
            bail!("render.step: {s} must be finite and > 0");
        }
    }
    if r.spp == 0 {
        bail!("render.spp: must be at least 1");
    }
    if r.path_spp == 0 {
        bail!("render.path_spp: must be at least 1");
    }
    Ok(())
}

fn validate_camera(c: &Camera, density: &Grid<f64>, n: usize) -> Result<()> {
    finite3(c.position.into(), &format!("cameras[{n}].position"))?;
    finite3(c.look_at.into(), &format!("cameras[{n}].look_at"))?;
    finite3(c.up.into(), &format!("cameras[{n}].up"))?;
    if c.width == 0 || c.height == 0 {
        bail!("cameras[{n}]: image size {}x{} is empty", c.width, c.height);
    }
    if c.width.saturating_mul(c.height) > 1 << 26 {
        bail!("cameras[{n}]: image size {}x{} is too large", c.width, c.height);
    }
    if !(c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
        bail!("cameras[{n}].fov_y_deg: {} must be in (0, 180)", c.fov_y_deg);
    }
    let forward = c.look_at - c.position;
    if forward.norm() < 1e-12 {
        bail!("cameras[{n}].look_at: equals the camera position");
    }
    if c.up.norm() < 1e-12 || forward.normalize().cross(&c.up.normalize()).norm() < 1e-9 {
        bail!("cameras[{n}].up: {:?} is zero or parallel to the viewing direction", c.up.as_slice());
    }
    // A 17x17 lattice of rays over the image, plus the pixel centres of a tiny image.
    let steps = 16;
    let hits = (0..=steps).any(|a| {
        (0..=steps).any(|b| {
            let ray = c.ray(a as f64 / steps as f64 * c.width as f64, b as f64 / steps as f64 * c.height as f64);
            intersect_box(&ray, &density.lo, &density.hi).is_some()
        })
    });
    let hits = hits
        || (0..c.height.min(64)).any(|y| {
            (0..c.width.min(64))
                .any(|x| intersect_box(&c.ray(x as f64 + 0.5, y as f64 + 0.5), &density.lo, &density.hi).is_some())
        });
    if !hits {
        bail!("cameras[{n}]: looks at nothing (the volume's box is outside its field of view)");
    }
    Ok(())
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
        },
        lights: scene.lights.iter().map(|l| LightFile { position: arr(&l.position), intensity: l.intensity }).collect(),
        cameras: scene
            .cameras
            .iter()
            .map(|c| CameraFile {
                position: arr(&c.position),
                look_at: arr(&c.look_at),
                up: arr(&c.up),
                fov_y_deg: c.fov_y_deg,
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
        },
    };
    let text = serde_json::to_string_pretty(&file).map_err(|e| Error(e.to_string()))?;
    std::fs::write(dir.join(format!("{name}.json")), text + "\n").map_err(|e| Error(format!("cannot write scene: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A valid scene: a 4^3 box of density 0.1, one light, one camera on +z.
    fn scene() -> Scene {
        let density = Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [4, 4, 4], vec![0.1; 64]);
        let camera = Camera {
            position: Vec3::new(0.0, 0.0, 3.0),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            fov_y_deg: 30.0,
            width: 8,
            height: 8,
        };
        Scene {
            density,
            medium: Medium { sigma_t_scale: 20.0, albedo: 0.9, g: 0.6, max_order: 3 },
            lights: vec![Light { position: Vec3::new(2.0, 0.0, 2.0), intensity: 10.0 }],
            cameras: vec![camera],
            render: RenderSettings::default(),
        }
    }

    fn rejected(scene: &Scene, field: &str) {
        match validate(scene) {
            Ok(()) => panic!("{field}: not rejected"),
            Err(e) => assert!(e.0.starts_with(field), "error does not name {field}: {e}"),
        }
    }

    #[test]
    fn scenes_built_in_code_get_the_checks_load_makes() {
        assert_eq!(validate(&scene()), Ok(()));
        let mut s = scene();
        s.density = Grid::new(s.density.lo, s.density.hi, [0, 4, 4], vec![]);
        rejected(&s, "volume.density");
        let mut s = scene();
        s.density = Grid::new(s.density.lo, Vec3::new(0.5, f64::INFINITY, 0.5), [4, 4, 4], vec![0.1; 64]);
        rejected(&s, "volume.bbox_max");
        let mut s = scene();
        s.lights[0].position.y = f64::NAN;
        rejected(&s, "lights[0].position");
        let mut s = scene();
        s.cameras[0].position.x = f64::NAN;
        rejected(&s, "cameras[0].position");
    }
}
