//! The built-in ground-truth smoke: a plume rising in the box
//! `[-0.5, 0.5]^3` (y up), deterministic from a seed, standing in for a
//! ScalarFlow frame (docs/DESIGN.md §4).
//!
//! How it is made, in three stages:
//! 1. **Simulation** (submodule `fluid`): buoyant smoke is released from a small
//!    ball near the bottom centre into air with random drafts, and the run
//!    stops when the head of the plume nears the top of the box ("captured
//!    mid-rise", about 40-60 steps). The grid is fixed (1/48 of the box per
//!    cell, 31 x 48 x 31 cells centred in x and z), so every output
//!    resolution sees the same plume.
//! 2. **Detail**: the plume is a continuous function of position: the
//!    simulated density (trilinear) looked up at a point displaced by a
//!    fractal noise warp that grows with height, times a log-normal fractal
//!    modulation `exp(3 fbm)`: turbulent puffs and wisps finer than the
//!    simulation grid.
//! 3. **Tone** (type `Tone`): a monotone curve, fitted per seed on a fixed
//!    48^3 lattice, maps that raw density by rank onto a power law, so that
//!    the statistics are those of the paper's ground truth: many voxels of
//!    thin smoke and a few dense ones (mean about [`TARGET_MEAN`] over
//!    occupied voxels).
//!
//! [`plume`] samples the function at voxel centres, scales it so that the
//! largest voxel is exactly [`PLUME_MAX`], and sets values below [`CUTOFF`]
//! to 0. The voxels within 0.03 of a face of the box are always 0 (two
//! voxels at res 64).
//!
//! Units: positions in world units of the scene (the box has side 1);
//! density is dimensionless (extinction is `sigma_t_scale * density`).
//! Seeds change the drafts, the initial stir and the uneven inflow, hence
//! the lean, curls and puffs. The result is bit-identical for a seed
//! whatever the number of threads.

mod fluid;
mod noise;
pub mod variation;

use crate::math::Vec3;
use crate::volume::Grid;
use fluid::{Field, Fluid, Settings};
use noise::Noise;
use rayon::prelude::*;
pub use variation::{Unusual, Variation};

/// Largest density of the plume (the paper's ground-truth maximum, 1.3585).
pub const PLUME_MAX: f64 = 1.36;

/// Densities below this are set to exactly 0 (docs/DESIGN.md §4).
pub const CUTOFF: f64 = 0.01;

/// Mean density over occupied voxels that the tone aims for (paper: 0.0432).
pub const TARGET_MEAN: f64 = 0.043;

/// Simulation cells per unit length (world).
const SIM_RES: f64 = 48.0;

/// Warp: largest displacement (world) and coarsest wavelength (world).
const WARP: (f64, f64) = (0.03, 0.12);

/// Log-normal detail: standard scale of the exponent and coarsest wavelength (world).
const DETAIL: (f64, f64) = (3.0, 0.1);

/// Raw densities below this fraction of the largest count as empty air.
const EMPTY: f64 = 4e-4;

/// At most this share of the calibration lattice is occupied.
const MAX_OCCUPANCY: f64 = 0.2;

/// Headroom of the tone above its last knot, relative (see [`Tone`]).
const KNEE: f64 = 0.1;

/// Occupancy and value statistics of a density grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlumeStats {
    /// Number of voxels with density > 0.
    pub occupied: usize,
    /// Mean density over those voxels (0 if there are none).
    pub mean_occupied: f64,
    /// Largest density (0 for an empty grid).
    pub max: f64,
    /// `occupied` over the number of voxels, in [0, 1].
    pub fraction_occupied: f64,
}

