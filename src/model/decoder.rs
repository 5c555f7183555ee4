//! The decoder `D(z; w)`: latent -> linear layer -> `4^3 x C0` grid ->
//! transposed 3-D convolutions (kernel 4, stride 2, padding 1, each doubling
//! the edge) -> one-channel density grid, ReLU, times a fixed output scale.
//! Owns the architecture, the flat parameter layout, its description and the
//! initialisation; the passes that evaluate it are in `passes`.
//!
//! Layout conventions. Grids are (Z, Y, X) C order with channels last:
//! value `(z, y, x, c)` of a grid with edge `n` and `C` channels is at
//! `((z * n + y) * n + x) * C + c`. The parameter vector `w` holds, in this
//! order: the linear weights `[j][k]` (`j` = base-grid value index, `k` =
//! latent index), the linear biases `[j]`, then per transposed convolution its
//! weights `[kz][ky][kx][ci][co]` and its biases `[co]`.

use super::conv::{Conv, TAPS};
use super::layout::Plans;
use crate::bail;
use crate::error::Result;
use crate::rng::{Purpose, Rng};

pub use super::conv::LEAKY_SLOPE;

/// Edge of the grid the linear layer produces (voxels).
pub const BASE: usize = 4;
/// Density (extinction, per unit length) per unit of the last layer's ReLU
/// output. With [`LAST_BIAS`] it sets the initial density, ~0.005.
pub const OUT_SCALE: f64 = 0.01;
/// Initial bias of the last layer: keeps its pre-activation positive at
/// the start, so that the ReLU passes gradient at almost every voxel.
pub const LAST_BIAS: f64 = 0.5;
/// Initial weight std of the last layer relative to He (`sqrt(2 / fan_in)`):
/// the pre-activation noise (~0.15) stays small against [`LAST_BIAS`], so
/// over a ball-shaped mask 98-100% of the voxels start positive (res 32 to
/// 128, 8 seeds), mean ~0.005, max 0.01-0.024 (the paper: 0.0045, 0.0209).
const LAST_GAIN: f64 = 0.12;
/// Stream index (under `Purpose::Scene`) of the linear layer's weights;
/// convolution `l` uses `STREAM + 1 + l`.
const STREAM: u64 = 0xDEC0_0000;
/// Stream index (under `Purpose::Scene`) of the initial latent.
const STREAM_LATENT: u64 = 0xDEC0_FFFF;
/// Most transposed convolutions: keeps the output at most 1024^3 voxels (so
/// that a layout's rows fit in `u32`).
const MAX_CONVS: usize = 8;

/// A latent-to-density decoder: the architecture and the layout of its flat
/// parameter vector (the parameters themselves are passed to every call, so
/// the same decoder serves `f64`, dual and reverse-mode evaluations).
#[derive(Clone, Debug)]
pub struct Decoder {
    /// Size of the latent `z`.
    pub(super) latent: usize,
    /// Output edge (voxels); the output has `res^3` values.
    pub(super) res: usize,
    /// Channels of the base grid (the linear layer's output).
    pub(super) c0: usize,
    /// The transposed convolutions, input to output.
    pub(super) convs: Vec<Conv>,
    /// Density per unit of the last ReLU's output.
    pub(super) out_scale: f64,
    /// Length of the parameter vector.
    pub(super) n_params: usize,
    /// Slope of the last layer below 0, relative (0: ReLU, the density
    /// model; > 0 only while a prior is trained).
    pub(super) out_leak: f64,
    /// The layouts of the last mask evaluated.
    pub(super) plans: Plans,
}

impl Decoder {
    /// A decoder from a latent of size `latent` to a `res^3` density grid.
    /// `channels[l]` is the channel count of the grid fed into transposed
    /// convolution `l`: `channels[0]` = `C0`, the base grid's, the rest the
    /// outputs of every convolution before the last (the last has 1 output
    /// channel). So there are `channels.len()` convolutions and `res` must be
    /// `4 * 2^channels.len()`.
    ///
    /// ```
    /// let d = dualphoton::model::Decoder::new(64, 16, &[4, 8]).unwrap();
    /// assert_eq!(d.res(), 16);
    /// assert!(dualphoton::model::Decoder::new(64, 24, &[4, 8]).is_err());
    /// ```
    pub fn new(latent: usize, res: usize, channels: &[usize]) -> Result<Decoder> {
        if latent == 0 {
            bail!("decoder.latent: must be at least 1");
        }
        if channels.is_empty() {
            bail!("decoder.channels: need at least one entry (C0; one transposed convolution)");
        }
        if let Some(l) = channels.iter().position(|&c| c == 0) {
            bail!("decoder.channels[{l}]: 0 channels");
        }
        let layers = channels.len();
        if layers > MAX_CONVS || res != BASE << layers {
            bail!(
                "decoder.res: {res} is not {BASE} * 2^{layers} = {} ({layers} channel entries = {layers} transposed convolutions)",
                BASE.checked_shl(layers as u32).unwrap_or(0)
            );
        }
        let c0 = channels[0];
        let mut off = latent * BASE.pow(3) * c0 + BASE.pow(3) * c0;
        let mut convs = Vec::with_capacity(layers);
        for l in 0..layers {
            let c_in = channels[l];
            let c_out = channels.get(l + 1).copied().unwrap_or(1);
            let conv = Conv { n: BASE << l, c_in, c_out, w_off: off, b_off: off + TAPS * c_in * c_out };
            off += conv.params();
            convs.push(conv);
        }
        Ok(Decoder {
            latent,
            res,
            c0,
            convs,
            out_scale: OUT_SCALE,
            n_params: off,
            out_leak: 0.0,
            plans: Plans::default(),
        })
    }

