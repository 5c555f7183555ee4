//! Reverse mode with the project's tape: `rev-full` (every pixel and every
//! photon path) and `rev-sub` (the paper's approximate learning: a random
//! subset of pixels and of photon paths, scaled so the estimate stays
//! unbiased).
//!
//! The gradient is assembled in three sweeps, each over independent units
//! with a tape of their own: (1) every differentiated pixel records its
//! ray-march on the tape with the density voxels, the photon-estimate grid
//! nodes and the light-depth grid nodes as leaves, and is swept back with
//! `dL/dÎ`; the light-depth adjoints go back along each node's shadow ray
//! (linear: no tape); (2) the adjoints of
//! the estimate's nodes become adjoints of the photon powers (the estimate is
//! linear in them, with the frozen kernel weights); (3) every differentiated
//! photon path is replayed on the tape and swept back from its powers.
//! Contributions are summed per fixed chunk of units and the chunks in
//! order, so the result does not depend on the number of threads.

use super::loss::mse_residuals;
use crate::ad::tape::{self, Var};
use crate::image::Image;
use crate::par;
use crate::render::frozen::Frozen;
use crate::render::splat::{phase_towards, Estimate};
use crate::rng::{Purpose, Rng};
use crate::volume::Grid;
use rayon::prelude::*;

/// Which units reverse mode differentiates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Subset {
    /// Pixels (over all cameras) to differentiate; `None`: all (the paper: 1,000).
    pub pixels: Option<usize>,
    /// Photon paths to differentiate; `None`: all (the paper: 5,000 of 300,000).
    pub paths: Option<usize>,
    /// Seed of the subset draws.
    pub seed: u64,
}

impl Subset {
    /// Every pixel and every path: `rev-full`.
    pub fn full() -> Self {
        Subset { pixels: None, paths: None, seed: 0 }
    }
}

/// A reverse-mode gradient and what it cost.
#[derive(Clone, Debug)]
pub struct Reverse {
    /// The loss at the frozen density.
    pub loss: f64,
    /// `dL/drho` per voxel (C order, like the density).
    pub grad: Vec<f64>,
    /// Largest tape one unit needed (bytes).
    pub peak_tape_bytes: usize,
}

/// Units per chunk: contributions are summed per chunk, then chunks in order.
const CHUNK: usize = 32;

/// Per-thread dense adjoints plus the touched leaves, kept by each thread
/// from sweep to sweep: a fresh one per chunk cleared megabytes each time.
struct Scratch {
    adjoint: Vec<f64>,
    /// One bit per leaf: touched since the last drain.
    seen: Vec<u64>,
    touched: Vec<u32>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = const { std::cell::RefCell::new(Scratch::new()) };
}

impl Scratch {
    /// An empty scratch, with room for no leaf yet.
    const fn new() -> Self {
        Scratch { adjoint: Vec::new(), seen: Vec::new(), touched: Vec::new() }
    }

    /// Room for `leaves` leaves (a drained scratch is all zero, whatever its size).
    fn reserve(&mut self, leaves: usize) {
        if self.adjoint.len() < leaves {
            self.adjoint.resize(leaves, 0.0);
            self.seen.resize(leaves.div_ceil(64), 0);
        }
    }

    #[inline]
    fn add(&mut self, leaf: u32, a: f64) {
        let l = leaf as usize;
        let (word, bit) = (l / 64, 1u64 << (l % 64));
        if self.seen[word] & bit == 0 {
            self.seen[word] |= bit;
            self.touched.push(leaf);
        }
        self.adjoint[l] += a;
    }

