//! A short buoyant smoke simulation on a staggered (MAC) grid, the engine
//! of the built-in plume.
//!
//! Everything here is in grid units: lengths in cells (cell `(k, j, i)`
//! spans `[i, i+1] x [j, j+1] x [k, k+1]`, centre at `+0.5`), velocities in
//! cells per unit time, density dimensionless. One step (Stam 1999, Fedkiw
//! et al. 2001, Selle et al. 2008): refresh the source, advect velocity
//! (semi-Lagrangian) and density (MacCormack with the min/max limiter, so
//! that puffs stay sharp), add buoyancy proportional to density, vorticity
//! confinement and a random draft, and make the velocity divergence-free
//! (red-black SOR on the 7-point Poisson equation, warm-started).
//! Walls are solid (zero normal velocity, free slip) except the top, which
//! is open (pressure 0).
//!
//! Parallel loops write disjoint cells from the previous state only, and the
//! pressure solve is serial, so the result is bit-identical for any number
//! of threads.

use super::noise::Noise;
use crate::math::Vec3;
use rayon::prelude::*;

/// Values on one of the staggered lattices: centres (density, pressure) or
/// the faces normal to x, y or z (velocity components).
#[derive(Clone, Debug)]
pub struct Field {
    /// Values, C order of `dims`.
    pub data: Vec<f64>,
    /// Lattice size `[nz, ny, nx]`.
    pub dims: [usize; 3],
    /// Grid-unit position of sample `(0, 0, 0)` along x, y, z.
    pub off: [f64; 3],
}

impl Field {
    fn zeros(dims: [usize; 3], off: [f64; 3]) -> Self {
        Field { data: vec![0.0; dims[0] * dims[1] * dims[2]], dims, off }
    }

    #[inline]
    fn idx(&self, k: usize, j: usize, i: usize) -> usize {
        (k * self.dims[1] + j) * self.dims[2] + i
    }

    /// Grid-unit position of sample `(k, j, i)`.
    #[inline]
    fn pos(&self, k: usize, j: usize, i: usize) -> Vec3 {
        Vec3::new(i as f64 + self.off[0], j as f64 + self.off[1], k as f64 + self.off[2])
    }

    /// Lower corner (flat index) of the trilinear cell holding `g`, and the
    /// fractions along x, y, z; clamped to the edge samples outside the lattice.
    #[inline]
    fn corner(&self, g: &Vec3) -> (usize, [f64; 3]) {
        corner(self.dims, &self.off, g)
    }

    /// Trilinear value at `g` and the min and max of the 8 samples used.
    #[inline]
    fn sample_bounds(&self, g: &Vec3) -> (f64, f64, f64) {
        let (n, f) = self.corner(g);
        let (sy, sz) = (self.dims[2], self.dims[2] * self.dims[1]);
        let d = &self.data;
        let c =
            [d[n], d[n + 1], d[n + sy], d[n + sy + 1], d[n + sz], d[n + sz + 1], d[n + sz + sy], d[n + sz + sy + 1]];
        let (lo, hi) = c.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        (trilinear(&c, &f), lo, hi)
    }

    /// Trilinear value at `g`.
    #[inline]
    pub fn sample(&self, g: &Vec3) -> f64 {
        let (n, f) = self.corner(g);
        let (sy, sz) = (self.dims[2], self.dims[2] * self.dims[1]);
        let d = &self.data;
        trilinear(
            &[d[n], d[n + 1], d[n + sy], d[n + sy + 1], d[n + sz], d[n + sz + 1], d[n + sz + sy], d[n + sz + sy + 1]],
            &f,
        )
    }
}

/// See [`Field::corner`]; `dims` is `[nz, ny, nx]` (each at least 2), `off` the
/// grid-unit position of sample 0 along x, y, z.
#[inline]
fn corner(dims: [usize; 3], off: &[f64; 3], g: &Vec3) -> (usize, [f64; 3]) {
    let mut i0 = [0usize; 3];
    let mut f = [0f64; 3];
    for a in 0..3 {
        let n = dims[2 - a];
        let t = (g[a] - off[a]).clamp(0.0, (n - 1) as f64);
        i0[a] = (t as usize).min(n - 2);
        f[a] = t - i0[a] as f64;
    }
    ((i0[2] * dims[1] + i0[1]) * dims[2] + i0[0], f)
}

