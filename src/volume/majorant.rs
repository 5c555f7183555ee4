//! A coarse grid of density upper bounds over blocks of voxels: it lets ray
//! marching skip empty space and gives delta tracking a tight majorant.

use super::grid::Grid;
use crate::math::{Ray, Vec3};
use rayon::prelude::*;

/// Voxels per majorant block edge, for every renderer: small enough to skip
/// the plume's empty surroundings, large enough that the block walk is cheap.
pub const MAJORANT_BLOCK: usize = 4;

/// Upper bounds of the trilinear density over cubic blocks of `block` voxels.
#[derive(Clone, Debug)]
pub struct Majorant {
    lo: Vec3,
    /// World size of one block along x, y, z.
    cell: Vec3,
    /// Number of blocks along x, y, z.
    n: [usize; 3],
    /// Bound per block, flat index `(bz * ny + by) * nx + bx`.
    max: Vec<f64>,
    /// Number of super-blocks ([`SUPER`]^3 blocks) along x, y, z.
    super_n: [usize; 3],
    /// What each super-block holds, flat like `max`.
    super_state: Vec<Occupancy>,
}

impl Majorant {
    /// Bounds for `grid`, in blocks of `block` voxels per axis.
    pub fn build(grid: &Grid<f64>, block: usize) -> Self {
        let block = block.max(1);
        let [nz, ny, nx] = grid.shape;
        let n = [nx.div_ceil(block), ny.div_ceil(block), nz.div_ceil(block)];
        let cell = grid.voxel_size() * block as f64;
        // Points in a block read voxels one beyond it on each side (trilinear reach).
        let range = |m: usize, len: usize| (m * block).saturating_sub(1)..((m + 1) * block + 1).min(len);
        let mut max = vec![0.0; n[0] * n[1] * n[2]];
        max.par_chunks_mut(n[0] * n[1]).enumerate().for_each(|(bz, layer)| {
            for by in 0..n[1] {
                for bx in 0..n[0] {
                    let mut m = 0.0f64;
                    for k in range(bz, nz) {
                        for j in range(by, ny) {
                            for i in range(bx, nx) {
                                m = m.max(grid.data[grid.index(k, j, i)]);
                            }
                        }
                    }
                    layer[by * n[0] + bx] = m;
                }
            }
        });
        let super_n = n.map(|b| b.div_ceil(SUPER));
        let mut super_state = Vec::with_capacity(super_n.iter().product());
        for sz in 0..super_n[2] {
            for sy in 0..super_n[1] {
                for sx in 0..super_n[0] {
                    let (mut any, mut all) = (false, true);
                    for bz in sz * SUPER..((sz + 1) * SUPER).min(n[2]) {
                        for by in sy * SUPER..((sy + 1) * SUPER).min(n[1]) {
                            for bx in sx * SUPER..((sx + 1) * SUPER).min(n[0]) {
                                let occupied = max[(bz * n[1] + by) * n[0] + bx] > 0.0;
                                any |= occupied;
                                all &= occupied;
                            }
                        }
                    }
                    super_state.push(match (any, all) {
                        (false, _) => Occupancy::Empty,
                        (true, true) => Occupancy::Full,
                        (true, false) => Occupancy::Mixed,
                    });
                }
            }
        }
        Majorant { lo: grid.lo, cell, n, max, super_n, super_state }
    }

    /// Flat indices of the nodes of a cell-centred grid of `shape` over the
    /// box `[lo, hi]` that a trilinear lookup inside a non-empty block can
    /// read, in increasing order. With the density's own box and shape these
    /// are [`reachable_voxels`](Self::reachable_voxels).
    pub fn reachable_nodes(&self, lo: &Vec3, hi: &Vec3, shape: [usize; 3]) -> Vec<usize> {
        let [nz, ny, nx] = shape;
        let counts = [nx, ny, nz];
        let mut mark = vec![false; nz * ny * nx];
        // Node coordinate of the point `w` past this grid's `lo` along axis `a`: centres at whole numbers.
        let node = |w: f64, a: usize| (self.lo[a] + w - lo[a]) / (hi[a] - lo[a]) * counts[a] as f64 - 0.5;
        let range = |b: usize, a: usize| {
            let lo = node(b as f64 * self.cell[a], a).floor().max(0.0) as usize;
            let hi = (node((b + 1) as f64 * self.cell[a], a).ceil().max(0.0) as usize).min(counts[a] - 1);
            lo.min(counts[a] - 1)..hi + 1
        };
        for bz in 0..self.n[2] {
            for by in 0..self.n[1] {
                for bx in 0..self.n[0] {
                    if self.max[(bz * self.n[1] + by) * self.n[0] + bx] > 0.0 {
                        for k in range(bz, 2) {
                            for j in range(by, 1) {
                                for i in range(bx, 0) {
                                    mark[(k * ny + j) * nx + i] = true;
                                }
                            }
                        }
                    }
                }
            }
        }
        (0..mark.len()).filter(|&v| mark[v]).collect()
    }