    /// The touched leaves' adjoints, in increasing leaf order (so that a
    /// merge can find a range of leaves by bisection), and a clean scratch.
    /// Where the touched leaves are dense in their range, reading the bits
    /// in order is cheaper than sorting them; both give the same list.
    fn drain(&mut self) -> Vec<(u32, f64)> {
        let mut out = Vec::with_capacity(self.touched.len());
        let Some(lo) = self.touched.iter().min() else { return out };
        let hi = self.touched.iter().max().unwrap();
        let words = (*lo as usize / 64)..(*hi as usize / 64 + 1);
        let mut take = |l: usize, out: &mut Vec<(u32, f64)>| out.push((l as u32, std::mem::take(&mut self.adjoint[l])));
        if words.len() <= 8 * self.touched.len() {
            for word in words {
                let mut bits = std::mem::take(&mut self.seen[word]);
                while bits != 0 {
                    take(word * 64 + bits.trailing_zeros() as usize, &mut out);
                    bits &= bits - 1;
                }
            }
        } else {
            self.touched.sort_unstable();
            for &l in &self.touched {
                self.seen[l as usize / 64] = 0;
                take(l as usize, &mut out);
            }
        }
        self.touched.clear();
        out
    }
}

/// `count` distinct indices below `n`, drawn uniformly (sorted), and `n / count`.
fn draw_subset(n: usize, count: Option<usize>, rng: &mut Rng) -> (Vec<usize>, f64) {
    match count {
        Some(c) if c < n => {
            // Floyd's algorithm: c draws, no n-sized allocation.
            let mut chosen = std::collections::BTreeSet::new();
            for j in n - c..n {
                let t = rng.below(j as u64 + 1) as usize;
                if !chosen.insert(t) {
                    chosen.insert(j);
                }
            }
            (chosen.into_iter().collect(), n as f64 / c as f64)
        }
        _ => ((0..n).collect(), 1.0),
    }
}

/// Runs `unit(scratch, index)` for every index in chunks of [`CHUNK`] and
/// adds the leaf adjoints into `total` in chunk order. Returns the peak tape size.
fn sweep(indices: &[usize], leaves: usize, total: &mut [f64], unit: impl Fn(&mut Scratch, usize) + Sync) -> usize {
    let parts: Vec<(Vec<(u32, f64)>, usize)> = indices
        .par_chunks(CHUNK)
        .with_max_len(1)
        .map(|chunk| {
            SCRATCH.with_borrow_mut(|scratch| {
                scratch.reserve(leaves);
                let mut peak = 0;
                for &i in chunk {
                    tape::reset();
                    unit(scratch, i);
                    peak = peak.max(tape::tape_bytes());
                    tape::reset();
                }
                (scratch.drain(), peak)
            })
        })
        .collect();
    merge(&parts.iter().map(|(part, _)| part.as_slice()).collect::<Vec<_>>(), total);
    let peak = parts.iter().map(|&(_, p)| p).max().unwrap_or(0);
    // Thousands of parts: freed on one thread, a serial part of every sweep.
    parts.into_par_iter().for_each(drop);
    peak
}

/// Adds every part's `(leaf, adjoint)` pairs (each sorted by leaf) to
/// `total`, in parallel over ranges of leaves; each leaf still receives its
/// adjoints in part order, so the sums do not depend on the number of threads.
fn merge(parts: &[&[(u32, f64)]], total: &mut [f64]) {
    // A few ranges per thread: every range bisects every part, and there
    // are thousands of parts (one per 32 pixels or paths); ranges of 4096
    // leaves made `rev-full` at 128^3 1.6x slower than a serial merge.
    let size = total.len().div_ceil(4 * rayon::current_num_threads()).max(4096);
    total.par_chunks_mut(size).enumerate().for_each(|(r, range)| {
        let (lo, hi) = ((r * size) as u32, (r * size + range.len()) as u32);
        for part in parts {
            let from = part.partition_point(|&(l, _)| l < lo);
            for &(l, a) in part[from..].iter().take_while(|&&(l, _)| l < hi) {
                range[(l - lo) as usize] += a;
            }
        }
    });
}

/// `values` as tape leaves numbered from `first`.
fn leaves(values: &[f64], first: usize) -> Vec<Var> {
    values.par_iter().enumerate().map(|(n, &v)| Var::leaf((first + n) as u32, v)).collect()
}

/// `grid` with its values as tape leaves numbered from `first` (C order).
fn leaf_grid(grid: &Grid<f64>, first: usize) -> Grid<Var> {
    Grid::new(grid.lo, grid.hi, grid.shape, leaves(&grid.data, first))
}

