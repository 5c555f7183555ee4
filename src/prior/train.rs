//! Learning the prior as an auto-decoder (Park et al., DeepSDF, 2019):
//! every training plume `i` has its own latent `z_i`, and Adam fits the
//! latents and the shared decoder weights `w` together to
//! `mean_v (D(z_i; w)_v - rho_i,v)^2 / s + penalty |z_i|^2`, with `s` the
//! mean square of the training densities (so predicting nothing scores 1).
//! The gradients are exact: the decoder's own vector-Jacobian product.
//!
//! Deterministic from the seed whatever the thread count, and resumable:
//! after every epoch the whole state (weights, latents, both Adams' moments,
//! the loss rows) is written to a checkpoint directory, and a run started
//! with the same settings continues from it, to the same bits.

use super::decoder;
use crate::error::{Error, Result};
use crate::io::npy;
use crate::model::Decoder;
use crate::optim::Adam;
use crate::rng::{Purpose, Rng};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

/// Stream index (under `Purpose::Scene`) of the initial latents; epoch `e`
/// shuffles with `STREAM + 1 + e`.
const STREAM: u64 = 0x9210_0000;

/// Slope below 0 of the last layer while training, relative
/// ([`Decoder::with_out_leak`]): otherwise most voxels' outputs die within
/// the first epochs (the loss stalls at that of predicting nothing).
pub const OUT_LEAK: f64 = 0.01;

/// How a prior is trained.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PriorSettings {
    /// Grid edge of the plumes and the decoder.
    pub res: usize,
    /// Training plumes (seeds `TRAIN_SEEDS.start ..`).
    pub plumes: usize,
    /// Passes over the training plumes.
    pub epochs: usize,
    /// Plumes per update of the weights.
    pub batch: usize,
    /// Adam step of the weights (first epoch).
    pub lr_weights: f64,
    /// Adam step of the latents (first epoch).
    pub lr_latent: f64,
    /// Both steps fall exponentially to this fraction over the epochs.
    pub lr_final: f64,
    /// Weight of `|z_i|^2` in every plume's loss.
    pub latent_penalty: f64,
    /// Standard deviation of the initial latents.
    pub latent_init_std: f64,
    /// The plumes are learned blurred by a Gaussian of this many voxels
    /// (0: as they are). Their voxel-scale detail is random, no view
    /// resolves it, and unblurred it dominates the squared loss.
    pub blur: f64,
    /// Seed of the initial weights, latents and the shuffles.
    pub seed: u64,
}

impl Default for PriorSettings {
    fn default() -> Self {
        PriorSettings {
            res: 64,
            plumes: 400,
            epochs: 100,
            batch: 8,
            lr_weights: 2e-3,
            lr_latent: 3e-2,
            lr_final: 0.05,
            latent_penalty: 1e-4,
            latent_init_std: 0.1,
            blur: 1.0,
            seed: 0,
        }
    }
}

/// One epoch's row of the loss log.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpochRow {
    /// Epoch number (1-based: the row is written after it).
    pub epoch: usize,
    /// Mean normalised density loss over the epoch's plumes (before each update).
    pub loss: f64,
    /// Root mean square of the latents' entries after the epoch.
    pub latent_rms: f64,
    /// Adam step of the weights during the epoch.
    pub lr_weights: f64,
    /// Seconds of training so far (summed over resumed runs).
    pub wall_s: f64,
}

/// Everything training produced, and everything a checkpoint holds.
#[derive(Clone, Debug)]
pub struct State {
    /// The decoder.
    pub decoder: Decoder,
    /// Its weights.
    pub w: Vec<f64>,
    /// One latent per training plume, concatenated.
    pub z: Vec<f64>,
    adam_w: Adam,
    adam_z: Adam,
    /// The loss log, one row per finished epoch.
    pub rows: Vec<EpochRow>,
}

impl State {
    /// Epochs finished.
    pub fn epochs_done(&self) -> usize {
        self.rows.len()
    }

    /// The latent of every plume.
    pub fn latents(&self) -> Vec<Vec<f64>> {
        self.z.chunks(self.decoder.latent()).map(|c| c.to_vec()).collect()
    }
}

/// The initial state of `settings`.
pub fn initial_state(settings: &PriorSettings) -> Result<State> {
    let decoder = decoder(settings.res)?;
    let w = decoder.init(settings.seed);
    let mut rng = Rng::new(settings.seed, Purpose::Scene, STREAM);
    let z: Vec<f64> =
        (0..settings.plumes * decoder.latent()).map(|_| settings.latent_init_std * rng.normal()).collect();
    let (adam_w, adam_z) = (Adam::new(w.len(), settings.lr_weights), Adam::new(z.len(), settings.lr_latent));
    Ok(State { decoder, w, z, adam_w, adam_z, rows: vec![] })
}

