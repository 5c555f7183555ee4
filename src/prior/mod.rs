//! A learned plume prior: a decoder `D(z; w)` trained on many simulated
//! plumes (an auto-decoder: one latent per training plume, fitted together
//! with the shared weights), and the distribution of its training latents.
//! Reconstructing a new plume with it means fitting only the 64-d latent
//! through the renderer, under a Gaussian penalty from that distribution:
//! the weights carry what smoke looks like, so the views need to pin down
//! only 64 numbers.
//!
//! This module owns the prior's architecture and its files; `training_set`
//! makes the plumes it learns from and `train` learns it.
//!
//! The saved decoder takes a *whitened* latent `u`: the training latents'
//! per-coordinate mean `m` and deviation `s` are folded into the linear
//! layer (`z = m + s u`), so that the training plumes' latents have mean 0
//! and deviation 1 in every coordinate. A fit then starts at `u = 0`, the
//! penalty is `|u|^2` and one Adam step size suits every coordinate.
//!
//! Files of a prior directory (e.g. `models/plume64/`):
//! - `prior.json`: format version, architecture (latent size, grid edge,
//!   channels, output scale) and the mean and standard deviation of the
//!   training latents before whitening (for the record);
//! - `weights.npy`: the decoder's parameter vector, whitened (float32);
//! - `latents.npy`: the training plumes' whitened latents (plumes x latent, float32);
//! - `manifest.json`, `loss.csv`, `loss.svg`: how it was trained.

pub mod train;
pub mod training_set;

use crate::error::{Error, Result};
use crate::io::npy;
use crate::model::Decoder;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Version of the `prior.json` format this build reads and writes.
pub const FORMAT: u32 = 1;

/// Where the committed prior lives, relative to the repository root.
pub const DEFAULT_DIR: &str = "models/plume64";

/// The project's prior: [`DEFAULT_DIR`] beside the working directory, else
/// in the source tree this was built from; an error naming both if in neither.
pub fn default_dir() -> Result<PathBuf> {
    let here = PathBuf::from(DEFAULT_DIR);
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_DIR);
    [here, built.clone()].into_iter().find(|d| d.join("prior.json").exists()).ok_or_else(|| {
        Error(format!("the default prior {DEFAULT_DIR} is in neither ./{DEFAULT_DIR} nor {}", built.display()))
    })
}

/// Latent size of the prior.
pub const LATENT: usize = 64;

/// Channels of the prior's decoder at 64^3 (base grid, then each
/// transposed convolution's input): wider than the per-scene decoder,
/// which has to learn one plume, not hundreds.
pub const CHANNELS: [usize; 4] = [64, 32, 16, 8];

/// Density per unit of the last ReLU's output: the densest voxels of the
/// training plumes (1.36) need pre-activations of ~27, not ~136.
pub const OUT_SCALE: f64 = 0.05;

/// What `prior.json` holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PriorFile {
    /// [`FORMAT`].
    pub format: u32,
    /// Latent size.
    pub latent: usize,
    /// Output grid edge (voxels).
    pub res: usize,
    /// Decoder channels (see [`Decoder::new`]).
    pub channels: Vec<usize>,
    /// Density per unit of the last ReLU's output.
    pub out_scale: f64,
    /// Mean of the training latents before whitening, per coordinate.
    pub latent_mean: Vec<f64>,
    /// Standard deviation of the training latents before whitening, per coordinate.
    pub latent_std: Vec<f64>,
}

/// A loaded prior: the decoder, its weights and the latent distribution.
#[derive(Clone, Debug)]
pub struct Prior {
    /// The architecture.
    pub decoder: Decoder,
    /// The trained weights, taking whitened latents (training latents: mean 0, deviation 1).
    pub w: Vec<f64>,
    /// Where it was loaded from.
    pub dir: PathBuf,
}

/// The prior's decoder for a `res`^3 grid.
pub fn decoder(res: usize) -> Result<Decoder> {
    let mut channels = CHANNELS.to_vec();
    // Other grids: one channel entry per doubling from the 4^3 base.
    let layers = (res.max(8) / 4).trailing_zeros() as usize;
    channels.resize(layers, *CHANNELS.last().unwrap_or(&8));
    Ok(Decoder::new(LATENT, res, &channels)?.with_out_scale(OUT_SCALE))
}