/// `dL/drho` of the frozen estimator by reverse mode over `subset`. The
/// targets belong to the scene's first `targets.len()` cameras.
pub fn reverse_gradient(frozen: &Frozen, targets: &[Image], subset: Subset) -> Reverse {
    let scene = frozen.scene;
    let density = &scene.density;
    let voxels = density.len();
    let residuals = mse_residuals(&frozen.images, targets);
    let loss: f64 = residuals
        .iter()
        .zip(&frozen.images)
        .zip(targets)
        .map(|((_, i), t)| i.data.iter().zip(&t.data).map(|(a, b)| (a - b).powi(2)).sum::<f64>())
        .sum::<f64>()
        / targets.iter().map(|t| t.data.len()).sum::<usize>().max(1) as f64;
    let mut rng = Rng::new(subset.seed, Purpose::Gradient, 0);

    // Leaves: voxels 0..V, then the estimate's slots camera by camera.
    let leaf_density = leaf_grid(density, 0);
    let multiple = frozen.multiple_with(|p| frozen.photons[p].power, scene.cameras.len());
    let nodes = multiple.as_ref().map_or(0, |m| m[0].values.len());
    let leaf_multiple: Option<Vec<Estimate<Var>>> = multiple.as_ref().map(|estimates| {
        estimates.iter().enumerate().map(|(c, e)| e.with_values(leaves(&e.values, voxels + c * nodes))).collect()
    });
    // Then the light-depth grids, light by light (a block of `depth_nodes` each).
    let first_depth = voxels + nodes * scene.cameras.len();
    let depths = frozen.primal_depths();
    let depth_nodes = frozen.light_depth().map_or(0, |d| d.grid_len());
    let leaf_depths = depths.map(|per_light| {
        per_light
            .iter()
            .enumerate()
            .map(|(l, g)| g.as_ref().map(|g| leaf_grid(g, first_depth + l * depth_nodes)))
            .collect::<Vec<_>>()
    });
    let leaves = first_depth + depths.map_or(0, |d| d.len() * depth_nodes);
    let mut total = par::filled(leaves, 0.0);

    // (1) Pixels.
    // Only cameras with a target are differentiated (later ones are held out).
    let sizes: Vec<usize> = scene.cameras.iter().take(targets.len()).map(|c| c.pixels()).collect();
    let (pixels, pixel_scale) = draw_subset(sizes.iter().sum(), subset.pixels, &mut rng);
    let rays = frozen.camera_rays(&leaf_density, None, leaf_depths.as_ref());
    let locate = |mut i: usize| {
        let mut c = 0;
        while i >= sizes[c] {
            i -= sizes[c];
            c += 1;
        }
        (c, i)
    };
    let mut peak = sweep(&pixels, leaves, &mut total, |scratch, i| {
        let (c, p) = locate(i);
        let seed = residuals[c][p] * pixel_scale;
        if seed == 0.0 {
            return;
        }
        let value = rays.pixel(&scene.cameras[c], frozen.first_pixel(c), p, leaf_multiple.as_ref().map(|m| &m[c]));
        tape::backward(&[(value, seed)], |leaf, a| scratch.add(leaf, a));
    });

    // (1b) Light-depth adjoints -> density adjoints, back along each node's shadow ray.
    if let Some(per_light) = depths {
        depth_adjoints(frozen, per_light, &mut total, first_depth, depth_nodes);
    }
    // (2) Estimate-node adjoints -> photon power adjoints.
    let power_adjoint = power_adjoints(frozen, &total[voxels..], nodes, targets.len());
    // (3) Photon paths.
    if !power_adjoint.is_empty() {
        let (paths, path_scale) = draw_subset(frozen.paths(), subset.paths, &mut rng);
        let paths: Vec<usize> = paths.into_iter().filter(|&i| !frozen.path_photons(i).is_empty()).collect();
        let p2 = sweep(&paths, leaves, &mut total, |scratch, i| {
            let mut steps = vec![];
            let mut powers: Vec<Var> = vec![];
            frozen.replay_path(i, &leaf_density, &mut steps, &mut powers);
            let seeds: Vec<(Var, f64)> =
                powers.iter().zip(frozen.path_photons(i)).map(|(&v, p)| (v, power_adjoint[p] * path_scale)).collect();
            tape::backward(&seeds, |leaf, a| scratch.add(leaf, a));
        });
        peak = peak.max(p2);
    }
    total.truncate(voxels);
    Reverse { loss, grad: total, peak_tape_bytes: peak }
}

