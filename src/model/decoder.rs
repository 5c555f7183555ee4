//! The decoder `D(z; w)`: latent -> linear layer -> `4^3 x C0` grid ->
//! transposed 3-D convolutions (kernel 4, stride 2, padding 1, each doubling
//! the edge) -> one-channel density grid, ReLU, times a fixed output scale.
//! Owns the architecture, the flat parameter layout, the initialisation, the
//! forward pass (generic over [`Real`]) and the reverse-mode VJP (`f64`).
//!
//! Layout conventions. Grids are (Z, Y, X) C order with channels last:
//! value `(z, y, x, c)` of a grid with edge `n` and `C` channels is at
//! `((z * n + y) * n + x) * C + c`. The parameter vector `w` holds, in this
//! order: the linear weights `[j][k]` (`j` = base-grid value index, `k` =
//! latent index), the linear biases `[j]`, then per transposed convolution its
//! weights `[kz][ky][kx][ci][co]` and its biases `[co]`. Tap `(kz, ky, kx)`
//! has PyTorch's `ConvTranspose3d` meaning: `out[o] += in[i] * k[o - 2 i + 1]`
//! along each axis.
//!
//! Work is saved in two exact ways: the last layer is evaluated only at
//! masked-in voxels, and every earlier layer only at the voxels some later
//! evaluated voxel reads (the mask pulled back through the kernel
//! footprints); each grid is stored compactly at just those voxels. Every
//! value is computed by one task in a fixed order, so results do not depend
//! on the number of threads. Generic code never divides two `R`s, so the
//! primal of every dual type is bit-identical to the `f64` forward.
//!
//! Meant for `f64` and the dual types. Not for the tape type `Var`: the
//! forward pass runs on rayon workers and each thread has its own tape;
//! reverse mode is [`Decoder::backward`].

use crate::ad::Real;
use crate::bail;
use crate::error::Result;
use crate::rng::{Purpose, Rng};
use rayon::prelude::*;

/// Edge of the grid the linear layer produces (voxels).
pub const BASE: usize = 4;
/// Negative slope of the LeakyReLU after the linear layer and every
/// transposed convolution but the last.
pub const LEAKY_SLOPE: f64 = 0.2;
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
/// Kernel taps per transposed convolution (4 x 4 x 4).
const TAPS: usize = 64;
/// Stream index (under `Purpose::Scene`) of the linear layer's weights;
/// convolution `l` uses `STREAM + 1 + l`.
const STREAM: u64 = 0xDEC0_0000;
/// Stream index (under `Purpose::Scene`) of the initial latent.
const STREAM_LATENT: u64 = 0xDEC0_FFFF;

/// One transposed convolution: kernel 4, stride 2, padding 1.
#[derive(Clone, Debug)]
struct Conv {
    /// Input edge (the output edge is twice this).
    n: usize,
    /// Input channels.
    c_in: usize,
    /// Output channels.
    c_out: usize,
    /// Offset of the weights `[kz][ky][kx][ci][co]` in `w`.
    w_off: usize,
    /// Offset of the biases `[co]` in `w`.
    b_off: usize,
}

impl Conv {
    fn weights<'a, T>(&self, w: &'a [T]) -> &'a [T] {
        &w[self.w_off..self.w_off + TAPS * self.c_in * self.c_out]
    }
    fn params(&self) -> usize {
        TAPS * self.c_in * self.c_out + self.c_out
    }
}

/// The nonlinearity after a layer.
#[derive(Clone, Copy, Debug)]
enum Act {
    /// `x` if `x > 0`, else `LEAKY_SLOPE * x`.
    Leaky,
    /// `s * x` if `x > 0`, else 0 (the last layer, `s` = output scale).
    ReluScaled(f64),
}

impl Act {
    /// Decided on the primal value; at 0 exactly the lower branch is taken.
    #[inline]
    fn apply<R: Real>(self, x: R) -> R {
        match self {
            Act::Leaky if x.re() > 0.0 => x,
            Act::Leaky => x * LEAKY_SLOPE,
            Act::ReluScaled(s) if x.re() > 0.0 => x * s,
            Act::ReluScaled(_) => R::cst(0.0),
        }
    }
    /// The derivative, from the activation's output `y` (whose sign is the
    /// input's for both functions).
    #[inline]
    fn slope_from_output(self, y: f64) -> f64 {
        match self {
            Act::Leaky if y > 0.0 => 1.0,
            Act::Leaky => LEAKY_SLOPE,
            Act::ReluScaled(s) if y > 0.0 => s,
            Act::ReluScaled(_) => 0.0,
        }
    }
}

/// The (input index, kernel index) pairs that feed output `o` along one axis
/// (input edge `n`): `k = o + 1 - 2 i` in `0..4`, `i` in `0..n`. Interior
/// outputs have two, the first and last output one.
#[inline]
fn taps(o: usize, n: usize) -> ([(usize, usize); 2], usize) {
    let m = o / 2;
    if o.is_multiple_of(2) {
        // o = 2m: k = 1 at i = m, k = 3 at i = m - 1.
        if m == 0 {
            ([(0, 1), (0, 0)], 1)
        } else {
            ([(m, 1), (m - 1, 3)], 2)
        }
    } else if m + 1 < n {
        // o = 2m + 1: k = 2 at i = m, k = 0 at i = m + 1.
        ([(m, 2), (m + 1, 0)], 2)
    } else {
        ([(m, 2), (0, 0)], 1)
    }
}

