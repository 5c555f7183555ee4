//! The scene zoo of the stability study: the base blob scene and its
//! one-change variants pushed to an extreme, and invalid scenes that must be
//! rejected with a message naming the bad field.

use super::Settings;
use crate::eval::scenes::{blob_density, unit_grid};
use crate::math::Vec3;
use crate::scene::Scene;
use crate::volume::Grid;

/// One extreme (but valid) scene to check.
pub struct Case {
    /// Name in the report ("optical depth 1e4").
    pub name: String,
    /// The scene.
    pub scene: Scene,
    /// Where derivatives are wanted beyond the occupied voxels (see
    /// [`Frozen::new`](crate::render::frozen::Frozen::new)).
    pub support: Option<Grid<f64>>,
    /// Also check the energy balance ([`crate::eval::energy`]).
    pub energy: bool,
    /// Why the case is set up as it is, for the report.
    pub note: &'static str,
}

/// One invalid scene.
pub struct InvalidCase {
    /// Name in the report ("invalid: g = 1").
    pub name: String,
    /// The field the error message must name ("volume.g").
    pub field: &'static str,
    /// The scene.
    pub scene: Scene,
}

fn case(name: impl Into<String>, scene: Scene) -> Case {
    Case { name: name.into(), scene, support: None, energy: false, note: "" }
}

/// The base scene with one change.
fn with(s: &Settings, f: &dyn Fn(&mut Scene)) -> Scene {
    let mut scene = s.base();
    f(&mut scene);
    scene
}

/// The extreme cases, each a change of [`Settings::base`]: optical depth up
/// to 1e4, zero density, one occupied voxel, albedo 0 and 1, g from -0.99
/// to 0.9999, lights on and inside the volume, tiny and huge kernels, 1^3,
/// 2^3 and non-cubic grids, no photons, intensities 1e12 and 1e-12.
pub fn cases(s: &Settings) -> Vec<Case> {
    let with = |f: &dyn Fn(&mut Scene)| with(s, f);
    let n = s.grid;
    let mut out = vec![case("base blob", s.base())];
    for depth in [1.0, 1e2, 1e4] {
        // Homogeneous: optical depth `depth` across the unit box.
        let scene = with(&|sc| sc.density.data.fill(depth / sc.medium.sigma_t_scale));
        // Energy checks where the sphere of cameras sees anything: thin (no kernel bias in a
        // homogeneous medium) and thick (the kernel's blur into the medium loses light).
        out.push(Case { energy: depth <= 1e2, ..case(format!("optical depth {depth:.0e}"), scene) });
    }
    let zero = with(&|sc| sc.density.data.fill(0.0));
    out.push(Case {
        support: Some(unit_grid([n; 3], |_| 1.0)),
        note: "support = every voxel, so derivatives exist at density 0",
        ..case("zero density", zero)
    });
    out.push(case(
        "single occupied voxel",
        with(&|sc| {
            sc.density.data.fill(0.0);
            let v = sc.density.index(n / 2, n / 2, n / 2);
            sc.density.data[v] = 1.0;
        }),
    ));
    for albedo in [0.0, 1.0] {
        out.push(Case { energy: true, ..case(format!("albedo {albedo}"), with(&|sc| sc.medium.albedo = albedo)) });
    }
    for g in [-0.99, 0.0, 0.99, 0.9999] {
        // Only isotropic scattering gets the energy check: the sphere of cameras cannot integrate a sharp lobe.
        out.push(Case { energy: g == 0.0, ..case(format!("g {g}"), with(&|sc| sc.medium.g = g)) });
    }
    out.push(case("light on the volume surface", with(&|sc| sc.lights[0].position = Vec3::new(0.5, 0.0, 0.0))));
    out.push(case("light inside the volume", with(&|sc| sc.lights[0].position = Vec3::zeros())));
    out.push(case("kernel radius 1e-4", with(&|sc| sc.render.kernel_radius = Some(1e-4))));
    out.push(case("kernel radius 10", with(&|sc| sc.render.kernel_radius = Some(10.0))));
    for shape in [[1, 1, 1], [2, 2, 2], [16, 8, 4]] {
        let name = format!("grid {}x{}x{} (x, y, z)", shape[2], shape[1], shape[0]);
        // The blob is too fine for 1^3 and 2^3: a smooth ramp instead.
        let f = if shape[0] < 4 { |p: Vec3| 0.2 + 0.1 * (p.x + p.y + p.z) } else { blob_density };
        out.push(case(name, with(&|sc| sc.density = unit_grid(shape, f))));
    }
    out.push(case("zero photons", with(&|sc| sc.render.photons = 0)));
    // Cheap extras: a camera in the medium, the deepest paths allowed, a nearly transparent medium.
    out.push(case("camera inside the volume", with(&|sc| sc.cameras[0].position = Vec3::new(0.0, 0.0, 0.3))));
    out.push(case("max_order 64", with(&|sc| sc.medium.max_order = 64)));
    out.push(case("sigma_t_scale 1e-12", with(&|sc| sc.medium.sigma_t_scale = 1e-12)));
    for intensity in [1e12, 1e-12] {
        out.push(case(format!("intensity {intensity:.0e}"), with(&|sc| sc.lights[0].intensity = intensity)));
    }
    out
}

