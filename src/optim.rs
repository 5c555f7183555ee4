//! Adam (Kingma & Ba 2015) for one block of parameters, with its own
//! learning rate; coordinates without a gradient this step can be skipped
//! (their moments are left as they are).

use rayon::prelude::*;

/// Adam state for `n` parameters.
#[derive(Clone, Debug)]
pub struct Adam {
    /// Step size.
    pub lr: f64,
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Denominator floor.
    pub eps: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    /// Updates seen per coordinate (for bias correction).
    t: Vec<u32>,
}

impl Adam {
    /// Adam with the usual betas (0.9, 0.999) for `n` parameters.
    pub fn new(n: usize, lr: f64) -> Self {
        Adam { lr, beta1: 0.9, beta2: 0.999, eps: 1e-8, m: vec![0.0; n], v: vec![0.0; n], t: vec![0; n] }
    }

    /// Applies the gradient `grad[i]` to `params[index[i]]` for every i.
    pub fn step_sparse(&mut self, params: &mut [f64], index: &[usize], grad: &[f64]) {
        let rule = self.rule();
        for (&i, &g) in index.iter().zip(grad) {
            rule.apply(&mut params[i], &mut self.m[i], &mut self.v[i], &mut self.t[i], g);
        }
    }

    /// The constants of one update.
    fn rule(&self) -> Rule {
        Rule { lr: self.lr, beta1: self.beta1, beta2: self.beta2, eps: self.eps }
    }

    /// The moments and per-coordinate step counts (to save a checkpoint).
    pub fn state(&self) -> (&[f64], &[f64], &[u32]) {
        (&self.m, &self.v, &self.t)
    }

    /// Adam resumed from a saved [`Adam::state`]; `None` if the lengths differ.
    pub fn resume(lr: f64, m: Vec<f64>, v: Vec<f64>, t: Vec<u32>) -> Option<Adam> {
        (m.len() == v.len() && v.len() == t.len()).then(|| Adam { m, v, t, ..Adam::new(0, lr) })
    }

    /// Applies a dense gradient; coordinate by coordinate in parallel (a
    /// serial part of every update otherwise).
    pub fn step(&mut self, params: &mut [f64], grad: &[f64]) {
        let rule = self.rule();
        let n = params.len().min(grad.len());
        (&mut params[..n], &grad[..n], &mut self.m[..n], &mut self.v[..n], &mut self.t[..n])
            .into_par_iter()
            .with_min_len(4096)
            .for_each(|(p, &g, m, v, t)| rule.apply(p, m, v, t, g));
    }
}

/// Adam's constants for one step.
#[derive(Clone, Copy)]
struct Rule {
    lr: f64,
    beta1: f64,
    beta2: f64,
    eps: f64,
}

impl Rule {
    /// Updates one coordinate `p` with moments `m`, `v` and count `t` by gradient `g`.
    #[inline]
    fn apply(self, p: &mut f64, m: &mut f64, v: &mut f64, t: &mut u32, g: f64) {
        if !g.is_finite() {
            return; // A non-finite gradient entry is a bug upstream; never let it into the parameters.
        }
        *t += 1;
        let ti = *t as i32;
        *m = self.beta1 * *m + (1.0 - self.beta1) * g;
        *v = self.beta2 * *v + (1.0 - self.beta2) * g * g;
        let m_hat = *m / (1.0 - self.beta1.powi(ti));
        let v_hat = *v / (1.0 - self.beta2.powi(ti));
        *p -= self.lr * m_hat / (v_hat.sqrt() + self.eps);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_parallel_dense_step_is_the_sparse_one_over_every_coordinate() {
        let n = 10_000;
        let x0: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut a, mut b) = (x0.clone(), x0);
        let (mut adam_a, mut adam_b) = (Adam::new(n, 0.01), Adam::new(n, 0.01));
        let all: Vec<usize> = (0..n).collect();
        for step in 0..3 {
            let mut g: Vec<f64> = (0..n).map(|i| (i as f64 * 1.3 + step as f64).cos()).collect();
            g[17] = f64::NAN;
            adam_a.step(&mut a, &g);
            adam_b.step_sparse(&mut b, &all, &g);
        }
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        assert_eq!(adam_a.state().2, adam_b.state().2);
    }

    #[test]
    fn minimises_a_quadratic() {
        let mut x = vec![3.0, -2.0];
        let mut adam = Adam::new(2, 0.1);
        for _ in 0..500 {
            let g = vec![2.0 * x[0], 20.0 * x[1]];
            adam.step(&mut x, &g);
        }
        assert!(x[0].abs() < 1e-2 && x[1].abs() < 1e-2, "{x:?}");
    }
}