/// Checks the settings; the error names the first bad one.
pub fn validate(s: &PriorSettings) -> Result<()> {
    let positive = [("lr_weights", s.lr_weights), ("lr_latent", s.lr_latent), ("latent_init_std", s.latent_init_std)];
    for (name, v) in positive {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error(format!("--{}: {v} must be finite and > 0", name.replace('_', "-"))));
        }
    }
    if !(s.lr_final.is_finite() && s.lr_final > 0.0 && s.lr_final <= 1.0) {
        return Err(Error(format!("--lr-final: {} must be in (0, 1]", s.lr_final)));
    }
    if !(s.blur.is_finite() && (0.0..=8.0).contains(&s.blur)) {
        return Err(Error(format!("--blur: {} voxels must be in [0, 8]", s.blur)));
    }
    if !(s.latent_penalty.is_finite() && s.latent_penalty >= 0.0) {
        return Err(Error(format!("--latent-penalty: {} must be finite and >= 0", s.latent_penalty)));
    }
    if s.plumes == 0 || s.batch == 0 {
        return Err(Error::new("--plumes and --batch must be at least 1"));
    }
    Ok(())
}

/// Trains from `state` (fresh or resumed) towards `settings.epochs` on
/// `plumes` (`settings.plumes` grids of `res`^3, already blurred: [`targets`]), stopping early after
/// `stop_after` epochs of this call if given (a later call resumes). After
/// each epoch, `checkpoint` (if given) is written and `progress(row, eta_s)`
/// is called.
pub fn train(
    settings: &PriorSettings,
    plumes: &[Vec<f64>],
    mut state: State,
    checkpoint: Option<&Path>,
    stop_after: Option<usize>,
    progress: &mut dyn FnMut(&EpochRow, f64),
) -> Result<State> {
    validate(settings)?;
    let n_vox = settings.res.pow(3);
    if plumes.len() != settings.plumes || plumes.iter().any(|p| p.len() != n_vox) {
        return Err(Error(format!("prior training: need {} plumes of {n_vox} voxels", settings.plumes)));
    }
    let d = state.decoder.clone().with_out_leak(OUT_LEAK);
    let latent = d.latent();
    let mask = vec![true; n_vox];
    // Predicting nothing scores 1.
    let scale =
        plumes.iter().map(|p| p.iter().map(|v| v * v).sum::<f64>()).sum::<f64>() / (settings.plumes * n_vox) as f64;
    let norm = 1.0 / (n_vox as f64 * scale.max(f64::MIN_POSITIVE));
    let started = Instant::now();
    let wall_before = state.rows.last().map_or(0.0, |r| r.wall_s);
    let first = state.epochs_done();
    let last = stop_after.map_or(settings.epochs, |n| (first + n).min(settings.epochs));
    for epoch in first..last {
        let decay = settings.lr_final.powf(epoch as f64 / settings.epochs.max(1) as f64);
        state.adam_w.lr = settings.lr_weights * decay;
        state.adam_z.lr = settings.lr_latent * decay;
        let mut order: Vec<usize> = (0..settings.plumes).collect();
        let mut rng = Rng::new(settings.seed, Purpose::Scene, STREAM + 1 + epoch as u64);
        for i in (1..order.len()).rev() {
            order.swap(i, rng.below(i as u64 + 1) as usize);
        }
        let mut loss_sum = 0.0;
        for batch in order.chunks(settings.batch) {
            let mut gw_sum = vec![0.0; state.w.len()];
            for &i in batch {
                let zi = state.z[i * latent..(i + 1) * latent].to_vec();
                let mut loss = 0.0;
                let (_, mut gz, gw) = d.forward_backward(&zi, &state.w, &mask, |out| {
                    let resid: Vec<f64> = out.iter().zip(&plumes[i]).map(|(a, b)| a - b).collect();
                    loss = resid.iter().map(|r| r * r).sum::<f64>() * norm;
                    resid.iter().map(|r| 2.0 * r * norm).collect()
                });
                loss_sum += loss;
                gz.iter_mut().zip(&zi).for_each(|(g, z)| *g += 2.0 * settings.latent_penalty * z);
                let index: Vec<usize> = (i * latent..(i + 1) * latent).collect();
                state.adam_z.step_sparse(&mut state.z, &index, &gz);
                gw_sum.iter_mut().zip(&gw).for_each(|(s, g)| *s += g / batch.len() as f64);
            }
            state.adam_w.step(&mut state.w, &gw_sum);
        }
        let row = EpochRow {
            epoch: epoch + 1,
            loss: loss_sum / settings.plumes as f64,
            latent_rms: (state.z.iter().map(|v| v * v).sum::<f64>() / state.z.len().max(1) as f64).sqrt(),
            lr_weights: state.adam_w.lr,
            wall_s: wall_before + started.elapsed().as_secs_f64(),
        };
        state.rows.push(row.clone());
        if let Some(dir) = checkpoint {
            save_checkpoint(settings, &state, dir)?;
        }
        let done = epoch + 1 - first;
        let eta = started.elapsed().as_secs_f64() / done as f64 * (settings.epochs - epoch - 1) as f64;
        progress(&row, eta);
    }
    Ok(state)
}