/// Trilinear blend of the 8 corner values (x fastest, then y, then z).
#[inline]
fn trilinear(c: &[f64; 8], f: &[f64; 3]) -> f64 {
    let lx = |a: f64, b: f64| a + (b - a) * f[0];
    let (x00, x10, x01, x11) = (lx(c[0], c[1]), lx(c[2], c[3]), lx(c[4], c[5]), lx(c[6], c[7]));
    let y0 = x00 + (x10 - x00) * f[1];
    let y1 = x01 + (x11 - x01) * f[1];
    y0 + (y1 - y0) * f[2]
}

/// Fills a lattice of `dims` with `f(k, j, i)`, rows in parallel.
fn fill<T: Copy + Default + Send>(dims: [usize; 3], f: impl Fn(usize, usize, usize) -> T + Sync) -> Vec<T> {
    let [nz, ny, nx] = dims;
    let mut out = vec![T::default(); nz * ny * nx];
    out.par_chunks_mut(nx).enumerate().for_each(|(r, row)| {
        let (k, j) = (r / ny, r % ny);
        for (i, x) in row.iter_mut().enumerate() {
            *x = f(k, j, i);
        }
    });
    out
}

/// Time over which the air's horizontal motion follows the draft (unit time).
const DRAFT_TIME: f64 = 15.0;

/// Physical knobs of the simulation (grid units, unit time).
#[derive(Clone, Debug)]
pub struct Settings {
    /// Cells `[nz, ny, nx]`.
    pub cells: [usize; 3],
    /// Time step.
    pub dt: f64,
    /// Upward acceleration per unit density (cells / time^2).
    pub buoyancy: f64,
    /// Vorticity confinement strength (dimensionless, Fedkiw's epsilon in cells).
    pub confinement: f64,
    /// Source balls: centre (grid units) and radius (cells), all at one
    /// height (the turbulence ramps up from the first one's).
    pub sources: Vec<(Vec3, f64)>,
    /// Density written into the source each step (before noise).
    pub source_density: f64,
    /// Upward speed imposed in the source (cells / time).
    pub inflow: f64,
    /// Relative amplitude of the random pulsing of the source, in [0, 1).
    pub pulse: f64,
    /// Amplitude of the random sideways sway of the jet (cells / time).
    pub sway: f64,
    /// Speed of the random, slowly changing horizontal draft of the air (cells / time).
    pub draft: f64,
    /// Steady horizontal wind the draft blows around (cells / time; y ignored): the plume's lean.
    pub lean: Vec3,
    /// Amplitude of the random initial air motion (cells / time).
    pub stir: f64,
    /// Red-black SOR sweeps per pressure solve.
    pub sweeps: usize,
    /// SOR relaxation factor in (1, 2).
    pub omega: f64,
}

/// The random functions of one seed that drive the simulation.
struct Noises {
    /// Initial air motion (three channels).
    stir: Noise,
    /// Lumps of the inflow's smoke.
    lumps: Noise,
    /// Pulse and sway of the source, as functions of time.
    slow: Noise,
    /// The draft (x and z channels).
    draft: Noise,
}

/// The simulation state.
pub struct Fluid {
    set: Settings,
    /// Smoke density at cell centres.
    pub density: Field,
    u: Field,
    v: Field,
    w: Field,
    /// Velocity at cell centres, refreshed after every change of the faces.
    centre: Vec<Vec3>,
    /// Pressure times dt over fluid density (grid units) with one ghost cell
    /// per side, kept to warm-start the next solve.
    q: Vec<f64>,
    noise: Noises,
    time: f64,
}