/// Statistics of `grid` (any density grid, not only a plume).
///
/// ```
/// use dualphoton::math::Vec3;
/// use dualphoton::data::plume::plume_stats;
/// use dualphoton::volume::Grid;
/// let g = Grid::new(Vec3::from_element(-0.5), Vec3::from_element(0.5), [1, 2, 2], vec![0.0, 0.5, 1.5, 0.0]);
/// let s = plume_stats(&g);
/// assert_eq!((s.occupied, s.mean_occupied, s.max, s.fraction_occupied), (2, 1.0, 1.5, 0.5));
/// ```
pub fn plume_stats(grid: &Grid<f64>) -> PlumeStats {
    let (occupied, sum) = grid.data.iter().filter(|&&v| v > 0.0).fold((0usize, 0.0), |(n, s), &v| (n + 1, s + v));
    PlumeStats {
        occupied,
        mean_occupied: if occupied > 0 { sum / occupied as f64 } else { 0.0 },
        max: grid.max_value(),
        fraction_occupied: occupied as f64 / grid.len().max(1) as f64,
    }
}

/// The plume of `seed` sampled at the voxel centres of a `(res, res, res)`
/// grid over `[-0.5, 0.5]^3`: max exactly [`PLUME_MAX`], values below
/// [`CUTOFF`] set to 0. `res = 0` is treated as 1; below about 8 the voxel
/// centres may all miss the smoke, and the grid is then all 0. Costs about
/// a second (the simulation) plus 0.1 s per million voxels, on one core.
///
/// ```
/// let g = dualphoton::data::plume::plume(16, 0);
/// assert_eq!(g.shape, [16, 16, 16]);
/// assert!((g.max_value() - 1.36).abs() < 1e-9);
/// ```
pub fn plume(res: usize, seed: u64) -> Grid<f64> {
    sample(&Smoke::new(seed, &Variation::default()), res.max(1))
}

/// [`plume`] with the simulation knobs of `variation` instead of the
/// built-in plume's (the same grid for [`Variation::default`]). Errors name
/// a bad knob.
///
/// ```
/// use dualphoton::data::plume::{plume, plume_with, Variation};
/// assert_eq!(plume_with(8, 3, &Variation::default())?.data, plume(8, 3).data);
/// # Ok::<(), dualphoton::error::Error>(())
/// ```
pub fn plume_with(res: usize, seed: u64, variation: &Variation) -> crate::error::Result<Grid<f64>> {
    variation.validate()?;
    Ok(sample(&Smoke::new(seed, variation), res.max(1)))
}

/// The plume of an [`Unusual`] case at `res`^3 (the smooth one blurred by a
/// Gaussian of `3 res / 64` voxels and rescaled to [`PLUME_MAX`]).
pub fn unusual_plume(res: usize, case: Unusual) -> Grid<f64> {
    let v = case.variation();
    let g = sample(&Smoke::new(case.seed(), &v), res.max(1));
    if case != Unusual::Smooth {
        return g;
    }
    let mut g = crate::volume::blur::gaussian_blur(&g, 3.0 * res as f64 / 64.0);
    let scale = PLUME_MAX / g.max_value().max(f64::MIN_POSITIVE);
    g.data.iter_mut().for_each(|v| *v = if *v * scale < CUTOFF { 0.0 } else { *v * scale });
    g
}

/// `smoke` at the voxel centres of a `(res, res, res)` grid, scaled and cut.
fn sample(smoke: &Smoke, res: usize) -> Grid<f64> {
    let lo = Vec3::from_element(-0.5);
    let mut grid = Grid::new(lo, -lo, [res, res, res], vec![0.0; res * res * res]);
    let h = 1.0 / res as f64;
    grid.data.par_chunks_mut(res).enumerate().for_each(|(row, out)| {
        let (k, j) = (row / res, row % res);
        for (i, v) in out.iter_mut().enumerate() {
            // The centre of voxel (k, j, i), docs/DESIGN.md §1.
            *v = smoke.at(&(lo + Vec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * h));
        }
    });
    let max = grid.max_value();
    if max > 0.0 {
        let scale = PLUME_MAX / max;
        for v in grid.data.iter_mut() {
            *v = if *v * scale < CUTOFF { 0.0 } else { *v * scale };
        }
    }
    grid
}

/// The plume as a continuous function of position.
struct Smoke {
    /// Simulated density (grid units, see [`fluid`]).
    sim: Field,
    /// World position of grid point 0 of `sim`.
    lo: Vec3,
    /// Warp noise (three channels) and detail noise.
    warp: Noise,
    detail: Noise,
    /// Raw density to output density.
    tone: Tone,
}

