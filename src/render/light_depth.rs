//! Light transmittance for the camera rays from a grid (docs/DESIGN.md §2):
//! per light, the optical depth from every node a camera ray can read to
//! the light, marched once per render. Camera-ray samples read it
//! trilinearly and take `exp(-depth)`. Marching a shadow ray from every
//! sample of every camera ray costs samples x steps x shadow steps density
//! lookups, most of them repeating what the neighbouring samples just did;
//! the grid costs nodes x shadow steps, once. The price is the
//! interpolation between nodes, a bias measured against the path tracer
//! (results/bench_render) and avoided where the medium is too thick for it
//! ([`crate::scene::Shadows::Auto`]).
//!
//! The depth is linear in the density, so its derivatives are exact and
//! cheap: forward mode marches the same steps in dual numbers, reverse mode
//! sends each node's depth adjoint back along the same steps
//! ([`LightDepth::adjoint`]).

use super::march::Marcher;
use crate::ad::Real;
use crate::math::{Ray, Vec3};
use crate::rng::{Purpose, Rng};
use crate::scene::Light;
use crate::volume::Grid;
use rayon::prelude::*;

/// Per light (scene order), its optical-depth grid; `None` for a light of
/// zero intensity, which no camera ray reads.
pub type Depths<R> = Vec<Option<Grid<R>>>;

/// Where the depth grids have values and how they are marched.
#[derive(Clone, Debug)]
pub struct LightDepth {
    /// The depth grids' box and shape: cell-centred nodes every `cell`
    /// voxels, plus one layer of nodes outside the density's box ("pads").
    /// Lookups in the half-cell along a face read a pad. The density jumps
    /// to 0 at the faces, a kink in the depth that interpolating the true
    /// depth outside would smear over the half-cell where a medium lit
    /// through the face scatters most; pads hold the linear extrapolation
    /// of the two nodes inside instead ([`extrapolate_pads`]).
    lo: Vec3,
    hi: Vec3,
    shape: [usize; 3],
    /// Per value of a depth grid, whether it is an inner node that is
    /// marched: every node a camera-ray lookup inside the occupied blocks can
    /// read, or a pad it reads depends on (the others stay 0, never read).
    marched: Vec<bool>,
    /// The lights, scene order.
    lights: Vec<Light>,
    /// Extinction per unit density.
    scale: f64,
    /// Seed of the shadow rays' jitter.
    seed: u64,
}

/// Nodes per parallel task, at most. The marched nodes cluster where the
/// medium is, so a task of many nodes can hold much of the loop's work and
/// finish long after the other threads ran out.
const CHUNK: usize = 64;

impl LightDepth {
    /// Depth grids of `lights` over `marcher`'s box, a node every `cell`
    /// voxels of `density` (1: the voxel centres), with `sigma_t = scale *
    /// density`, shadow rays jittered from `seed`.
    pub fn new(marcher: &Marcher, density: &Grid<f64>, cell: usize, lights: &[Light], scale: f64, seed: u64) -> Self {
        let inner = density.shape.map(|n| n.div_ceil(cell.max(1)));
        let shape = inner.map(|n| n + 2);
        let e = density.hi - density.lo;
        let pad = Vec3::new(e.x / inner[2] as f64, e.y / inner[1] as f64, e.z / inner[0] as f64);
        let (lo, hi) = (density.lo - pad, density.hi + pad);
        let mut needed = vec![false; shape.iter().product()];
        marcher.majorant.reachable_nodes(&lo, &hi, shape).into_iter().for_each(|v| needed[v] = true);
        // Pads are filled along x, then y, then z: mark what each needed pad reads, in reverse.
        for axis in [2, 1, 0] {
            for_each_pad(shape, axis, |pad, from| {
                if needed[pad] {
                    from.iter().for_each(|&(v, _)| needed[v] = true);
                }
            });
        }
        let marched: Vec<bool> =
            (0..needed.len()).into_par_iter().with_min_len(4096).map(|v| needed[v] && !is_pad(shape, v)).collect();
        LightDepth { lo, hi, shape, marched, lights: lights.to_vec(), scale, seed }
    }