    /// Flat indices of the voxels a lookup inside a non-empty block can read
    /// (the blocks' voxels plus one on each side), in increasing order.
    pub fn reachable_voxels(&self, shape: [usize; 3], block: usize) -> Vec<usize> {
        let [nz, ny, nx] = shape;
        let mut mark = vec![false; nz * ny * nx];
        let range = |m: usize, len: usize| (m * block).saturating_sub(1)..((m + 1) * block + 1).min(len);
        for bz in 0..self.n[2] {
            for by in 0..self.n[1] {
                for bx in 0..self.n[0] {
                    if self.max[(bz * self.n[1] + by) * self.n[0] + bx] > 0.0 {
                        for k in range(bz, nz) {
                            for j in range(by, ny) {
                                for i in range(bx, nx) {
                                    mark[(k * ny + j) * nx + i] = true;
                                }
                            }
                        }
                    }
                }
            }
        }
        (0..mark.len()).filter(|&v| mark[v]).collect()
    }

    /// The box spanned by the blocks with a non-zero bound, or `None` if all are empty.
    pub fn occupied_bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = [usize::MAX; 3];
        let mut hi = [0usize; 3];
        let mut any = false;
        for bz in 0..self.n[2] {
            for by in 0..self.n[1] {
                for bx in 0..self.n[0] {
                    if self.max[(bz * self.n[1] + by) * self.n[0] + bx] > 0.0 {
                        any = true;
                        for (a, b) in [bx, by, bz].into_iter().enumerate() {
                            lo[a] = lo[a].min(b);
                            hi[a] = hi[a].max(b + 1);
                        }
                    }
                }
            }
        }
        any.then(|| {
            let f = |b: [usize; 3]| {
                self.lo + Vec3::new(b[0] as f64 * self.cell.x, b[1] as f64 * self.cell.y, b[2] as f64 * self.cell.z)
            };
            (f(lo), f(hi))
        })
    }

    /// Visits the blocks crossed by `ray` over `[t0, t1]` (a part of the
    /// ray inside the grid's box) in order, as `(ta, tb, bound)`; stops when
    /// `visit` returns false.
    pub fn walk(&self, ray: &Ray, t0: f64, t1: f64, mut visit: impl FnMut(f64, f64, f64) -> bool) {
        dda(&self.lo, &self.cell, self.n, ray, t0, t1, |ta, tb, flat| visit(ta, tb, self.max[flat]));
    }

    /// The parts of `[t0, t1]` along `ray` in non-empty blocks, merged into
    /// maximal intervals, appended to `out` as `(ta, tb)`. Walks the
    /// super-blocks first and the blocks only inside mixed ones: inside the
    /// plume nearly every block is occupied, and visiting them one by one
    /// cost as much as the marching itself.
    pub fn occupied_intervals(&self, ray: &Ray, t0: f64, t1: f64, out: &mut Vec<(f64, f64)>) {
        let mut merge = |ta: f64, tb: f64| match out.last_mut() {
            // Super-block and block walks compute shared boundaries apart: allow for rounding.
            Some(last) if last.1 >= ta - 1e-12 * (1.0 + ta.abs()) => last.1 = last.1.max(tb),
            _ => out.push((ta, tb)),
        };
        let cell = self.cell * SUPER as f64;
        dda(&self.lo, &cell, self.super_n, ray, t0, t1, |ta, tb, flat| {
            match self.super_state[flat] {
                Occupancy::Empty => {}
                Occupancy::Full => merge(ta, tb),
                Occupancy::Mixed => self.walk(ray, ta, tb, |a, b, m| {
                    if m > 0.0 {
                        merge(a, b);
                    }
                    true
                }),
            }
            true
        });
    }
}

/// Blocks per super-block edge.
const SUPER: usize = 4;

/// What a super-block's blocks hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Occupancy {
    /// Every block's bound is 0.
    Empty,
    /// Every block's bound is above 0.
    Full,
    /// Some of each.
    Mixed,
}

