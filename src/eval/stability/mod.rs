//! Numerical stability on stiff and extreme cases, shared by the
//! `stability` study and the tests: a zoo of small scenes each pushed to one
//! extreme ([`cases()`]), invalid scenes that must be rejected
//! ([`invalid_cases`]), and the checks of one case ([`check`]).
//!
//! Every case is the base scene ([`Settings::base`]: an 8^3 blob, two small
//! cameras, a few thousand photons) with one change.

pub mod cases;
pub mod check;

pub use cases::{cases, invalid_cases, Case, InvalidCase};
pub use check::{check_case, check_invalid, FD_TOL, FLOOR, FWD_REV_TOL};

use crate::eval::energy::EnergySettings;
use crate::eval::scenes::one_light_blob;
use crate::scene::Scene;
use serde::Serialize;
use std::path::Path;

/// Sizes of one run.
#[derive(Clone, Debug, Serialize)]
pub struct Settings {
    /// Grid edge of the base blob (voxels).
    pub grid: usize,
    /// Image edge of the two case cameras (pixels).
    pub res: usize,
    /// Photons per case.
    pub photons: u64,
    /// Cameras on the sphere of the energy check.
    pub energy_cameras: usize,
    /// Image edge of those cameras (pixels).
    pub energy_res: usize,
    /// Photons of the energy check.
    pub energy_photons: u64,
    /// Scattering orders of the energy check (the remainder beyond is bounded).
    pub energy_order: u32,
    /// Seed of every random stream (photons, pixels, gradient directions).
    pub seed: u64,
}

impl Settings {
    /// The study's sizes, or smaller images, fewer photons and cameras with `smoke`.
    pub fn new(smoke: bool, seed: u64) -> Self {
        let (res, photons, energy_cameras, energy_res, energy_photons, energy_order) =
            if smoke { (8, 800, 48, 8, 3000, 12) } else { (16, 3000, 96, 12, 6000, 16) };
        Settings { grid: 8, res, photons, energy_cameras, energy_res, energy_photons, energy_order, seed }
    }

    /// The sizes of the energy check.
    pub fn energy(&self) -> EnergySettings {
        EnergySettings {
            cameras: self.energy_cameras,
            res: self.energy_res,
            photons: self.energy_photons,
            order: self.energy_order,
        }
    }

    /// The base scene: the blob lit by one light, seen by two cameras (front
    /// and side), orders 1-3 ([`one_light_blob`]), at these sizes and seed.
    pub fn base(&self) -> Scene {
        let mut scene = one_light_blob(self.grid, self.res);
        scene.render.photons = self.photons;
        scene.render.seed = self.seed;
        scene
    }
}

/// Which list a case comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// An extreme but valid scene.
    Extreme,
    /// An invalid scene.
    Invalid,
}

impl Kind {
    /// The report's name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Extreme => "extreme",
            Kind::Invalid => "invalid",
        }
    }
}

/// What a case showed (`None`: not measured for this kind of case).
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The case's name.
    pub case: String,
    /// Extreme or invalid.
    pub kind: Kind,
    /// Every check passed.
    pub passed: bool,
    /// Images finite and >= 0.
    pub values_finite: Option<bool>,
    /// Loss and every derivative finite.
    pub derivatives_finite: Option<bool>,
    /// Largest relative error of forward mode against finite differences at the probes.
    pub fd_rel_error: Option<f64>,
    /// Largest relative error of forward against reverse mode at the probes.
    pub fwd_rev_error: Option<f64>,
    /// Power into first collisions (W), see [`Energy`](crate::eval::energy::Energy).
    pub energy_in: Option<f64>,
    /// Single-scattered power leaving the volume (W).
    pub energy_single_out: Option<f64>,
    /// What single scattering should send out (W).
    pub energy_single_expected: Option<f64>,
    /// Power leaving the volume, all orders checked (W).
    pub energy_out: Option<f64>,
    /// Wall time of the case (s).
    pub seconds: f64,
    /// What went wrong, or what to know about the case.
    pub note: String,
}

impl Outcome {
    fn new(case: &str, kind: Kind) -> Self {
        Outcome {
            case: case.into(),
            kind,
            passed: false,
            values_finite: None,
            derivatives_finite: None,
            fd_rel_error: None,
            fwd_rev_error: None,
            energy_in: None,
            energy_single_out: None,
            energy_single_expected: None,
            energy_out: None,
            seconds: 0.0,
            note: String::new(),
        }
    }
}

/// Runs every extreme case, then every invalid one (scene files go to
/// `scratch`), in order; `progress` sees each outcome as it comes.
pub fn run_all(s: &Settings, scratch: &Path, progress: &mut dyn FnMut(&Outcome)) -> Vec<Outcome> {
    let mut out = vec![];
    for case in cases(s) {
        out.push(check_case(&case, s));
        progress(&out[out.len() - 1]);
    }
    for case in invalid_cases(s) {
        out.push(check_invalid(&case, scratch));
        progress(&out[out.len() - 1]);
    }
    out
}
