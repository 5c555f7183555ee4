//! The plumes a prior learns from: the built-in simulator with knobs drawn
//! from the training distribution ([`Variation::sample`]), one per training
//! seed, stored as float32 (so a plume read back from the cache equals a
//! freshly made one) and cached under `cache/` (git-ignored): making one
//! costs about half a second at 64^3, reading it back a millisecond.

use crate::data::plume::variation::TRAIN_SEEDS;
use crate::data::plume::{plume_with, Variation};
use crate::error::Result;
use crate::io::npy;
use std::path::{Path, PathBuf};

/// Bumped whenever the simulator or the variation changes what a seed
/// makes, so that a stale cache is never read.
pub const GENERATOR_VERSION: u32 = 1;

/// The cache directory of `res`^3 plumes under `root`.
pub fn cache_dir(root: &Path, res: usize) -> PathBuf {
    root.join(format!("plumes{res}-v{GENERATOR_VERSION}"))
}

/// The seed of training plume `i`.
pub fn training_seed(i: usize) -> u64 {
    TRAIN_SEEDS.start + i as u64
}

/// Plume `seed` at `res`^3 with its drawn variation, rounded to float32;
/// read from `cache` if there, made and written there otherwise (no cache:
/// just made).
pub fn load_or_make(res: usize, seed: u64, cache: Option<&Path>) -> Result<Vec<f64>> {
    let path = cache.map(|c| c.join(format!("seed_{seed}.npy")));
    if let Some(p) = path.as_ref().filter(|p| p.exists()) {
        if let Ok(a) = npy::read(p, "plume cache") {
            if a.data.len() == res * res * res {
                return Ok(a.data);
            }
        }
        // A truncated or foreign file: make the plume again.
    }
    let grid = plume_with(res, seed, &Variation::sample(seed))?;
    let data: Vec<f64> = grid.data.iter().map(|&v| v as f32 as f64).collect();
    if let Some(p) = path {
        std::fs::create_dir_all(p.parent().unwrap_or(Path::new(".")))?;
        // Written under a temporary name and renamed, so that a run cut off
        // mid-write leaves no half file behind.
        let tmp = p.with_extension("npy.tmp");
        npy::write_f32(&tmp, &[res, res, res], &data)?;
        std::fs::rename(&tmp, &p)?;
    }
    Ok(data)
}

/// The first `n` training plumes at `res`^3, with a progress line per plume on stderr.
pub fn training_set(res: usize, n: usize, cache: Option<&Path>) -> Result<Vec<Vec<f64>>> {
    let started = std::time::Instant::now();
    let mut set = Vec::with_capacity(n);
    for i in 0..n {
        set.push(load_or_make(res, training_seed(i), cache)?);
        let t = started.elapsed().as_secs_f64();
        let eta = t / (i + 1) as f64 * (n - i - 1) as f64;
        eprint!("\rtraining plumes: {}/{n}  {t:.0} s, ETA {eta:.0} s   ", i + 1);
    }
    eprintln!();
    Ok(set)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cached_plume_equals_a_fresh_one() {
        let dir = std::env::temp_dir().join(format!("dualphoton-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let fresh = load_or_make(12, training_seed(5), None).unwrap();
        let written = load_or_make(12, training_seed(5), Some(&dir)).unwrap();
        let read = load_or_make(12, training_seed(5), Some(&dir)).unwrap();
        assert!(dir.join(format!("seed_{}.npy", training_seed(5))).exists());
        assert_eq!((&fresh, &written), (&read, &read));
        assert!(fresh.iter().any(|&v| v > 0.0));
    }
}
