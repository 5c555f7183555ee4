//! Validation of a scene, whether read from a file or built in code: the
//! first bad field makes a one-line error that names it (`volume.g`,
//! `lights[0].intensity`, `cameras[1].up`, `render.photons`).

use super::{Camera, RenderSettings, Scene};
use crate::bail;
use crate::error::Result;
use crate::math::{intersect_box, Vec3};
use crate::volume::Grid;

fn vec3(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

/// `v` as a vector, or an error naming `field` if a coordinate is NaN or infinite.
pub(super) fn finite3(v: [f64; 3], field: &str) -> Result<Vec3> {
    if v.iter().any(|x| !x.is_finite()) {
        bail!("{field}: {v:?} is not finite");
    }
    Ok(vec3(v))
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
    if (0..3).any(|a| d.hi[a] <= d.lo[a]) {
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
    if m.g.is_nan() || m.g.abs() >= 1.0 {
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
    check_photons(r.photons, m.max_order, "render.photons")?;
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
    if let Some(s) = r.photon_step {
        if !(s.is_finite() && s > 0.0) {
            bail!("render.photon_step: {s} must be finite and > 0");
        }
    }
    if r.shadow_cell == Some(0) {
        bail!("render.shadow_cell: must be at least 1 (voxels per light-depth node)");
    }
    if r.spp == 0 {
        bail!("render.spp: must be at least 1");
    }
    if r.path_spp == 0 {
        bail!("render.path_spp: must be at least 1");
    }
    Ok(())
}

/// Checks that `photons` emitted photons fit in memory at `max_order`
/// ([`RenderSettings::max_photons`]); `field` names the setting in the error.
pub fn check_photons(photons: u64, max_order: u32, field: &str) -> Result<()> {
    let most = RenderSettings::max_photons(max_order);
    if photons > most {
        bail!(
            "{field}: {photons} is more than the {most} a render can hold: the photon map keeps every stored \
             photon in memory (at least 72 bytes each, up to max_order - 1 = {} stored per emitted photon, 2^30 stored at most)",
            max_order.max(2) - 1
        );
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Light, Medium};

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

    #[test]
    fn photon_counts_that_cannot_fit_in_memory_are_rejected() {
        let mut s = scene();
        s.render.photons = RenderSettings::max_photons(3);
        assert_eq!(RenderSettings::max_photons(3), 1 << 29);
        assert_eq!(validate(&s), Ok(()));
        s.render.photons += 1;
        rejected(&s, "render.photons");
        s.render.photons = 1_000_000_000_000_000;
        rejected(&s, "render.photons");
        s.medium.max_order = 1;
        assert_eq!(RenderSettings::max_photons(1), 1 << 30);
        rejected(&s, "render.photons");
    }
}