    /// The default decoder for a `res^3` grid (`res` = 4 * 2^L with
    /// 1 <= L <= 8: 8, 16, 32, ..., 1024): a 64-d latent, `C0 = 4` base
    /// channels, and per intermediate grid of edge `e` 16 channels if
    /// `e <= 8`, 8 if `e == 16`, 4 if `e >= 32`. About 30k parameters at res
    /// 32..128, most of them in the linear layer.
    ///
    /// Errors if `res` is not one of those edges.
    ///
    /// ```
    /// use dualphoton::model::Decoder;
    /// let d = Decoder::paper_small(32)?;
    /// assert_eq!(d.param_count(), 29465);
    /// assert!(Decoder::paper_small(24).is_err());
    /// # Ok::<(), dualphoton::error::Error>(())
    /// ```
    pub fn paper_small(res: usize) -> Result<Decoder> {
        if !(res.is_power_of_two() && (2 * BASE..=BASE << MAX_CONVS).contains(&res)) {
            bail!(
                "the decoder needs a cubic grid of {BASE} * 2^n voxels per side (8, 16, 32, 64, 128, ..., {}), got {res}",
                BASE << MAX_CONVS
            );
        }
        let mut channels = vec![4];
        let mut e = 2 * BASE;
        while e < res {
            channels.push(match e {
                0..=8 => 16,
                16 => 8,
                _ => 4,
            });
            e *= 2;
        }
        Decoder::new(64, res, &channels)
    }

    /// The same decoder with `scale` density per unit of the last ReLU's
    /// output (a prior that must reach the densest voxels of many plumes
    /// wants a larger one than [`OUT_SCALE`]).
    pub fn with_out_scale(mut self, scale: f64) -> Decoder {
        self.out_scale = scale;
        self
    }

    /// The same decoder with a leaky last layer (`leak` times the slope
    /// below 0; 0 gives back the ReLU). With a ReLU, a voxel whose output
    /// is pushed below 0 early in training gets no gradient again; a prior
    /// trained on mostly empty plumes loses every voxel that way. A prior is
    /// trained leaky and used with the ReLU, which differs only where the
    /// leaky output is negative (there the density is 0).
    pub fn with_out_leak(mut self, leak: f64) -> Decoder {
        self.out_leak = leak;
        self
    }

    /// The last layer's activation.
    pub(super) fn out_act(&self) -> super::conv::Act {
        if self.out_leak > 0.0 {
            super::conv::Act::LeakyScaled(self.out_scale, self.out_leak)
        } else {
            super::conv::Act::ReluScaled(self.out_scale)
        }
    }

    /// Values of the base grid (`4^3 x C0`): the linear layer's rows.
    pub fn base_values(&self) -> usize {
        BASE.pow(3) * self.c0
    }

    /// The `channels` argument of [`Decoder::new`] that made this decoder.
    pub fn channels(&self) -> Vec<usize> {
        self.convs.iter().map(|c| c.c_in).collect()
    }

    /// Size of the latent `z`.
    pub fn latent(&self) -> usize {
        self.latent
    }

    /// Output edge: the output grid has `res^3` voxels.
    pub fn res(&self) -> usize {
        self.res
    }

    /// Density per unit of the last layer's ReLU output.
    pub fn out_scale(&self) -> f64 {
        self.out_scale
    }

    /// Length of the parameter vector `w`.
    pub fn param_count(&self) -> usize {
        self.n_params
    }

    /// One line per layer with its input and output shapes and parameter
    /// count, and a total line.
    pub fn describe(&self) -> String {
        let n0 = BASE.pow(3) * self.c0;
        let mut s = format!(
            "linear   z {} -> {BASE}^3 x {}   params {} (w {}, b {n0}), LeakyReLU {LEAKY_SLOPE}\n",
            self.latent,
            self.c0,
            self.latent * n0 + n0,
            self.latent * n0
        );
        for (l, c) in self.convs.iter().enumerate() {
            let last = l + 1 == self.convs.len();
            s += &format!(
                "tconv {}  {}^3 x {} -> {}^3 x {}   params {} (w {}, b {}), {}\n",
                l + 1,
                c.n,
                c.c_in,
                2 * c.n,
                c.c_out,
                c.params(),
                TAPS * c.c_in * c.c_out,
                c.c_out,
                if last && self.out_leak > 0.0 {
                    format!("LeakyReLU {} x {}", self.out_leak, self.out_scale)
                } else if last {
                    format!("ReLU x {}", self.out_scale)
                } else {
                    format!("LeakyReLU {LEAKY_SLOPE}")
                }
            );
        }
        s += &format!("total    {} params", self.n_params);
        s
    }