/// Largest magnitude of a prior's (whitened) weight accepted on load. The
/// shipped priors' weights stay below 2; four layers of weights of 1e30
/// decode infinite densities, and 1e3 leaves room for any trained prior.
pub const MAX_WEIGHT: f64 = 1e3;

impl Prior {
    /// Loads the prior in `dir`. Every error is one line naming the file and the problem.
    pub fn load(dir: &Path) -> Result<Prior> {
        let shown = crate::error::show(dir);
        let fail = |what: &str, msg: String| Error(format!("prior {shown}: {what}: {msg}"));
        let json = dir.join("prior.json");
        let bytes = npy::read_bounded(&json, 1 << 20).map_err(|e| fail("prior.json", e))?;
        let text = String::from_utf8(bytes).map_err(|_| fail("prior.json", "not UTF-8 text".into()))?;
        let file: PriorFile =
            serde_json::from_str(&text).map_err(|e| fail("prior.json", format!("not a prior description: {e}")))?;
        if file.format != FORMAT {
            return Err(fail("prior.json", format!("format {} (this build reads format {FORMAT})", file.format)));
        }
        if file.latent_mean.len() != file.latent || file.latent_std.len() != file.latent {
            return Err(fail("prior.json", format!("latent statistics do not have {} entries", file.latent)));
        }
        if file.latent_std.iter().any(|s| !(s.is_finite() && *s > 0.0))
            || file.latent_mean.iter().any(|m| !m.is_finite())
        {
            return Err(fail("prior.json", "latent statistics must be finite, standard deviations > 0".into()));
        }
        if !(file.out_scale.is_finite() && file.out_scale > 0.0) {
            return Err(fail("prior.json", format!("out_scale {} must be finite and > 0", file.out_scale)));
        }
        let decoder = Decoder::new(file.latent, file.res, &file.channels)
            .map_err(|e| fail("prior.json", e.0))?
            .with_out_scale(file.out_scale);
        let weights = npy::read(&dir.join("weights.npy"), &format!("prior {shown}"))?;
        if weights.data.len() != decoder.param_count() {
            return Err(fail(
                "weights.npy",
                format!(
                    "{} values, the architecture in prior.json needs {}",
                    weights.data.len(),
                    decoder.param_count()
                ),
            ));
        }
        if weights.data.iter().any(|v| !v.is_finite()) {
            return Err(fail("weights.npy", "holds a NaN or an infinity".into()));
        }
        if let Some(n) = weights.data.iter().position(|v| v.abs() > MAX_WEIGHT) {
            return Err(fail(
                "weights.npy",
                format!(
                    "weight {n} is {:.3e}: weights must be within +-{MAX_WEIGHT:e} (a trained prior's stay below 2; \
                     larger ones decode densities that overflow)",
                    weights.data[n]
                ),
            ));
        }
        Ok(Prior { decoder, w: weights.data, dir: dir.to_path_buf() })
    }

    /// Errors unless the prior decodes a `shape` grid (cubic, its edge).
    pub fn check_grid(&self, shape: [usize; 3]) -> Result<()> {
        let r = self.decoder.res();
        if shape != [r, r, r] {
            return Err(Error(format!(
                "prior {}: decodes {r}^3 grids, the scene's grid is {}x{}x{}",
                self.dir.display(),
                shape[2],
                shape[1],
                shape[0]
            )));
        }
        Ok(())
    }