    /// The nodes that carry a depth and pass `keep` (flat indices into the
    /// depth grids), in order; found in parallel.
    pub fn nodes_where(&self, keep: impl Fn(usize) -> bool + Sync) -> Vec<usize> {
        (0..self.marched.len()).into_par_iter().with_min_len(4096).filter(|&v| self.marched[v] && keep(v)).collect()
    }

    /// Number of values of one depth grid.
    pub fn grid_len(&self) -> usize {
        self.shape.iter().product()
    }

    /// The shadow ray of node `v` towards `light` (number `l`): its ray,
    /// length and jitter; `None` if the node sits on the light.
    fn shadow_ray(&self, v: usize, l: usize, light: &Light) -> Option<(Ray, f64, f64)> {
        let [nz, ny, nx] = self.shape;
        let (k, j, i) = (v / (ny * nx), v / nx % ny, v % nx);
        let e = self.hi - self.lo;
        let from = self.lo
            + Vec3::new(
                (i as f64 + 0.5) * e.x / nx as f64,
                (j as f64 + 0.5) * e.y / ny as f64,
                (k as f64 + 0.5) * e.z / nz as f64,
            );
        let d: Vec3 = light.position - from;
        let dist = d.norm();
        if dist == 0.0 {
            return None;
        }
        let index = (l * self.grid_len() + v) as u64;
        let jitter = Rng::new(self.seed, Purpose::Shadow, index).uniform();
        Some((Ray { origin: from, dir: d / dist }, dist, jitter))
    }

    /// The optical depth to each light at every node of `density`. The
    /// same value whatever the number of threads: every node is one
    /// independent march.
    pub fn depths<R: Real>(&self, marcher: &Marcher, density: &Grid<R>) -> Depths<R> {
        self.lights
            .iter()
            .enumerate()
            .map(|(l, light)| {
                if light.intensity <= 0.0 {
                    return None;
                }
                // Over the whole grid, not only the marched nodes: a grid of dual numbers is large, and
                // filling it on one thread would be a serial part of every render.
                let mut data: Vec<R> = (0..self.grid_len())
                    .into_par_iter()
                    .with_max_len(CHUNK)
                    .map(|v| match self.marched[v].then(|| self.shadow_ray(v, l, light)).flatten() {
                        Some((ray, dist, jitter)) => marcher.optical_depth(density, self.scale, &ray, dist, jitter),
                        None => R::cst(0.0),
                    })
                    .collect();
                extrapolate_pads(self.shape, &mut data);
                Some(Grid::new(self.lo, self.hi, self.shape, data))
            })
            .collect()
    }

    /// Reverse mode of the pads: moves the adjoints of a depth grid's pads
    /// onto the inner nodes they extrapolate (pads end at 0).
    pub fn pad_adjoints(&self, adjoint: &mut [f64]) {
        for axis in [2, 1, 0] {
            for_each_pad(self.shape, axis, |pad, from| {
                let a = std::mem::take(&mut adjoint[pad]);
                if a != 0.0 {
                    from.iter().for_each(|&(v, w)| adjoint[v] += w * a);
                }
            });
        }
    }

    /// Reverse mode: given `dL/d depth` of light `l` at inner `node`, whose
    /// depth [`depths`](Self::depths) gave as `depth`, calls `add(voxel,
    /// dL/d rho)` for every density voxel its march reads.
    #[allow(clippy::too_many_arguments)]
    pub fn adjoint(
        &self,
        marcher: &Marcher,
        density: &Grid<f64>,
        l: usize,
        node: usize,
        depth: f64,
        adjoint: f64,
        add: &mut impl FnMut(usize, f64),
    ) {
        let light = &self.lights[l];
        if adjoint == 0.0 || light.intensity <= 0.0 {
            return;
        }
        if let Some((ray, dist, jitter)) = self.shadow_ray(node, l, light) {
            marcher.optical_depth_adjoint(density, self.scale, &ray, dist, jitter, depth, adjoint, add);
        }
    }
}

/// True if node `v` of a padded grid of `shape` is a pad along any axis.
fn is_pad(shape: [usize; 3], v: usize) -> bool {
    let [nz, ny, nx] = shape;
    let (k, j, i) = (v / (ny * nx), v / nx % ny, v % nx);
    k == 0 || k == nz - 1 || j == 0 || j == ny - 1 || i == 0 || i == nx - 1
}