/// The training targets: `plumes` (`res`^3 each) blurred by `settings.blur` voxels.
pub fn targets(settings: &PriorSettings, plumes: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    if settings.blur <= 0.0 {
        return plumes;
    }
    let r = settings.res;
    let lo = crate::math::Vec3::from_element(-0.5);
    plumes
        .into_iter()
        .map(|p| {
            crate::volume::blur::gaussian_blur(&crate::volume::Grid::new(lo, -lo, [r, r, r], p), settings.blur).data
        })
        .collect()
}

/// Fits only a latent to `target` (a `res`^3 density) with the weights
/// fixed, from `z0`, by `steps` Adam steps of size `lr` on the training
/// loss (normalised by `target`'s own mean square) plus `penalty |z|^2`:
/// how well the prior represents a plume it was not trained on, the best a
/// reconstruction through the renderer could do. Returns the latent and its
/// normalised loss.
pub fn fit_latent(
    decoder: &Decoder,
    w: &[f64],
    target: &[f64],
    z0: &[f64],
    steps: usize,
    lr: f64,
    penalty: f64,
) -> (Vec<f64>, f64) {
    let mask = vec![true; target.len()];
    let norm = 1.0 / (target.iter().map(|v| v * v).sum::<f64>()).max(f64::MIN_POSITIVE);
    let mut z = z0.to_vec();
    let mut adam = Adam::new(z.len(), lr);
    let loss =
        |z: &[f64]| decoder.forward(z, w, &mask).iter().zip(target).map(|(a, b)| (a - b).powi(2)).sum::<f64>() * norm;
    for _ in 0..steps {
        let (_, mut gz, _) = decoder
            .forward_backward(&z, w, &mask, |out| out.iter().zip(target).map(|(a, b)| 2.0 * (a - b) * norm).collect());
        gz.iter_mut().zip(&z).for_each(|(g, z)| *g += 2.0 * penalty * z);
        adam.step(&mut z, &gz);
    }
    let l = loss(&z);
    (z, l)
}

/// What `checkpoint.json` holds beside the arrays.
#[derive(Serialize, Deserialize)]
struct CheckpointFile {
    settings: PriorSettings,
    rows: Vec<EpochRow>,
}

/// The arrays of a checkpoint, by file name.
fn arrays(state: &State) -> Vec<(&'static str, Vec<f64>)> {
    let (mw, vw, tw) = state.adam_w.state();
    let (mz, vz, tz) = state.adam_z.state();
    let f = |t: &[u32]| t.iter().map(|&x| x as f64).collect::<Vec<f64>>();
    vec![
        ("w", state.w.clone()),
        ("z", state.z.clone()),
        ("adam_w_m", mw.to_vec()),
        ("adam_w_v", vw.to_vec()),
        ("adam_w_t", f(tw)),
        ("adam_z_m", mz.to_vec()),
        ("adam_z_v", vz.to_vec()),
        ("adam_z_t", f(tz)),
    ]
}