/// Visits the cells of the regular grid (`n` cells of size `cell` from
/// `lo`) crossed by `ray` over `[t0, t1]`, in order, as `(ta, tb, flat
/// index)`; stops when `visit` returns false (3-D DDA).
fn dda(
    lo: &Vec3,
    cell: &Vec3,
    n: [usize; 3],
    ray: &Ray,
    t0: f64,
    t1: f64,
    mut visit: impl FnMut(f64, f64, usize) -> bool,
) {
    if t1 <= t0 {
        return;
    }
    let p = ray.at(t0);
    let mut idx = [0i64; 3];
    let mut step = [0i64; 3];
    let mut t_next = [f64::INFINITY; 3];
    let mut t_delta = [f64::INFINITY; 3];
    for a in 0..3 {
        let u = ((p[a] - lo[a]) / cell[a]).floor() as i64;
        idx[a] = u.clamp(0, n[a] as i64 - 1);
        let d = ray.dir[a];
        if d > 0.0 {
            step[a] = 1;
            t_next[a] = t0 + ((lo[a] + (idx[a] + 1) as f64 * cell[a]) - p[a]) / d;
            t_delta[a] = cell[a] / d;
        } else if d < 0.0 {
            step[a] = -1;
            t_next[a] = t0 + ((lo[a] + idx[a] as f64 * cell[a]) - p[a]) / d;
            t_delta[a] = -cell[a] / d;
        }
    }
    let mut t = t0;
    loop {
        let a = if t_next[0] < t_next[1] {
            if t_next[0] < t_next[2] {
                0
            } else {
                2
            }
        } else if t_next[1] < t_next[2] {
            1
        } else {
            2
        };
        let t_exit = t_next[a].min(t1);
        let flat = ((idx[2] as usize) * n[1] + idx[1] as usize) * n[0] + idx[0] as usize;
        if t_exit > t && !visit(t, t_exit, flat) {
            return;
        }
        if t_next[a] >= t1 {
            return;
        }
        t = t_exit;
        idx[a] += step[a];
        if idx[a] < 0 || idx[a] >= n[a] as i64 {
            return;
        }
        t_next[a] += t_delta[a];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_cover_trilinear_values_and_walk_is_contiguous() {
        let n = 10;
        let mut data = vec![0.0; n * n * n];
        data[(5 * n + 5) * n + 5] = 2.0;
        let g = Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [n, n, n], data);
        let m = Majorant::build(&g, 4);
        let ray = Ray { origin: Vec3::new(-1.0, 0.03, 0.01), dir: Vec3::new(1.0, 0.02, 0.01).normalize() };
        let (t0, t1) = crate::math::intersect_box(&ray, &g.lo, &g.hi).unwrap();
        let mut last = t0;
        m.walk(&ray, t0, t1, |ta, tb, bound| {
            assert!((ta - last).abs() < 1e-12);
            last = tb;
            for s in 0..=20 {
                let t = ta + (tb - ta) * s as f64 / 20.0;
                assert!(g.at(&ray.at(t)) <= bound + 1e-12);
            }
            true
        });
        assert!((last - t1).abs() < 1e-9);
        let mut iv = vec![];
        m.occupied_intervals(&ray, t0, t1, &mut iv);
        assert_eq!(iv.len(), 1);
    }

    /// The super-block walk finds the same intervals as merging the
    /// occupied blocks one by one, on rays through a grid with scattered
    /// empty and full regions.
    #[test]
    fn super_block_walk_matches_the_block_walk() {
        let n = 40;
        let mut rng = crate::rng::Rng::from_seed(5);
        let data: Vec<f64> = (0..n * n * n)
            .map(|v| {
                let (k, j, i) = (v / (n * n), v / n % n, v % n);
                let ball = (k as f64 - 20.0).powi(2) + (j as f64 - 18.0).powi(2) + (i as f64 - 22.0).powi(2) < 150.0;
                if ball || rng.uniform() < 0.002 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let g = Grid::new(Vec3::from_element(-1.0), Vec3::from_element(1.0), [n, n, n], data);
        let m = Majorant::build(&g, 2);
        for _ in 0..500 {
            let origin = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 6.0 - Vec3::from_element(3.0);
            let dir = (Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - Vec3::from_element(0.5)).normalize();
            let ray = Ray { origin, dir };
            let Some((t0, t1)) = crate::math::intersect_box(&ray, &g.lo, &g.hi) else { continue };
            let mut want: Vec<(f64, f64)> = vec![];
            m.walk(&ray, t0, t1, |ta, tb, bound| {
                if bound > 0.0 {
                    match want.last_mut() {
                        Some(last) if last.1 >= ta => last.1 = tb,
                        _ => want.push((ta, tb)),
                    }
                }
                true
            });
            let mut got = vec![];
            m.occupied_intervals(&ray, t0, t1, &mut got);
            assert_eq!(got.len(), want.len());
            for (a, b) in got.iter().zip(&want) {
                assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn reachable_nodes_at_the_density_shape_are_the_reachable_voxels() {
        let n = 18;
        let data: Vec<f64> = (0..n * n * n).map(|v| if v % 997 == 3 || v % 1301 == 0 { 1.0 } else { 0.0 }).collect();
        let g = Grid::new(Vec3::from_element(-1.0), Vec3::new(1.0, 2.0, 1.5), [n, n, n], data);
        let m = Majorant::build(&g, 4);
        assert_eq!(m.reachable_nodes(&g.lo, &g.hi, g.shape), m.reachable_voxels(g.shape, 4));
    }
}
