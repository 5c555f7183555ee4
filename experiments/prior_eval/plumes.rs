//! The plumes of the evaluation and its rows: which plume, its truth, and
//! one (plume, method) row of measures, as written under `<out>/rows/`.

use dualphoton::data::plume::variation::{TEST_SEEDS, VALIDATION_SEEDS};
use dualphoton::data::plume::{plume, plume_with, unusual_plume, Unusual, Variation};
use dualphoton::error::{Error, Result};
use dualphoton::eval::density::DensityMetrics;
use dualphoton::volume::Grid;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The rows a plume can have, in table order.
pub const ROWS: [&str; 8] = [
    "paper",
    "prior",
    "prior_refine",
    "oracle_exact",
    "oracle_truth",
    "oracle_truth_refine",
    "oracle_latent",
    "oracle_latent_refine",
];

/// The blur (voxels) `train_prior` learned its plumes with (models/plume64/manifest.json).
pub const PRIOR_BLUR: f64 = 1.0;

/// One plume of the evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Which {
    Table1,
    /// The Table 1 plume, its images made by the path tracer (another renderer) instead of the photon mapper.
    PathTraced,
    Test(u64),
    Validation(u64),
    Unusual(Unusual),
}

impl Which {
    pub fn parse(name: &str) -> Result<Which> {
        let number = |prefix: &str, range: &std::ops::Range<u64>| {
            name.strip_prefix(prefix).and_then(|n| n.parse::<u64>().ok()).filter(|&n| n < range.end - range.start)
        };
        if name == "table1" {
            return Ok(Which::Table1);
        }
        if name == "table1_path" {
            return Ok(Which::PathTraced);
        }
        if let Some(n) = number("test", &TEST_SEEDS) {
            return Ok(Which::Test(n));
        }
        if let Some(n) = number("val", &VALIDATION_SEEDS) {
            return Ok(Which::Validation(n));
        }
        Unusual::ALL
            .iter()
            .find(|u| u.name() == name)
            .map(|&u| Which::Unusual(u))
            .ok_or_else(|| Error(format!("--plumes: unknown plume '{name}'")))
    }

    pub fn name(self) -> String {
        match self {
            Which::Table1 => "table1".into(),
            Which::PathTraced => "table1_path".into(),
            Which::Test(n) => format!("test{n}"),
            Which::Validation(n) => format!("val{n}"),
            Which::Unusual(u) => u.name().into(),
        }
    }

    /// `training distribution`, `unusual` or `validation`.
    pub fn group(self) -> &'static str {
        match self {
            Which::Table1 | Which::Test(_) => "training distribution",
            Which::Validation(_) => "validation",
            Which::Unusual(_) | Which::PathTraced => "unusual",
        }
    }

    pub fn seed(self) -> u64 {
        match self {
            Which::Table1 | Which::PathTraced => 0,
            Which::Test(n) => TEST_SEEDS.start + n,
            Which::Validation(n) => VALIDATION_SEEDS.start + n,
            Which::Unusual(u) => u.seed(),
        }
    }

    pub fn truth(self, res: usize) -> Result<Grid<f64>> {
        match self {
            Which::Table1 | Which::PathTraced => Ok(plume(res, 0)),
            Which::Test(_) | Which::Validation(_) => plume_with(res, self.seed(), &Variation::sample(self.seed())),
            Which::Unusual(u) => Ok(unusual_plume(res, u)),
        }
    }
}

/// One (plume, method) result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    pub plume: String,
    pub group: String,
    pub method: String,
    pub hull_voxels: usize,
    /// Voxels of the hull the fit ran in (None in rows written before it was recorded: the default hull).
    #[serde(default)]
    pub fit_hull_voxels: Option<usize>,
    /// Fraction of the truth's mass outside the fit's hull (None in rows written before it was recorded).
    #[serde(default)]
    pub carved_mass: Option<f64>,
    pub block_pearson_r: f64,
    pub block_rel_l1_epsilon: f64,
    pub block_max_error: f64,
    pub pearson_r: f64,
    pub rel_l1_epsilon: f64,
    pub max_error: f64,
    pub mass_error: f64,
    pub held_out_rel_rmse: f64,
    pub blur_ceiling_r: f64,
    /// Fraction of the truth's mass in voxels the estimate leaves at 0 (None in rows written before it was recorded).
    #[serde(default)]
    pub empty_truth_mass: Option<f64>,
    /// Fraction of the estimate's mass in voxels where the truth is 0 (None in rows written before it was recorded).
    #[serde(default)]
    pub haze_mass: Option<f64>,
    pub wall_s: f64,
    pub updates: usize,
}

impl Row {
    pub fn new(
        which: Which,
        method: &str,
        m: &DensityMetrics,
        fit: &FitHull,
        held: f64,
        wall_s: f64,
        updates: usize,
    ) -> Row {
        Row {
            plume: which.name(),
            group: which.group().into(),
            method: method.into(),
            hull_voxels: m.hull_voxels,
            fit_hull_voxels: Some(fit.voxels),
            carved_mass: Some(fit.carved_mass),
            block_pearson_r: m.block_pearson_r,
            block_rel_l1_epsilon: m.block_rel_l1_epsilon,
            block_max_error: m.block_max_error,
            pearson_r: m.pearson_r,
            rel_l1_epsilon: m.rel_l1_epsilon,
            max_error: m.max_error,
            mass_error: m.mass_error,
            held_out_rel_rmse: held,
            blur_ceiling_r: m.blur_ceiling_r,
            empty_truth_mass: Some(m.empty_truth_mass),
            haze_mass: Some(m.haze_mass),
            wall_s,
            updates,
        }
    }
}

/// The hull a fit ran in: its voxels and the fraction of the truth's mass it carved away.
pub struct FitHull {
    pub voxels: usize,
    pub carved_mass: f64,
}

/// Where the measures are taken: the default hull, joined with the fit's
/// own hull `fit_mask` (the same for the default settings). One region for
/// every hull setting keeps the measures comparable: an estimate is 0
/// outside its hull, so mass a tighter hull carves away counts as error.
pub fn measured_region(default_hull: &[bool], fit_mask: &[bool], truth: &Grid<f64>) -> (Vec<bool>, FitHull) {
    let region = default_hull.iter().zip(fit_mask).map(|(&a, &b)| a || b).collect();
    let total: f64 = truth.data.iter().sum();
    let outside: f64 = truth.data.iter().zip(fit_mask).filter(|(_, &m)| !m).map(|(v, _)| v).sum();
    let carved_mass = if total > 0.0 { outside / total } else { 0.0 };
    (region, FitHull { voxels: fit_mask.iter().filter(|&&m| m).count(), carved_mass })
}

/// The rows of `plumes` found in `dir`, in plume then method order.
pub fn read_rows(dir: &Path, plumes: &[Which]) -> Result<Vec<Row>> {
    let mut rows = vec![];
    for which in plumes {
        for method in ROWS {
            let path = dir.join(format!("{}_{method}.json", which.name()));
            if let Ok(text) = std::fs::read_to_string(&path) {
                let row: Row =
                    serde_json::from_str(&text).map_err(|e| Error(format!("{}: damaged: {e}", path.display())))?;
                rows.push(row);
            }
        }
    }
    Ok(rows)
}
