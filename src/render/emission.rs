//! Where photons leave the lights: each point light emits into the cone
//! around the occupied region, restricted by a projection map (Jensen 1996)
//! to the cone's cells whose rays cross a non-empty block. Photons are
//! spread uniformly over those cells' solid angle, so a light spends its
//! photons only on directions that can meet the medium.

use crate::math::{cone_solid_angle, direction_around, intersect_box, Ray, Vec3};
use crate::scene::Light;
use crate::volume::Majorant;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Cells per side of a projection map (equal solid angle each).
const MAP: usize = 64;
/// Test rays per cell side.
const PROBES: usize = 3;

/// How one light emits.
#[derive(Clone, Debug)]
pub struct Emitter {
    /// Light position.
    pub position: Vec3,
    /// Cone axis (unit), from the light to the occupied region's centre.
    pub axis: Vec3,
    /// Cosine of the cone's half-angle (-1: the whole sphere).
    pub cos_max: f64,
    /// Cells (`u * MAP + v`) of the cone's `MAP x MAP` map that photons use.
    pub active: Vec<u32>,
    /// Power sent into the active cells (W): intensity times their solid angle.
    pub power: f64,
}

impl Emitter {
    /// The direction of cone parameters `(u, v)` in [0, 1)^2 (equal-area: u in cos theta, v in azimuth).
    fn direction(&self, u: f64, v: f64) -> Vec3 {
        direction_around(&self.axis, 1.0 - u * (1.0 - self.cos_max), 2.0 * PI * v)
    }

    /// A direction uniform over the active cells, from three uniforms.
    pub fn sample(&self, u0: f64, u1: f64, u2: f64) -> Vec3 {
        let cell = self.active[((u0 * self.active.len() as f64) as usize).min(self.active.len() - 1)] as usize;
        self.direction(((cell / MAP) as f64 + u1) / MAP as f64, ((cell % MAP) as f64 + u2) / MAP as f64)
    }
}

/// Emitters for `lights` aimed at the occupied region of `majorant` (empty
/// if nothing is occupied). Lights of zero intensity get zero power.
pub fn emitters(lights: &[Light], majorant: &Majorant, lo: &Vec3, hi: &Vec3) -> Vec<Emitter> {
    let Some((olo, ohi)) = majorant.occupied_bounds() else {
        return vec![];
    };
    let centre = (olo + ohi) * 0.5;
    let radius = (ohi - olo).norm() * 0.5;
    lights
        .iter()
        .map(|l| {
            let to = centre - l.position;
            let d = to.norm();
            let (axis, cos_max) = if d <= radius * 1.000001 {
                (Vec3::new(0.0, 0.0, 1.0), -1.0)
            } else {
                (to / d, (1.0 - (radius / d).powi(2)).max(0.0).sqrt())
            };
            let mut e = Emitter { position: l.position, axis, cos_max, active: vec![], power: 0.0 };
            if l.intensity > 0.0 {
                e.active = active_cells(&e, majorant, lo, hi);
                e.power = l.intensity * cone_solid_angle(cos_max) * e.active.len() as f64 / (MAP * MAP) as f64;
            }
            e
        })
        .collect()
}

/// The cells some probe ray of which crosses a non-empty block, dilated by
/// one cell so that features thinner than the probe spacing are kept.
fn active_cells(e: &Emitter, majorant: &Majorant, lo: &Vec3, hi: &Vec3) -> Vec<u32> {
    let hits = |u: f64, v: f64| {
        let ray = Ray { origin: e.position, dir: e.direction(u, v) };
        let Some((t0, t1)) = intersect_box(&ray, lo, hi) else { return false };
        let mut hit = false;
        majorant.walk(&ray, t0, t1, |_, _, bound| {
            hit = bound > 0.0;
            !hit
        });
        hit
    };
    // Every cell is probed on its own: in parallel, the same marks for any number of threads.
    let mark: Vec<bool> = (0..MAP * MAP)
        .into_par_iter()
        .with_min_len(MAP)
        .with_max_len(MAP)
        .map(|cell| {
            let (cu, cv) = ((cell / MAP) as f64, (cell % MAP) as f64);
            (0..PROBES * PROBES).any(|s| {
                let (a, b) = ((s / PROBES) as f64 + 0.5, (s % PROBES) as f64 + 0.5);
                hits((cu + a / PROBES as f64) / MAP as f64, (cv + b / PROBES as f64) / MAP as f64)
            })
        })
        .collect();
    let mut dilated = vec![false; MAP * MAP];
    for cu in 0..MAP {
        for cv in 0..MAP {
            if mark[cu * MAP + cv] {
                for du in -1i64..=1 {
                    let u = cu as i64 + du;
                    if !(0..MAP as i64).contains(&u) {
                        continue;
                    }
                    for dv in -1i64..=1 {
                        // Azimuth wraps around.
                        let v = (cv as i64 + dv).rem_euclid(MAP as i64);
                        dilated[u as usize * MAP + v as usize] = true;
                    }
                }
            }
        }
    }
    (0..MAP * MAP).filter(|&c| dilated[c]).map(|c| c as u32).collect()
}