/// The (output index, kernel index) pairs that input `i` feeds along one
/// axis (output edge `m`): `o = 2 i - 1 + k` for `k` in `0..4`, `o` in `0..m`.
#[inline]
fn outs(i: usize, m: usize) -> ([(usize, usize); 4], usize) {
    let mut r = [(0, 0); 4];
    let mut c = 0;
    for k in 0..4 {
        let o = 2 * i + k;
        if o >= 1 && o - 1 < m {
            r[c] = (o - 1, k);
            c += 1;
        }
    }
    (r, c)
}

/// Marks a voxel a layout does not store.
const NONE: u32 = u32::MAX;

/// Where the evaluated voxels of a cubic grid are stored: grids are kept
/// only at the voxels that are evaluated (the rest is never read), compactly
/// in C order with all channels of a voxel in one row, so the rows of one
/// z-slab are contiguous.
#[derive(Clone, Debug)]
struct Layout {
    /// Edge (voxels).
    edge: usize,
    /// Row of each voxel (C order), or [`NONE`].
    index: Vec<u32>,
    /// First row of each z-slab; `start[edge]` is the number of rows.
    start: Vec<usize>,
}

impl Layout {
    /// The layout of the voxels where `need` (C order, edge `edge`) is true.
    fn new(need: &[bool], edge: usize) -> Layout {
        let plane = edge * edge;
        let counts: Vec<usize> = need.par_chunks(plane).map(|s| s.iter().filter(|&&b| b).count()).collect();
        let mut start = Vec::with_capacity(edge + 1);
        start.push(0);
        for c in counts {
            start.push(start[start.len() - 1] + c);
        }
        let mut index = vec![NONE; plane * edge];
        index.par_chunks_mut(plane).zip(need.par_chunks(plane)).enumerate().for_each(|(z, (slab, nd))| {
            // Rows fit in u32: Decoder::new caps the output at 1024^3 voxels.
            for (r, (i, _)) in (start[z] as u32..).zip(slab.iter_mut().zip(nd).filter(|(_, &b)| b)) {
                *i = r;
            }
        });
        Layout { edge, index, start }
    }

    /// Number of stored voxels.
    fn rows(&self) -> usize {
        self.start[self.edge]
    }

    /// Is voxel `v` (C order) stored?
    #[inline]
    fn has(&self, v: usize) -> bool {
        self.index[v] != NONE
    }

    /// The `c` values of voxel `v` in `values`; panics if `v` is not stored
    /// (a bug: needed voxels only read needed voxels).
    #[inline]
    fn row<'a, T>(&self, values: &'a [T], v: usize, c: usize) -> &'a [T] {
        &values[self.index[v] as usize * c..][..c]
    }

    /// `values` (`c` per row) cut into the rows of each z-slab, paired with
    /// the in-slab voxel indices (`y * edge + x`) stored there, for one
    /// parallel task per slab.
    fn slabs<'a, T: Send>(&'a self, values: &'a mut [T], c: usize) -> Vec<(usize, &'a mut [T])> {
        let mut parts = Vec::with_capacity(self.edge);
        let mut rest = values;
        for z in 0..self.edge {
            let (part, tail) = rest.split_at_mut((self.start[z + 1] - self.start[z]) * c);
            parts.push((z, part));
            rest = tail;
        }
        parts
    }

    /// The stored voxels of slab `z` as in-slab indices `y * edge + x`.
    fn in_slab(&self, z: usize) -> impl Iterator<Item = usize> + '_ {
        let plane = self.edge * self.edge;
        (0..plane).filter(move |&yx| self.index[z * plane + yx] != NONE)
    }
}

/// Output-centric transposed convolution of `input` (stored in `lin`, edge
/// `n`, `c_in` channels) into the voxels of `lout` (edge `2n`), `act`
/// applied. `kernel` is the convolution's weights as `R` or, when none
/// carries a tangent, as `f64` (a dual times an `f64` skips the constant's
/// empty tangent; the values are the same).
fn conv_forward<R, W>(
    conv: &Conv,
    kernel: &[W],
    bias: &[R],
    input: &[R],
    lin: &Layout,
    lout: &Layout,
    act: Act,
) -> Vec<R>
where
    R: Real + std::ops::Mul<W, Output = R>,
    W: Copy + Send + Sync,
{
    let (n, c_in, c_out) = (conv.n, conv.c_in, conv.c_out);
    let m = 2 * n;
    let mut out = vec![R::cst(0.0); lout.rows() * c_out];
    lout.slabs(&mut out, c_out).into_par_iter().for_each(|(oz, part)| {
        let (tz, nz) = taps(oz, n);
        for (yx, row) in lout.in_slab(oz).zip(part.chunks_exact_mut(c_out)) {
            let (ty, ny) = taps(yx / m, n);
            let (tx, nx) = taps(yx % m, n);
            row.copy_from_slice(&bias[..c_out]);
            for &(iz, kz) in &tz[..nz] {
                for &(iy, ky) in &ty[..ny] {
                    for &(ix, kx) in &tx[..nx] {
                        let a = lin.row(input, (iz * n + iy) * n + ix, c_in);
                        let k = &kernel[((kz * 4 + ky) * 4 + kx) * c_in * c_out..][..c_in * c_out];
                        for (&av, krow) in a.iter().zip(k.chunks_exact(c_out)) {
                            for (r, &kv) in row.iter_mut().zip(krow) {
                                *r += av * kv;
                            }
                        }
                    }
                }
            }
            for r in row.iter_mut() {
                *r = act.apply(*r);
            }
        }
    });
    out
}