/// How the pads across `axis` (0 = x) of a padded grid of `shape`
/// extrapolate: the axis' stride and length, and per pad its two sources
/// as (slices inward from the pad's face, weight): the linear
/// extrapolation `2 a - b` of the two nodes inside it (a constant `a`
/// where only one node is inside).
fn pad_rule(shape: [usize; 3], axis: usize) -> (usize, usize, [(usize, f64); 2]) {
    let [_, ny, nx] = shape;
    let n = shape[2 - axis];
    debug_assert!(n >= 3, "a padded axis has an inner node");
    let sources = if n >= 4 { [(1, 2.0), (2, -1.0)] } else { [(1, 1.0), (1, 0.0)] };
    ([1, nx, nx * ny][axis], n, sources)
}

/// Calls `visit(pad, [(source, weight); 2])` for every pad node along
/// `axis` of a padded grid of `shape` ([`pad_rule`]).
fn for_each_pad(shape: [usize; 3], axis: usize, mut visit: impl FnMut(usize, [(usize, f64); 2])) {
    let (stride, n, sources) = pad_rule(shape, axis);
    // Only the two faces across `axis`, in increasing flat order (the order
    // in which reverse mode adds to a node is that of the forward pass).
    for outer in 0..shape.iter().product::<usize>() / (stride * n) {
        for (c, inward) in [(0, 1isize), (n - 1, -1)] {
            for rest in 0..stride {
                let v = outer * stride * n + c * stride + rest;
                let at = |d: usize| (v as isize + d as isize * inward * stride as isize) as usize;
                visit(v, sources.map(|(d, w)| (at(d), w)));
            }
        }
    }
}

/// Pad nodes per parallel task of one face in [`extrapolate_pads`].
const PAD_PIECE: usize = 256;

