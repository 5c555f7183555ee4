//! The layer kernel of the decoder: one transposed 3-D convolution (kernel
//! 4, stride 2, padding 1, doubling the edge) with its activation, its
//! output-centric forward pass (generic over [`Real`]) and the two halves of
//! its hand-written adjoint (`f64`): dL/d(weights, biases) and dL/d(input).
//!
//! Grids are read and written where their `Layout` stores them. A
//! convolution's parameters are its weights `[kz][ky][kx][ci][co]` then its
//! biases `[co]`; tap `(kz, ky, kx)` has PyTorch's `ConvTranspose3d`
//! meaning: `out[o] += in[i] * k[o - 2 i + 1]` along each axis.
//!
//! Every value is computed by one task in a fixed order, so results do not
//! depend on the number of threads. Generic code never divides two `R`s, so
//! the primal of every dual type is bit-identical to the `f64` forward.

use super::layout::Layout;
use crate::ad::Real;
use crate::par;
use rayon::prelude::*;

/// Negative slope of the LeakyReLU after the linear layer and every
/// transposed convolution but the last.
pub const LEAKY_SLOPE: f64 = 0.2;
/// Kernel taps per transposed convolution (4 x 4 x 4).
pub(super) const TAPS: usize = 64;
/// Voxels per parallel task of a layer, at least: tasks of whole z-slabs
/// would differ in size (the hull mask), and a layer of edge 16 has 16.
const ROWS: usize = 8;

/// One transposed convolution: kernel 4, stride 2, padding 1.
#[derive(Clone, Debug)]
pub(super) struct Conv {
    /// Input edge (the output edge is twice this).
    pub(super) n: usize,
    /// Input channels.
    pub(super) c_in: usize,
    /// Output channels.
    pub(super) c_out: usize,
    /// Offset of the weights `[kz][ky][kx][ci][co]` in `w`.
    pub(super) w_off: usize,
    /// Offset of the biases `[co]` in `w`.
    pub(super) b_off: usize,
}

impl Conv {
    pub(super) fn weights<'a, T>(&self, w: &'a [T]) -> &'a [T] {
        &w[self.w_off..self.w_off + TAPS * self.c_in * self.c_out]
    }
    pub(super) fn params(&self) -> usize {
        TAPS * self.c_in * self.c_out + self.c_out
    }
}

/// The nonlinearity after a layer.
#[derive(Clone, Copy, Debug)]
pub(super) enum Act {
    /// `x` if `x > 0`, else `LEAKY_SLOPE * x`.
    Leaky,
    /// `s * x` if `x > 0`, else 0 (the last layer, `s` = output scale).
    ReluScaled(f64),
    /// `s * x` if `x > 0`, else `s * leak * x`: the last layer while a
    /// prior is trained, so that no voxel's output dies.
    LeakyScaled(f64, f64),
}

impl Act {
    /// Decided on the primal value; at 0 exactly the lower branch is taken.
    #[inline]
    pub(super) fn apply<R: Real>(self, x: R) -> R {
        match self {
            Act::Leaky if x.re() > 0.0 => x,
            Act::Leaky => x * LEAKY_SLOPE,
            Act::ReluScaled(s) if x.re() > 0.0 => x * s,
            Act::ReluScaled(_) => R::cst(0.0),
            Act::LeakyScaled(s, _) if x.re() > 0.0 => x * s,
            Act::LeakyScaled(s, leak) => x * (s * leak),
        }
    }
    /// The derivative, from the activation's output `y` (whose sign is the
    /// input's for both functions).
    #[inline]
    pub(super) fn slope_from_output(self, y: f64) -> f64 {
        match self {
            Act::Leaky if y > 0.0 => 1.0,
            Act::Leaky => LEAKY_SLOPE,
            Act::ReluScaled(s) if y > 0.0 => s,
            Act::ReluScaled(_) => 0.0,
            Act::LeakyScaled(s, _) if y > 0.0 => s,
            Act::LeakyScaled(s, leak) => s * leak,
        }
    }
}

