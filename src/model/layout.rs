//! The sparse layout of the decoder's grids: which voxels each layer
//! evaluates given the mask, and where their values are stored.
//!
//! Work is saved in two exact ways: the last layer is evaluated only at
//! masked-in voxels, and every earlier layer only at the voxels some later
//! evaluated voxel reads (the mask pulled back through the kernel
//! footprints); each grid is stored compactly at just those voxels.

use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// Marks a voxel a layout does not store.
const NONE: u32 = u32::MAX;

/// Where the evaluated voxels of a cubic grid are stored: grids are kept
/// only at the voxels that are evaluated (the rest is never read), compactly
/// in C order with all channels of a voxel in one row, so the rows of one
/// z-slab are contiguous.
#[derive(Clone, Debug)]
pub(super) struct Layout {
    /// Edge (voxels).
    edge: usize,
    /// Row of each voxel (C order), or [`NONE`].
    index: Vec<u32>,
    /// In-slab index (`y * edge + x`) of each row: the inverse of `index`.
    voxels: Vec<u32>,
    /// First row of each z-slab; `start[edge]` is the number of rows.
    pub(super) start: Vec<usize>,
}

impl Layout {
    /// The layout of the voxels where `need` (C order, edge `edge`) is true.
    pub(super) fn new(need: &[bool], edge: usize) -> Layout {
        let plane = edge * edge;
        let counts: Vec<usize> = need.par_chunks(plane).map(|s| s.iter().filter(|&&b| b).count()).collect();
        let mut start = Vec::with_capacity(edge + 1);
        start.push(0);
        for c in counts {
            start.push(start[start.len() - 1] + c);
        }
        let mut index = vec![NONE; plane * edge];
        let mut voxels = vec![0; start[edge]];
        let slabs = index.par_chunks_mut(plane).zip(need.par_chunks(plane)).zip(by_slab(&start, &mut voxels, 1));
        slabs.enumerate().for_each(|(z, ((slab, nd), vox))| {
            // Rows and in-slab indices fit in u32: Decoder::new caps the output at 1024^3 voxels.
            let stored = (0u32..).zip(slab.iter_mut().zip(nd)).filter(|(_, (_, &b))| b);
            for ((r, v), (yx, (i, _))) in (start[z] as u32..).zip(vox).zip(stored) {
                (*i, *v) = (r, yx);
            }
        });
        Layout { edge, index, voxels, start }
    }

    /// Number of stored voxels.
    pub(super) fn rows(&self) -> usize {
        self.start[self.edge]
    }

    /// Is voxel `v` (C order) stored?
    #[inline]
    pub(super) fn has(&self, v: usize) -> bool {
        self.index[v] != NONE
    }

    /// The `c` values of voxel `v` in `values`; panics if `v` is not stored
    /// (a bug: needed voxels only read needed voxels).
    #[inline]
    pub(super) fn row<'a, T>(&self, values: &'a [T], v: usize, c: usize) -> &'a [T] {
        &values[self.index[v] as usize * c..][..c]
    }

    /// Rows `first..first + len` as (z-slab, in-slab index `y * edge + x`):
    /// lets a parallel loop cut the rows into tasks of equal size, where
    /// slabs differ in size and a coarse layer has only a few.
    pub(super) fn voxels_of(&self, first: usize, len: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let mut z = self.start.partition_point(|&s| s <= first).saturating_sub(1);
        (first..first + len).map(move |r| {
            while self.start[z + 1] <= r {
                z += 1;
            }
            (z, self.voxels[r] as usize)
        })
    }

    /// The stored voxels of slab `z` as in-slab indices `y * edge + x`.
    pub(super) fn in_slab(&self, z: usize) -> impl Iterator<Item = usize> + '_ {
        let plane = self.edge * self.edge;
        (0..plane).filter(move |&yx| self.index[z * plane + yx] != NONE)
    }
}

/// `values` (`c` per row) cut at the slab starts `start`.
fn by_slab<'a, T>(start: &[usize], values: &'a mut [T], c: usize) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(start.len());
    let mut rest = values;
    for w in start.windows(2) {
        let (part, tail) = rest.split_at_mut((w[1] - w[0]) * c);
        parts.push(part);
        rest = tail;
    }
    parts
}