impl Fluid {
    /// Still air with a weak random stir (different for every seed), no smoke yet.
    pub fn new(set: Settings, seed: u64) -> Self {
        let [nz, ny, nx] = set.cells;
        let noise = Noises {
            stir: Noise::new(seed, 100),
            lumps: Noise::new(seed, 101),
            slow: Noise::new(seed, 102),
            draft: Noise::new(seed, 103),
        };
        let mut u = Field::zeros([nz, ny, nx + 1], [0.0, 0.5, 0.5]);
        let mut v = Field::zeros([nz, ny + 1, nx], [0.5, 0.0, 0.5]);
        let mut w = Field::zeros([nz + 1, ny, nx], [0.5, 0.5, 0.0]);
        // Low-frequency random air motion (wavelength ~ 16 cells); the first
        // projection makes it divergence-free.
        for (c, f) in [&mut u, &mut v, &mut w].into_iter().enumerate() {
            let g = &*f;
            let fresh = fill(g.dims, |k, j, i| set.stir * noise.stir.fbm3(&(g.pos(k, j, i) / 16.0), 2)[c]);
            f.data = fresh;
        }
        let density = Field::zeros([nz, ny, nx], [0.5, 0.5, 0.5]);
        let mut fluid = Fluid {
            q: vec![0.0; (nz + 2) * (ny + 2) * (nx + 2)],
            centre: vec![],
            set,
            density,
            u,
            v,
            w,
            noise,
            time: 0.0,
        };
        fluid.walls();
        fluid.project();
        fluid.centre_velocity();
        fluid
    }

    /// Refreshes the cell-centre velocities (mean of the two faces per axis).
    fn centre_velocity(&mut self) {
        let (u, v, w) = (&self.u, &self.v, &self.w);
        self.centre = fill(self.set.cells, |k, j, i| {
            Vec3::new(
                0.5 * (u.data[u.idx(k, j, i)] + u.data[u.idx(k, j, i + 1)]),
                0.5 * (v.data[v.idx(k, j, i)] + v.data[v.idx(k, j + 1, i)]),
                0.5 * (w.data[w.idx(k, j, i)] + w.data[w.idx(k + 1, j, i)]),
            )
        });
    }

    /// Velocity at sample `(k, j, i)` of a lattice: at a cell centre (`axis =
    /// None`) or on a face normal to `axis`, where it is the mean of the two
    /// cells the face separates (the edge cell at a wall), as trilinear
    /// interpolation of the centres would give.
    #[inline]
    fn velocity_at(&self, axis: Option<usize>, k: usize, j: usize, i: usize) -> Vec3 {
        let [nz, ny, nx] = self.set.cells;
        let at = |k: usize, j: usize, i: usize| (k * ny + j) * nx + i;
        let c = &self.centre;
        match axis {
            None => c[at(k, j, i)],
            Some(0) => 0.5 * (c[at(k, j, i.saturating_sub(1))] + c[at(k, j, i.min(nx - 1))]),
            Some(1) => 0.5 * (c[at(k, j.saturating_sub(1), i)] + c[at(k, j.min(ny - 1), i)]),
            Some(_) => 0.5 * (c[at(k.saturating_sub(1), j, i)] + c[at(k.min(nz - 1), j, i)]),
        }
    }

    /// One time step.
    pub fn step(&mut self) {
        self.source();
        self.centre_velocity();
        self.advect();
        self.centre_velocity();
        self.forces();
        self.walls();
        self.project();
        self.centre_velocity();
        self.time += self.set.dt;
    }

    /// Height (grid units) of the highest cell layer holding density above `level`, or 0.
    pub fn top(&self, level: f64) -> f64 {
        let [nz, ny, nx] = self.set.cells;
        (0..ny)
            .rev()
            .find(|&j| (0..nz).any(|k| (0..nx).any(|i| self.density.data[self.density.idx(k, j, i)] > level)))
            .map_or(0.0, |j| j as f64 + 0.5)
    }

