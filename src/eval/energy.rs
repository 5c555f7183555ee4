//! The energy balance of a scene: power into first collisions, by quadrature
//! over directions from each light (independent of the photon tracer),
//! against the flux of scattered light through a sphere of cameras around
//! the volume, rendered by the photon mapper.
//!
//! It can fail: a tracer that loses or creates power (forced-collision or
//! guiding weights, emission cones, the kernel's normalisation) or a camera
//! integral off by a factor breaks a balance.

use crate::eval::scenes::look_at_origin;
use crate::image::Image;
use crate::math::{frame, intersect_box, Ray, Vec3};
use crate::render::frozen::Frozen;
use crate::scene::{Light, Scene};
use crate::volume::Grid;
use std::f64::consts::PI;

/// Relative tolerance of the single-scattering balance: sphere quadrature,
/// photon noise of the second-collision power (measured: under 1%).
pub const SINGLE_TOL: f64 = 0.03;
/// ... and of the all-orders balance, which adds the photon kernel's bias:
/// emission blurred from dense voxels into thinner ones escapes more easily
/// (measured: +3% on the 8^3 blob, shrinking with the voxel size).
pub const ENERGY_TOL: f64 = 0.05;
/// Directions `(u, v)` per axis of the quadrature over each light's cone (stratified midpoints).
const CONE_SAMPLES: usize = 200;
/// Radius of the sphere of cameras (world units; the volume is the unit box).
const RADIUS: f64 = 3.0;
/// Vertical field of view of those cameras (degrees): wide enough to see the whole box.
const FOV: f64 = 38.0;

/// Sizes of the energy check.
#[derive(Clone, Copy, Debug)]
pub struct EnergySettings {
    /// Cameras on the sphere.
    pub cameras: usize,
    /// Image edge of those cameras (pixels).
    pub res: usize,
    /// Photons of the renders.
    pub photons: u64,
    /// Scattering orders of the all-orders render (the remainder beyond is bounded).
    pub order: u32,
}

/// Power balance of a scene's medium (W).
#[derive(Clone, Debug)]
pub struct Energy {
    /// Power the lights send into a first collision, `P_in = sum_l I_l ∫ (1 - e^{-tau(w)}) dw`,
    /// by quadrature over directions from each light (independent of the photon tracer).
    pub input: f64,
    /// Power entering a second collision: the stored order-2 photons (before that collision's albedo).
    pub second: f64,
    /// Single-scattered power leaving the volume, seen by the cameras at max_order 1.
    pub single_out: f64,
    /// Scattered power leaving the volume, orders 1..=K.
    pub output: f64,
    /// Upper bound of what orders > K would add: albedo times the power of the stored order-K photons.
    pub remainder: f64,
}

impl Energy {
    /// What single scattering should send out: of the `albedo * P_in`
    /// scattered at first collisions, what does not collide again.
    pub fn single_expected(&self, albedo: f64) -> f64 {
        albedo * self.input - self.second
    }

    /// Two balances, each within its tolerance:
    /// - single scattering (no photon kernel involved):
    ///   `single_out = albedo * P_in - second` ([`SINGLE_TOL`]);
    /// - all orders: `output <= albedo * P_in` (absorption only removes
    ///   power), and at albedo 1 `output >= P_in - remainder` (nothing is
    ///   absorbed: what collides leaves after some order) ([`ENERGY_TOL`]).
    ///
    /// At albedo 0 nothing may leave at all.
    pub fn passes(&self, albedo: f64) -> bool {
        if albedo == 0.0 {
            return self.output == 0.0 && self.single_out == 0.0;
        }
        let scattered = albedo * self.input;
        let single = (self.single_out - (scattered - self.second)).abs() <= SINGLE_TOL * scattered;
        let upper = self.output <= scattered * (1.0 + ENERGY_TOL);
        let lower = albedo < 1.0 || self.output >= (self.input - self.remainder) * (1.0 - ENERGY_TOL);
        single && upper && lower
    }

    /// One line of ratios for a report.
    pub fn describe(&self, albedo: f64) -> String {
        let scattered = albedo * self.input;
        format!(
            "energy: in {:.4e} W; single out/expected {:.4}; all orders out/(albedo in) {:.4}, remainder bound {:.1e}{}",
            self.input,
            if scattered > 0.0 { self.single_out / (scattered - self.second) } else { 0.0 },
            if scattered > 0.0 { self.output / scattered } else { 0.0 },
            self.remainder / self.input,
            if self.passes(albedo) { "" } else { " -- BALANCE FAILED" }
        )
    }
}

