//! Adam (Kingma & Ba 2015) for one block of parameters, with its own
//! learning rate; coordinates without a gradient this step can be skipped
//! (their moments are left as they are).

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
        for (&i, &g) in index.iter().zip(grad) {
            if !g.is_finite() {
                continue; // A non-finite gradient entry is a bug upstream; never let it into the parameters.
            }
            self.t[i] += 1;
            let t = self.t[i] as i32;
            self.m[i] = self.beta1 * self.m[i] + (1.0 - self.beta1) * g;
            self.v[i] = self.beta2 * self.v[i] + (1.0 - self.beta2) * g * g;
            let m_hat = self.m[i] / (1.0 - self.beta1.powi(t));
            let v_hat = self.v[i] / (1.0 - self.beta2.powi(t));
            params[i] -= self.lr * m_hat / (v_hat.sqrt() + self.eps);
        }
    }

    /// The moments and per-coordinate step counts (to save a checkpoint).
    pub fn state(&self) -> (&[f64], &[f64], &[u32]) {
        (&self.m, &self.v, &self.t)
    }

    /// Adam resumed from a saved [`Adam::state`]; `None` if the lengths differ.
    pub fn resume(lr: f64, m: Vec<f64>, v: Vec<f64>, t: Vec<u32>) -> Option<Adam> {
        (m.len() == v.len() && v.len() == t.len()).then(|| Adam { m, v, t, ..Adam::new(0, lr) })
    }

    /// Applies a dense gradient.
    pub fn step(&mut self, params: &mut [f64], grad: &[f64]) {
        let index: Vec<usize> = (0..params.len()).collect();
        self.step_sparse(params, &index, grad);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