    /// Writes smoke and velocity into the source ball. Like a real inflow it
    /// is uneven: the smoke is modulated by noise drifting with time, the
    /// strength pulses and the jet sways sideways.
    fn source(&mut self) {
        let s = &self.set;
        let t = self.time;
        let n = &self.noise;
        // Slow random functions of time (period ~ 12 time units).
        let slow = n.slow.at3(&Vec3::new(t / 12.0, 0.37, 0.61));
        let pulse = (1.0 + s.pulse * slow.y).max(0.0);
        let sway = Vec3::new(slow.x, 0.0, slow.z) * s.sway;
        // The strongest of the balls' weights (they rarely overlap).
        let ball = |p: Vec3| {
            s.sources.iter().fold(0.0f64, |b, (c, r)| {
                let x = (p - c).norm_squared() / (r * r);
                if x < 1.0 {
                    b.max(1.0 - x)
                } else {
                    b
                }
            })
        };
        let d = &self.density;
        self.density.data = fill(d.dims, |k, j, i| {
            let p = d.pos(k, j, i);
            let old = d.data[d.idx(k, j, i)];
            let b = ball(p);
            if b == 0.0 {
                return old;
            }
            let lumps = (1.0 + 0.8 * n.lumps.at(&(p / 2.5 + Vec3::new(0.0, -1.5 * t, 0.7 * t)))).max(0.0);
            old.max(s.source_density * b * lumps * pulse)
        });
        let jet = Vec3::new(0.0, s.inflow * pulse, 0.0) + sway;
        for (a, f) in [&mut self.u, &mut self.v, &mut self.w].into_iter().enumerate() {
            let g = &*f;
            let fresh = fill(g.dims, |k, j, i| {
                let old = g.data[g.idx(k, j, i)];
                let b = ball(g.pos(k, j, i));
                old + (jet[a] - old) * b
            });
            f.data = fresh;
        }
    }

    /// Semi-Lagrangian velocity, MacCormack density.
    fn advect(&mut self) {
        let dt = self.set.dt;
        // One Euler step back along the velocity at the sample (RK2 made no
        // visible difference at this resolution and cost a third of the run).
        let ad = |f: &Field, a: usize| {
            fill(f.dims, |k, j, i| f.sample(&(f.pos(k, j, i) - self.velocity_at(Some(a), k, j, i) * dt)))
        };
        let (u, v, w) = (ad(&self.u, 0), ad(&self.v, 1), ad(&self.w, 2));
        let d = &self.density;
        let shift = |k, j, i| self.velocity_at(None, k, j, i) * dt;
        let back: Vec<(f64, f64, f64)> = fill(d.dims, |k, j, i| d.sample_bounds(&(d.pos(k, j, i) - shift(k, j, i))));
        let hat = Field { data: back.iter().map(|b| b.0).collect(), ..d.clone() };
        let fresh = fill(d.dims, |k, j, i| {
            let n = d.idx(k, j, i);
            let again = hat.sample(&(d.pos(k, j, i) + shift(k, j, i)));
            // Half the round-trip error corrects the forward step; the limiter
            // keeps the result within the values it was interpolated from.
            (back[n].0 + 0.5 * (d.data[n] - again)).clamp(back[n].1, back[n].2)
        });
        self.density.data = fresh;
        self.u.data = u;
        self.v.data = v;
        self.w.data = w;
    }