/// Calls `f::<.., C>(args)` with `C` = `width` where it is one of the
/// channel counts the decoders use, else with `C` = 0 (any width).
macro_rules! by_width {
    ($width:expr, $f:ident $(::<$($t:ty),*>)? ($($arg:expr),*)) => {
        match $width {
            1 => $f::<$($($t,)*)? 1>($($arg),*),
            2 => $f::<$($($t,)*)? 2>($($arg),*),
            4 => $f::<$($($t,)*)? 4>($($arg),*),
            8 => $f::<$($($t,)*)? 8>($($arg),*),
            16 => $f::<$($($t,)*)? 16>($($arg),*),
            32 => $f::<$($($t,)*)? 32>($($arg),*),
            64 => $f::<$($($t,)*)? 64>($($arg),*),
            _ => $f::<$($($t,)*)? 0>($($arg),*),
        }
    };
}

/// The (input index, kernel index) pairs that feed output `o` along one axis
/// (input edge `n`): `k = o + 1 - 2 i` in `0..4`, `i` in `0..n`. Interior
/// outputs have two, the first and last output one.
#[inline]
pub(super) fn taps(o: usize, n: usize) -> ([(usize, usize); 2], usize) {
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

/// Output-centric transposed convolution of `input` (stored in `lin`, edge
/// `n`, `c_in` channels) into the voxels of `lout` (edge `2n`), `act`
/// applied. `kernel` is the convolution's weights as `R` or, when none
/// carries a tangent, as `f64` (a dual times an `f64` skips the constant's
/// empty tangent; the values are the same).
pub(super) fn conv_forward<R, W>(
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
    by_width!(conv.c_out, forward_at::<R, W>(conv, kernel, bias, input, lin, lout, act))
}

/// [`conv_forward`] with the output channels `C` known when compiling (0:
/// any number): the inner loops unroll and each voxel's sums stay in
/// registers. Every sum adds the same terms in the same order for every
/// `C`, so the bits are the same.
fn forward_at<R, W, const C: usize>(
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
    let mut out = par::filled(lout.rows() * c_out, R::cst(0.0));
    out.par_chunks_mut(ROWS * c_out).enumerate().for_each(|(t, part)| {
        for ((oz, yx), row) in lout.voxels_of(t * ROWS, part.len() / c_out).zip(part.chunks_exact_mut(c_out)) {
            let (tz, nz) = taps(oz, n);
            let (ty, ny) = taps(yx / m, n);
            let (tx, nx) = taps(yx % m, n);
            let mut acc: [R; C] = std::array::from_fn(|j| bias[j]);
            if C == 0 {
                row.copy_from_slice(&bias[..c_out]);
            }
            for &(iz, kz) in &tz[..nz] {
                for &(iy, ky) in &ty[..ny] {
                    for &(ix, kx) in &tx[..nx] {
                        let a = lin.row(input, (iz * n + iy) * n + ix, c_in);
                        let k = &kernel[((kz * 4 + ky) * 4 + kx) * c_in * c_out..][..c_in * c_out];
                        if C == 0 {
                            for (&av, krow) in a.iter().zip(k.chunks_exact(c_out)) {
                                for (r, &kv) in row.iter_mut().zip(krow) {
                                    *r += av * kv;
                                }
                            }
                        } else {
                            for (&av, krow) in a.iter().zip(k.chunks_exact(C)) {
                                for j in 0..C {
                                    acc[j] += av * krow[j];
                                }
                            }
                        }
                    }
                }
            }
            if C > 0 {
                row.copy_from_slice(&acc);
            }
            for r in row.iter_mut() {
                *r = act.apply(*r);
            }
        }
    });
    out
}

/// dL/d(weights) and dL/d(biases) of one convolution into `gw`, from its
/// input (stored in `lin`) and dL/d(pre-activation) of its output `g`
/// (stored in `lout`). Output centric like the forward pass: every output
/// z-slab sums its voxels' contributions into a partial of its own, in a
/// fixed order; the partials are then added in slab order.
pub(super) fn conv_grad_weights(c: &Conv, input: &[f64], lin: &Layout, g: &[f64], lout: &Layout, gw: &mut [f64]) {
    by_width!(c.c_out, grad_weights_at(c, input, lin, g, lout, gw))
}

/// [`conv_grad_weights`] with the output channels `C` known when compiling
/// (0: any); the same sums in the same order for every `C`.
fn grad_weights_at<const C: usize>(c: &Conv, input: &[f64], lin: &Layout, g: &[f64], lout: &Layout, gw: &mut [f64]) {
    let (n, c_in, c_out) = (c.n, c.c_in, c.c_out);
    let m = 2 * n;
    let size = TAPS * c_in * c_out + c_out;
    let partials: Vec<Vec<f64>> = (0..m)
        .into_par_iter()
        .with_max_len(1)
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
                            if C == 0 {
                                for (&av, brow) in a.iter().zip(blk.chunks_exact_mut(c_out)) {
                                    for (bv, &gv) in brow.iter_mut().zip(gr) {
                                        *bv += av * gv;
                                    }
                                }
                            } else {
                                let gr: &[f64; C] = gr.try_into().expect("a row has C channels");
                                for (&av, brow) in a.iter().zip(blk.chunks_exact_mut(C)) {
                                    for j in 0..C {
                                        brow[j] += av * gr[j];
                                    }
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
pub(super) fn conv_grad_input(c: &Conv, w: &[f64], g: &[f64], lout: &Layout, lin: &Layout) -> Vec<f64> {
    by_width!(c.c_out, grad_input_at(c, w, g, lout, lin))
}

/// [`conv_grad_input`] with the output channels `C` known when compiling
/// (0: any); the same sums in the same order for every `C`.
fn grad_input_at<const C: usize>(c: &Conv, w: &[f64], g: &[f64], lout: &Layout, lin: &Layout) -> Vec<f64> {
    let (n, c_in, c_out) = (c.n, c.c_in, c.c_out);
    let m = 2 * n;
    let kernel = c.weights(w);
    let mut gin = vec![0.0; lin.rows() * c_in];
    gin.par_chunks_mut(ROWS * c_in).enumerate().for_each(|(t, part)| {
        for ((iz, yx), row) in lin.voxels_of(t * ROWS, part.len() / c_in).zip(part.chunks_exact_mut(c_in)) {
            let (oz, cz) = outs(iz, m);
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
                        if C == 0 {
                            for (r, krow) in row.iter_mut().zip(k.chunks_exact(c_out)) {
                                let mut s = 0.0;
                                for (&kv, &gv) in krow.iter().zip(gr) {
                                    s += kv * gv;
                                }
                                *r += s;
                            }
                        } else {
                            let gr: &[f64; C] = gr.try_into().expect("a row has C channels");
                            for (r, krow) in row.iter_mut().zip(k.chunks_exact(C)) {
                                let mut s = 0.0;
                                for j in 0..C {
                                    s += krow[j] * gr[j];
                                }
                                *r += s;
                            }
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
    use crate::model::normals;

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
    fn every_channel_width_gives_the_bits_of_the_generic_loops() {
        for c_out in [1, 2, 4, 8, 16] {
            let (n, c_in) = (3, 5);
            let conv = Conv { n, c_in, c_out, w_off: 0, b_off: TAPS * c_in * c_out };
            let w = normals(4, conv.b_off + c_out);
            let input = normals(5, n * n * n * c_in);
            let m = 2 * n;
            let (lin, lout) = (Layout::new(&vec![true; n * n * n], n), Layout::new(&vec![true; m * m * m], m));
            let (k, b) = (conv.weights(&w), &w[conv.b_off..]);
            let act = Act::Leaky;
            let out = conv_forward(&conv, k, b, &input, &lin, &lout, act);
            assert_eq!(out, forward_at::<f64, f64, 0>(&conv, k, b, &input, &lin, &lout, act));
            let g = normals(6, m * m * m * c_out);
            let (mut fast, mut generic) = (vec![0.0; w.len()], vec![0.0; w.len()]);
            conv_grad_weights(&conv, &input, &lin, &g, &lout, &mut fast);
            grad_weights_at::<0>(&conv, &input, &lin, &g, &lout, &mut generic);
            assert_eq!(fast, generic);
            assert_eq!(conv_grad_input(&conv, &w, &g, &lout, &lin), grad_input_at::<0>(&conv, &w, &g, &lout, &lin));
        }
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
}
