//! Photon tracing (docs/DESIGN.md §2): photons leave the point lights towards the
//! occupied part of the volume ([`emission`](super::emission)), every free
//! flight is forced to end in a collision inside the medium (weight `1 - T`
//! of the whole segment, so no photon is wasted on escaping), directions
//! follow Henyey-Greenstein mixed with lobes towards the cameras
//! (`Tracer::scatter`'s one-sample mixture), and a photon is stored at its
//! 2nd..max_order-th collision with the power that arrives there (the 1st
//! collision is single scattering, computed directly). Every decision uses
//! the sampling density; [`Tracer::replay`] re-evaluates a path's power as a
//! function of another density for the frozen estimator.

pub use super::emission::{emitters, Emitter};
use super::march::{Marcher, Step};
use crate::ad::Real;
use crate::math::{Ray, Vec3};
use crate::par;
use crate::rng::{Purpose, Rng};
use crate::scene::Medium;
use crate::volume::phase::{hg_eval, hg_sample};
use crate::volume::Grid;
use rayon::prelude::*;

/// A stored photon: the flux arriving at a collision.
#[derive(Clone, Copy, Debug)]
pub struct Photon {
    /// Collision position.
    pub pos: Vec3,
    /// Propagation direction of the arriving light (unit).
    pub dir: Vec3,
    /// Power (W) arriving, before the albedo of this collision.
    pub power: f64,
    /// Index of the emitted photon whose path this is.
    pub path: u32,
    /// Collision number along the path (2..=max_order); the scattering order it feeds.
    pub order: u8,
}

/// One free flight of a traced path, as a replay needs it: where it
/// collided and what the sampling density gave along it, so that a replay
/// marches only up to the collision, in the density it differentiates,
/// instead of marching the sampling density along the whole ray again.
#[derive(Clone, Copy, Debug)]
pub struct Flight {
    /// Collision distance along the flight's ray.
    t: f64,
    /// `1 - T` of the whole segment (the forced collision's weight).
    weight: f64,
    /// Number of the marching step the collision is in.
    step: u32,
    /// Optical depth of the sampling density from the ray's origin to `t`.
    depth: f64,
    /// Extinction of the sampling density in that step.
    sigma: f64,
}

/// The flights of every traced path: path `i`'s are
/// `flights[start[i]..start[i + 1]]`, in order.
#[derive(Clone, Debug, Default)]
pub struct Flights {
    flights: Vec<Flight>,
    start: Vec<usize>,
}

impl Flights {
    /// Path `i`'s flights.
    pub fn of(&self, i: usize) -> &[Flight] {
        &self.flights[self.start[i]..self.start[i + 1]]
    }
}

/// Everything photon tracing reads.
pub struct Tracer<'a> {
    /// Density the sampling decisions use.
    pub density: &'a Grid<f64>,
    /// Optical properties.
    pub medium: &'a Medium,
    /// Occupied-space marching.
    pub marcher: &'a Marcher,
    /// The lights' emission cones.
    pub emitters: &'a [Emitter],
    /// Camera positions that steer part of the scattered photons (empty: plain HG sampling).
    pub guide: &'a [Vec3],
}

/// Share of scattering events whose direction is drawn towards a camera.
pub const GUIDE_SHARE: f64 = 0.5;