    /// Whitens `w` by the statistics of `latents` and writes `prior.json`
    /// and `weights.npy` (float32) into `dir`, and the whitened training
    /// latents (one row per plume) as `latents.npy`.
    pub fn save(decoder: &Decoder, w: &[f64], latents: &[Vec<f64>], dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir)?;
        let (mean, std) = latent_statistics(latents, decoder.latent());
        let w = whiten(decoder, w, &mean, &std);
        let latents: Vec<Vec<f64>> =
            latents.iter().map(|z| z.iter().zip(&mean).zip(&std).map(|((z, m), s)| (z - m) / s).collect()).collect();
        let file = PriorFile {
            format: FORMAT,
            latent: decoder.latent(),
            res: decoder.res(),
            channels: decoder.channels(),
            out_scale: decoder.out_scale(),
            latent_mean: mean,
            latent_std: std,
        };
        let text = serde_json::to_string_pretty(&file).map_err(|e| Error(e.to_string()))?;
        std::fs::write(dir.join("prior.json"), text + "\n")?;
        npy::write_f32(&dir.join("weights.npy"), &[w.len()], &w)?;
        let flat: Vec<f64> = latents.iter().flatten().copied().collect();
        npy::write_f32(&dir.join("latents.npy"), &[latents.len(), decoder.latent()], &flat)
    }
}

/// The weights `w'` with `D(u; w') = D(mean + std * u; w)`: the mean and
/// deviation folded into the linear layer (weights `[j][k]`, then biases `[j]`).
pub fn whiten(decoder: &Decoder, w: &[f64], mean: &[f64], std: &[f64]) -> Vec<f64> {
    let k = decoder.latent();
    let rows = decoder.base_values();
    let mut out = w.to_vec();
    let (lw, rest) = out.split_at_mut(rows * k);
    for (j, row) in lw.chunks_exact_mut(k).enumerate() {
        rest[j] += row.iter().zip(mean).map(|(a, m)| a * m).sum::<f64>();
        row.iter_mut().zip(std).for_each(|(a, s)| *a *= s);
    }
    out
}

/// Per-coordinate mean and standard deviation of `latents` (each of length
/// `n`); the deviation is floored at 1e-6 so that the penalty stays finite.
pub fn latent_statistics(latents: &[Vec<f64>], n: usize) -> (Vec<f64>, Vec<f64>) {
    let count = latents.len().max(1) as f64;
    let mean: Vec<f64> = (0..n).map(|k| latents.iter().map(|z| z[k]).sum::<f64>() / count).collect();
    let std = (0..n)
        .map(|k| (latents.iter().map(|z| (z[k] - mean[k]).powi(2)).sum::<f64>() / count).sqrt().max(1e-6))
        .collect();
    (mean, std)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("dualphoton-prior-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn saves_and_loads_and_names_what_is_wrong() {
        let dir = temp("roundtrip");
        let d = decoder(16).unwrap();
        let w: Vec<f64> = d.init(3).iter().map(|&v| v as f32 as f64).collect();
        let latents = vec![vec![1.0; LATENT], vec![3.0; LATENT]];
        Prior::save(&d, &w, &latents, &dir).unwrap();
        let p = Prior::load(&dir).unwrap();
        let m = vec![true; 16 * 16 * 16];
        let (u, z) = (vec![0.5; LATENT], vec![2.5; LATENT]); // 2 + 1 * 0.5
        let (a, b) = (p.decoder.forward(&u, &p.w, &m), d.forward(&z, &w, &m));
        assert!(
            a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-5 * (1.0 + y.abs())),
            "whitened weights decode alike"
        );
        assert!(p.check_grid([16; 3]).is_ok());
        assert!(p.check_grid([32; 3]).unwrap_err().0.contains("decodes 16^3 grids, the scene's grid is 32x32x32"));
        // A wrong weight count, a corrupt description, a missing directory.
        npy::write_f32(&dir.join("weights.npy"), &[3], &[0.0; 3]).unwrap();
        assert!(Prior::load(&dir).unwrap_err().0.contains("weights.npy: 3 values"));
        std::fs::write(dir.join("prior.json"), "{ nonsense").unwrap();
        assert!(Prior::load(&dir).unwrap_err().0.contains("prior.json: not a prior description"));
        let e = Prior::load(&temp("missing")).unwrap_err().0;
        assert!(e.contains("prior.json: cannot read") && !e.contains('\n'), "{e}");
    }

    #[test]
    fn the_prior_decoder_fits_the_paper_grid_sizes() {
        assert_eq!(decoder(64).unwrap().res(), 64);
        assert_eq!(decoder(32).unwrap().res(), 32);
        assert!(decoder(48).is_err());
    }
}
