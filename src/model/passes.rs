//! The decoder's two derivative paths: the forward pass (generic over
//! [`Real`]) and the reverse-mode vector-Jacobian product (`f64`), both
//! evaluating only the voxels the mask needs (see `layout`) with the layer
//! kernels of `conv`.
//!
//! Meant for `f64` and the dual types. Not for the tape type `Var`: the
//! forward pass runs on rayon workers and each thread has its own tape;
//! reverse mode is [`Decoder::backward`].

use super::conv::{conv_forward, conv_grad_input, conv_grad_weights, Act};
use super::decoder::{Decoder, BASE};
use super::layout::Layout;
use crate::ad::Real;
use rayon::prelude::*;
use std::sync::Arc;

impl Decoder {
    /// Where each grid is evaluated: the base grid (everywhere), then each
    /// convolution's output; the last is `mask`, each earlier one what the
    /// next one reads. Planned once per mask (see [`super::layout::Plans`]).
    fn layouts(&self, mask: &[bool]) -> Arc<Vec<Layout>> {
        let edges: Vec<usize> = self.convs.iter().map(|c| c.n).collect();
        self.plans.get(mask, self.res, &edges)
    }

    /// Panics on a wrong length: every caller builds `z`, `w` and `mask`
    /// for this decoder, so only a bug gets here.
    fn check(&self, z: usize, w: usize, mask: usize) {
        assert_eq!(z, self.latent, "Decoder: latent has the wrong length");
        assert_eq!(w, self.n_params, "Decoder: parameter vector has the wrong length");
        assert_eq!(mask, self.res.pow(3), "Decoder: mask has the wrong length");
    }

