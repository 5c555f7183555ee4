//! Gaussian blur of a density grid, separable along x, y and z, with the
//! grid's own edge rule (values beyond the faces repeat the edge voxel).
//! Used to make smoother, thicker media from the built-in plume and to
//! measure how much of a density lives below a given scale.

use super::Grid;

/// `grid` blurred by a Gaussian of standard deviation `sigma` voxels
/// (truncated at 3 sigma, normalised); `sigma <= 0` returns a copy.
///
/// ```
/// use dualphoton::volume::{blur::gaussian_blur, Grid};
/// use dualphoton::math::Vec3;
/// let mut g = Grid::new(Vec3::zeros(), Vec3::from_element(1.0), [5, 5, 5], vec![0.0; 125]);
/// g.data[62] = 1.0; // the centre voxel
/// let b = gaussian_blur(&g, 1.0);
/// // Mass is kept away from the faces, and the peak spreads.
/// assert!((b.data.iter().sum::<f64>() - 1.0).abs() < 0.05);
/// assert!(b.data[62] < 0.1 && b.data[62] > b.data[63]);
/// ```
pub fn gaussian_blur(grid: &Grid<f64>, sigma: f64) -> Grid<f64> {
    if sigma.is_nan() || sigma <= 0.0 {
        return grid.clone();
    }
    let reach = (3.0 * sigma).ceil() as isize;
    let raw: Vec<f64> = (-reach..=reach).map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let total: f64 = raw.iter().sum();
    let kernel: Vec<f64> = raw.iter().map(|w| w / total).collect();
    let [nz, ny, nx] = grid.shape;
    let mut data = grid.data.clone();
    for (stride, n) in [(1, nx), (nx, ny), (nx * ny, nz)] {
        let src = data.clone();
        for (v, out) in data.iter_mut().enumerate() {
            let c = (v / stride % n) as isize;
            let base = v as isize - c * stride as isize;
            *out = kernel
                .iter()
                .enumerate()
                .map(|(m, w)| {
                    let at = (c + m as isize - reach).clamp(0, n as isize - 1);
                    w * src[(base + at * stride as isize) as usize]
                })
                .sum();
        }
    }
    Grid::new(grid.lo, grid.hi, grid.shape, data)
}
