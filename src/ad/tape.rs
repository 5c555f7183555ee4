//! Reverse mode, the project's own: `Var` is a `Copy` value plus an id that
//! names a node of the calling thread's tape, a leaf (a parameter, numbered
//! by the caller) or nothing (a constant: constants never touch the tape).
//! A tape records one independent unit of work (one pixel, one photon path),
//! is swept backwards once with [`backward`], and is [`reset`] for the
//! next unit; it is never shared between threads, so rayon workers each
//! fill their own.

use super::Real;
use std::cell::RefCell;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub};

/// A number recorded on the thread's tape.
#[derive(Clone, Copy, Debug)]
pub struct Var {
    val: f64,
    id: u32,
}

/// Id of constants.
const CONST: u32 = u32::MAX;
/// Ids from here up to (not including) `CONST` are leaves `id - LEAF_BASE`.
const LEAF_BASE: u32 = 1 << 31;
/// Largest leaf index.
pub const MAX_LEAF: u32 = CONST - LEAF_BASE - 1;

#[derive(Default)]
struct Tape {
    /// Node `i` has parents `parents[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    parents: Vec<u32>,
    partials: Vec<f64>,
    adjoint: Vec<f64>,
}

thread_local! {
    static TAPE: RefCell<Tape> = RefCell::new(Tape { start: vec![0], ..Default::default() });
}

impl Var {
    /// A constant.
    #[inline]
    pub fn constant(val: f64) -> Self {
        Var { val, id: CONST }
    }

    /// Parameter number `index` (at most [`MAX_LEAF`]) with value `val`.
    #[inline]
    pub fn leaf(index: u32, val: f64) -> Self {
        assert!(index <= MAX_LEAF, "leaf index {index} out of range");
        Var { val, id: LEAF_BASE + index }
    }

    /// The value.
    #[inline]
    pub fn value(&self) -> f64 {
        self.val
    }

    /// True if no parameter reaches this value.
    #[inline]
    pub fn is_constant(&self) -> bool {
        self.id == CONST
    }

    /// A node of value `val` with the given (parent, partial) pairs; constant parents are dropped.
    #[inline]
    fn node<const N: usize>(val: f64, parents: [(u32, f64); N]) -> Self {
        if parents.iter().all(|p| p.0 == CONST) {
            return Var::constant(val);
        }
        TAPE.with(|t| {
            let mut t = t.borrow_mut();
            for (id, partial) in parents {
                if id != CONST {
                    t.parents.push(id);
                    t.partials.push(partial);
                }
            }
            let end = t.parents.len() as u32;
            t.start.push(end);
            let id = t.start.len() as u32 - 2;
            assert!(id < LEAF_BASE, "tape overflow: reset the tape between units of work");
            Var { val, id }
        })
    }
}

/// Sweeps the thread's tape backwards from `seeds` (output, adjoint) and
/// calls `leaf(index, adjoint)` for every leaf contribution (a leaf may be
/// reported several times; the caller adds them up). The tape is kept.
pub fn backward(seeds: &[(Var, f64)], mut leaf: impl FnMut(u32, f64)) {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        let nodes = t.start.len() - 1;
        let Tape { start, parents, partials, adjoint } = &mut *t;
        adjoint.clear();
        adjoint.resize(nodes, 0.0);
        for &(v, a) in seeds {
            match v.id {
                CONST => {}
                id if id >= LEAF_BASE => leaf(id - LEAF_BASE, a),
                id => adjoint[id as usize] += a,
            }
        }
        for i in (0..nodes).rev() {
            let a = adjoint[i];
            if a == 0.0 {
                continue;
            }
            for e in start[i] as usize..start[i + 1] as usize {
                let (p, d) = (parents[e], partials[e]);
                if p >= LEAF_BASE {
                    leaf(p - LEAF_BASE, a * d);
                } else {
                    adjoint[p as usize] += a * d;
                }
            }
        }
    })
}

/// Empties the thread's tape (its memory is kept for the next unit).
pub fn reset() {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        t.start.truncate(1);
        t.parents.clear();
        t.partials.clear();
    })
}

