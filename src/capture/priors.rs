//! Priors on a real frame's density, beside the images: what four views
//! leave open, these settle. Each is invariant to the density's scale (a
//! term that is not would pull the density towards 0 and the lights up
//! without bound where nothing in the images resists) and comes with its
//! exact gradient.

use crate::volume::Grid;

/// The smoothness term `weight * A / B^2` and its gradient: `A` the mean
/// over neighbouring voxel pairs of `(h (rho_a - rho_b))^2` (h the voxel size
/// along the pair's axis), `B` the mean of `h rho` over the hull. It does
/// not change when the density is scaled, so it leaves the scale to the
/// images (a term in `A` alone would pull every density towards 0 and
/// every light up without bound, where nothing in the images resists).
/// `axes` weighs each axis's pairs (z, y, x, as the grid's shape).
pub fn smoothness(density: &Grid<f64>, hull: &[bool], weight: f64, axes: [f64; 3]) -> (f64, Vec<f64>) {
    let mut grad = vec![0.0; density.len()];
    if weight == 0.0 {
        return (0.0, grad);
    }
    let [nz, ny, nx] = density.shape;
    let h = density.voxel_size();
    let pairs: usize = [nz, ny, nx].iter().map(|&n| density.len() / n * (n - 1)).sum();
    let axes =
        [(h.z, nz, 0usize), (h.y, ny, 1), (h.x, nx, 2)].map(|(step, n, axis)| (step * axes[axis].sqrt(), n, axis));
    let scale = 1.0 / pairs.max(1) as f64;
    let mut sum = 0.0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let a = density.index(k, j, i);
                for &(step, n, axis) in &axes {
                    let (kk, jj, ii) = match axis {
                        0 => (k + 1, j, i),
                        1 => (k, j + 1, i),
                        _ => (k, j, i + 1),
                    };
                    if [kk, jj, ii][axis] >= n {
                        continue;
                    }
                    let b = density.index(kk, jj, ii);
                    let d = step * (density.data[a] - density.data[b]);
                    sum += d * d;
                    grad[a] += 2.0 * scale * step * d;
                    grad[b] -= 2.0 * scale * step * d;
                }
            }
        }
    }
    // A = scale * sum with gradient `grad`; B = mean over the hull of h rho.
    let (big_b, db) = hull_mean_depth(density, hull);
    if big_b <= 0.0 {
        return (0.0, vec![0.0; density.len()]);
    }
    let a_val = scale * sum;
    for (g, &x) in grad.iter_mut().zip(hull) {
        *g = weight * (*g / (big_b * big_b) - if x { 2.0 * a_val * db / big_b.powi(3) } else { 0.0 });
    }
    (weight * a_val / (big_b * big_b), grad)
}

/// `B`, the mean of `h rho` over the hull (h the voxels' geometric mean
/// edge), and its derivative by the density of a voxel inside the hull:
/// dividing by a power of it makes a prior scale-invariant.
fn hull_mean_depth(density: &Grid<f64>, hull: &[bool]) -> (f64, f64) {
    let h = density.voxel_size();
    let h_mean = (h.x * h.y * h.z).cbrt();
    let inside = hull.iter().filter(|&&x| x).count().max(1) as f64;
    let b_sum: f64 = density.data.iter().zip(hull).filter(|(_, &x)| x).map(|(d, _)| d).sum();
    (h_mean * b_sum / inside, h_mean / inside)
}

