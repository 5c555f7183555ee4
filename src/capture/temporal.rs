//! Neighbouring frames' densities brought onto one frame's: the plume's
//! motion between two fitted densities as one shift of the grid (whole
//! voxels across, a fraction of a voxel along the vertical, the way the
//! smoke rises), and their mean once shifted.
//!
//! Why: each frame is fitted from the same four views, and what four views
//! cannot place is placed by each fit on its own. Where those errors differ
//! from frame to frame and the smoke does not, a mean over neighbouring
//! frames keeps the smoke and averages the errors out; where they agree, it
//! only blurs. Which it does is measured by `temporal_mean`.

use crate::volume::Grid;

/// The largest shift searched across the vertical (voxels, each way).
pub const ACROSS_VOXELS: isize = 2;

/// A shift of a grid's content: the voxel at `p` of the reference holds
/// what the moved grid has at `p + shift` (voxels along z, y, x).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shift(pub [f64; 3]);

/// The two voxels along one axis a shifted sample lies between, and their weights.
type Taps = [(usize, f64); 2];

/// `grid` sampled at every voxel `p + shift` (linearly between voxels
/// along each axis), with a weight per voxel: 1 where the sample lies in
/// the grid, 0 where it falls outside (its value then 0).
pub fn shifted(grid: &Grid<f64>, shift: Shift) -> (Vec<f64>, Vec<f64>) {
    let [nz, ny, nx] = grid.shape;
    let n = [nz, ny, nx];
    let mut values = vec![0.0; grid.len()];
    let mut weights = vec![0.0; grid.len()];
    // Per axis and index: the two neighbours and their weights, or none.
    let taps: Vec<Vec<Option<Taps>>> = (0..3)
        .map(|a| {
            (0..n[a])
                .map(|i| {
                    let at = i as f64 + shift.0[a];
                    let lo = at.floor();
                    let t = at - lo;
                    let last = n[a] as f64 - 1.0;
                    if lo < 0.0 || lo > last || (t > 0.0 && lo + 1.0 > last) {
                        return None;
                    }
                    let lo = lo as usize;
                    Some([(lo, 1.0 - t), ((lo + 1).min(n[a] - 1), t)])
                })
                .collect()
        })
        .collect();
    for k in 0..nz {
        let Some(tk) = taps[0][k] else { continue };
        for j in 0..ny {
            let Some(tj) = taps[1][j] else { continue };
            for (i, ti) in taps[2].iter().enumerate() {
                let Some(ti) = ti else { continue };
                let mut v = 0.0;
                for &(kk, wk) in &tk {
                    for &(jj, wj) in &tj {
                        for &(ii, wi) in ti {
                            let w = wk * wj * wi;
                            if w != 0.0 {
                                v += w * grid.data[grid.index(kk, jj, ii)];
                            }
                        }
                    }
                }
                let idx = grid.index(k, j, i);
                values[idx] = v;
                weights[idx] = 1.0;
            }
        }
    }
    (values, weights)
}

/// How alike `reference` and `moved` shifted by `shift` are: the cosine
/// of the two over the voxels the shifted grid covers (0 if either is 0 there).
fn alike(reference: &Grid<f64>, moved: &Grid<f64>, shift: Shift) -> f64 {
    let (values, weights) = shifted(moved, shift);
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for ((&a, &b), &w) in reference.data.iter().zip(&values).zip(&weights) {
        if w > 0.0 {
            ab += a * b;
            aa += a * a;
            bb += b * b;
        }
    }
    if aa > 0.0 && bb > 0.0 {
        ab / (aa * bb).sqrt()
    } else {
        0.0
    }
}

/// The shift that brings `moved` onto `reference` (same shape): whole
/// voxels up to [`ACROSS_VOXELS`] across the vertical (grid axes z and x)
/// and up to `along` along it (axis y), then along it refined to a quarter
/// voxel. The grids are on the same box.
pub fn motion(reference: &Grid<f64>, moved: &Grid<f64>, along: isize) -> Shift {
    assert_eq!(reference.shape, moved.shape, "motion: grids of different shapes");
    let mut best = (f64::NEG_INFINITY, Shift([0.0; 3]));
    for dz in -ACROSS_VOXELS..=ACROSS_VOXELS {
        for dy in -along..=along {
            for dx in -ACROSS_VOXELS..=ACROSS_VOXELS {
                let shift = Shift([dz as f64, dy as f64, dx as f64]);
                let score = alike(reference, moved, shift);
                if score > best.0 {
                    best = (score, shift);
                }
            }
        }
    }
    let Shift([dz, dy, dx]) = best.1;
    for step in [-0.75, -0.5, -0.25, 0.25, 0.5, 0.75] {
        let shift = Shift([dz, dy + step, dx]);
        let score = alike(reference, moved, shift);
        if score > best.0 {
            best = (score, shift);
        }
    }
    best.1
}