/// The inputs (edge `n`) that some stored output of `lout` (edge `2n`)
/// reads. The footprint is a product of per-axis ranges (input `i` feeds
/// outputs `2i - 1 ..= 2i + 2`), so the "any" is taken one axis at a time:
/// along x per output row, then as ORs of whole rows (y) and planes (z).
fn pull_back(lout: &Layout, n: usize) -> Vec<bool> {
    let m = 2 * n;
    let span = |i: usize| (2 * i).saturating_sub(1)..(2 * i + 3).min(m);
    // [oz][oy][ix]
    let mut x = vec![false; m * m * n];
    x.par_chunks_mut(n).zip(lout.index.par_chunks(m)).for_each(|(row, line)| {
        for (ix, v) in row.iter_mut().enumerate() {
            *v = line[span(ix)].iter().any(|&r| r != NONE);
        }
    });
    // [oz][iy][ix]
    let mut y = vec![false; m * n * n];
    y.par_chunks_mut(n * n).zip(x.par_chunks(m * n)).for_each(|(plane, src)| {
        for (iy, row) in plane.chunks_exact_mut(n).enumerate() {
            for oy in span(iy) {
                for (v, &s) in row.iter_mut().zip(&src[oy * n..][..n]) {
                    *v |= s;
                }
            }
        }
    });
    // [iz][iy][ix]
    let mut need = vec![false; n * n * n];
    need.par_chunks_mut(n * n).enumerate().for_each(|(iz, plane)| {
        for oz in span(iz) {
            for (v, &s) in plane.iter_mut().zip(&y[oz * n * n..][..n * n]) {
                *v |= s;
            }
        }
    });
    need
}

/// A latent-to-density decoder: the architecture and the layout of its flat
/// parameter vector (the parameters themselves are passed to every call, so
/// the same decoder serves `f64`, dual and reverse-mode evaluations).
#[derive(Clone, Debug)]
pub struct Decoder {
    /// Size of the latent `z`.
    latent: usize,
    /// Output edge (voxels); the output has `res^3` values.
    res: usize,
    /// Channels of the base grid (the linear layer's output).
    c0: usize,
    /// The transposed convolutions, input to output.
    convs: Vec<Conv>,
    /// Density per unit of the last ReLU's output.
    out_scale: f64,
    /// Length of the parameter vector.
    n_params: usize,
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
        if layers > 8 || res != BASE << layers {
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
        Ok(Decoder { latent, res, c0, convs, out_scale: OUT_SCALE, n_params: off })
    }