impl Smoke {
    /// Simulates the plume of `seed` with the knobs of `variation` and fits its tone.
    fn new(seed: u64, variation: &Variation) -> Self {
        let set = settings(variation);
        let head = (variation.head + 0.5) * SIM_RES;
        let mut fluid = Fluid::new(set, seed);
        // Capture the plume mid-rise: stop when the head reaches `head` (the
        // cap on steps is only a guard; plumes arrive in 40-60 steps), then
        // run on for the overrun.
        let mut after = None; // steps since the head arrived
        for _ in 0..200 + variation.overrun {
            fluid.step();
            after = match after {
                Some(n) => Some(n + 1),
                None => (fluid.top(0.05) >= head).then_some(0),
            };
            if after >= Some(variation.overrun) {
                break;
            }
        }
        let sim = fluid.density;
        let lo = Vec3::new(-(sim.dims[2] as f64) / SIM_RES / 2.0, -0.5, -(sim.dims[0] as f64) / SIM_RES / 2.0);
        let mut smoke =
            Smoke { sim, lo, warp: Noise::new(seed, 10), detail: Noise::new(seed, 20), tone: Tone::default() };
        smoke.tone = Tone::fit(smoke.calibration_values());
        smoke
    }

    /// Density before the tone: the simulation looked up at a noise-displaced
    /// point, times the log-normal detail, times [`margin`]; 0 outside the
    /// simulated box.
    fn raw(&self, p: &Vec3) -> f64 {
        let m = margin(p);
        let n = self.sim.dims;
        let g = (p - self.lo) * SIM_RES;
        // The warp moves a point by less than 2 WARP.0: beyond that, nothing.
        let reach = 2.0 * WARP.0 * SIM_RES;
        if m <= 0.0 || (0..3).any(|a| g[a] < -reach || g[a] > n[2 - a] as f64 + reach) {
            return 0.0;
        }
        // Turbulence grows with height: a third of the warp at the bottom, all of it at the top.
        let grow = (1.0 + 2.0 * (p.y + 0.5).clamp(0.0, 1.0)) / 3.0;
        let g = g + self.warp.fbm3(&(p / WARP.1), 3) * (WARP.0 * SIM_RES * grow);
        // Fade over the outer cell of the simulated box, so that smoke never ends at a wall.
        let edge = (0..3).map(|a| g[a].min(n[2 - a] as f64 - g[a])).fold(1.0, f64::min);
        if edge <= 0.0 {
            return 0.0;
        }
        let dens = self.sim.sample(&g) * edge * m;
        if dens <= 0.0 {
            return 0.0;
        }
        dens * (DETAIL.0 * self.detail.fbm(&(p / DETAIL.1), 4)).exp()
    }

    /// Density after the tone, in [0, about PLUME_MAX].
    fn at(&self, p: &Vec3) -> f64 {
        self.tone.map(self.raw(p))
    }

    /// Raw densities at the voxel centres of a fixed 48^3 lattice over the box.
    fn calibration_values(&self) -> Vec<f64> {
        let n = 48;
        (0..n * n * n)
            .into_par_iter()
            .map(|c| {
                let ijk = Vec3::new((c % n) as f64, ((c / n) % n) as f64, (c / (n * n)) as f64);
                self.raw(&((ijk + Vec3::from_element(0.5)) / n as f64 - Vec3::from_element(0.5)))
            })
            .collect()
    }
}

/// 0 within 0.03 of a face of the box, rising smoothly to 1 at 0.08 from
/// it: the outer voxels stay empty at any resolution (two layers at 64).
fn margin(p: &Vec3) -> f64 {
    (0..3)
        .map(|a| {
            let t = ((0.5 - p[a].abs() - 0.03) / 0.05).clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        })
        .fold(1.0, f64::min)
}