    /// Buoyancy (up, proportional to density), vorticity confinement and the
    /// draft.
    fn forces(&mut self) {
        let [nz, ny, nx] = self.set.cells;
        let (dt, eps) = (self.set.dt, self.set.confinement);
        let d = &self.density;
        let cv = &self.centre;
        let at = |k: usize, j: usize, i: usize| (k * ny + j) * nx + i;
        // Central difference of `f` along axis a at (k, j, i), one-sided at walls.
        let diff = |f: &dyn Fn(usize) -> Vec3, k: usize, j: usize, i: usize, a: usize| -> Vec3 {
            let (c, n) = ([i, j, k][a], [nx, ny, nz][a]);
            let (lo, hi) = (c.saturating_sub(1), (c + 1).min(n - 1));
            let put = |m: usize| match a {
                0 => at(k, j, m),
                1 => at(k, m, i),
                _ => at(m, j, i),
            };
            (f(put(hi)) - f(put(lo))) / (hi - lo).max(1) as f64
        };
        let curl: Vec<Vec3> = fill(d.dims, |k, j, i| {
            let g = |n: usize| cv[n];
            let (dx, dy, dz) = (diff(&g, k, j, i, 0), diff(&g, k, j, i, 1), diff(&g, k, j, i, 2));
            Vec3::new(dy.z - dz.y, dz.x - dx.z, dx.y - dy.x)
        });
        let force: Vec<Vec3> = fill(d.dims, |k, j, i| {
            let g = |n: usize| Vec3::new(curl[n].norm(), 0.0, 0.0);
            let eta = Vec3::new(diff(&g, k, j, i, 0).x, diff(&g, k, j, i, 1).x, diff(&g, k, j, i, 2).x);
            let len = eta.norm();
            // Turbulence grows as the plume rises: full strength from a third
            // of the height above the source.
            let ramp =
                ((j as f64 - self.set.sources.first().map_or(0.0, |s| s.0.y)) / (ny as f64 / 3.0)).clamp(0.0, 1.0);
            let conf = if len > 1e-12 { (eta / len).cross(&curl[at(k, j, i)]) * (eps * ramp) } else { Vec3::zeros() };
            let q =
                Vec3::new(i as f64, j as f64, k as f64) / 10.0 + Vec3::new(0.0, -self.time / 30.0, self.time / 25.0);
            // Horizontal air motion relaxes towards a random, slowly changing
            // draft, calmer near the floor.
            let flat = Vec3::new(1.0, 0.0, 1.0);
            let wind = self.noise.draft.at3(&q).component_mul(&flat) * (self.set.draft * (0.3 + 0.7 * ramp))
                + self.set.lean.component_mul(&flat) * (0.3 + 0.7 * ramp);
            let here = cv[at(k, j, i)];
            let draft = (wind - Vec3::new(here.x, 0.0, here.z)) / DRAFT_TIME;
            conf + draft + Vec3::new(0.0, self.set.buoyancy * d.data[at(k, j, i)], 0.0)
        });
        // Faces take the mean of the forces of the two cells they separate.
        let face = |f: &Field, a: usize, k: usize, j: usize, i: usize| -> f64 {
            let c = [i, j, k][a];
            let n = [nx, ny, nz][a];
            let cell = |m: usize| match a {
                0 => at(k, j, m),
                1 => at(k, m, i),
                _ => at(m, j, i),
            };
            let old = f.data[f.idx(k, j, i)];
            let fa = match (c, c == n) {
                (0, _) => force[cell(0)][a],
                (_, true) => force[cell(n - 1)][a],
                _ => 0.5 * (force[cell(c - 1)][a] + force[cell(c)][a]),
            };
            old + dt * fa
        };
        self.u.data = fill(self.u.dims, |k, j, i| face(&self.u, 0, k, j, i));
        self.v.data = fill(self.v.dims, |k, j, i| face(&self.v, 1, k, j, i));
        self.w.data = fill(self.w.dims, |k, j, i| face(&self.w, 2, k, j, i));
    }

    /// Zero normal velocity on the solid walls (all but the top).
    fn walls(&mut self) {
        let [nz, ny, nx] = self.set.cells;
        for k in 0..nz {
            for j in 0..ny {
                let (a, b) = (self.u.idx(k, j, 0), self.u.idx(k, j, nx));
                self.u.data[a] = 0.0;
                self.u.data[b] = 0.0;
            }
            for i in 0..nx {
                let a = self.v.idx(k, 0, i);
                self.v.data[a] = 0.0;
            }
        }
        for j in 0..ny {
            for i in 0..nx {
                let (a, b) = (self.w.idx(0, j, i), self.w.idx(nz, j, i));
                self.w.data[a] = 0.0;
                self.w.data[b] = 0.0;
            }
        }
    }