/// The sparsity term `weight * (mean rho)^2 / mean(rho^2)` over the hull
/// and its gradient: 1 for a density spread evenly over the hull, towards 0
/// as it gathers into fewer voxels. Few views leave copies of the smoke
/// along their rays wherever the hull allows it (limited-angle tomography's
/// ghosts); among densities that explain the images alike, this term
/// prefers the one gathered into fewer voxels.
pub fn sparsity(density: &Grid<f64>, hull: &[bool], weight: f64) -> (f64, Vec<f64>) {
    let mut grad = vec![0.0; density.len()];
    let inside = density.data.iter().zip(hull).filter(|(_, &h)| h).map(|(d, _)| *d);
    let (n, sum, sum2) = inside.fold((0.0, 0.0, 0.0), |(n, a, b), d| (n + 1.0, a + d, b + d * d));
    if weight == 0.0 || sum2 <= 0.0 {
        return (0.0, grad);
    }
    for ((g, &d), &h) in grad.iter_mut().zip(&density.data).zip(hull) {
        if h {
            *g = weight * 2.0 * sum / (n * sum2) * (1.0 - sum * d / sum2);
        }
    }
    (weight * sum * sum / (n * sum2), grad)
}

/// The total-variation term `weight * T / B` and its gradient: `T` the mean
/// over voxels of `sqrt(|g|^2 + (eps B)^2) - eps B`, `g` the differences of
/// `h rho` to the voxel's next neighbour along each axis (0 past the grid's
/// edge), `B` the mean of `h rho` over the hull, `eps` [`TV_CORNER`]. Unlike
/// the squared differences of [`smoothness`], it charges a rise by its
/// height, not its square: meant to keep the smoke's edges and remove what
/// spreads thinly, as the ghosts few views leave along their rays do
/// (sparse-view tomography's usual prior). Like the others it does not
/// change when the density is scaled.
pub fn total_variation(density: &Grid<f64>, hull: &[bool], weight: f64) -> (f64, Vec<f64>) {
    let mut grad = vec![0.0; density.len()];
    if weight == 0.0 {
        return (0.0, grad);
    }
    let (big_b, db) = hull_mean_depth(density, hull);
    if big_b <= 0.0 {
        return (0.0, grad);
    }
    let [nz, ny, nx] = density.shape;
    let h = density.voxel_size();
    let corner = TV_CORNER * big_b;
    let n = density.len() as f64;
    // T, and dT/dB through the corner alone (the rest of dT goes to `grad`).
    let (mut t_sum, mut dt_db_sum) = (0.0, 0.0);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let a = density.index(k, j, i);
                let next = [
                    (k + 1 < nz, h.z, (k + 1, j, i)),
                    (j + 1 < ny, h.y, (k, j + 1, i)),
                    (i + 1 < nx, h.x, (k, j, i + 1)),
                ];
                let diffs = next.map(|(exists, step, (kk, jj, ii))| {
                    if exists {
                        let b = density.index(kk, jj, ii);
                        (step * (density.data[b] - density.data[a]), step, b)
                    } else {
                        (0.0, 0.0, a)
                    }
                });
                let r = (diffs.iter().map(|d| d.0 * d.0).sum::<f64>() + corner * corner).sqrt();
                t_sum += r - corner;
                dt_db_sum += TV_CORNER * corner / r - TV_CORNER;
                for (d, step, b) in diffs {
                    grad[b] += step * d / r;
                    grad[a] -= step * d / r;
                }
            }
        }
    }
    let t = t_sum / n;
    let dt_db = dt_db_sum / n;
    for (g, &x) in grad.iter_mut().zip(hull) {
        let through_b = if x { (dt_db / big_b - t / (big_b * big_b)) * db } else { 0.0 };
        *g = weight * (*g / n / big_b + through_b);
    }
    (weight * t / big_b, grad)
}