/// A monotone map from raw density to output density, fitted on the raw
/// values of a calibration lattice: the occupied ones (above [`EMPTY`] of
/// the largest, at most the top [`MAX_OCCUPANCY`]) are mapped by rank onto
/// the power law `pdf(v) ~ v^-alpha` on `[CUTOFF, PLUME_MAX]` whose mean is
/// [`TARGET_MEAN`] (alpha about 2.1: 70 % of the occupied voxels
/// below 0.03, about 1 % above 0.5). Piecewise linear between 256 rank
/// knots, 0 below the first, and above the last rising with unit slope
/// (in raw / last raw) into a soft knee that saturates at `1 + KNEE` times
/// [`PLUME_MAX`].
#[derive(Clone, Debug, Default)]
struct Tone {
    /// Raw values of the knots, strictly increasing.
    raw: Vec<f64>,
    /// Output values of the knots, increasing.
    out: Vec<f64>,
}

impl Tone {
    fn fit(mut raw: Vec<f64>) -> Tone {
        raw.sort_by(|a, b| a.total_cmp(b));
        let top = raw.last().copied().unwrap_or(0.0);
        if top <= 0.0 {
            return Tone::default(); // no smoke at all: everything maps to 0
        }
        let first = ((raw.len() as f64 * (1.0 - MAX_OCCUPANCY)) as usize).min(raw.len() - 1);
        let cut = raw[first].max(EMPTY * top);
        let occupied: Vec<f64> = raw.into_iter().filter(|&r| r >= cut).collect();
        let alpha = power_law_exponent(CUTOFF, PLUME_MAX, TARGET_MEAN);
        let (a, b) = (CUTOFF.powf(1.0 - alpha), PLUME_MAX.powf(1.0 - alpha));
        let knots = 256;
        let mut tone = Tone::default();
        for m in 0..knots {
            let u = m as f64 / (knots - 1) as f64;
            let r = occupied[(u * (occupied.len() - 1) as f64).round() as usize];
            // Tied raw values keep the first (lowest) output.
            if tone.raw.last().is_none_or(|&last| r > last) {
                tone.raw.push(r);
                tone.out.push((a + u * (b - a)).powf(1.0 / (1.0 - alpha))); // inverse CDF at u
            }
        }
        tone
    }

    fn map(&self, r: f64) -> f64 {
        let n = self.raw.len();
        if n == 0 || r < self.raw[0] {
            return 0.0;
        }
        let m = self.raw.partition_point(|&x| x <= r);
        if m == n {
            // Soft knee: finer sampling than the calibration lattice finds
            // higher peaks; saturating them keeps the final rescale to
            // PLUME_MAX, hence the statistics, nearly the same at every res.
            let x = r / self.raw[n - 1] - 1.0;
            return self.out[n - 1] * (1.0 + KNEE * (1.0 - (-x / KNEE).exp()));
        }
        let t = (r - self.raw[m - 1]) / (self.raw[m] - self.raw[m - 1]);
        self.out[m - 1] + t * (self.out[m] - self.out[m - 1])
    }
}

/// The exponent `alpha > 1` for which `pdf(v) ~ v^-alpha` on `[a, b]` has
/// mean `mean`, which must lie in `(a, (b - a) / ln(b / a))` (bisection;
/// the mean falls as alpha grows).
fn power_law_exponent(a: f64, b: f64, mean: f64) -> f64 {
    // Integral of v^p over [a, b].
    let integral =
        |p: f64| if (p + 1.0).abs() < 1e-12 { (b / a).ln() } else { (b.powf(p + 1.0) - a.powf(p + 1.0)) / (p + 1.0) };
    let mean_of = |alpha: f64| integral(1.0 - alpha) / integral(-alpha);
    let (mut lo, mut hi) = (1.0 + 1e-9, 10.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if mean_of(mid) > mean {
            lo = mid
        } else {
            hi = mid
        }
    }
    0.5 * (lo + hi)
}

