//! The unbiased reference: a plain volumetric path tracer with next-event
//! estimation to the point lights, in exactly the conventions of docs/DESIGN.md
//! §1-§2 (monochrome, black background, no surfaces, index-matched box,
//! isotropic point lights, a pixel = mean radiance over its footprint).
//!
//! Paths are traced backwards from the camera. Free flights are sampled by
//! delta tracking against the piecewise-constant [`Majorant`], so every real
//! collision is distributed exactly as `T(0, t) sigma_t(x_t)` of the trilinear
//! density: no ray-marching step, no bias. At the n-th collision
//! (`min_order <= n <= max_order`) the path adds next-event estimation to
//! every light, with the light's transmittance from ratio tracking against
//! the same majorant (plus an unbiased Russian roulette once the running
//! transmittance falls below 0.05, as in pbrt-v4); it then samples a new
//! direction from Henyey-Greenstein and goes on, until `max_order` events or until it leaves the box. Because
//! delta tracking samples real collisions with density `T sigma_t` and HG
//! sampling is exact, the path weight is `albedo^n` and nothing else.
//!
//! Sign conventions (phase in propagation directions, `mu = w_in . w_out`):
//! the current ray direction is `d`; light leaves the vertex `x` along `-d`
//! towards the previous vertex (or the camera). Light from a point light at
//! `p` arrives propagating along `w_l = (x - p) / |x - p|`, so the NEE phase is
//! `p_HG(w_l . (-d)) = p_HG(dir_to_light . d)`. The continuation `d'` carries
//! light propagating along `-d'` into `x` and out along `-d`, phase
//! `p_HG((-d') . (-d)) = p_HG(d' . d)`: exactly the pdf of `hg_sample(g, d)`.
//!
//! Randomness: pixel `i` (counted over all cameras, in order) owns the stream
//! `Rng::new(seed, Purpose::PathPixel, i)`, so images are bit-identical for
//! any number of threads.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::image::Image;
use crate::math::{intersect_box, Ray, Vec3};
use crate::rng::{Purpose, Rng};
use crate::scene::{Camera, Scene};
use crate::volume::majorant::MAJORANT_BLOCK;
use crate::volume::phase::{hg_eval, hg_sample};
use crate::volume::{Grid, Majorant};

// Voxels per majorant block edge (MAJORANT_BLOCK): small blocks give tight
// bounds (fewer null collisions), large ones fewer block crossings. On the
// 64^3 sphere of the benchmark test 4 and 8 are within timing noise; 4 is the tighter.

/// Ratio tracking plays Russian roulette once its running transmittance
/// falls below this (as pbrt-v4 does): unbiased, and it bounds the work in
/// optically thick media whose majorant is loose.
const RR_THRESHOLD: f64 = 0.05;
/// Probability that Russian roulette ends a ratio-tracking walk.
const RR_KILL: f64 = 0.75;

/// Settings of one path-traced render.
#[derive(Clone, Debug, PartialEq)]
pub struct PathOptions {
    /// Samples (camera paths) per pixel, each at a jittered sub-pixel position.
    /// 0 gives black images and `samples == 0`.
    pub spp: u32,
    /// Seed of the per-pixel random streams.
    pub seed: u64,
    /// Most scattering events per path; `None` = `scene.medium.max_order`.
    pub max_order: Option<u32>,
    /// Only paths with at least this many scattering events are counted, so
    /// that one order can be isolated (`min_order = max_order = n`); 0 acts as
    /// 1 (a point light is never seen directly). Default 1. Vertices below
    /// `min_order` skip next-event estimation, so the random numbers (not the
    /// expectation) differ from a render with another `min_order`.
    pub min_order: u32,
}

impl Default for PathOptions {
    fn default() -> Self {
        PathOptions { spp: 256, seed: 0, max_order: None, min_order: 1 }
    }
}