/// Invalid scenes (NaN, Inf or negative density, |g| >= 1, albedo outside
/// [0, 1], bad lights, empty grids and images, a camera looking away, a
/// zero kernel), each a change of [`Settings::base`].
pub fn invalid_cases(s: &Settings) -> Vec<InvalidCase> {
    let with = |f: &dyn Fn(&mut Scene)| with(s, f);
    let invalid = |name: String, field, scene| InvalidCase { name, field, scene };
    let mut out = vec![];
    for (what, v) in [("NaN", f64::NAN), ("Inf", f64::INFINITY), ("negative", -0.5)] {
        out.push(invalid(format!("invalid: {what} density"), "volume.density", with(&|sc| sc.density.data[100] = v)));
    }
    for g in [1.0, -1.0, 1.5, f64::NAN] {
        out.push(invalid(format!("invalid: g = {g}"), "volume.g", with(&|sc| sc.medium.g = g)));
    }
    for albedo in [-0.1, 1.5] {
        out.push(invalid(format!("invalid: albedo {albedo}"), "volume.albedo", with(&|sc| sc.medium.albedo = albedo)));
    }
    let scale = with(&|sc| sc.medium.sigma_t_scale = f64::NAN);
    out.push(invalid("invalid: NaN sigma_t_scale".into(), "volume.sigma_t_scale", scale));
    out.push(invalid("invalid: max_order 0".into(), "volume.max_order", with(&|sc| sc.medium.max_order = 0)));
    for (what, v) in [("NaN", f64::NAN), ("negative", -1.0), ("Inf", f64::INFINITY)] {
        let name = format!("invalid: {what} light intensity");
        out.push(invalid(name, "lights[0].intensity", with(&|sc| sc.lights[0].intensity = v)));
    }
    let position = with(&|sc| sc.lights[0].position.x = f64::NAN);
    out.push(invalid("invalid: NaN light position".into(), "lights[0].position", position));
    let empty = with(&|sc| sc.density = Grid::new(sc.density.lo, sc.density.hi, [0, 8, 8], vec![]));
    out.push(invalid("invalid: zero-size grid".into(), "volume.density", empty));
    out.push(invalid("invalid: zero-width image".into(), "cameras[0]", with(&|sc| sc.cameras[0].width = 0)));
    let away = with(&|sc| sc.cameras[1].look_at = Vec3::new(4.0, 0.3, 0.0));
    out.push(invalid("invalid: camera looking away".into(), "cameras[1]", away));
    let kernel = with(&|sc| sc.render.kernel_radius = Some(0.0));
    out.push(invalid("invalid: kernel radius 0".into(), "render.kernel_radius", kernel));
    out
}