/// The simulation, in grid units (cells of 1/48 of the box, unit time).
/// The knobs were tuned by eye against smoke-plume footage: a narrow,
/// steady jet at the source that breaks into puffs and widens upwards.
/// `variation` sets the sources, buoyancy, turbulence, drafts and width.
fn settings(variation: &Variation) -> Settings {
    let v = variation;
    let (nx, ny) = (v.width, 48);
    let centre = nx as f64 / 2.0;
    Settings {
        cells: [nx, ny, nx],
        dt: 2.0,
        buoyancy: v.buoyancy,
        confinement: v.confinement,
        // y = -0.39 in the world (built-in: radius 0.052 at the centre).
        sources: v
            .sources
            .iter()
            .map(|s| (Vec3::new(centre + s.x * SIM_RES, 0.11 * SIM_RES, centre + s.z * SIM_RES), s.radius))
            .collect(),
        source_density: 1.0,
        inflow: 2.0,
        pulse: 0.5,
        sway: 0.25,
        draft: v.draft,
        lean: Vec3::new(v.lean[0], 0.0, v.lean[1]),
        stir: v.stir,
        sweeps: 20,
        omega: 1.7,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::OnceLock;

    /// The plume of seed 0 at res 64, simulated once for all tests.
    fn shared() -> &'static (Smoke, Grid<f64>) {
        static PLUME: OnceLock<(Smoke, Grid<f64>)> = OnceLock::new();
        PLUME.get_or_init(|| {
            let smoke = Smoke::new(0, &Variation::default());
            let grid = sample(&smoke, 64);
            (smoke, grid)
        })
    }

    /// Density-weighted mean position of a grid.
    fn centre_of_mass(g: &Grid<f64>) -> Vec3 {
        let [nz, ny, nx] = g.shape;
        let (mut sum, mut mass) = (Vec3::zeros(), 0.0);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let v = g.data[g.index(k, j, i)];
                    sum += g.voxel_center(k, j, i) * v;
                    mass += v;
                }
            }
        }
        sum / mass
    }

    #[test]
    fn same_seed_same_grid_whatever_the_threads() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let alone = pool.install(|| plume(64, 0));
        let bits = |g: &Grid<f64>| g.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&alone), bits(&shared().1));
    }

    #[test]
    fn statistics_like_the_papers_ground_truth() {
        let g = &shared().1;
        assert!(g.data.iter().all(|&v| v == 0.0 || (CUTOFF..=PLUME_MAX + 1e-9).contains(&v)));
        let s = plume_stats(g);
        assert!((s.max - PLUME_MAX).abs() < 1e-9, "{s:?}");
        assert!((0.035..0.055).contains(&s.mean_occupied), "{s:?}");
        assert!((0.03..0.2).contains(&s.fraction_occupied), "{s:?}");
    }

    #[test]
    fn rises_from_a_source_at_the_bottom_centre() {
        let g = &shared().1;
        // The lowest occupied layer: near the bottom, centred in x and z.
        let n = 64;
        let j0 = (0..n).find(|&j| (0..n * n).any(|c| g.data[g.index(c / n, j, c % n)] > 0.0)).unwrap();
        let layer: Vec<Vec3> = (0..n * n)
            .filter(|&c| g.data[g.index(c / n, j0, c % n)] > 0.0)
            .map(|c| g.voxel_center(c / n, j0, c % n))
            .collect();
        let mid = layer.iter().sum::<Vec3>() / layer.len() as f64;
        assert!(mid.y < -0.4 && mid.x.abs() < 0.05 && mid.z.abs() < 0.05, "{mid:?}");
        // Most of the smoke is well above the source, and the plume reaches high.
        let c = centre_of_mass(g);
        assert!(c.y > -0.2 && c.x.abs() < 0.15 && c.z.abs() < 0.15, "{c:?}");
        let top = (0..n).rev().find(|&j| (0..n * n).any(|c| g.data[g.index(c / n, j, c % n)] > 0.0)).unwrap();
        assert!(top > 3 * n / 4, "{top}");
    }

    #[test]
    fn empty_margin_at_the_faces() {
        let g = &shared().1;
        let n = 64;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    if [i, j, k].iter().any(|&a| a < 2 || a >= n - 2) {
                        assert_eq!(g.data[g.index(k, j, i)], 0.0, "voxel {k} {j} {i}");
                    }
                }
            }
        }
    }

    #[test]
    fn resolutions_sample_the_same_plume() {
        let (smoke, at64) = shared();
        let at96 = sample(smoke, 96);
        let d = centre_of_mass(&at96) - centre_of_mass(at64);
        assert!(d.norm() < 0.01, "{d:?}");
        let (a, b) = (plume_stats(&at96), plume_stats(at64));
        assert!((a.fraction_occupied / b.fraction_occupied - 1.0).abs() < 0.05, "{a:?} {b:?}");
        assert!((a.mean_occupied / b.mean_occupied - 1.0).abs() < 0.05, "{a:?} {b:?}");
    }

    #[test]
    fn power_law_has_the_target_mean() {
        let alpha = power_law_exponent(CUTOFF, PLUME_MAX, TARGET_MEAN);
        // Mean by the midpoint rule on a log grid.
        let (mut num, mut den) = (0.0, 0.0);
        let steps = 100_000;
        for s in 0..steps {
            let v = CUTOFF * (PLUME_MAX / CUTOFF).powf((s as f64 + 0.5) / steps as f64);
            num += v * v.powf(-alpha) * v; // v pdf(v) dv, with dv ~ v on a log grid
            den += v.powf(-alpha) * v;
        }
        assert!((num / den - TARGET_MEAN).abs() < 1e-5, "alpha {alpha}: mean {}", num / den);
    }

    #[test]
    fn tone_is_monotone_and_spans_the_range() {
        let raw: Vec<f64> = (0..10_000).map(|i| if i < 8000 { 0.0 } else { (i - 7999) as f64 / 2000.0 }).collect();
        let tone = Tone::fit(raw);
        assert_eq!(tone.map(0.0), 0.0);
        assert!((tone.map(1.0) - PLUME_MAX).abs() < 1e-9);
        assert!((tone.map(tone.raw[0]) - CUTOFF).abs() < 1e-9);
        let ys: Vec<f64> = (1..1000).map(|i| tone.map(i as f64 / 1000.0)).collect();
        assert!(ys.windows(2).all(|w| w[1] >= w[0]));
        assert_eq!(Tone::fit(vec![0.0; 10]).map(1.0), 0.0);
    }

    /// Writes max projections along z and x and smoke-like opacity views
    /// (`1 - exp(-20 * integral)`) of seeds 0 and 1 into the temp directory:
    /// `cargo test --release --lib plume::tests::preview -- --ignored`.
    #[test]
    #[ignore]
    fn preview() {
        for seed in [0, 1] {
            let g = plume(128, seed);
            let n = g.shape[0];
            let w = 4 * n;
            let mut img = vec![0.0; n * w];
            for k in 0..n {
                for j in 0..n {
                    for i in 0..n {
                        let v = g.data[g.index(k, j, i)];
                        let r = (n - 1 - j) * w;
                        img[r + i] = f64::max(img[r + i], v / PLUME_MAX);
                        img[r + n + k] = f64::max(img[r + n + k], v / PLUME_MAX);
                        img[r + 2 * n + i] += 20.0 * v / n as f64;
                        img[r + 3 * n + k] += 20.0 * v / n as f64;
                    }
                }
            }
            for j in 0..n {
                for x in &mut img[j * w + 2 * n..(j + 1) * w] {
                    *x = 1.0 - (-*x).exp();
                }
            }
            let path = std::env::temp_dir().join(format!("dualphoton-plume-{seed}.png"));
            crate::io::png::write_preview(&path, w, n, &img, Some(1.0)).unwrap();
            println!("{}: {:?}", path.display(), plume_stats(&g));
        }
    }

    #[test]
    fn knobs_change_the_plume_and_an_overrun_reaches_the_top() {
        let base = Variation::sample(variation::TRAIN_SEEDS.start);
        let a = plume_with(24, 5, &base).unwrap();
        let b = plume_with(24, 5, &Variation { sources: Variation::sample(7).sources, ..base.clone() }).unwrap();
        assert_ne!(a.data, b.data);
        let top =
            |g: &Grid<f64>| (0..24).rev().find(|&j| (0..24 * 24).any(|c| g.data[g.index(c / 24, j, c % 24)] > 0.0));
        let low = plume_with(24, 5, &Variation { head: -0.05, ..base.clone() }).unwrap();
        let cut = plume_with(24, 5, &Variation { head: 0.41, overrun: 25, ..base }).unwrap();
        assert!(top(&low) < top(&cut), "{:?} {:?}", top(&low), top(&cut));
        assert!(plume_with(24, 5, &Variation { width: 99, ..Variation::default() }).is_err());
    }
}