impl PathOptions {
    /// The scene's own settings: `render.path_spp`, `render.seed`, all orders.
    pub fn for_scene(scene: &Scene) -> Self {
        PathOptions { spp: scene.render.path_spp, seed: scene.render.seed, ..Default::default() }
    }
}

/// The result of a path-traced render, one image per camera in scene order.
#[derive(Clone, Debug)]
pub struct PathRender {
    /// Mean radiance per pixel.
    pub radiance: Vec<Image>,
    /// Standard error of that mean: `sqrt(sample variance / spp)`; 0 when
    /// `spp < 2` (the variance is unknown then) or when a pixel is exactly
    /// constant (for example black).
    pub std_err: Vec<Image>,
    /// Camera paths traced in all: pixels of all cameras times `spp`.
    pub samples: u64,
}

/// Renders every camera of `scene`; see [`render_path_with_progress`].
pub fn render_path(scene: &Scene, opts: &PathOptions) -> PathRender {
    render_path_with_progress(scene, opts, &|_, _| {})
}

/// Renders every camera of `scene`, calling `progress(done_pixels,
/// total_pixels)` from the worker threads now and then (calls may arrive
/// slightly out of order; the last one reports `total_pixels`).
pub fn render_path_with_progress(
    scene: &Scene,
    opts: &PathOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> PathRender {
    let offsets: Vec<usize> = scene
        .cameras
        .iter()
        .scan(0, |acc, c| {
            let start = *acc;
            *acc += c.pixels();
            Some(start)
        })
        .collect();
    let total: usize = scene.cameras.iter().map(Camera::pixels).sum();
    let samples = total as u64 * opts.spp as u64;
    let pixels: Vec<(f64, f64)> = match Tracer::new(scene, opts) {
        None => vec![(0.0, 0.0); total],
        Some(tracer) => {
            let done = AtomicUsize::new(0);
            let stride = (total / 256).max(1);
            (0..total)
                .into_par_iter()
                .map(|gi| {
                    let c = offsets.partition_point(|&o| o <= gi) - 1;
                    let local = gi - offsets[c];
                    let cam = &scene.cameras[c];
                    let mut rng = Rng::new(opts.seed, Purpose::PathPixel, gi as u64);
                    let px = tracer.pixel(cam, local % cam.width, local / cam.width, opts.spp, &mut rng);
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if n.is_multiple_of(stride) && n < total {
                        progress(n, total);
                    }
                    px
                })
                .collect()
        }
    };
    if total > 0 {
        progress(total, total);
    }
    let (mut radiance, mut std_err) = (Vec::new(), Vec::new());
    for (cam, &start) in scene.cameras.iter().zip(&offsets) {
        let slice = &pixels[start..start + cam.pixels()];
        let image = |f: fn(&(f64, f64)) -> f64| Image {
            width: cam.width,
            height: cam.height,
            data: slice.iter().map(f).collect(),
        };
        radiance.push(image(|p| p.0));
        std_err.push(image(|p| p.1));
    }
    PathRender { radiance, std_err, samples }
}

/// An exponential sample of unit mean: an optical depth to the next
/// tentative collision. `1 - u` is in (0, 1], so the result is finite.
#[inline]
fn exp1(rng: &mut Rng) -> f64 {
    -(1.0 - rng.uniform()).ln()
}

/// Everything a camera path needs, built once per render.
struct Tracer<'a> {
    density: &'a Grid<f64>,
    majorant: Majorant,
    /// `sigma_t = sigma_t_scale * density`.
    scale: f64,
    albedo: f64,
    g: f64,
    /// The medium's emission per unit extinction, added at the first collision.
    emission: f64,
    /// Lights of non-zero intensity: `(position, intensity)`.
    lights: Vec<(Vec3, f64)>,
    /// The grid's box clipped to the blocks of non-zero bound: outside it
    /// the density is exactly 0 and a path has nothing to do.
    lo: Vec3,
    hi: Vec3,
    min_order: u32,
    max_order: u32,
}