    /// The default decoder for a `res^3` grid (`res` = 4 * 2^L, L >= 1): a
    /// 64-d latent, `C0 = 4` base channels, and per intermediate grid of
    /// edge `e` 16 channels if `e <= 8`, 8 if `e == 16`, 4 if `e >= 32`.
    /// About 30k parameters at res 32..128, most of them in the linear layer.
    ///
    /// Panics if `res` is not 4 * 2^L with 1 <= L <= 8.
    ///
    /// ```
    /// let d = dualphoton::model::Decoder::paper_small(32);
    /// assert_eq!(d.param_count(), 29465);
    /// ```
    pub fn paper_small(res: usize) -> Decoder {
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
        match Decoder::new(64, res, &channels) {
            Ok(d) => d,
            Err(e) => panic!("Decoder::paper_small: {e}"),
        }
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
                if last { format!("ReLU x {}", self.out_scale) } else { format!("LeakyReLU {LEAKY_SLOPE}") }
            );
        }
        s += &format!("total    {} params", self.n_params);
        s
    }

    /// Initial parameters, deterministic from `seed`: He-normal weights (std
    /// `sqrt(2 / fan_in)`, fan_in = latent for the linear layer and
    /// `C_in * 8` effective taps for a transposed convolution), zero biases,
    /// except the last layer: weights at [`LAST_GAIN`] times He and bias
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

    /// Where each grid is evaluated: the base grid (everywhere), then each
    /// convolution's output; the last is `mask`, each earlier one what the
    /// next one reads.
    fn layouts(&self, mask: &[bool]) -> Vec<Layout> {
        let mut layouts = vec![Layout::new(mask, self.res)];
        for c in self.convs.iter().rev() {
            let need = match layouts.last() {
                Some(l) if c.n > BASE => pull_back(l, c.n),
                _ => vec![true; c.n.pow(3)],
            };
            layouts.push(Layout::new(&need, c.n));
        }
        layouts.reverse();
        layouts
    }

    fn check(&self, z: usize, w: usize, mask: usize) {
        assert_eq!(z, self.latent, "Decoder: latent has the wrong length");
        assert_eq!(w, self.n_params, "Decoder: parameter vector has the wrong length");
        assert_eq!(mask, self.res.pow(3), "Decoder: mask has the wrong length");
    }

    /// The base grid, then every convolution's output, post-activation and
    /// stored in `layouts` (the last is the density at the mask's voxels).
    fn activations<R: Real>(&self, z: &[R], w: &[R], layouts: &[Layout]) -> Vec<Vec<R>> {
        let n0 = BASE.pow(3) * self.c0;
        let (lw, lb) = w.split_at(self.latent * n0);
        let base: Vec<R> = lw
            .chunks_exact(self.latent)
            .zip(lb)
            .map(|(row, &b)| {
                let mut s = b;
                for (&wv, &zv) in row.iter().zip(z) {
                    s += wv * zv;
                }
                Act::Leaky.apply(s)
            })
            .collect();
        // Weights without tangents (the usual case when differentiating
        // with respect to z only) are used as plain numbers. `x - re(x)` is
        // an exact zero iff x has no tangent (stops at the first that has).
        let plain: Option<Vec<f64>> =
            w.iter().all(|x| (*x - R::cst(x.re())).is_exact_zero()).then(|| w.iter().map(R::re).collect());
        let mut acts = vec![base];
        for (l, c) in self.convs.iter().enumerate() {
            let act = if l + 1 == self.convs.len() { Act::ReluScaled(self.out_scale) } else { Act::Leaky };
            let bias = &w[c.b_off..c.b_off + c.c_out];
            let (lin, lout) = (&layouts[l], &layouts[l + 1]);
            let next = match &plain {
                Some(wf) => conv_forward(c, c.weights(wf), bias, &acts[l], lin, lout, act),
                None => conv_forward(c, c.weights(w), bias, &acts[l], lin, lout, act),
            };
            acts.push(next);
        }
        acts
    }

    /// The density grid `D(z; w)`: (Z, Y, X) C order, length `res^3`, the
    /// last layer's `ReLU(.) * out_scale`, exactly 0 where `mask` is false.
    /// Only the masked-in voxels and what they read are evaluated.
    ///
    /// Panics if `z`, `w` or `mask` has the wrong length.
    ///
    /// ```
    /// use dualphoton::model::Decoder;
    /// let d = Decoder::paper_small(8);
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mut mask = vec![true; 8 * 8 * 8];
    /// mask[0] = false;
    /// let rho = d.forward(&z, &w, &mask);
    /// assert_eq!(rho[0], 0.0);
    /// assert!(rho.iter().all(|&r| r >= 0.0));
    /// ```
    pub fn forward<R: Real>(&self, z: &[R], w: &[R], mask: &[bool]) -> Vec<R> {
        self.check(z.len(), w.len(), mask.len());
        let layouts = self.layouts(mask);
        let acts = self.activations(z, w, &layouts);
        let (lout, density) = (&layouts[self.convs.len()], &acts[self.convs.len()]);
        // Scattered in parallel: for K-lane duals at res 128 the dense grid
        // is ~170 MB, and writing it costs more than the arithmetic.
        let mut out = Vec::new();
        (0..mask.len())
            .into_par_iter()
            .map(|v| if lout.has(v) { lout.row(density, v, 1)[0] } else { R::cst(0.0) })
            .collect_into_vec(&mut out);
        out
    }

    /// [`Decoder::forward`] at the masked-in voxels only, in C order (length
    /// = number of true entries of `mask`): the same values without the
    /// dense grid (which for K-lane duals is large).
    ///
    /// ```
    /// use dualphoton::model::Decoder;
    /// let d = Decoder::paper_small(8);
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mask: Vec<bool> = (0..512).map(|v| v % 3 == 0).collect();
    /// let dense = d.forward(&z, &w, &mask);
    /// let inside: Vec<f64> = (0..512).filter(|v| mask[*v]).map(|v| dense[v]).collect();
    /// assert_eq!(d.forward_masked(&z, &w, &mask), inside);
    /// ```
    pub fn forward_masked<R: Real>(&self, z: &[R], w: &[R], mask: &[bool]) -> Vec<R> {
        self.check(z.len(), w.len(), mask.len());
        let layouts = self.layouts(mask);
        let mut acts = self.activations(z, w, &layouts);
        acts.pop().unwrap_or_default()
    }

    /// Reverse mode: the vector-Jacobian product of [`Decoder::forward`] at
    /// `(z, w)` with `grad_out` = dL/d(density) (length `res^3`; entries
    /// outside the mask are ignored, the output there is constant).
    /// Returns `(dL/dz, dL/dw)`. The ReLU and LeakyReLU derivatives are those
    /// of the branch the forward pass takes.
    ///
    /// Panics if an argument has the wrong length.
    ///
    /// ```
    /// use dualphoton::model::Decoder;
    /// let d = Decoder::paper_small(8);
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mask = vec![true; 512];
    /// let (gz, gw) = d.backward(&z, &w, &mask, &vec![1.0; 512]);
    /// assert_eq!((gz.len(), gw.len()), (64, d.param_count()));
    /// ```
    pub fn backward(&self, z: &[f64], w: &[f64], mask: &[bool], grad_out: &[f64]) -> (Vec<f64>, Vec<f64>) {
        self.check(z.len(), w.len(), mask.len());
        assert_eq!(grad_out.len(), mask.len(), "Decoder: grad_out has the wrong length");
        let layouts = self.layouts(mask);
        let acts = self.activations(z, w, &layouts);
        let mut gw = vec![0.0; self.n_params];
        // g: dL/d(pre-activation) of the current layer's output, stored like it.
        let last = Act::ReluScaled(self.out_scale);
        let density = &acts[self.convs.len()];
        let mut g: Vec<f64> = (0..mask.len()).filter(|&v| mask[v]).map(|v| grad_out[v]).collect();
        for (gv, &d) in g.iter_mut().zip(density) {
            *gv *= last.slope_from_output(d);
        }
        for (l, c) in self.convs.iter().enumerate().rev() {
            let (lin, lout) = (&layouts[l], &layouts[l + 1]);
            conv_grad_weights(c, &acts[l], lin, &g, lout, &mut gw);
            g = conv_grad_input(c, w, &g, lout, lin);
            for (gv, &a) in g.iter_mut().zip(&acts[l]) {
                *gv *= Act::Leaky.slope_from_output(a);
            }
        }
        // Linear layer: g is dL/d(pre-activation) of the base grid (dense).
        let n0 = BASE.pow(3) * self.c0;
        let mut gz = vec![0.0; self.latent];
        let (gw_lin, gb_lin) = gw[..n0 * (self.latent + 1)].split_at_mut(self.latent * n0);
        for (j, &gj) in g.iter().enumerate() {
            gb_lin[j] = gj;
            let wrow = &w[j * self.latent..][..self.latent];
            for (k, gwk) in gw_lin[j * self.latent..][..self.latent].iter_mut().enumerate() {
                *gwk = gj * z[k];
                gz[k] += wrow[k] * gj;
            }
        }
        (gz, gw)
    }
}