/// Where [`total_variation`] turns from quadratic to linear: differences
/// below this fraction of the mean voxel's optical depth are smoothed as
/// squares (the term then has a gradient everywhere).
pub const TV_CORNER: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// A prior on a small grid, and its hull.
    fn small() -> (Grid<f64>, Vec<bool>) {
        let data: Vec<f64> = (0..60).map(|i| ((i * 37) % 11) as f64 * 0.3).collect();
        let grid = Grid::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 1.5), [3, 5, 4], data);
        (grid, (0..60).map(|i| i % 7 != 3).collect())
    }

    /// A prior's value and gradient from the density, the hull and the weight.
    type Prior = fn(&Grid<f64>, &[bool], f64) -> (f64, Vec<f64>);

    /// `prior` does not change when the density is scaled, and its gradient
    /// matches central finite differences (inside and outside the hull).
    fn check(prior: Prior) {
        let (grid, hull) = small();
        let (value, grad) = prior(&grid, &hull, 0.7);
        let scaled = grid.map(|d| 3.0 * d);
        assert!((prior(&scaled, &hull, 0.7).0 - value).abs() < 1e-12 * value, "not scale-invariant");
        for v in [0, 17, 59] {
            let h = 1e-6;
            let mut up = grid.clone();
            up.data[v] += h;
            let mut down = grid.clone();
            down.data[v] -= h;
            let fd = (prior(&up, &hull, 0.7).0 - prior(&down, &hull, 0.7).0) / (2.0 * h);
            assert!((fd - grad[v]).abs() < 1e-6 * fd.abs().max(1e-3), "voxel {v}: {fd} vs {}", grad[v]);
        }
    }

    #[test]
    fn the_smoothness_gradient_matches_finite_differences() {
        check(|d, h, w| smoothness(d, h, w, [1.0; 3]));
        check(|d, h, w| smoothness(d, h, w, [2.0, 0.5, 3.0]));
    }

    #[test]
    fn smoothness_weighs_each_axis_as_told() {
        let (grid, hull) = small();
        // A density that varies along y alone costs nothing where y's pairs weigh nothing.
        let layered = Grid::new(grid.lo, grid.hi, grid.shape, (0..60).map(|i| ((i / 4) % 5) as f64 + 1.0).collect());
        assert!(smoothness(&layered, &hull, 0.7, [1.0, 1.0, 1.0]).0 > 0.0);
        assert_eq!(smoothness(&layered, &hull, 0.7, [1.0, 0.0, 1.0]).0, 0.0);
        // Weights scale each axis's share: twice every weight, twice the term.
        let (one, _) = smoothness(&grid, &hull, 0.7, [1.0, 2.0, 3.0]);
        let (two, _) = smoothness(&grid, &hull, 0.7, [2.0, 4.0, 6.0]);
        assert!((two - 2.0 * one).abs() < 1e-12 * one, "{one} {two}");
    }

    #[test]
    fn the_total_variation_gradient_matches_finite_differences_and_charges_a_rise_not_its_steps() {
        check(total_variation);
        let (grid, hull) = small();
        let even = grid.map(|_| 2.0);
        assert_eq!(total_variation(&even, &hull, 0.7).0, 0.0, "an even density costs something");
        // The same rise at the same mean, in four steps or two twice as high: the
        // squared differences charge the two twice as much, total variation about alike.
        let column = |data: Vec<f64>| Grid::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.2, 0.2, 1.0), [5, 1, 1], data);
        let (gentle, steep) = (column(vec![0.0, 1.0, 2.0, 3.0, 4.0]), column(vec![0.0, 0.0, 2.0, 4.0, 4.0]));
        let all = [true; 5];
        let tv = total_variation(&steep, &all, 1.0).0 / total_variation(&gentle, &all, 1.0).0;
        let squares = smoothness(&steep, &all, 1.0, [1.0; 3]).0 / smoothness(&gentle, &all, 1.0, [1.0; 3]).0;
        assert!((squares - 2.0).abs() < 1e-9, "{squares}");
        assert!((1.0..1.15).contains(&tv), "{tv}");
    }

    #[test]
    fn the_sparsity_gradient_matches_finite_differences_and_prefers_fewer_voxels() {
        check(sparsity);
        let (grid, hull) = small();
        let even = grid.map(|_| 2.0);
        assert!((sparsity(&even, &hull, 0.7).0 - 0.7).abs() < 1e-12, "an even density is not 1");
        let mut one = grid.map(|_| 0.0);
        one.data[5] = 1.0;
        assert!(sparsity(&one, &hull, 0.7).0 < 0.7 / 50.0, "one voxel is not near 0");
    }
}