impl<'a> Tracer<'a> {
    /// `None` when every image is black for sure (no medium, neither a
    /// light with albedo > 0 nor emission, no order to count, no samples): such renders cost nothing.
    fn new(scene: &'a Scene, opts: &PathOptions) -> Option<Self> {
        let m = &scene.medium;
        let max_order = opts.max_order.unwrap_or(m.max_order);
        let min_order = opts.min_order.max(1);
        let lights: Vec<(Vec3, f64)> =
            scene.lights.iter().filter(|l| l.intensity > 0.0).map(|l| (l.position, l.intensity)).collect();
        let lit = !lights.is_empty() && m.albedo > 0.0;
        let emits = m.emission > 0.0 && min_order == 1;
        if opts.spp == 0 || !(lit || emits) || m.sigma_t_scale <= 0.0 || min_order > max_order {
            return None;
        }
        let majorant = Majorant::build(&scene.density, MAJORANT_BLOCK);
        let (occ_lo, occ_hi) = majorant.occupied_bounds()?;
        let (lo, hi) = (scene.density.lo.sup(&occ_lo), scene.density.hi.inf(&occ_hi));
        Some(Tracer {
            density: &scene.density,
            majorant,
            scale: m.sigma_t_scale,
            albedo: m.albedo,
            g: m.g,
            emission: m.emission,
            lights,
            lo,
            hi,
            min_order,
            max_order,
        })
    }

    /// Mean and standard error of the mean of `spp` jittered samples of pixel
    /// `(x, y)` (Welford's running moments).
    fn pixel(&self, cam: &Camera, x: usize, y: usize, spp: u32, rng: &mut Rng) -> (f64, f64) {
        let (mut mean, mut m2) = (0.0f64, 0.0f64);
        for k in 1..=spp {
            let (u, v) = (rng.uniform(), rng.uniform());
            let l = self.trace(cam.ray(x as f64 + u, y as f64 + v), rng);
            let delta = l - mean;
            mean += delta / k as f64;
            m2 += delta * (l - mean);
        }
        let se = if spp > 1 { (m2.max(0.0) / (spp - 1) as f64 / spp as f64).sqrt() } else { 0.0 };
        (mean, se)
    }

    /// Radiance carried back along one camera ray by one path.
    fn trace(&self, mut ray: Ray, rng: &mut Rng) -> f64 {
        let (mut weight, mut radiance) = (1.0, 0.0);
        for n in 1..=self.max_order {
            let Some(t) = self.free_flight(&ray, rng) else { break };
            let x = ray.at(t);
            if n == 1 && self.min_order == 1 {
                // The camera ray's emission `T sigma_t e`: the collision's pdf is `T sigma_t`.
                radiance += self.emission;
            }
            // Delta tracking samples real collisions with pdf T sigma_t, so
            // the collision's weight is sigma_s / sigma_t.
            weight *= self.albedo;
            if n >= self.min_order {
                radiance += weight * self.next_event(&x, &ray.dir, rng);
            }
            if n == self.max_order {
                break;
            }
            // Sampled with pdf = phase: the weight is unchanged (module docs for the sign).
            let dir = hg_sample(self.g, &ray.dir, rng.uniform(), rng.uniform());
            ray = Ray { origin: x, dir };
        }
        radiance
    }

    /// Distance along `ray` to the next real collision (delta tracking), or
    /// `None` if the ray leaves the medium first.
    fn free_flight(&self, ray: &Ray, rng: &mut Rng) -> Option<f64> {
        let (t0, t1) = intersect_box(ray, &self.lo, &self.hi)?;
        let mut hit = None;
        self.tentative_collisions(ray, t0, t1, rng, |t, mu, rng| {
            if rng.uniform() * mu < self.sigma_t(&ray.at(t)) {
                hit = Some(t);
                return false;
            }
            true
        });
        hit
    }