/// Adds to the voxels' adjoints (the start of `total`) the adjoints of each
/// light's depth grid (its block of `depth_nodes` from `first_depth`), sent
/// back along each node's shadow ray: the depths are linear in the density.
fn depth_adjoints(
    frozen: &Frozen,
    per_light: &[Option<Grid<f64>>],
    total: &mut [f64],
    first_depth: usize,
    depth_nodes: usize,
) {
    let Some(light_depth) = frozen.light_depth() else {
        return;
    };
    let density = &frozen.scene.density;
    let voxels = density.len();
    for (l, primal) in per_light.iter().enumerate().filter_map(|(l, g)| g.as_ref().map(|g| (l, g))) {
        // The light's adjoints in place (nothing reads them after), the voxels' apart.
        let (density_adjoint, rest) = total.split_at_mut(first_depth + l * depth_nodes);
        let adjoint = &mut rest[..depth_nodes];
        light_depth.pad_adjoints(adjoint);
        let active: Vec<usize> = light_depth.nodes_where(|v| adjoint[v] != 0.0);
        sweep(&active, voxels, &mut density_adjoint[..voxels], |scratch, v| {
            let add = &mut |voxel: usize, a| scratch.add(voxel as u32, a);
            light_depth.adjoint(frozen.marcher(), density, l, v, primal.data[v], adjoint[v], add);
        });
    }
}

/// Each photon's power adjoint from the adjoints of the estimate's nodes
/// (`node_adjoints`: `nodes` per camera, the first `cameras` cameras): the
/// adjoint of the deposit in `SplatGeometry::estimate_with`, linear in the
/// powers with the frozen kernel's weights. Empty without photons.
fn power_adjoints(frozen: &Frozen, node_adjoints: &[f64], nodes: usize, cameras: usize) -> Vec<f64> {
    let Some((geometry, kernel)) = frozen.kernel() else {
        return vec![];
    };
    let scene = frozen.scene;
    let m = &scene.medium;
    (0..frozen.photons.len())
        .into_par_iter()
        .map(|p| {
            let mut adj = 0.0;
            for (c, cam) in scene.cameras.iter().enumerate().take(cameras) {
                let Some(phase) = phase_towards(&frozen.photons[p], &cam.position, m.g) else {
                    continue;
                };
                let node_adj = &node_adjoints[c * nodes..(c + 1) * nodes];
                let s: f64 = kernel.deposits(p).map(|(n, w)| node_adj[geometry.slot(n)] * w).sum();
                adj += s * m.albedo * phase;
            }
            adj
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drain lists every touched leaf once, in increasing order, with its
    /// summed adjoint, and leaves the scratch clean: whether the leaves are
    /// dense in their range (read from the bits) or sparse (sorted).
    #[test]
    fn a_drain_lists_touched_leaves_in_order_and_cleans_up() {
        let mut scratch = Scratch::new();
        scratch.reserve(1 << 20);
        let dense: Vec<u32> = (0..300).map(|i| (i * 37 % 500) + 1000).collect();
        let sparse = vec![1_000_000, 5, 640_001, 64, 63];
        for leaves in [dense, sparse] {
            for round in 0..2 {
                for (n, &l) in leaves.iter().enumerate() {
                    scratch.add(l, n as f64 + 0.5);
                    scratch.add(l, 1.0);
                }
                let mut want: Vec<(u32, f64)> = leaves.iter().enumerate().map(|(n, &l)| (l, n as f64 + 1.5)).collect();
                want.sort_by_key(|&(l, _)| l);
                assert_eq!(scratch.drain(), want, "round {round}");
                assert!(scratch.adjoint.iter().all(|&a| a == 0.0) && scratch.seen.iter().all(|&w| w == 0));
            }
        }
    }
}