/// The inputs (edge `n`) that some stored output of `lout` (edge `2n`)
/// reads. The footprint is a product of per-axis ranges (input `i` feeds
/// outputs `2i - 1 ..= 2i + 2`), so the "any" is taken one axis at a time:
/// along x per output row, then as ORs of whole rows (y) and planes (z).
pub(super) fn pull_back(lout: &Layout, n: usize) -> Vec<bool> {
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

/// Where each grid of a decoder is evaluated, input to output. `edges[l]`
/// is the input edge of convolution `l` (its output edge is twice that);
/// the output of the last is the `res^3` grid of `mask`. The base grid
/// (edge `edges[0]`) is evaluated everywhere, as the linear layer making it
/// is dense; the last layout is `mask`, each earlier one what the next one
/// reads.
pub(super) fn plan(mask: &[bool], res: usize, edges: &[usize]) -> Vec<Layout> {
    let mut layouts = vec![Layout::new(mask, res)];
    for (l, &n) in edges.iter().enumerate().rev() {
        let need = if l == 0 { vec![true; n.pow(3)] } else { pull_back(&layouts[layouts.len() - 1], n) };
        layouts.push(Layout::new(&need, n));
    }
    layouts.reverse();
    layouts
}

/// The layouts of the last mask a decoder was evaluated on. A training
/// update evaluates the decoder several times on one mask (every pass of
/// every update): planning anew each time cost about 100 parallel loops
/// per coarse update, most under 0.1 ms, each a wake-up and a join of the
/// pool's workers for little work.
#[derive(Debug, Default)]
pub(super) struct Plans(Mutex<Option<Plan>>);

/// A mask and its layouts.
#[derive(Debug)]
struct Plan {
    mask: Vec<bool>,
    layouts: Arc<Vec<Layout>>,
}

impl Plans {
    /// [`plan`]`(mask, res, edges)`, reused while the mask stays the same.
    pub(super) fn get(&self, mask: &[bool], res: usize, edges: &[usize]) -> Arc<Vec<Layout>> {
        // Held while planning: two passes side by side on a new mask plan it once.
        let mut last = self.0.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        match &*last {
            Some(last) if last.mask == mask => last.layouts.clone(),
            _ => {
                let layouts = Arc::new(plan(mask, res, edges));
                *last = Some(Plan { mask: mask.to_vec(), layouts: layouts.clone() });
                layouts
            }
        }
    }
}

impl Clone for Plans {
    /// An empty cache: a copy plans on its first evaluation.
    fn clone(&self) -> Plans {
        Plans::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::conv::taps;
    use crate::model::normals;

    #[test]
    fn rows_name_their_voxels_from_any_first_row() {
        let edge = 8;
        // Sparse enough that some slabs are empty.
        let mut need: Vec<bool> = normals(6, 512).iter().map(|&u| u > 1.0).collect();
        need[..3 * 64].iter_mut().for_each(|b| *b = false);
        let l = Layout::new(&need, edge);
        let all: Vec<(usize, usize)> = (0..edge).flat_map(|z| l.in_slab(z).map(move |yx| (z, yx))).collect();
        assert_eq!(all.len(), l.rows());
        for (r, &(z, yx)) in all.iter().enumerate() {
            assert_eq!(l.index[z * 64 + yx] as usize, r);
        }
        for first in 0..l.rows() {
            let got: Vec<(usize, usize)> = l.voxels_of(first, l.rows() - first).collect();
            assert_eq!(got, all[first..], "from row {first}");
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
    fn plans_are_reused_only_for_the_same_mask() {
        let (res, edges) = (16, [4, 8]);
        let a: Vec<bool> = normals(5, 4096).iter().map(|&u| u > 0.0).collect();
        let mut b = a.clone();
        b[100] = !b[100];
        let plans = Plans::default();
        let first = plans.get(&a, res, &edges);
        assert!(Arc::ptr_eq(&first, &plans.get(&a, res, &edges)));
        let other = plans.get(&b, res, &edges);
        assert!(!Arc::ptr_eq(&first, &other));
        let rows = |ls: &[Layout]| ls.iter().map(|l| (l.start.clone(), l.index.clone())).collect::<Vec<_>>();
        assert_eq!(rows(&other), rows(&plan(&b, res, &edges)));
        assert_eq!(rows(&plans.get(&a, res, &edges)), rows(&first));
    }
}