    /// Subtracts the gradient of `q`, where `sum over neighbours (q_nb - q) =
    /// divergence` in every cell (solid neighbours left out, the open top
    /// counted with `q = 0`), so that the flux out of every cell is ~0.
    fn project(&mut self) {
        let [nz, ny, nx] = self.set.cells;
        let at = |k: usize, j: usize, i: usize| (k * ny + j) * nx + i;
        let div = self.divergence();
        // q lives on a lattice padded by one ghost cell per side. A ghost
        // next to a wall holds its cell's value (so the wall adds nothing to
        // the equation's solution: zero normal gradient), the ghosts above
        // the open top hold 0.
        let (px, py) = (nx + 2, ny + 2);
        let pad = |k: usize, j: usize, i: usize| ((k + 1) * py + j + 1) * px + i + 1;
        let q = &mut self.q;
        let (sy, sz) = (px, px * py);
        let omega = self.set.omega;
        for _ in 0..self.set.sweeps {
            for k in 0..nz {
                for j in 0..ny {
                    q[pad(k, j, 0) - 1] = q[pad(k, j, 0)];
                    q[pad(k, j, nx - 1) + 1] = q[pad(k, j, nx - 1)];
                }
                for i in 0..nx {
                    q[pad(k, 0, i) - sy] = q[pad(k, 0, i)];
                }
            }
            for j in 0..ny {
                for i in 0..nx {
                    q[pad(0, j, i) - sz] = q[pad(0, j, i)];
                    q[pad(nz - 1, j, i) + sz] = q[pad(nz - 1, j, i)];
                }
            }
            for colour in 0..2 {
                for k in 0..nz {
                    for j in 0..ny {
                        let row = pad(k, j, 0);
                        for i in ((k + j + colour) % 2..nx).step_by(2) {
                            let c = row + i;
                            let target = (q[c - 1] + q[c + 1] + q[c - sy] + q[c + sy] + q[c - sz] + q[c + sz]
                                - div[at(k, j, i)])
                                / 6.0;
                            q[c] += omega * (target - q[c]);
                        }
                    }
                }
            }
        }
        let q = &self.q;
        let grad = |f: &Field, a: usize, k: usize, j: usize, i: usize| -> f64 {
            let old = f.data[f.idx(k, j, i)];
            let (c, n) = ([i, j, k][a], [nx, ny, nz][a]);
            let cell = |m: usize| match a {
                0 => pad(k, j, m),
                1 => pad(k, m, i),
                _ => pad(m, j, i),
            };
            if c == 0 || (c == n && a != 1) {
                old // solid wall
            } else if c == n {
                old + q[cell(n - 1)] // open top: q = 0 outside
            } else {
                old - (q[cell(c)] - q[cell(c - 1)])
            }
        };
        self.u.data = fill(self.u.dims, |k, j, i| grad(&self.u, 0, k, j, i));
        self.v.data = fill(self.v.dims, |k, j, i| grad(&self.v, 1, k, j, i));
        self.w.data = fill(self.w.dims, |k, j, i| grad(&self.w, 2, k, j, i));
    }

    /// Net outflow of every cell (C order of the cells).
    fn divergence(&self) -> Vec<f64> {
        let (u, v, w) = (&self.u, &self.v, &self.w);
        fill(self.set.cells, |k, j, i| {
            (u.data[u.idx(k, j, i + 1)] - u.data[u.idx(k, j, i)])
                + (v.data[v.idx(k, j + 1, i)] - v.data[v.idx(k, j, i)])
                + (w.data[w.idx(k + 1, j, i)] - w.data[w.idx(k, j, i)])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Settings {
        Settings {
            cells: [12, 20, 12],
            dt: 0.5,
            buoyancy: 2.0,
            confinement: 0.3,
            sources: vec![(Vec3::new(6.0, 3.0, 6.0), 2.5)],
            source_density: 1.0,
            inflow: 1.0,
            pulse: 0.5,
            sway: 0.5,
            draft: 0.02,
            lean: Vec3::zeros(),
            stir: 0.3,
            sweeps: 200,
            omega: 1.8,
        }
    }

    #[test]
    fn projection_removes_divergence_and_smoke_rises() {
        let mut f = Fluid::new(small(), 1);
        let before = f.top(0.05);
        for _ in 0..6 {
            f.step();
        }
        let div = f.divergence().iter().fold(0.0, |m: f64, d| m.max(d.abs()));
        assert!(div < 1e-3, "{div}");
        assert!(f.top(0.05) > before + 3.0, "{} -> {}", before, f.top(0.05));
        assert!(f.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
    }

    #[test]
    fn seeds_give_different_smoke() {
        let run = |seed| {
            let mut f = Fluid::new(Settings { draft: 0.5, ..small() }, seed);
            for _ in 0..6 {
                f.step();
            }
            f.density.data
        };
        let (a, b, again) = (run(3), run(4), run(3));
        assert_eq!(a, again);
        let diff: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum();
        let mass: f64 = a.iter().sum();
        assert!(diff > 0.05 * mass, "{diff} vs {mass}");
    }
}