    /// Initial parameters, deterministic from `seed`: He-normal weights (std
    /// `sqrt(2 / fan_in)`, fan_in = latent for the linear layer and
    /// `C_in * 8` effective taps for a transposed convolution), zero biases,
    /// except the last layer: weights at `LAST_GAIN` = 0.12 times He and bias
    /// [`LAST_BIAS`], so the initial density (with [`Decoder::init_latent`])
    /// is about `LAST_BIAS * OUT_SCALE` = 0.005 plus noise, positive almost
    /// everywhere.
    pub fn init(&self, seed: u64) -> Vec<f64> {
        let mut w = vec![0.0; self.n_params];
        let n0 = BASE.pow(3) * self.c0;
        let mut rng = Rng::new(seed, Purpose::Scene, STREAM);
        let std = (2.0 / self.latent as f64).sqrt();
        for v in &mut w[..self.latent * n0] {
            *v = std * rng.normal();
        }
        for (l, c) in self.convs.iter().enumerate() {
            let last = l + 1 == self.convs.len();
            let mut rng = Rng::new(seed, Purpose::Scene, STREAM + 1 + l as u64);
            let std = (2.0 / (c.c_in * 8) as f64).sqrt() * if last { LAST_GAIN } else { 1.0 };
            for v in &mut w[c.w_off..c.b_off] {
                *v = std * rng.normal();
            }
            if last {
                w[c.b_off] = LAST_BIAS;
            }
        }
        w
    }

    /// An initial latent, deterministic from `seed`: standard normal entries.
    pub fn init_latent(&self, seed: u64) -> Vec<f64> {
        let mut rng = Rng::new(seed, Purpose::Scene, STREAM_LATENT);
        (0..self.latent).map(|_| rng.normal()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ball;

    #[test]
    fn init_is_deterministic_and_small_positive_in_the_mask() {
        let d = Decoder::paper_small(32).unwrap();
        assert_eq!(d.init(7), d.init(7));
        assert_ne!(d.init(7), d.init(8));
        assert_eq!(d.init_latent(7), d.init_latent(7));
        let mask = ball(32, 12.0);
        let n = mask.iter().filter(|&&m| m).count() as f64;
        for seed in 0..4 {
            let rho = d.forward(&d.init_latent(seed), &d.init(seed), &mask);
            let inside: Vec<f64> = rho.iter().zip(&mask).filter(|(_, &m)| m).map(|(&r, _)| r).collect();
            let pos = inside.iter().filter(|&&r| r > 0.0).count() as f64 / n;
            let mean = inside.iter().sum::<f64>() / n;
            let max = inside.iter().fold(0.0f64, |a, &r| a.max(r));
            eprintln!("seed {seed}: positive {pos:.4} mean {mean:.5} max {max:.5}");
            assert!(pos > 0.95, "seed {seed}: only {pos} positive");
            assert!((0.002..=0.01).contains(&mean), "seed {seed}: mean {mean}");
        }
    }

    #[test]
    fn bad_shapes_are_errors_and_counts_are_known() {
        assert!(Decoder::new(64, 64, &[4, 16, 8]).is_err());
        assert!(Decoder::new(64, 48, &[4, 16]).is_err());
        assert!(Decoder::new(0, 8, &[4]).is_err());
        assert!(Decoder::new(64, 8, &[]).is_err());
        assert!(Decoder::new(64, 16, &[4, 0]).is_err());
        assert_eq!(Decoder::paper_small(32).unwrap().param_count(), 29465);
        assert_eq!(Decoder::paper_small(64).unwrap().param_count(), 31261);
        assert_eq!(Decoder::paper_small(128).unwrap().param_count(), 32289);
        let d = Decoder::paper_small(64).unwrap();
        assert_eq!(d.describe().lines().count(), 6);
        assert_eq!(d.channels(), vec![4, 16, 8, 4]);
        assert_eq!(d.init(1).len(), d.param_count());
    }

    #[test]
    fn paper_small_needs_4_times_a_power_of_two() {
        for res in [0, 1, 4, 12, 24, 48, 100, 2048, usize::MAX] {
            let e = Decoder::paper_small(res).unwrap_err().0;
            assert!(e.contains("4 * 2^n voxels per side") && e.ends_with(&format!("got {res}")), "{e}");
        }
        for res in [8, 16, 32, 64, 128, 256, 512, 1024] {
            assert_eq!(Decoder::paper_small(res).unwrap().res(), res);
        }
    }
}