    /// The base grid, then every convolution's output, post-activation and
    /// stored in `layouts` (the last is the density at the mask's voxels).
    fn activations<R: Real>(&self, z: &[R], w: Weights<'_, R>, layouts: &[Layout]) -> Vec<Vec<R>> {
        let n0 = BASE.pow(3) * self.c0;
        let split = self.latent * n0;
        let base = match w {
            Weights::Plain(w) => base_layer(z, &w[..split], &w[split..split + n0], R::cst),
            Weights::Carrying(w) => base_layer(z, &w[..split], &w[split..split + n0], |b| b),
        };
        let mut acts = vec![base];
        for (l, c) in self.convs.iter().enumerate() {
            let act = if l + 1 == self.convs.len() { self.out_act() } else { Act::Leaky };
            let (lin, lout) = (&layouts[l], &layouts[l + 1]);
            let next = match w {
                Weights::Plain(w) => {
                    let bias: Vec<R> = w[c.b_off..c.b_off + c.c_out].iter().map(|&b| R::cst(b)).collect();
                    conv_forward(c, c.weights(w), &bias, &acts[l], lin, lout, act)
                }
                Weights::Carrying(w) => {
                    conv_forward(c, c.weights(w), &w[c.b_off..c.b_off + c.c_out], &acts[l], lin, lout, act)
                }
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
    /// let d = Decoder::paper_small(8)?;
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mut mask = vec![true; 8 * 8 * 8];
    /// mask[0] = false;
    /// let rho = d.forward(&z, &w, &mask);
    /// assert_eq!(rho[0], 0.0);
    /// assert!(rho.iter().all(|&r| r >= 0.0));
    /// # Ok::<(), dualphoton::error::Error>(())
    /// ```
    pub fn forward<R: Real>(&self, z: &[R], w: &[R], mask: &[bool]) -> Vec<R> {
        self.check(z.len(), w.len(), mask.len());
        let plain = plain_values(w);
        let layouts = self.layouts(mask);
        let acts = self.activations(z, Weights::of(w, plain.as_deref()), &layouts);
        self.dense(&layouts, &acts)
    }

    /// [`Decoder::forward`] with weights that carry no derivative, given
    /// as plain numbers: the same values, without a copy of the weights in
    /// `R` (for 64-lane duals and a large decoder, hundreds of megabytes).
    ///
    /// ```
    /// use dualphoton::model::Decoder;
    /// use num_dual::Dual64;
    /// let d = Decoder::paper_small(8)?;
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mask = vec![true; 512];
    /// let zd: Vec<Dual64> = z.iter().map(|&v| Dual64::new(v, 1.0)).collect();
    /// let wd: Vec<Dual64> = w.iter().map(|&v| Dual64::from(v)).collect();
    /// let (a, b) = (d.forward_fixed_weights(&zd, &w, &mask), d.forward(&zd, &wd, &mask));
    /// assert!(a.iter().zip(&b).all(|(a, b)| a.re == b.re && a.eps == b.eps));
    /// # Ok::<(), dualphoton::error::Error>(())
    /// ```
    pub fn forward_fixed_weights<R: Real>(&self, z: &[R], w: &[f64], mask: &[bool]) -> Vec<R> {
        self.check(z.len(), w.len(), mask.len());
        let layouts = self.layouts(mask);
        let acts = self.activations(z, Weights::Plain(w), &layouts);
        self.dense(&layouts, &acts)
    }

    /// The last layer's output as a dense grid (0 where it is not evaluated).
    fn dense<R: Real>(&self, layouts: &[Layout], acts: &[Vec<R>]) -> Vec<R> {
        let (lout, density) = (&layouts[self.convs.len()], &acts[self.convs.len()]);
        // Scattered in parallel: for K-lane duals at res 128 the dense grid
        // is ~170 MB, and writing it costs more than the arithmetic.
        let mut out = Vec::new();
        (0..self.res.pow(3))
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
    /// let d = Decoder::paper_small(8)?;
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mask: Vec<bool> = (0..512).map(|v| v % 3 == 0).collect();
    /// let dense = d.forward(&z, &w, &mask);
    /// let inside: Vec<f64> = (0..512).filter(|v| mask[*v]).map(|v| dense[v]).collect();
    /// assert_eq!(d.forward_masked(&z, &w, &mask), inside);
    /// # Ok::<(), dualphoton::error::Error>(())
    /// ```
    pub fn forward_masked<R: Real>(&self, z: &[R], w: &[R], mask: &[bool]) -> Vec<R> {
        self.check(z.len(), w.len(), mask.len());
        let plain = plain_values(w);
        let layouts = self.layouts(mask);
        let mut acts = self.activations(z, Weights::of(w, plain.as_deref()), &layouts);
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
    /// let d = Decoder::paper_small(8)?;
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mask = vec![true; 512];
    /// let (gz, gw) = d.backward(&z, &w, &mask, &vec![1.0; 512]);
    /// assert_eq!((gz.len(), gw.len()), (64, d.param_count()));
    /// # Ok::<(), dualphoton::error::Error>(())
    /// ```
    pub fn backward(&self, z: &[f64], w: &[f64], mask: &[bool], grad_out: &[f64]) -> (Vec<f64>, Vec<f64>) {
        self.check(z.len(), w.len(), mask.len());
        let layouts = self.layouts(mask);
        let acts = self.activations(z, Weights::Plain(w), &layouts);
        self.backward_from(z, w, mask, &layouts, &acts, grad_out)
    }

    /// [`Decoder::forward`], then [`Decoder::backward`] with `grad_out =
    /// grad_of(density)`, evaluating the layers once for both: returns
    /// `(density, dL/dz, dL/dw)`, the same bits as the two calls.
    ///
    /// ```
    /// use dualphoton::model::Decoder;
    /// let d = Decoder::paper_small(8)?;
    /// let (z, w) = (d.init_latent(1), d.init(1));
    /// let mask = vec![true; 512];
    /// let (rho, gz, gw) = d.forward_backward(&z, &w, &mask, |rho| rho.to_vec());
    /// assert_eq!(rho, d.forward(&z, &w, &mask));
    /// assert_eq!((gz, gw), d.backward(&z, &w, &mask, &rho));
    /// # Ok::<(), dualphoton::error::Error>(())
    /// ```
    pub fn forward_backward(
        &self,
        z: &[f64],
        w: &[f64],
        mask: &[bool],
        grad_of: impl FnOnce(&[f64]) -> Vec<f64>,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        self.check(z.len(), w.len(), mask.len());
        let layouts = self.layouts(mask);
        let acts = self.activations(z, Weights::Plain(w), &layouts);
        let density = self.dense(&layouts, &acts);
        let grad_out = grad_of(&density);
        let (gz, gw) = self.backward_from(z, w, mask, &layouts, &acts, &grad_out);
        (density, gz, gw)
    }

    /// The vector-Jacobian product from the activations of a forward pass.
    fn backward_from(
        &self,
        z: &[f64],
        w: &[f64],
        mask: &[bool],
        layouts: &[Layout],
        acts: &[Vec<f64>],
        grad_out: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        assert_eq!(grad_out.len(), mask.len(), "Decoder: grad_out has the wrong length");
        let mut gw = vec![0.0; self.n_params];
        // g: dL/d(pre-activation) of the current layer's output, stored like it.
        let last = self.out_act();
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

/// The decoder weights as a forward pass reads them.
#[derive(Clone, Copy)]
enum Weights<'a, R> {
    /// Without derivatives (the usual case when differentiating with
    /// respect to the latent only): plain numbers, cheaper to multiply.
    Plain(&'a [f64]),
    /// Carrying tangents (directional derivatives in weight space).
    Carrying(&'a [R]),
}

impl<'a, R> Weights<'a, R> {
    /// `w` as plain numbers where [`plain_values`] found them so.
    fn of(w: &'a [R], plain: Option<&'a [f64]>) -> Self {
        plain.map_or(Weights::Carrying(w), Weights::Plain)
    }
}

/// The primal values of `w` if no weight carries a derivative (`x -
/// re(x)` is an exact zero iff `x` has no tangent).
fn plain_values<R: Real>(w: &[R]) -> Option<Vec<f64>> {
    w.par_iter().all(|x| (*x - R::cst(x.re())).is_exact_zero()).then(|| w.par_iter().map(R::re).collect())
}

/// The linear layer from the latent to the base grid, LeakyReLU'd: output
/// `j` is `bias_j + sum_k weights[j, k] z_k`, rows in parallel (each the
/// same sum in the same order, whatever the threads).
fn base_layer<R, W>(z: &[R], weights: &[W], biases: &[W], lift: impl Fn(W) -> R + Sync) -> Vec<R>
where
    R: Real + std::ops::Mul<W, Output = R>,
    W: Copy + Send + Sync,
{
    weights
        .par_chunks_exact(z.len())
        .zip(biases)
        .map(|(row, &b)| {
            let mut s = lift(b);
            for (&wv, &zv) in row.iter().zip(z) {
                s += zv * wv;
            }
            Act::Leaky.apply(s)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ad::dual::{lane, with_tangents};
    use crate::model::{ball, normals};
    use num_dual::{Dual64, DualSVec64};

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
        // A leaky last layer (as a prior is trained with) takes the same paths.
        let leaky = Decoder::new(6, 16, &[3, 4]).unwrap().with_out_leak(0.05).with_out_scale(0.3);
        vec![(Decoder::paper_small(16).unwrap(), ball(16, 6.5)), (deep, scattered), (leaky, ball(16, 7.5))]
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
    fn fixed_weights_give_the_bits_of_tangent_free_dual_weights() {
        for (d, mask) in cases() {
            let (z, w) = (d.init_latent(21), d.init(21));
            let dirs = normals(22, 4 * z.len());
            let zd: Vec<DualSVec64<4>> =
                (0..z.len()).map(|i| with_tangents(z[i], std::array::from_fn(|k| dirs[k * z.len() + i]))).collect();
            let wd: Vec<DualSVec64<4>> = w.iter().map(|&v| DualSVec64::from_re(v)).collect();
            let (fixed, dual) = (d.forward_fixed_weights(&zd, &w, &mask), d.forward(&zd, &wd, &mask));
            for (a, b) in fixed.iter().zip(&dual) {
                assert_eq!(a.re.to_bits(), b.re.to_bits());
                for k in 0..4 {
                    assert_eq!(lane(a, k).to_bits(), lane(b, k).to_bits(), "res {} lane {k}", d.res);
                }
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
        let d = Decoder::paper_small(16).unwrap();
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
            let d = Decoder::paper_small(res).unwrap();
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
                time(|| d.clone().layouts(&mask))
            );
        }
    }
}