/// Writes `state` into `dir` (exact float64 arrays and `checkpoint.json`),
/// replacing what was there only once the new one is complete: it is
/// written beside `dir` (`checkpoint.json` last), then swapped in by two
/// renames. A run killed between them leaves no `dir` but the complete new
/// one beside it, which [`load_checkpoint`] then reads.
pub fn save_checkpoint(settings: &PriorSettings, state: &State, dir: &Path) -> Result<()> {
    let (tmp, old) = (dir.with_extension("tmp"), dir.with_extension("old"));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp)?;
    for (name, data) in arrays(state) {
        npy::write_f64(&tmp.join(format!("{name}.npy")), &[data.len()], &data)?;
    }
    let file = CheckpointFile { settings: settings.clone(), rows: state.rows.clone() };
    let text = serde_json::to_string_pretty(&file).map_err(|e| Error(e.to_string()))?;
    std::fs::write(tmp.join("checkpoint.json"), text)?;
    let _ = std::fs::remove_dir_all(&old);
    if dir.exists() {
        std::fs::rename(dir, &old)?;
    }
    std::fs::rename(&tmp, dir)?;
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// The state saved in `dir` by a run with the same `settings`; `None` if
/// there is no checkpoint, an error if it was made with other settings or
/// is damaged.
pub fn load_checkpoint(settings: &PriorSettings, dir: &Path) -> Result<Option<State>> {
    let beside = dir.with_extension("tmp");
    // A save killed between its two renames left the complete new checkpoint beside `dir`.
    let dir = if !dir.exists() && beside.join("checkpoint.json").exists() { beside.as_path() } else { dir };
    let json = dir.join("checkpoint.json");
    if !json.exists() {
        return Ok(None);
    }
    let fail = |msg: String| Error(format!("checkpoint {}: {msg}", dir.display()));
    let text = std::fs::read_to_string(&json).map_err(|e| fail(format!("cannot read: {e}")))?;
    let file: CheckpointFile = serde_json::from_str(&text).map_err(|e| fail(format!("damaged: {e}")))?;
    let mut same = file.settings.clone();
    same.epochs = settings.epochs; // more epochs may be asked of a finished run
    if same != *settings {
        return Err(fail("made with other settings; delete it or run with the same settings".into()));
    }
    let mut state = initial_state(settings)?;
    let read = |name: &str, n: usize| -> Result<Vec<f64>> {
        let a = npy::read(&dir.join(format!("{name}.npy")), "checkpoint")?;
        if a.data.len() != n {
            return Err(fail(format!("{name}.npy has {} values, expected {n}", a.data.len())));
        }
        Ok(a.data)
    };
    let (nw, nz) = (state.w.len(), state.z.len());
    state.w = read("w", nw)?;
    state.z = read("z", nz)?;
    let t = |v: Vec<f64>| v.into_iter().map(|x| x as u32).collect::<Vec<u32>>();
    let adam = |m, v, tt, lr| Adam::resume(lr, m, v, t(tt)).ok_or_else(|| fail("Adam moments differ in length".into()));
    state.adam_w = adam(read("adam_w_m", nw)?, read("adam_w_v", nw)?, read("adam_w_t", nw)?, settings.lr_weights)?;
    state.adam_z = adam(read("adam_z_m", nz)?, read("adam_z_v", nz)?, read("adam_z_t", nz)?, settings.lr_latent)?;
    state.rows = file.rows;
    Ok(Some(state))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> (PriorSettings, Vec<Vec<f64>>) {
        let s = PriorSettings { res: 8, plumes: 3, epochs: 4, batch: 2, ..PriorSettings::default() };
        let plumes = (0..3)
            .map(|i| (0..512).map(|v| if (v + i) % 7 == 0 { 0.3 + 0.1 * i as f64 } else { 0.0 }).collect())
            .collect();
        (s, plumes)
    }

    #[test]
    fn the_loss_falls_and_a_resumed_run_ends_on_the_same_bits() {
        let (s, plumes) = tiny();
        let whole = train(&s, &plumes, initial_state(&s).unwrap(), None, None, &mut |_, _| {}).unwrap();
        assert!(whole.rows[3].loss < whole.rows[0].loss, "{:?}", whole.rows);
        let dir = std::env::temp_dir().join(format!("dualphoton-ckpt-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        train(&s, &plumes, initial_state(&s).unwrap(), Some(&dir), Some(2), &mut |_, _| {}).unwrap();
        let resumed = load_checkpoint(&s, &dir).unwrap().unwrap();
        assert_eq!(resumed.epochs_done(), 2);
        let end = train(&s, &plumes, resumed, None, None, &mut |_, _| {}).unwrap();
        assert_eq!(end.w, whole.w);
        assert_eq!(end.z, whole.z);
        let other = PriorSettings { seed: 9, ..s.clone() };
        assert!(load_checkpoint(&other, &dir).unwrap_err().0.contains("other settings"));
        // Killed between the two renames of a save: the new checkpoint is read from beside `dir`.
        std::fs::rename(&dir, dir.with_extension("tmp")).unwrap();
        assert_eq!(
            load_checkpoint(&s, &dir).unwrap().unwrap().w,
            load_checkpoint(&s, &dir.with_extension("tmp")).unwrap().unwrap().w
        );
        assert_eq!(load_checkpoint(&s, &dir).unwrap().unwrap().epochs_done(), 2);
        let _ = std::fs::remove_dir_all(dir.with_extension("tmp"));
    }
}