impl Tracer<'_> {
    /// Power sent towards the medium by all lights (W).
    pub fn total_power(&self) -> f64 {
        self.emitters.iter().map(|e| e.power).sum()
    }

    /// True if this scene needs no photons (single scattering only, albedo
    /// 0, nothing lit, or no photons asked for).
    fn idle(&self, count: u64) -> bool {
        self.medium.max_order < 2 || count == 0 || self.total_power() <= 0.0 || self.medium.albedo == 0.0
    }

    /// Traces `count` photons with streams of `seed`: the stored photons in
    /// path order, whatever the number of threads (empty at max_order 1),
    /// and, if `keep_flights`, every path's flights for [`replay`](Self::replay)
    /// (else none: replaying then panics).
    pub fn trace(&self, count: u64, seed: u64, keep_flights: bool) -> (Vec<Photon>, Flights) {
        if self.idle(count) {
            let start = vec![0; if keep_flights { count as usize + 1 } else { 1 }];
            return (vec![], Flights { flights: vec![], start });
        }
        // Small enough for 16 threads to share 50,000 photons evenly, one task each (see `crate::par`).
        const CHUNK: u64 = 256;
        let chunks: Vec<(Vec<Photon>, Vec<Flight>, Vec<usize>)> = (0..count.div_ceil(CHUNK) as usize)
            .into_par_iter()
            .with_max_len(1)
            .map(|c| {
                let range = c as u64 * CHUNK..((c as u64 + 1) * CHUNK).min(count);
                let mut out = Vec::with_capacity(range.clone().count() * (self.medium.max_order as usize - 1));
                let (mut flights, mut per_path) = (vec![], vec![]);
                let mut steps = Vec::new();
                for i in range {
                    let before = flights.len();
                    self.trace_one(i, count, seed, &mut steps, &mut out, &mut flights);
                    if keep_flights {
                        per_path.push(flights.len() - before);
                    } else {
                        flights.clear();
                    }
                }
                (out, flights, per_path)
            })
            .collect();
        // Without flights kept, every `per_path` is empty and `start` stays `[0]`: nothing to replay.
        let mut start = vec![0];
        let (mut photons, mut flights) = (Vec::with_capacity(chunks.len()), Vec::with_capacity(chunks.len()));
        for (out, f, per_path) in chunks {
            photons.push(out);
            flights.push(f);
            for n in per_path {
                start.push(start.last().unwrap() + n);
            }
        }
        (par::concat(photons), Flights { flights: par::concat(flights), start })
    }

    /// Replays path `i` of `trace(count, seed)`, whose flights are
    /// `flights`, with its decisions unchanged and appends the powers of its
    /// stored photons, in the same order, as functions of `density` (the
    /// frozen estimator, docs/DESIGN.md §3). Each free flight's weight gets
    /// the factor `sigma_t T / (sigma_t T)_detached` (exactly 1 in the
    /// primal), where the derivatives live.
    #[allow(clippy::too_many_arguments)]
    pub fn replay<R: Real>(
        &self,
        i: u64,
        count: u64,
        seed: u64,
        flights: &[Flight],
        density: &Grid<R>,
        steps: &mut Vec<Step>,
        powers: &mut Vec<R>,
    ) {
        if self.idle(count) {
            return;
        }
        let mut rng = Rng::new(seed, Purpose::Photon, i);
        let mut ray = self.emission(i, count, &mut rng);
        let mut power_r = R::cst(self.total_power() / count as f64);
        for (n, f) in flights.iter().enumerate() {
            let order = n as u32 + 1;
            // The draws of the forced collision: the marching jitter, then the collision.
            let jitter = rng.uniform();
            rng.uniform();
            power_r = power_r * f.weight * self.flight_ratio(density, &ray, jitter, f, steps);
            if order >= 2 {
                powers.push(power_r);
            }
            if order == self.medium.max_order {
                return;
            }
            let pos = ray.at(f.t);
            let (dir, weight) = self.scatter(&pos, &ray.dir, &mut rng);
            power_r = power_r * (self.medium.albedo * weight);
            ray = Ray { origin: pos, dir };
        }
    }

    /// The emitter of photon `i` of `count`: stratified over the lights' power.
    fn emitter_of(&self, i: u64, count: u64, total: f64) -> &Emitter {
        let u = (i as f64 + 0.5) / count as f64 * total;
        let mut acc = 0.0;
        for e in self.emitters {
            acc += e.power;
            if u < acc {
                return e;
            }
        }
        self.emitters.iter().rev().find(|e| e.power > 0.0).unwrap()
    }

    /// Photon `i`'s first ray, from its emitter (three draws of `rng`).
    fn emission(&self, i: u64, count: u64, rng: &mut Rng) -> Ray {
        let e = self.emitter_of(i, count, self.total_power());
        Ray { origin: e.position, dir: e.sample(rng.uniform(), rng.uniform(), rng.uniform()) }
    }

    /// Traces path `i`: appends its stored photons to `out` and its flights to `flights`.
    fn trace_one(
        &self,
        i: u64,
        count: u64,
        seed: u64,
        steps: &mut Vec<(Step, f64)>,
        out: &mut Vec<Photon>,
        flights: &mut Vec<Flight>,
    ) {
        let mut rng = Rng::new(seed, Purpose::Photon, i);
        let mut ray = self.emission(i, count, &mut rng);
        let mut power = self.total_power() / count as f64;
        for order in 1..=self.medium.max_order {
            let Some((t, weight, m)) = self.forced_collision(&ray, &mut rng, steps) else { return };
            flights.push(detached_flight(steps, m, t, weight));
            power *= weight;
            let pos = ray.at(t);
            if order >= 2 {
                out.push(Photon { pos, dir: ray.dir, power, path: i as u32, order: order as u8 });
            }
            if order == self.medium.max_order {
                return;
            }
            let (dir, weight) = self.scatter(&pos, &ray.dir, &mut rng);
            power *= self.medium.albedo * weight;
            ray = Ray { origin: pos, dir };
        }
    }

    /// A scattered direction at `x` for light arriving along `w_in`, and its
    /// weight `p_HG / pdf`. With cameras to guide, the direction comes with
    /// probability [`GUIDE_SHARE`] from a Henyey-Greenstein lobe (same g)
    /// around the direction to a random camera, else from p_HG itself: the
    /// one-sample mixture keeps the estimate unbiased and the weight at most
    /// `1 / (1 - GUIDE_SHARE)`. It matters because with g near 1 and the
    /// cameras beside the lights, the few photons heading for a camera
    /// carry most of what the cameras see.
    fn scatter(&self, x: &Vec3, w_in: &Vec3, rng: &mut Rng) -> (Vec3, f64) {
        let g = self.medium.g;
        let axes = || self.guide.iter().filter_map(|c| (c - x).try_normalize(0.0));
        let n = axes().count();
        if n == 0 {
            return (hg_sample(g, w_in, rng.uniform(), rng.uniform()), 1.0);
        }
        let dir = if rng.uniform() < GUIDE_SHARE {
            let axis = axes().nth((rng.uniform() * n as f64) as usize % n).unwrap();
            hg_sample(g, &axis, rng.uniform(), rng.uniform())
        } else {
            hg_sample(g, w_in, rng.uniform(), rng.uniform())
        };
        let p = hg_eval(g, w_in.dot(&dir));
        let q: f64 = axes().map(|a| hg_eval(g, a.dot(&dir))).sum::<f64>() / n as f64;
        (dir, p / ((1.0 - GUIDE_SHARE) * p + GUIDE_SHARE * q))
    }

    /// `sigma_t(x_t) e^{-tau(t)}` of `density` over the same of the sampling
    /// density, for flight `f` along `ray` marched with `jitter`; the primal
    /// is exactly 1. Marches only the steps up to the collision (`steps`
    /// is scratch).
    fn flight_ratio<R: Real>(&self, density: &Grid<R>, ray: &Ray, jitter: f64, f: &Flight, steps: &mut Vec<Step>) -> R {
        let m = f.step as usize;
        steps.clear();
        self.marcher.steps(ray, f64::INFINITY, jitter, |s| {
            steps.push(s);
            steps.len() <= m
        });
        let scale = self.medium.sigma_t_scale;
        let mut depth = R::cst(0.0);
        for s in &steps[..m] {
            depth += density.at(&ray.at(s.sample)) * scale * s.h;
        }
        let s = steps[m];
        let sigma_r = density.at(&ray.at(s.sample)) * scale;
        depth += sigma_r * (f.t - s.start);
        sigma_r / f.sigma * ((depth - f.depth) * -1.0).exp()
    }

    /// A collision distance along `ray` drawn from `sigma_t T / (1 - T_all)`
    /// over the ray's part in the medium, the weight `1 - T_all` and the
    /// collision's step; `None` if the ray meets no medium. `steps` keeps
    /// the marched steps with their extinction.
    fn forced_collision(&self, ray: &Ray, rng: &mut Rng, steps: &mut Vec<(Step, f64)>) -> Option<(f64, f64, usize)> {
        let scale = self.medium.sigma_t_scale;
        steps.clear();
        let mut depth = 0.0;
        self.marcher.steps(ray, f64::INFINITY, rng.uniform(), |s| {
            let sigma = self.density.at(&ray.at(s.sample)) * scale;
            depth += sigma * s.h;
            steps.push((s, sigma));
            depth < 800.0
        });
        if depth <= 0.0 {
            return None;
        }
        // 1 - T_all without cancellation for thin media.
        let weight = -(-depth).exp_m1();
        let target = -(-rng.uniform() * weight).ln_1p();
        let mut before = 0.0;
        for (m, (s, sigma)) in steps.iter().enumerate() {
            let after = before + sigma * s.h;
            if after >= target && *sigma > 0.0 {
                let t = s.start + ((target - before) / sigma).clamp(0.0, s.h);
                return Some((t, weight, m));
            }
            before = after;
        }
        // Rounding left the target just past the end: collide at the end of the last non-empty step.
        let m = steps.iter().rposition(|(_, sigma)| *sigma > 0.0)?;
        Some((steps[m].0.start + steps[m].0.h, weight, m))
    }
}

/// The flight of a collision at `t` in step `m` of the marched `steps`:
/// the sampling density's optical depth up to `t`, summed in step order
/// as a replay's own depth is.
fn detached_flight(steps: &[(Step, f64)], m: usize, t: f64, weight: f64) -> Flight {
    let mut depth = 0.0;
    for (s, sigma) in &steps[..m] {
        depth += sigma * s.h;
    }
    let (s, sigma) = steps[m];
    depth += sigma * (t - s.start);
    Flight { t, weight, step: m as u32, depth, sigma }
}