/// Fills the pads of a padded grid of `shape` from its inner nodes, along
/// x, then y, then z (corners and edges extrapolate already filled pads):
/// the values [`for_each_pad`] would write, computed in parallel (the pads
/// across one axis read no pad across that axis). In parallel over the
/// blocks of the grid that hold two faces, and over pieces of a face: the
/// faces across z are one block, which would otherwise fill them on the
/// calling thread.
fn extrapolate_pads<R: Real>(shape: [usize; 3], data: &mut [R]) {
    for axis in [0, 1, 2] {
        let (stride, n, [(da, wa), (db, wb)]) = pad_rule(shape, axis);
        // Each block of `n` slices of `stride` nodes holds its two pad slices, 0 and n - 1.
        data.par_chunks_mut(stride * n).for_each(|block| {
            let (first, rest) = block.split_at_mut(stride);
            let (inner, last) = rest.split_at_mut((n - 2) * stride);
            let slice = |s: usize| &inner[s * stride..(s + 1) * stride];
            for (face, near, far) in
                [(first, slice(da - 1), slice(db - 1)), (last, slice(n - 2 - da), slice(n - 2 - db))]
            {
                let pieces =
                    face.par_chunks_mut(PAD_PIECE).zip(near.par_chunks(PAD_PIECE)).zip(far.par_chunks(PAD_PIECE));
                pieces.for_each(|((face, near), far)| {
                    face.iter_mut().zip(near).zip(far).for_each(|((f, a), b)| *f = *a * wa + *b * wb);
                });
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ad::tape::{self, Var};
    use crate::volume::majorant::MAJORANT_BLOCK;
    use crate::volume::Majorant;

    fn blob() -> Grid<f64> {
        let n = 12;
        let data = (0..n * n * n)
            .map(|v| {
                let (k, j, i) = (v / (n * n), v / n % n, v % n);
                let r2 = [k, j, i].iter().map(|&c| (c as f64 - 5.5).powi(2)).sum::<f64>();
                (1.0 - r2 / 30.0).max(0.0) * 2.0
            })
            .collect();
        Grid::new(Vec3::from_element(-1.0), Vec3::from_element(1.0), [n, n, n], data)
    }

    /// Only the faces are walked, in the order a walk over every node visits
    /// the pads (reverse mode's additions depend on it).
    #[test]
    fn pads_are_visited_as_a_full_walk_would() {
        for shape in [[3, 3, 3], [4, 5, 6], [7, 3, 9], [66, 66, 66]] {
            for axis in 0..3 {
                let [nz, ny, nx] = shape;
                let stride = [1, nx, nx * ny][axis];
                let n = shape[2 - axis];
                let mut want = vec![];
                for v in 0..nz * ny * nx {
                    let c = v / stride % n;
                    let inward: isize = match c {
                        0 => 1,
                        _ if c == n - 1 => -1,
                        _ => continue,
                    };
                    let at = |d: isize| (v as isize + d * inward * stride as isize) as usize;
                    let second = if n >= 4 { at(2) } else { at(1) };
                    want.push((v, at(1), second));
                }
                let mut got = vec![];
                for_each_pad(shape, axis, |v, [(a, _), (b, _)]| got.push((v, a, b)));
                assert_eq!(got, want, "shape {shape:?}, axis {axis}");
            }
        }
    }

    /// The parallel fill writes what the serial walk would, bit for bit.
    #[test]
    fn pads_extrapolate_as_the_serial_walk() {
        for shape in [[3, 3, 3], [4, 5, 6], [7, 3, 9], [20, 34, 66]] {
            let len = shape.iter().product::<usize>();
            let inner: Vec<f64> = (0..len).map(|v| ((v * 7919) % 1000) as f64 / 37.0 - 9.0).collect();
            let mut want = inner.clone();
            for axis in [0, 1, 2] {
                for_each_pad(shape, axis, |pad, [(a, wa), (b, wb)]| want[pad] = want[a] * wa + want[b] * wb);
            }
            let mut got = inner;
            extrapolate_pads(shape, &mut got);
            assert!(got.iter().zip(&want).all(|(g, w)| g.to_bits() == w.to_bits()), "shape {shape:?}");
        }
    }

    /// The reverse sweep of one node's depth equals the tape's derivative of
    /// the same march, voxel by voxel, also where the march stops at the
    /// depth cutoff (extinction 3000 per unit density: depths in the thousands).
    #[test]
    fn adjoint_matches_the_tape() {
        for scale in [3.0, 3000.0] {
            adjoint_matches_the_tape_at(scale);
        }
    }

    fn adjoint_matches_the_tape_at(scale: f64) {
        let density = blob();
        let majorant = Majorant::build(&density, MAJORANT_BLOCK);
        let marcher = Marcher::new(&density, majorant, 0.5 * density.voxel_size().min());
        let light = Light { position: Vec3::new(0.3, 2.5, -0.4), intensity: 1.0 };
        let depth = LightDepth::new(&marcher, &density, 2, std::slice::from_ref(&light), scale, 7);
        let nodes: Vec<usize> = depth.nodes_where(|_| true);
        let plain = depth.depths(&marcher, &density);
        let leaves = Grid::new(
            density.lo,
            density.hi,
            density.shape,
            (0..density.len()).map(|v| Var::leaf(v as u32, density.data[v])).collect(),
        );
        let mut stopped = 0;
        for &node in nodes.iter().step_by(7) {
            tape::reset();
            let (ray, dist, jitter) = depth.shadow_ray(node, 0, &light).unwrap();
            let d = marcher.optical_depth(&leaves, scale, &ray, dist, jitter);
            stopped += usize::from(d.value() >= 800.0);
            let mut want = vec![0.0; density.len()];
            tape::backward(&[(d, 1.5)], |leaf, a| want[leaf as usize] += a);
            let mut got = vec![0.0; density.len()];
            let primal = plain[0].as_ref().unwrap().data[node];
            depth.adjoint(&marcher, &density, 0, node, primal, 1.5, &mut |v, a| got[v] += a);
            for v in 0..density.len() {
                assert!((got[v] - want[v]).abs() <= 1e-12 * (1.0 + want[v].abs()), "node {node}, voxel {v}");
            }
            assert_eq!(plain[0].as_ref().unwrap().data[node].to_bits(), d.value().to_bits());
        }
        tape::reset();
        assert_eq!(stopped > 0, scale > 100.0, "extinction {scale}: {stopped} marches stopped at the cutoff");
    }
}