/// The energy balance of `scene`'s medium, lights and density, rendered by
/// `s.cameras` cameras on a Fibonacci sphere of radius 3 around the box
/// (they see only scattered light: lights are not rendered), once with
/// single scattering only and once with `s.order` orders. The flux through
/// the sphere is
/// `∮ ∫ L (w·n) dw dA ≈ (4π R² / N) Σ_cameras Σ_pixels L_p Ω_p (w_p·n)`,
/// `Ω_p` a pixel's solid angle.
pub fn energy(scene: &Scene, s: &EnergySettings) -> Energy {
    let mut rig = scene.clone();
    rig.render.photons = s.photons;
    let golden = PI * (3.0 - 5f64.sqrt());
    let n = s.cameras;
    rig.cameras = (0..n)
        .map(|c| {
            let y = 1.0 - (c as f64 + 0.5) / n as f64 * 2.0;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * c as f64;
            look_at_origin(Vec3::new(r * phi.cos(), y, r * phi.sin()) * RADIUS, s.res, FOV)
        })
        .collect();
    let leaving = |images: &[Image]| {
        let mut flux = 0.0;
        for (cam, image) in rig.cameras.iter().zip(images) {
            let normal = cam.position.normalize();
            let pixel = 2.0 * (FOV.to_radians() / 2.0).tan() / cam.height as f64;
            let axis = (cam.look_at - cam.position).normalize();
            for (p, l) in image.data.iter().enumerate() {
                let d = cam.ray((p % cam.width) as f64 + 0.5, (p / cam.width) as f64 + 0.5).dir;
                flux += l * pixel * pixel * d.dot(&axis).powi(3) * (-d.dot(&normal));
            }
        }
        flux * 4.0 * PI * RADIUS * RADIUS / n as f64
    };
    rig.medium.max_order = 1;
    let single_out = leaving(&Frozen::new(&rig, None).images);
    rig.medium.max_order = s.order;
    let frozen = Frozen::new(&rig, None);
    let power = |order: u32| frozen.photons.iter().filter(|p| p.order as u32 == order).fold(0.0, |a, p| a + p.power);
    Energy {
        input: scene.lights.iter().map(|l| collided_power(&scene.density, scene.medium.sigma_t_scale, l)).sum(),
        second: power(2),
        single_out,
        output: leaving(&frozen.images),
        remainder: scene.medium.albedo * power(s.order),
    }
}

/// `I ∫ (1 - e^{-tau(w)}) dw` over the cone from light `l` around the box's
/// bounding sphere (the whole sphere of directions if the light is inside),
/// with `tau` by the midpoint rule at a quarter voxel.
pub fn collided_power(density: &Grid<f64>, scale: f64, l: &Light) -> f64 {
    let centre = (density.lo + density.hi) * 0.5;
    let radius = (density.hi - density.lo).norm() * 0.5;
    let to = centre - l.position;
    let dist = to.norm();
    let (axis, cos_max) =
        if dist > radius { (to / dist, (1.0 - (radius / dist).powi(2)).sqrt()) } else { (Vec3::z(), -1.0) };
    let (a, b) = frame(&axis);
    let step = 0.25 * density.voxel_size().min();
    let mut sum = 0.0;
    for iu in 0..CONE_SAMPLES {
        for iv in 0..CONE_SAMPLES {
            let cos = 1.0 - (iu as f64 + 0.5) / CONE_SAMPLES as f64 * (1.0 - cos_max);
            let phi = 2.0 * PI * (iv as f64 + 0.5) / CONE_SAMPLES as f64;
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let ray = Ray { origin: l.position, dir: a * (sin * phi.cos()) + b * (sin * phi.sin()) + axis * cos };
            let Some((t0, t1)) = intersect_box(&ray, &density.lo, &density.hi) else { continue };
            let m = ((t1 - t0) / step).ceil().max(1.0);
            let h = (t1 - t0) / m;
            let tau: f64 = (0..m as usize).map(|k| density.at(&ray.at(t0 + (k as f64 + 0.5) * h)) * scale * h).sum();
            sum += -(-tau).exp_m1();
        }
    }
    l.intensity * 2.0 * PI * (1.0 - cos_max) * sum / (CONE_SAMPLES * CONE_SAMPLES) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scenes::homogeneous;

    #[test]
    fn a_far_light_sends_its_cone_into_an_opaque_box() {
        // Optical depth 1e3 across: every direction that hits the box collides.
        let light = Light { position: Vec3::new(0.0, 0.0, 10.0), intensity: 2.0 };
        let p = collided_power(&homogeneous(4, 50.0), 20.0, &light);
        // The box's face seen from 9.5 away: about 1 / 9.5^2 sr; the cone is wider, the box narrower.
        assert!(p > 2.0 * 0.9 / 9.5f64.powi(2) && p < 2.0 * 1.1 / 9.5f64.powi(2), "{p}");
        assert_eq!(collided_power(&homogeneous(4, 0.0), 20.0, &light), 0.0);
    }
}