/// Bytes the thread's tape holds now (capacity), for memory reports.
pub fn tape_bytes() -> usize {
    TAPE.with(|t| {
        let t = t.borrow();
        t.start.capacity() * 4 + t.parents.capacity() * 4 + t.partials.capacity() * 8 + t.adjoint.capacity() * 8
    })
}

impl Add for Var {
    type Output = Var;
    #[inline]
    fn add(self, o: Var) -> Var {
        Var::node(self.val + o.val, [(self.id, 1.0), (o.id, 1.0)])
    }
}

impl Sub for Var {
    type Output = Var;
    #[inline]
    fn sub(self, o: Var) -> Var {
        Var::node(self.val - o.val, [(self.id, 1.0), (o.id, -1.0)])
    }
}

impl Mul for Var {
    type Output = Var;
    #[inline]
    fn mul(self, o: Var) -> Var {
        Var::node(self.val * o.val, [(self.id, o.val), (o.id, self.val)])
    }
}

impl Div for Var {
    type Output = Var;
    #[inline]
    fn div(self, o: Var) -> Var {
        let q = self.val / o.val;
        Var::node(q, [(self.id, 1.0 / o.val), (o.id, -q / o.val)])
    }
}

impl Neg for Var {
    type Output = Var;
    #[inline]
    fn neg(self) -> Var {
        Var::node(-self.val, [(self.id, -1.0)])
    }
}

impl Add<f64> for Var {
    type Output = Var;
    #[inline]
    fn add(self, o: f64) -> Var {
        Var::node(self.val + o, [(self.id, 1.0)])
    }
}

impl Sub<f64> for Var {
    type Output = Var;
    #[inline]
    fn sub(self, o: f64) -> Var {
        Var::node(self.val - o, [(self.id, 1.0)])
    }
}

impl Mul<f64> for Var {
    type Output = Var;
    #[inline]
    fn mul(self, o: f64) -> Var {
        Var::node(self.val * o, [(self.id, o)])
    }
}

impl Div<f64> for Var {
    type Output = Var;
    #[inline]
    fn div(self, o: f64) -> Var {
        Var::node(self.val / o, [(self.id, 1.0 / o)])
    }
}

impl AddAssign for Var {
    #[inline]
    fn add_assign(&mut self, o: Var) {
        *self = *self + o;
    }
}

impl MulAssign for Var {
    #[inline]
    fn mul_assign(&mut self, o: Var) {
        *self = *self * o;
    }
}

impl Real for Var {
    #[inline]
    fn cst(x: f64) -> Self {
        Var::constant(x)
    }
    #[inline]
    fn re(&self) -> f64 {
        self.val
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.val.exp();
        Var::node(e, [(self.id, e)])
    }
    #[inline]
    fn exp_m1(self) -> Self {
        Var::node(self.val.exp_m1(), [(self.id, self.val.exp())])
    }
    #[inline]
    fn is_exact_zero(&self) -> bool {
        self.val == 0.0 && self.id == CONST
    }
    #[inline]
    fn weighted_sum8(values: [&Self; 8], weights: [f64; 8]) -> Self {
        // Same operation order as the default, so the primal is bit-identical to f64's.
        let mut val = values[0].val * weights[0];
        for c in 1..8 {
            val += values[c].val * weights[c];
        }
        Var::node(val, std::array::from_fn::<_, 8, _>(|c| (values[c].id, weights[c])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_of_a_small_function() {
        reset();
        let (x, y) = (Var::leaf(0, 0.7), Var::leaf(1, -1.3));
        // f = exp(x y) / (x + 2) - 3 y
        let f = (x * y).exp() / (x + 2.0) - y * 3.0;
        let mut g = [0.0; 2];
        backward(&[(f, 1.0)], |i, a| g[i as usize] += a);
        let e = (0.7f64 * -1.3).exp();
        let dx = e * -1.3 / 2.7 - e / (2.7 * 2.7);
        let dy = e * 0.7 / 2.7 - 3.0;
        assert!((g[0] - dx).abs() < 1e-14 && (g[1] - dy).abs() < 1e-14);
        reset();
    }

    #[test]
    fn constants_stay_off_the_tape() {
        reset();
        let c = Var::constant(2.0) * 3.0 + 1.0;
        assert!(c.is_constant());
        assert_eq!(TAPE.with(|t| t.borrow().start.len()), 1);
    }
}
