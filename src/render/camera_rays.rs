//! The camera-ray integral `L = ∫ T(0,t) sigma_s(x_t) L_s(x_t, -w) dt`
//! (docs/DESIGN.md §2) by ray marching: per step, single scattering towards every
//! light, its transmittance read from the light-depth grids (or marched,
//! everywhere or near voxels too deep for the grids),
//! the medium's emission, and the photon estimate of the higher orders read
//! from a grid. Generic
//! over `R: Real`: the density carries derivatives, the step placement does not.

use super::light_depth::Depths;
use super::march::Marcher;
use super::splat::Estimate;
use super::thick::ThickVoxels;
use crate::ad::Real;
use crate::math::Ray;
use crate::rng::{Purpose, Rng};
use crate::scene::{Camera, Light, Medium};
use crate::volume::phase::hg_eval;
use crate::volume::Grid;
use rayon::prelude::*;

/// Everything a camera ray reads.
pub struct CameraRays<'a, R: Real> {
    /// The density (weights and derivatives).
    pub density: &'a Grid<R>,
    /// Frozen mode: the density the sampling decisions use. `None`: the
    /// primal of `density` (detached sampling, docs/DESIGN.md §3).
    pub sampling: Option<&'a Grid<f64>>,
    /// Optical properties.
    pub medium: &'a Medium,
    /// Point lights (those of zero intensity are skipped).
    pub lights: &'a [Light],
    /// Occupied-space marching.
    pub marcher: &'a Marcher,
    /// Per light, the optical depth to it on a grid; `None`: a shadow ray is
    /// marched from every sample.
    pub depths: Option<&'a Depths<R>>,
    /// Where samples march their shadow rays although `depths` is given:
    /// near voxels too deep for the grids (`auto` shadows).
    pub marched_near: Option<&'a ThickVoxels>,
    /// Jittered samples per pixel.
    pub spp: u32,
    /// Seed of the pixel streams.
    pub seed: u64,
}

/// Transmittance below which a camera ray stops: nothing behind it can reach 1e-12 of the front.
const T_MIN: f64 = 1e-12;

impl<R: Real> CameraRays<'_, R> {
    /// The image of `camera`; `first_pixel` is the index of its first pixel
    /// among all cameras of the scene (it names the random streams), and
    /// `multiple` the photon estimate towards this camera, if any.
    pub fn image(&self, camera: &Camera, first_pixel: u64, multiple: Option<&Estimate<R>>) -> Vec<R> {
        (0..camera.pixels())
            .into_par_iter()
            // Pixels that see the medium cost far more than the others (see `crate::par`).
            .with_min_len(16)
            .with_max_len(32)
            .map(|p| self.pixel(camera, first_pixel, p, multiple))
            .collect()
    }

    /// The images of several cameras, each given with the index of its
    /// first pixel and its photon estimate ([`image`](Self::image)), in
    /// one parallel loop: no camera waits for the last pixels of another.
    pub fn images(&self, cameras: &[(&Camera, u64, Option<&Estimate<R>>)]) -> Vec<Vec<R>> {
        cameras.par_iter().map(|&(camera, first_pixel, multiple)| self.image(camera, first_pixel, multiple)).collect()
    }

    /// Pixel `p` (row-major) of `camera`: the mean of `spp` jittered rays,
    /// stratified as a Latin hypercube over the pixel (one sample per row
    /// and per column stratum).
    pub fn pixel(&self, camera: &Camera, first_pixel: u64, p: usize, multiple: Option<&Estimate<R>>) -> R {
        let mut rng = Rng::new(self.seed, Purpose::Pixel, first_pixel + p as u64);
        let (x, y) = ((p % camera.width) as f64, (p / camera.width) as f64);
        let n = self.spp as usize;
        // A random permutation pairs the x strata with the y strata.
        let mut rows: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            rows.swap(i, rng.below(i as u64 + 1) as usize);
        }
        let mut sum = R::cst(0.0);
        for (s, &row) in rows.iter().enumerate() {
            let sx = (s as f64 + rng.uniform()) / n as f64;
            let sy = (row as f64 + rng.uniform()) / n as f64;
            let ray = camera.ray(x + sx, y + sy);
            sum += self.radiance(&ray, rng.uniform(), rng.uniform(), multiple);
        }
        sum * (1.0 / n as f64)
    }

    /// Radiance arriving along `-ray.dir` at the ray's origin.
    pub fn radiance(&self, ray: &Ray, jitter: f64, shadow_jitter: f64, multiple: Option<&Estimate<R>>) -> R {
        let scale = self.medium.sigma_t_scale;
        let w_out = -ray.dir;
        let mut transmittance = R::cst(1.0);
        let mut transmittance_detached = 1.0;
        let mut radiance = R::cst(0.0);
        self.marcher.steps(ray, f64::INFINITY, jitter, |s| {
            // The step's extinction, constant over the step, read at the jittered sample.
            let xs = ray.at(s.sample);
            let sigma_t = self.density.at(&xs) * scale;
            let sigma = self.sampling.map_or_else(|| sigma_t.re(), |g| g.at(&xs) * scale);
            // Light is gathered at a second point, drawn from q(u) = e^{-sigma u} / z on
            // [0, h] with the same uniform (detached: the sampling density is a plain value).
            // Dividing by q gives the weight z e^{-(sigma_t - sigma) u}, which is
            // 1 - e^{-sigma h} (times 1/sigma_t) in the primal and exact for any
            // stiffness; it is where the derivative of the within-step attenuation lives.
            let z = sigma.one_minus_exp_over(s.h);
            let xi = (s.sample - s.start) / s.h;
            let u = if sigma > 0.0 { (-(-xi * sigma * z).ln_1p() / sigma).min(s.h) } else { xi * s.h };
            let x = ray.at(s.start + u);
            let within = transmittance * ((sigma_t - sigma) * -u).exp() * z;
            if let Some(ms) = multiple {
                let m = ms.at(&x);
                if !m.is_exact_zero() {
                    // Photons estimate sigma_t L (per unit length) directly.
                    radiance += within * m;
                }
            }
            if self.medium.emission > 0.0 && !sigma_t.is_exact_zero() {
                radiance += within * sigma_t * self.medium.emission;
            }
            if !sigma_t.is_exact_zero() && self.medium.albedo > 0.0 {
                let mut single = R::cst(0.0);
                let depths = self.depths.filter(|_| !self.marched_near.is_some_and(|t| t.near(&x)));
                for (l, light) in self.lights.iter().enumerate().filter(|(_, l)| l.intensity > 0.0) {
                    let to_light = light.position - x;
                    let dist2 = to_light.norm_squared();
                    if dist2 == 0.0 {
                        continue; // A sample exactly on a point light: a set of measure zero.
                    }
                    let mu = (-to_light / dist2.sqrt()).dot(&w_out);
                    let t = match depths.and_then(|d| d[l].as_ref()) {
                        Some(depth) => (depth.at(&x) * -1.0).exp(),
                        None => self.marcher.transmittance(self.density, scale, &x, &light.position, shadow_jitter),
                    };
                    single += t * (hg_eval(self.medium.g, mu) * light.intensity / dist2);
                }
                radiance += within * sigma_t * single * self.medium.albedo;
            }
            transmittance *= (sigma_t * -s.h).exp();
            transmittance_detached *= (-(sigma * s.h)).exp();
            transmittance_detached > T_MIN
        });
        radiance
    }
}