/// The mean of `centre` and each of `others` shifted onto it by its
/// [`motion`] (searched up to `along` voxels along the vertical), voxel by
/// voxel over the grids that cover it, and 0 where `centre` is 0 (outside
/// its fit's hull). Returns the mean and each other grid's shift.
pub fn mean_onto(centre: &Grid<f64>, others: &[Grid<f64>], along: isize) -> (Grid<f64>, Vec<Shift>) {
    let mut sum = centre.data.clone();
    let mut count = vec![1.0; centre.len()];
    let mut shifts = Vec::new();
    for other in others {
        let shift = motion(centre, other, along);
        let (values, weights) = shifted(other, shift);
        for v in 0..centre.len() {
            sum[v] += values[v];
            count[v] += weights[v];
        }
        shifts.push(shift);
    }
    let data = sum.iter().zip(&count).zip(&centre.data).map(|((s, c), &d)| if d > 0.0 { s / c } else { 0.0 }).collect();
    (Grid::new(centre.lo, centre.hi, centre.shape, data), shifts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// A smooth blob on a (12, 16, 10) grid, centred at (`cz`, `cy`, `cx`) voxels.
    fn blob(cz: f64, cy: f64, cx: f64) -> Grid<f64> {
        let shape = [12, 16, 10];
        let mut data = Vec::new();
        for k in 0..shape[0] {
            for j in 0..shape[1] {
                for i in 0..shape[2] {
                    let r2 = (k as f64 - cz).powi(2) + ((j as f64 - cy) / 1.5).powi(2) + (i as f64 - cx).powi(2);
                    data.push((-r2 / 6.0).exp() + 0.01);
                }
            }
        }
        Grid::new(Vec3::zeros(), Vec3::new(1.0, 1.6, 1.2), shape, data)
    }

    #[test]
    fn a_whole_voxel_shift_moves_the_content_and_marks_what_falls_outside() {
        let g = blob(6.0, 7.0, 5.0);
        let (values, weights) = shifted(&g, Shift([0.0, 2.0, -1.0]));
        // Inside: the voxel (k, j, i) holds the grid's (k, j + 2, i - 1).
        assert_eq!(values[g.index(3, 4, 5)], g.data[g.index(3, 6, 4)]);
        assert_eq!(weights[g.index(3, 4, 5)], 1.0);
        // Outside: the top two rows and the first column have nothing to take.
        for (k, j, i) in [(3, 14, 5), (3, 15, 5), (3, 4, 0)] {
            assert_eq!((values[g.index(k, j, i)], weights[g.index(k, j, i)]), (0.0, 0.0));
        }
        // A fraction of a voxel interpolates linearly.
        let (half, _) = shifted(&g, Shift([0.0, 0.5, 0.0]));
        let expected = 0.5 * (g.data[g.index(3, 4, 5)] + g.data[g.index(3, 5, 5)]);
        assert!((half[g.index(3, 4, 5)] - expected).abs() < 1e-12);
    }

    #[test]
    fn motion_finds_a_known_rise_and_a_sideways_step() {
        let reference = blob(6.0, 6.0, 5.0);
        // The smoke 2.5 voxels higher and one voxel along x.
        let moved = blob(6.0, 8.5, 6.0);
        assert_eq!(motion(&reference, &moved, 4), Shift([0.0, 2.5, 1.0]));
        // Beyond the search along the vertical, it stops at its edge.
        assert_eq!(motion(&reference, &moved, 1).0[1], 1.75);
    }

    #[test]
    fn the_mean_of_shifted_copies_gives_the_centre_back() {
        let centre = blob(6.0, 6.0, 5.0);
        let others = [blob(6.0, 7.0, 5.0), blob(6.0, 5.0, 5.0)];
        let (mean, shifts) = mean_onto(&centre, &others, 3);
        assert_eq!(shifts, vec![Shift([0.0, 1.0, 0.0]), Shift([0.0, -1.0, 0.0])]);
        let worst = mean.data.iter().zip(&centre.data).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        // Each copy, shifted back, is the centre wherever it covers it.
        assert!(worst < 1e-12, "largest difference {worst}");
        // Where the centre is 0, so is the mean.
        let mut holed = centre.clone();
        holed.data[0] = 0.0;
        assert_eq!(mean_onto(&holed, &others, 3).0.data[0], 0.0);
    }
}
