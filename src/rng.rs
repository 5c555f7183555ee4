//! Deterministic random streams: one stream per (seed, purpose, index), so
//! results depend on the seed only, never on the number of threads.

use rand::{Rng as _, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

/// What a stream is used for; keeps photon and pixel streams apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Purpose {
    /// Photon tracing, indexed by photon.
    Photon = 1,
    /// Camera rays of the photon-mapping renderer, indexed by pixel.
    Pixel = 2,
    /// Camera paths of the reference path tracer, indexed by pixel.
    PathPixel = 3,
    /// Scene generation (the plume), indexed by anything.
    Scene = 4,
    /// Gradient estimators (direction and subset draws), indexed by step.
    Gradient = 5,
    /// Shadow rays of the light-depth grids, indexed by light and voxel.
    Shadow = 6,
}

/// A seeded generator of uniform numbers in [0, 1).
pub struct Rng(Pcg64);

/// SplitMix64 finaliser: spreads nearby integers over all 64 bits.
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// The stream for `index` of `purpose` under `seed`.
    pub fn new(seed: u64, purpose: Purpose, index: u64) -> Self {
        let state = ((mix(seed) as u128) << 64) | mix(seed ^ mix(purpose as u64)) as u128;
        let stream = ((purpose as u128) << 64) | index as u128;
        Rng(Pcg64::new(state, stream))
    }

    /// A generator from a single seed (for one-off draws).
    pub fn from_seed(seed: u64) -> Self {
        Rng(Pcg64::seed_from_u64(mix(seed)))
    }

    /// A uniform number in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        self.0.random::<f64>()
    }

    /// A uniform integer in `0..n` (`n > 0`).
    #[inline]
    pub fn below(&mut self, n: u64) -> u64 {
        self.0.random_range(0..n)
    }

    /// A standard normal number (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    /// `n` standard normals: the same numbers, and the same state after, as
    /// `n` calls of [`Rng::normal`], drawn in parallel. Each normal takes
    /// exactly two draws, so a chunk's generator is this one advanced past
    /// the chunks before it. Written in place: collecting chunks would join
    /// them on the calling thread.
    pub fn normals(&mut self, n: usize) -> Vec<f64> {
        const CHUNK: usize = 1024;
        let mut out = vec![0.0; n];
        let start = &self.0;
        out.par_chunks_mut(CHUNK).with_max_len(1).enumerate().for_each(|(c, chunk)| {
            let mut r = Rng(start.clone());
            r.0.advance(2 * (c * CHUNK) as u128);
            chunk.iter_mut().for_each(|x| *x = r.normal());
        });
        self.skip_normals(n);
        out
    }

    /// The state `n` normals later, without drawing them.
    pub fn skip_normals(&mut self, n: usize) {
        self.0.advance(2 * n as u128);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f64> = (0..4).map(|_| 0.0).scan(Rng::new(7, Purpose::Photon, 3), |r, _| Some(r.uniform())).collect();
        let b: Vec<f64> = (0..4).map(|_| 0.0).scan(Rng::new(7, Purpose::Photon, 3), |r, _| Some(r.uniform())).collect();
        let c: Vec<f64> = (0..4).map(|_| 0.0).scan(Rng::new(7, Purpose::Photon, 4), |r, _| Some(r.uniform())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn parallel_normals_are_the_sequential_ones() {
        for n in [0, 1, 1023, 1024, 1025, 10_001] {
            let fresh = || Rng::new(3, Purpose::Gradient, 9);
            let (mut a, mut b, mut c) = (fresh(), fresh(), fresh());
            let want: Vec<u64> = (0..n).map(|_| a.normal().to_bits()).collect();
            let got: Vec<u64> = b.normals(n).iter().map(|v| v.to_bits()).collect();
            assert_eq!(got, want, "n = {n}");
            c.skip_normals(n);
            let after = a.uniform().to_bits();
            assert_eq!(b.uniform().to_bits(), after, "state after n = {n}");
            assert_eq!(c.uniform().to_bits(), after, "state after skipping n = {n}");
        }
    }
}