    /// Calls `visit(t, mu, rng)` at each tentative collision along `ray` in
    /// `[t0, t1]`, drawn against the block majorants `mu`, until it returns
    /// false: the loop delta and ratio tracking share; only what they do at
    /// a tentative collision differs.
    fn tentative_collisions(
        &self,
        ray: &Ray,
        t0: f64,
        t1: f64,
        rng: &mut Rng,
        mut visit: impl FnMut(f64, f64, &mut Rng) -> bool,
    ) {
        let mut tau = exp1(rng); // majorant optical depth left to the next tentative collision
        self.majorant.walk(ray, t0, t1, |ta, tb, bound| {
            let mu = bound * self.scale;
            if mu <= 0.0 {
                return true;
            }
            let mut t = ta;
            loop {
                let room = (tb - t) * mu;
                if tau >= room {
                    tau -= room;
                    return true;
                }
                t += tau / mu;
                if !visit(t, mu, rng) {
                    return false;
                }
                tau = exp1(rng);
            }
        });
    }

    /// Radiance scattered at `x` into `-dir` from every light, per unit
    /// `sigma_s` weight: `sum_l p_HG(dir_to_light . dir) I_l T(x, p_l) / r^2`.
    fn next_event(&self, x: &Vec3, dir: &Vec3, rng: &mut Rng) -> f64 {
        let mut sum = 0.0;
        for &(p, intensity) in &self.lights {
            let to_light = p - x;
            let r2 = to_light.norm_squared();
            // A light exactly on the vertex is a zero-probability event whose
            // 1/r^2 is infinite: skip it (no clamp anywhere else). Any r2 > 0
            // is at least ~1e-32 for coordinates of order one, so I/r2 is finite.
            if r2 == 0.0 {
                continue;
            }
            let r = r2.sqrt();
            let w = to_light / r;
            let phase = hg_eval(self.g, w.dot(dir));
            sum += phase * intensity * self.transmittance(&Ray { origin: *x, dir: w }, r, rng) / r2;
        }
        sum
    }

    /// Ratio-tracking estimate of the transmittance along `ray` over `[0, r]`.
    fn transmittance(&self, ray: &Ray, r: f64, rng: &mut Rng) -> f64 {
        let Some((t0, t1)) = intersect_box(ray, &self.lo, &self.hi) else { return 1.0 };
        let mut tr = 1.0;
        self.tentative_collisions(ray, t0, t1.min(r), rng, |t, mu, rng| {
            // The bound holds exactly in real numbers; rounding of the
            // trilinear weights can put sigma_t an ulp above mu, hence the max.
            tr *= (1.0 - self.sigma_t(&ray.at(t)) / mu).max(0.0);
            if tr < RR_THRESHOLD {
                if tr == 0.0 || rng.uniform() < RR_KILL {
                    tr = 0.0;
                    return false;
                }
                tr /= 1.0 - RR_KILL;
            }
            true
        });
        tr
    }

    #[inline]
    fn sigma_t(&self, p: &Vec3) -> f64 {
        let rho: f64 = self.density.at(p);
        self.scale * rho
    }
}

#[cfg(test)]
mod tests {
    //! Checks that need the tracer's internals; the path tracer's checks
    //! against independent estimators (quadrature, a second Monte Carlo
    //! estimator) are in `tests/path_tracer.rs`.
    use super::*;
    use crate::scene::{Light, Medium, RenderSettings};

    fn opts(spp: u32, seed: u64, min_order: u32, max_order: u32) -> PathOptions {
        PathOptions { spp, seed, max_order: Some(max_order), min_order }
    }

