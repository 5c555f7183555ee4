//! Validation of a scene, whether read from a file or built in code: the
//! first bad field makes a one-line error that names it (`volume.g`,
//! `lights[0].intensity`, `cameras[1].up`, `render.photons`).

use super::{Camera, Lens, RenderSettings, Scene};
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
    let depth = m.sigma_t_scale * d.max_value() * (d.hi - d.lo).norm();
    if depth.is_nan() || depth > MAX_OPTICAL_DEPTH {
        bail!(
            "volume.sigma_t_scale: {} times the densest voxel ({}) across the box's diagonal is an optical depth of \
             {depth:e}, more than the {MAX_OPTICAL_DEPTH:e} the renderers accept (the path tracer's work grows with it)",
            m.sigma_t_scale,
            d.max_value()
        );
    }
    if !(0.0..=1.0).contains(&m.albedo) {
        bail!("volume.albedo: {} must be in [0, 1]", m.albedo);
    }
    if m.g.is_nan() || m.g.abs() >= 1.0 {
        bail!("volume.g: {} must be in (-1, 1)", m.g);
    }
    if !(m.emission.is_finite() && (0.0..=MAX_INTENSITY).contains(&m.emission)) {
        bail!("volume.emission: {} must be in [0, {MAX_INTENSITY:e}]", m.emission);
    }
    if m.max_order == 0 || m.max_order > 64 {
        bail!("volume.max_order: {} must be in 1..=64", m.max_order);
    }
    for (n, l) in scene.lights.iter().enumerate() {
        near_the_box(
            finite3(l.position.into(), &format!("lights[{n}].position"))?,
            d,
            &format!("lights[{n}].position"),
        )?;
        if !(l.intensity.is_finite() && (0.0..=MAX_INTENSITY).contains(&l.intensity)) {
            bail!("lights[{n}].intensity: {} must be in [0, {MAX_INTENSITY:e}]", l.intensity);
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
    let finest = d.voxel_size().min() / MAX_STEPS_PER_VOXEL;
    for (s, field) in [(r.step, "render.step"), (r.photon_step, "render.photon_step")] {
        if let Some(s) = s {
            if !(s.is_finite() && s >= finest) {
                bail!(
                    "{field}: {s} must be finite and at least the smallest voxel size / {MAX_STEPS_PER_VOXEL} = \
                     {finest:e} (smaller steps add work, not accuracy)"
                );
            }
        }
    }
    if r.shadow_cell == Some(0) {
        bail!("render.shadow_cell: must be at least 1 (voxels per light-depth node)");
    }
    if !(1..=MAX_SPP).contains(&r.spp) {
        bail!("render.spp: {} must be in 1..={MAX_SPP}", r.spp);
    }
    if !(2..=MAX_SPP).contains(&r.path_spp) {
        bail!(
            "render.path_spp: {} must be in 2..={MAX_SPP} (the standard-error images need at least 2 samples)",
            r.path_spp
        );
    }
    check_memory(scene)
}

/// Largest optical depth a scene may have: `sigma_t_scale` times the
/// densest voxel times the box's diagonal. The path tracer's free flights
/// and shadow rays take work in proportion to the optical depth they
/// cross, so a scene of optical depth 1e9 would stall it; 1e6 is a hundred
/// times the thickest scene the stability study renders (1e4 across the box).
pub const MAX_OPTICAL_DEPTH: f64 = 1e6;

/// Largest light intensity (W/sr): far beyond any physical scene, and
/// small enough that radiance, its square (variances) and its sums over
/// pixels stay finite in float32 outputs.
pub const MAX_INTENSITY: f64 = 1e30;

/// Most ray-marching steps per voxel (`render.step`, `render.photon_step`
/// at least the smallest voxel size over this): 32 times the default's 2.
pub const MAX_STEPS_PER_VOXEL: f64 = 64.0;

/// Most samples per pixel (`render.spp`, `render.path_spp`). A pixel keeps
/// a permutation of its `spp` samples (8 bytes each, per thread) and its
/// work grows with them; 65,536 is 16,000 times the default's 4.
pub const MAX_SPP: u32 = 1 << 16;

/// Farthest a light, a camera or the point it looks at may be from the
/// box's centre, in box diagonals: beyond this, differences of
/// coordinates lose the box's scale (a camera at 1e300 has no direction).
pub const MAX_DISTANCE_IN_DIAGONALS: f64 = 1e6;

/// Largest memory a render may need beyond its photon map (which
/// [`check_photons`] bounds): 16 GiB. See [`render_memory`].
pub const MAX_RENDER_BYTES: u64 = 16 << 30;

/// An estimate (upper bound) of the bytes a photon-mapping or path-traced
/// render of `scene` holds besides its photon map: the images (radiance and
/// standard error, 16 bytes a pixel), each camera's photon estimate (8
/// bytes per grid node, every node counted, when the scene has photons and
/// orders above 1), the light-depth grids (8 bytes per node per light) and
/// each thread's sample permutation (8 bytes per sample per pixel).
pub fn render_memory(scene: &Scene) -> u64 {
    let cells = scene.density.data.len() as u64;
    let pixels: u64 = scene.cameras.iter().map(|c| c.pixels() as u64).sum();
    let m = &scene.medium;
    let multiple = scene.render.photons > 0 && m.max_order > 1 && m.albedo > 0.0;
    let estimates = if multiple { scene.cameras.len() as u64 * cells * 8 } else { 0 };
    let depths = scene.lights.len() as u64 * cells * 8;
    let threads = rayon::current_num_threads() as u64;
    let per_pixel = u64::from(scene.render.spp.max(scene.render.path_spp)) * 8 * threads;
    pixels.saturating_mul(16).saturating_add(estimates).saturating_add(depths).saturating_add(per_pixel)
}

/// Checks [`render_memory`] against [`MAX_RENDER_BYTES`]; the error names
/// the cameras (or the samples per pixel) and the estimate.
fn check_memory(scene: &Scene) -> Result<()> {
    let bytes = render_memory(scene);
    if bytes > MAX_RENDER_BYTES {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        bail!(
            "cameras: {} cameras of {} pixels in all and {} lights on a grid of {} voxels need about {:.1} GiB \
             (images, one photon estimate per camera, one light-depth grid per light), more than the {:.0} GiB a \
             render may use: use fewer cameras or lights, a coarser grid or fewer pixels",
            scene.cameras.len(),
            scene.cameras.iter().map(|c| c.pixels() as u64).sum::<u64>(),
            scene.lights.len(),
            scene.density.data.len(),
            gib(bytes),
            gib(MAX_RENDER_BYTES)
        );
    }
    Ok(())
}

/// `p` unless it is farther than [`MAX_DISTANCE_IN_DIAGONALS`] box
/// diagonals from the centre of `density`'s box; `field` names it.
fn near_the_box(p: Vec3, density: &Grid<f64>, field: &str) -> Result<Vec3> {
    let diagonal = (density.hi - density.lo).norm();
    let most = MAX_DISTANCE_IN_DIAGONALS * diagonal;
    let centre = (density.hi + density.lo) * 0.5;
    let distance = (p - centre).norm();
    if distance.is_nan() || distance > most {
        bail!(
            "{field}: {:?} is {distance:e} from the volume's centre, more than {MAX_DISTANCE_IN_DIAGONALS:e} box \
             diagonals ({most:e})",
            p.as_slice()
        );
    }
    Ok(p)
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

/// `Err` naming `field` unless `v` is a number of pixels a pinhole lens
/// takes: finite and at most 1e9 in size, and positive for a focal length
/// (`positive`; a principal point may lie outside the image).
pub(crate) fn pixels(v: f64, positive: bool, field: &str) -> Result<()> {
    if !v.is_finite() || (positive && v <= 0.0) || v.abs() > 1e9 {
        let want = if positive { "a positive number of pixels" } else { "a finite number of pixels" };
        bail!("{field}: {v} must be {want} (at most 1e9)");
    }
    Ok(())
}

fn validate_camera(c: &Camera, density: &Grid<f64>, n: usize) -> Result<()> {
    let position = finite3(c.position.into(), &format!("cameras[{n}].position"))?;
    near_the_box(position, density, &format!("cameras[{n}].position"))?;
    let look_at = finite3(c.look_at.into(), &format!("cameras[{n}].look_at"))?;
    near_the_box(look_at, density, &format!("cameras[{n}].look_at"))?;
    finite3(c.up.into(), &format!("cameras[{n}].up"))?;
    if c.width == 0 || c.height == 0 {
        bail!("cameras[{n}]: image size {}x{} is empty", c.width, c.height);
    }
    if c.width.saturating_mul(c.height) > 1 << 26 {
        bail!("cameras[{n}]: image size {}x{} is too large", c.width, c.height);
    }
    match c.lens {
        Lens::FovY(deg) if !(deg > 0.0 && deg < 180.0) => bail!("cameras[{n}].fov_y_deg: {deg} must be in (0, 180)"),
        Lens::Pinhole { fx, fy, cx, cy } => {
            for (name, v, positive) in [("fx", fx, true), ("fy", fy, true), ("cx", cx, false), ("cy", cy, false)] {
                pixels(v, positive, &format!("cameras[{n}].{name}"))?;
            }
        }
        Lens::FovY(_) => {}
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
            lens: Lens::FovY(30.0),
            width: 8,
            height: 8,
        };
        Scene {
            density,
            medium: Medium { sigma_t_scale: 20.0, albedo: 0.9, g: 0.6, max_order: 3, emission: 0.0 },
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