/// dL/d(weights) and dL/d(biases) of one convolution into `gw`, from its
/// input (stored in `lin`) and dL/d(pre-activation) of its output `g`
/// (stored in `lout`). Output centric like the forward pass: every output
/// z-slab sums its voxels' contributions into a partial of its own, in a
/// fixed order; the partials are then added in slab order.
fn conv_grad_weights(c: &Conv, input: &[f64], lin: &Layout, g: &[f64], lout: &Layout, gw: &mut [f64]) {
    let (n, c_in, c_out) = (c.n, c.c_in, c.c_out);
    let m = 2 * n;
    let size = TAPS * c_in * c_out + c_out;
    let partials: Vec<Vec<f64>> = (0..m)
        .into_par_iter()
        .map(|oz| {
            let mut part = vec![0.0; size];
            let (kernel, bias) = part.split_at_mut(TAPS * c_in * c_out);
            let (tz, nz) = taps(oz, n);
            let rows = g[lout.start[oz] * c_out..lout.start[oz + 1] * c_out].chunks_exact(c_out);
            for (yx, gr) in lout.in_slab(oz).zip(rows) {
                for (b, &gv) in bias.iter_mut().zip(gr) {
                    *b += gv;
                }
                let (ty, ny) = taps(yx / m, n);
                let (tx, nx) = taps(yx % m, n);
                for &(iz, kz) in &tz[..nz] {
                    for &(iy, ky) in &ty[..ny] {
                        for &(ix, kx) in &tx[..nx] {
                            let a = lin.row(input, (iz * n + iy) * n + ix, c_in);
                            let blk = &mut kernel[((kz * 4 + ky) * 4 + kx) * c_in * c_out..][..c_in * c_out];
                            for (&av, brow) in a.iter().zip(blk.chunks_exact_mut(c_out)) {
                                for (bv, &gv) in brow.iter_mut().zip(gr) {
                                    *bv += av * gv;
                                }
                            }
                        }
                    }
                }
            }
            part
        })
        .collect();
    // Weights then biases are contiguous in `w`, as in a partial.
    let out = &mut gw[c.w_off..c.w_off + size];
    for part in &partials {
        for (o, &p) in out.iter_mut().zip(part) {
            *o += p;
        }
    }
}