    #[test]
    fn finite_in_extreme_cases() {
        let cam = Camera {
            position: Vec3::new(0.3, 0.2, 2.0),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: crate::scene::Lens::FovY(45.0),
            width: 8,
            height: 8,
        };
        let light = |x, y, z, intensity| Light { position: Vec3::new(x, y, z), intensity };
        let lights = vec![
            light(0.0, 0.0, 0.0, 50.0),
            light(0.5, 0.1, -0.2, 10.0),
            light(-0.5, 0.5, 0.5, 10.0),
            light(0.0, 3.0, 0.0, 0.0),
            light(1.0, 1.0, 2.0, 10.0),
        ];
        // Unit box, `n^3` voxels.
        let scene = |n: usize, data: Vec<f64>, sigma_t_scale, albedo, g| Scene {
            density: Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [n, n, n], data),
            medium: Medium { sigma_t_scale, albedo, g, max_order: 4, emission: 0.0 },
            lights: lights.clone(),
            cameras: vec![cam.clone()],
            render: RenderSettings::default(),
        };
        let noise = |seed| {
            let mut rng = Rng::new(seed, Purpose::Scene, 0);
            (0..216).map(|_| rng.uniform()).collect::<Vec<f64>>()
        };
        let mut hot = vec![0.0; 216];
        hot[3 * 36 + 2 * 6 + 3] = 1e4 / 20.0;
        let cases = [
            ("optical depth 1e4", scene(4, vec![1e4 / 20.0; 64], 20.0, 0.9, 0.9)),
            ("one hot voxel", scene(6, hot, 20.0, 1.0, 0.5)),
            ("g = 0.99", scene(6, noise(1), 5.0, 1.0, 0.99)),
            ("g = -0.99", scene(6, noise(2), 5.0, 1.0, -0.99)),
        ];
        for (what, s) in &cases {
            let r = render_path(s, &opts(8, 0, 1, 4));
            for im in r.radiance.iter().chain(&r.std_err) {
                assert!(im.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{what}: {:?}", im.data);
            }
            assert!(r.radiance[0].data.iter().any(|&v| v > 0.0), "{what}: black");
            // A vertex exactly on a light: that light is skipped, nothing blows up.
            let tracer = Tracer::new(s, &opts(1, 0, 1, 4)).unwrap();
            let mut rng = Rng::new(0, Purpose::PathPixel, 0);
            for l in &s.lights {
                let v = tracer.next_event(&l.position, &Vec3::new(0.0, 0.0, -1.0), &mut rng);
                assert!(v.is_finite() && v >= 0.0, "{what}: NEE at a light gives {v}");
            }
        }
    }

    #[test]
    #[ignore = "benchmark: cargo test --release --lib render::path::tests::bench -- --ignored --nocapture"]
    fn bench_sphere_64() {
        let n = 64;
        let mut g = Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [n, n, n], vec![0.0; n * n * n]);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let idx = g.index(k, j, i);
                    g.data[idx] = if g.voxel_center(k, j, i).norm() < 0.4 { 0.1 } else { 0.0 };
                }
            }
        }
        let s = crate::scene::rig::paper_scene(g, 64);
        let tracer = Tracer::new(&s, &opts(1, 0, 1, 3)).unwrap();
        let hit = s
            .cameras
            .iter()
            .map(|c| {
                (0..c.pixels())
                    .filter(|&i| {
                        intersect_box(
                            &c.ray((i % c.width) as f64 + 0.5, (i / c.width) as f64 + 0.5),
                            &tracer.lo,
                            &tracer.hi,
                        )
                        .is_some()
                    })
                    .count()
            })
            .sum::<usize>();
        eprintln!(
            "{} cameras, {} lights; {hit} of {} pixel centres see the occupied box",
            s.cameras.len(),
            s.lights.len(),
            5 * 64 * 64
        );
        for (order, spp) in [(1, 64), (3, 64)] {
            let t = std::time::Instant::now();
            let r = render_path(&s, &opts(spp, 0, 1, order));
            let dt = t.elapsed().as_secs_f64();
            let n = r.radiance[0].data.len() as f64;
            let m = r.radiance[0].data.iter().sum::<f64>() / n;
            let se = r.std_err[0].data.iter().map(|s| s * s).sum::<f64>().sqrt() / n;
            eprintln!(
                "max_order {order}: {} samples in {dt:.2} s = {:.0} samples/s on {} threads; image mean {m:.4e} +- {se:.1e}",
                r.samples,
                r.samples as f64 / dt,
                rayon::current_num_threads()
            );
        }
    }
}
