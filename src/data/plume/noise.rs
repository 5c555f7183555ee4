//! Seeded gradient (Perlin-style) noise and its fractal sum, written out here
//! so that the plume depends on nothing but the seed.
//!
//! Lattice gradients come from a hash of (seed, lattice point), not from a
//! shuffled table, so the noise is defined on all of space, never repeats,
//! and is the same function whatever order or thread evaluates it.

use crate::math::Vec3;
use crate::rng::mix;

/// Gradient noise in about [-1, 1], zero at every integer lattice point.
#[derive(Clone, Copy, Debug)]
pub struct Noise {
    seed: u64,
}

/// Quintic fade `6t^5 - 15t^4 + 10t^3`: C2 across lattice cells.
#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

impl Noise {
    /// The noise of `seed`; `salt` gives independent channels of one seed.
    pub fn new(seed: u64, salt: u64) -> Self {
        Noise { seed: mix(seed ^ mix(salt.wrapping_add(0x5EED))) }
    }

    /// Three independent channels of noise at `p` (lattice spacing 1): one
    /// hash per lattice point, whose bits pick three gradients, each one of
    /// Perlin's 12 cube-edge directions.
    pub fn at3(&self, p: &Vec3) -> Vec3 {
        let (fx, fy, fz) = (p.x.floor(), p.y.floor(), p.z.floor());
        let (ix, iy, iz) = (fx as i64, fy as i64, fz as i64);
        let (x, y, z) = (p.x - fx, p.y - fy, p.z - fz);
        let (u, v, w) = (fade(x), fade(y), fade(z));
        let mut corner = [Vec3::zeros(); 8];
        for (c, out) in corner.iter_mut().enumerate() {
            let (dx, dy, dz) = ((c & 1) as i64, ((c >> 1) & 1) as i64, (c >> 2) as i64);
            // Large odd multipliers spread the three coordinates before one mix.
            let key = ((ix + dx) as u64).wrapping_mul(0x8CB9_2BA7_2F3D_8DD7)
                ^ ((iy + dy) as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93)
                ^ ((iz + dz) as u64).wrapping_mul(0xA076_1D64_78BD_642F);
            let h = mix(self.seed ^ key);
            let d = [x - dx as f64, y - dy as f64, z - dz as f64];
            *out = Vec3::new(grad(h, &d), grad(h >> 21, &d), grad(h >> 42, &d));
        }
        let lerp = |a: Vec3, b: Vec3, t: f64| a + (b - a) * t;
        let x00 = lerp(corner[0], corner[1], u);
        let x10 = lerp(corner[2], corner[3], u);
        let x01 = lerp(corner[4], corner[5], u);
        let x11 = lerp(corner[6], corner[7], u);
        lerp(lerp(x00, x10, v), lerp(x01, x11, v), w)
    }

    /// One channel of noise at `p` (the first of [`Noise::at3`]).
    pub fn at(&self, p: &Vec3) -> f64 {
        self.at3(p).x
    }

    /// Fractal sum of `octaves` octaves of the three channels, each octave
    /// at twice the frequency and half the amplitude of the one before,
    /// divided by the total amplitude (so each channel stays in about
    /// [-1, 1]). `p` is in units of the coarsest lattice spacing.
    pub fn fbm3(&self, p: &Vec3, octaves: u32) -> Vec3 {
        let (mut sum, mut amp, mut norm, mut q) = (Vec3::zeros(), 1.0, 0.0, *p);
        for o in 0..octaves {
            // Shift each octave so that lattice points of different octaves do not coincide.
            sum += self.at3(&(q + Vec3::new(17.3, 5.1, 11.7) * o as f64)) * amp;
            norm += amp;
            amp *= 0.5;
            q *= 2.0;
        }
        sum / norm
    }

    /// One channel of [`Noise::fbm3`].
    pub fn fbm(&self, p: &Vec3, octaves: u32) -> f64 {
        self.fbm3(p, octaves).x
    }
}

/// Dot product of the offset `d` with the cube-edge gradient picked by `h`.
#[inline]
fn grad(h: u64, d: &[f64; 3]) -> f64 {
    let [x, y, z] = *d;
    match (h & 0xFFFF) % 12 {
        0 => x + y,
        1 => -x + y,
        2 => x - y,
        3 => -x - y,
        4 => x + z,
        5 => -x + z,
        6 => x - z,
        7 => -x - z,
        8 => y + z,
        9 => -y + z,
        10 => y - z,
        _ => -y - z,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_on_lattice_bounded_and_seeded() {
        let n = Noise::new(3, 0);
        assert_eq!(n.at(&Vec3::new(2.0, -1.0, 5.0)), 0.0);
        let mut max: f64 = 0.0;
        for s in 0..2000 {
            let p = Vec3::new(s as f64 * 0.137, s as f64 * 0.071 - 30.0, (s % 17) as f64 * 0.53);
            max = max.max(n.at(&p).abs());
        }
        assert!(max > 0.3 && max <= 1.5, "{max}");
        let p = Vec3::new(0.3, 0.4, 0.5);
        let c = n.at3(&p);
        assert!(c.x != c.y && c.y != c.z, "channels differ");
        assert_ne!(n.at(&p), Noise::new(4, 0).at(&p));
        assert_ne!(n.at(&p), Noise::new(3, 1).at(&p));
        assert_eq!(n.at(&p), Noise::new(3, 0).at(&p));
    }
}