/// dL/d(input) of one convolution (edge `n`, `c_in` channels), stored in
/// `lin`, from dL/d(pre-activation) `g` of its output (stored in `lout`):
/// the transposed operation, input centric (each input gathers from the up
/// to 4^3 outputs it feeds, skipping those not stored: their `g` is 0).
fn conv_grad_input(c: &Conv, w: &[f64], g: &[f64], lout: &Layout, lin: &Layout) -> Vec<f64> {
    let (n, c_in, c_out) = (c.n, c.c_in, c.c_out);
    let m = 2 * n;
    let kernel = c.weights(w);
    let mut gin = vec![0.0; lin.rows() * c_in];
    lin.slabs(&mut gin, c_in).into_par_iter().for_each(|(iz, part)| {
        let (oz, cz) = outs(iz, m);
        for (yx, row) in lin.in_slab(iz).zip(part.chunks_exact_mut(c_in)) {
            let (oy, cy) = outs(yx / n, m);
            let (ox, cx) = outs(yx % n, m);
            for &(z, kz) in &oz[..cz] {
                for &(y, ky) in &oy[..cy] {
                    for &(x, kx) in &ox[..cx] {
                        let o = (z * m + y) * m + x;
                        if !lout.has(o) {
                            continue;
                        }
                        let gr = lout.row(g, o, c_out);
                        let k = &kernel[((kz * 4 + ky) * 4 + kx) * c_in * c_out..][..c_in * c_out];
                        for (r, krow) in row.iter_mut().zip(k.chunks_exact(c_out)) {
                            let mut s = 0.0;
                            for (&kv, &gv) in krow.iter().zip(gr) {
                                s += kv * gv;
                            }
                            *r += s;
                        }
                    }
                }
            }
        }
    });
    gin
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ad::dual::{lane, with_tangents};
    use num_dual::{Dual64, DualSVec64};

    fn normals(seed: u64, n: usize) -> Vec<f64> {
        let mut rng = Rng::new(seed, Purpose::Scene, 77);
        (0..n).map(|_| rng.normal()).collect()
    }

    /// A ball of voxels around the grid centre, radius `r` voxels.
    fn ball(res: usize, r: f64) -> Vec<bool> {
        let c = (res as f64 - 1.0) / 2.0;
        let mut m = vec![false; res * res * res];
        for z in 0..res {
            for y in 0..res {
                for x in 0..res {
                    let d2 = (z as f64 - c).powi(2) + (y as f64 - c).powi(2) + (x as f64 - c).powi(2);
                    m[(z * res + y) * res + x] = d2 <= r * r;
                }
            }
        }
        m
    }

    /// Scatter-style transposed convolution, PyTorch's ConvTranspose3d
    /// (kernel 4, stride 2, padding 1): out[o] += in[i] k[o - 2 i + 1].
    fn naive(c: &Conv, w: &[f64], input: &[f64]) -> Vec<f64> {
        let (n, m) = (c.n, 2 * c.n);
        let mut out = vec![0.0; m * m * m * c.c_out];
        for o in 0..m * m * m {
            for co in 0..c.c_out {
                out[o * c.c_out + co] = w[c.b_off + co];
            }
        }
        for i in 0..n * n * n {
            let (iz, iy, ix) = (i / (n * n), (i / n) % n, i % n);
            for t in 0..TAPS {
                let (kz, ky, kx) = (t / 16, (t / 4) % 4, t % 4);
                let o = [2 * iz + kz, 2 * iy + ky, 2 * ix + kx];
                if o.iter().any(|&v| v < 1 || v > m) {
                    continue;
                }
                let o = ((o[0] - 1) * m + o[1] - 1) * m + o[2] - 1;
                for ci in 0..c.c_in {
                    for co in 0..c.c_out {
                        out[o * c.c_out + co] += input[i * c.c_in + ci] * w[c.w_off + (t * c.c_in + ci) * c.c_out + co];
                    }
                }
            }
        }
        out
    }

    #[test]
    fn output_centric_conv_equals_scatter() {
        for (n, c_in, c_out) in [(4, 3, 5), (3, 2, 1), (2, 1, 4)] {
            let conv = Conv { n, c_in, c_out, w_off: 3, b_off: 3 + TAPS * c_in * c_out };
            let w = normals(1, conv.b_off + c_out);
            let input = normals(2, n * n * n * c_in);
            let m = 2 * n;
            let want: Vec<f64> = naive(&conv, &w, &input).into_iter().map(|x| Act::Leaky.apply(x)).collect();
            let full = |e: usize| Layout::new(&vec![true; e * e * e], e);
            let (lin, lout) = (full(n), full(m));
            let got = conv_forward(&conv, conv.weights(&w), &w[conv.b_off..], &input, &lin, &lout, Act::Leaky);
            for (a, b) in got.iter().zip(&want) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
            // A sparse output: the stored voxels' values unchanged.
            let need: Vec<bool> = normals(3, m * m * m).iter().map(|&u| u > 0.5).collect();
            let sparse = Layout::new(&need, m);
            let part = conv_forward(&conv, conv.weights(&w), &w[conv.b_off..], &input, &lin, &sparse, Act::Leaky);
            let kept: Vec<f64> =
                (0..m * m * m).filter(|&o| need[o]).flat_map(|o| got[o * c_out..][..c_out].to_vec()).collect();
            assert_eq!(part, kept);
        }
    }

    #[test]
    fn pull_back_marks_exactly_the_read_inputs() {
        let n = 4;
        let need: Vec<bool> = normals(4, 512).iter().map(|&u| u > 1.2).collect();
        let got = pull_back(&Layout::new(&need, 2 * n), n);
        let mut want = vec![false; 64];
        for o in (0..512).filter(|&o| need[o]) {
            let (tz, nz) = taps(o / 64, n);
            let (ty, ny) = taps((o / 8) % 8, n);
            let (tx, nx) = taps(o % 8, n);
            for &(z, _) in &tz[..nz] {
                for &(y, _) in &ty[..ny] {
                    for &(x, _) in &tx[..nx] {
                        want[(z * n + y) * n + x] = true;
                    }
                }
            }
        }
        assert_eq!(got, want);
    }

    #[test]
    fn mask_zeroes_outside_and_keeps_inside() {
        for (d, ball_mask) in cases() {
            let (z, w) = (d.init_latent(3), d.init(3));
            let n = ball_mask.len();
            let all = d.forward(&z, &w, &vec![true; n]);
            let scattered: Vec<bool> = normals(5, n).iter().map(|&u| u > 0.8).collect();
            for mask in [ball_mask, scattered] {
                let part = d.forward(&z, &w, &mask);
                for v in 0..n {
                    assert_eq!(part[v].to_bits(), if mask[v] { all[v].to_bits() } else { 0 });
                }
            }
        }
    }

    /// Dual64 forward with tangent 1 on coordinate `i` of z (`on_z`) or w.
    fn dual_forward(d: &Decoder, z: &[f64], w: &[f64], mask: &[bool], on_z: bool, i: usize) -> Vec<f64> {
        let dz: Vec<Dual64> =
            z.iter().enumerate().map(|(k, &v)| Dual64::new(v, (on_z && k == i) as u8 as f64)).collect();
        let dw: Vec<Dual64> =
            w.iter().enumerate().map(|(k, &v)| Dual64::new(v, (!on_z && k == i) as u8 as f64)).collect();
        d.forward(&dz, &dw, mask).iter().map(|x| x.eps).collect()
    }

    /// The decoders the derivative tests run on, each with a mask: the
    /// default at res 16 (two convolutions), and a narrow one at res 32
    /// (three; two levels of pulled-back masks) with a ball and scattered
    /// voxels.
    fn cases() -> Vec<(Decoder, Vec<bool>)> {
        let deep = Decoder::new(6, 32, &[3, 4, 2]).unwrap();
        let scattered: Vec<bool> =
            normals(14, 32 * 32 * 32).iter().zip(ball(32, 9.0)).map(|(&u, b)| b || u > 2.5).collect();
        vec![(Decoder::paper_small(16), ball(16, 6.5)), (deep, scattered)]
    }

    /// Some coordinates of w: linear weight and bias, a weight and a bias of
    /// every convolution (the last bias included).
    fn w_coords(d: &Decoder) -> Vec<usize> {
        let mut v = vec![5, d.latent * 64 * d.c0 + 3];
        for c in &d.convs {
            v.push(c.w_off + (c.b_off - c.w_off) / 3);
            v.push(c.b_off);
        }
        v
    }

    #[test]
    fn dual_forward_matches_central_differences() {
        for (d, mask) in cases() {
            let (z, w) = (d.init_latent(11), d.init(11));
            let coords: Vec<(bool, usize)> = [(true, 0), (true, d.latent - 1)]
                .into_iter()
                .chain(w_coords(&d).into_iter().map(|i| (false, i)))
                .collect();
            for (on_z, i) in coords {
                let tangent = dual_forward(&d, &z, &w, &mask, on_z, i);
                // The decoder is piecewise linear in each coordinate: central
                // differences have no truncation error unless a kink is crossed,
                // so h is large against round-off (~1e-17 in densities ~0.005).
                let h = 1e-4;
                let eval = |s: f64| {
                    let (mut z2, mut w2) = (z.clone(), w.clone());
                    if on_z {
                        z2[i] += s
                    } else {
                        w2[i] += s
                    }
                    d.forward(&z2, &w2, &mask)
                };
                let (p, m) = (eval(h), eval(-h));
                let scale = tangent.iter().fold(0.0f64, |a, t| a.max(t.abs()));
                assert!(scale > 0.0, "coordinate {i} has no effect");
                let worst = (0..tangent.len())
                    .map(|v| ((p[v] - m[v]) / (2.0 * h) - tangent[v]).abs() / tangent[v].abs().max(1e-3 * scale))
                    .fold(0.0f64, f64::max);
                eprintln!("res {} on_z {on_z} i {i}: largest relative error {worst:.2e}", d.res);
                assert!(worst <= 1e-6, "res {} on_z {on_z} i {i}: relative error {worst}", d.res);
            }
        }
    }

    #[test]
    fn backward_matches_forward_mode() {
        for (d, mask) in cases() {
            let (z, w) = (d.init_latent(12), d.init(12));
            let v = normals(13, mask.len());
            let (gz, gw) = d.backward(&z, &w, &mask, &v);
            let check = |on_z: bool, i: usize, rev: f64| {
                let t = dual_forward(&d, &z, &w, &mask, on_z, i);
                let fwd: f64 = t.iter().zip(&v).map(|(a, b)| a * b).sum();
                let err = (fwd - rev).abs() / fwd.abs().max(1e-12);
                assert!(err <= 1e-10, "res {} on_z {on_z} i {i}: fwd {fwd} rev {rev}", d.res);
            };
            for i in [0, 5, d.latent - 1] {
                check(true, i, gz[i]);
            }
            for i in w_coords(&d) {
                check(false, i, gw[i]);
            }
            // Outside the mask grad_out is ignored.
            let v2: Vec<f64> = v.iter().zip(&mask).map(|(&g, &m)| if m { g } else { 1e3 }).collect();
            assert_eq!(d.backward(&z, &w, &mask, &v2), (gz, gw));
        }
    }

    #[test]
    fn vector_lanes_equal_single_duals() {
        let d = Decoder::paper_small(16);
        let (z, w) = (d.init_latent(21), d.init(21));
        let mask = ball(16, 7.0);
        let (nz, nw) = (z.len(), w.len());
        // Lane tangents: e_z3, a random z direction, e_(last bias), a random w direction.
        let last_b = d.convs.last().map_or(0, |c| c.b_off);
        let rz = normals(22, nz);
        let rw = normals(23, nw);
        let tz = |k: usize, i: usize| [(i == 3) as u8 as f64, rz[i], 0.0, 0.0][k];
        let tw = |k: usize, i: usize| [0.0, 0.0, (i == last_b) as u8 as f64, rw[i]][k];
        let vz: Vec<DualSVec64<4>> = (0..nz).map(|i| with_tangents(z[i], [0, 1, 2, 3].map(|k| tz(k, i)))).collect();
        let vw: Vec<DualSVec64<4>> = (0..nw).map(|i| with_tangents(w[i], [0, 1, 2, 3].map(|k| tw(k, i)))).collect();
        let out = d.forward(&vz, &vw, &mask);
        let primal = d.forward(&z, &w, &mask);
        for k in 0..4 {
            let sz: Vec<Dual64> = (0..nz).map(|i| Dual64::new(z[i], tz(k, i))).collect();
            let sw: Vec<Dual64> = (0..nw).map(|i| Dual64::new(w[i], tw(k, i))).collect();
            let single = d.forward(&sz, &sw, &mask);
            for v in 0..out.len() {
                assert_eq!(out[v].re.to_bits(), single[v].re.to_bits());
                assert_eq!(out[v].re.to_bits(), primal[v].to_bits());
                assert_eq!(lane(&out[v], k), single[v].eps, "lane {k} voxel {v}");
            }
        }
    }

    #[test]
    fn init_is_deterministic_and_small_positive_in_the_mask() {
        let d = Decoder::paper_small(32);
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
        assert_eq!(Decoder::paper_small(32).param_count(), 29465);
        assert_eq!(Decoder::paper_small(64).param_count(), 31261);
        assert_eq!(Decoder::paper_small(128).param_count(), 32289);
        let d = Decoder::paper_small(64);
        assert_eq!(d.describe().lines().count(), 6);
        assert_eq!(d.init(1).len(), d.param_count());
    }

    /// Timings at res 64 (mask: a ball of ~20,000 voxels) and res 128;
    /// run with `cargo test --release --lib model:: -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_timings() {
        /// Process CPU time (user + system) in ms, from /proc/self/stat
        /// (clock ticks of 10 ms): other jobs on the shared cores inflate
        /// wall times but not this.
        fn cpu_ms() -> f64 {
            let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
            let f: Vec<f64> =
                s.rsplit(')').next().unwrap_or("").split_whitespace().map(|v| v.parse().unwrap_or(0.0)).collect();
            (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) * 10.0
        }
        /// (median wall ms, mean CPU ms) per call.
        fn time<T>(f: impl Fn() -> T) -> String {
            let c0 = cpu_ms();
            let mut t: Vec<f64> = (0..15)
                .map(|_| {
                    let s = std::time::Instant::now();
                    std::hint::black_box(f());
                    s.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            let cpu = (cpu_ms() - c0) / 15.0;
            t.sort_by(f64::total_cmp);
            format!("{:.1} ms (cpu {cpu:.1} ms)", t[7])
        }
        for (res, r) in [(64, 16.84), (64, 100.0), (128, 25.4)] {
            let d = Decoder::paper_small(res);
            let (z, w) = (d.init_latent(1), d.init(1));
            let mask = ball(res, r);
            let count = mask.iter().filter(|&&m| m).count();
            let zd: Vec<DualSVec64<8>> = z
                .iter()
                .enumerate()
                .map(|(i, &v)| {
                    if i < 8 {
                        with_tangents(v, std::array::from_fn(|k| (k == i) as u8 as f64))
                    } else {
                        DualSVec64::cst(v)
                    }
                })
                .collect();
            let wd: Vec<DualSVec64<8>> = w.iter().map(|&v| DualSVec64::cst(v)).collect();
            // Random directions over all of z and w: every parameter a tangent.
            let rw = normals(2, 8 * w.len());
            let rz = normals(3, 8 * z.len());
            let zr: Vec<DualSVec64<8>> =
                (0..z.len()).map(|i| with_tangents(z[i], std::array::from_fn(|k| rz[8 * i + k]))).collect();
            let wr: Vec<DualSVec64<8>> =
                (0..w.len()).map(|i| with_tangents(w[i], std::array::from_fn(|k| rw[8 * i + k]))).collect();
            let g = normals(1, res * res * res);
            let rho = d.forward_masked(&z, &w, &mask);
            let (pos, mean) = (
                rho.iter().filter(|&&r| r > 0.0).count() as f64 / rho.len() as f64,
                rho.iter().sum::<f64>() / rho.len() as f64,
            );
            eprintln!(
                "{}\ninit (seed 1) over the mask: positive {pos:.4}, mean {mean:.5}, max {:.5}",
                d.describe(),
                rho.iter().fold(0.0f64, |a, &r| a.max(r))
            );
            let per_layer: Vec<usize> = d.layouts(&mask).iter().map(Layout::rows).collect();
            eprintln!(
                "res {res} mask {count} (voxels evaluated per layer {per_layer:?}):\n  f64 {}\n  dual8(z) {}\n  dual8(z, w) {}\n  dual8(z) masked only {}\n  backward {}\n  layouts {}",
                time(|| d.forward(&z, &w, &mask)),
                time(|| d.forward(&zd, &wd, &mask)),
                time(|| d.forward(&zr, &wr, &mask)),
                time(|| d.forward_masked(&zd, &wd, &mask)),
                time(|| d.backward(&z, &w, &mask, &g)),
                time(|| d.layouts(&mask))
            );
        }
    }
}
