//! Resolutions of the training loop: the problem's own, and half of it
//! (grid and images pooled 2x) for the coarse updates.

use super::problem::Problem;
use crate::ad::Real;
use crate::image::Image;
use crate::par;
use crate::render::frozen::Frozen;
use crate::render::render_photon;
use crate::scene::Scene;
use crate::volume::Grid;
use rayon::prelude::*;

/// One resolution the training loop renders at.
#[derive(Clone)]
pub struct Level {
    /// Scene at this resolution (its density is replaced every update).
    pub scene: Scene,
    /// Training targets at this resolution.
    pub targets: Vec<Image>,
    /// Held-out targets at this resolution.
    pub held_out: Vec<Image>,
    /// True if densities are the decoder's grid averaged over 2x2x2 blocks.
    pooled: bool,
    /// Where the density may be non-zero (the hull, pooled like the density).
    pub support: Grid<f64>,
}

impl Level {
    /// The problem's own resolution.
    pub fn full(problem: &Problem, mask: &[bool]) -> Level {
        let d = &problem.scene.density;
        let support = Grid::new(d.lo, d.hi, d.shape, mask.iter().map(|&m| f64::from(u8::from(m))).collect());
        Level {
            scene: problem.scene.clone(),
            targets: problem.targets.to_vec(),
            held_out: problem.held_out.to_vec(),
            pooled: false,
            support,
        }
    }

    /// Half resolution, or `None` if a grid or image edge is odd or too small.
    pub fn half(problem: &Problem, mask: &[bool]) -> Option<Level> {
        let full = Level::full(problem, mask);
        let even = |n: usize| n.is_multiple_of(2) && n >= 8;
        if !full.scene.density.shape.iter().all(|&n| even(n))
            || !full.scene.cameras.iter().all(|c| even(c.width) && even(c.height))
        {
            return None;
        }
        let mut scene = full.scene.clone();
        scene.density = pool(&full.scene.density);
        for c in &mut scene.cameras {
            c.width /= 2;
            c.height /= 2;
        }
        let support = pool(&full.support);
        Some(Level {
            scene,
            targets: full.targets.iter().map(halve).collect(),
            held_out: full.held_out.iter().map(halve).collect(),
            pooled: true,
            support,
        })
    }

    /// The density this level renders, from the decoder's grid values.
    pub fn grid<R: Real>(&self, fine: Grid<R>) -> Grid<R> {
        if self.pooled {
            pool(&fine)
        } else {
            fine
        }
    }

    /// This level's scene at the decoder's grid `decoded`, rendered with
    /// `photons`, `spp` and `seed`; freeze it with [`Level::freeze`] (or
    /// `Frozen::new(&scene, Some(&level.support))`).
    pub fn scene_at(&self, decoded: &Grid<f64>, photons: u64, spp: u32, seed: u64) -> Scene {
        // Field by field: copying the level's own density only to replace it is a serial part of every update.
        let s = &self.scene;
        let density = if self.pooled { pool(decoded) } else { decoded.clone() };
        let mut render = s.render.clone();
        (render.photons, render.spp, render.seed) = (photons, spp, seed);
        Scene { density, medium: s.medium.clone(), lights: s.lights.clone(), cameras: s.cameras.clone(), render }
    }

    /// This level with targets shifted so that the residual of `images` is
    /// that of `residual_images`: `T' = T + images - residual_images`, hence
    /// `images - T' = residual_images - T`. The squared-loss gradient on the
    /// render of `images` then takes its residual from an independent render.
    pub fn with_residual_from(&self, images: &[Image], residual_images: &[Image]) -> Level {
        let mut level = self.clone();
        for ((t, i), r) in level.targets.iter_mut().zip(images).zip(residual_images) {
            t.data.iter_mut().zip(&i.data).zip(&r.data).for_each(|((t, i), r)| *t += i - r);
        }
        level
    }

    /// The frozen estimator of `scene` (this level's scene at `decoded`,
    /// [`Level::scene_at`]) and, if `residual_seed` is given, this level
    /// with its residual taken from a second, independent render of
    /// `decoded` with that seed ([`Level::with_residual_from`]): the two
    /// renders side by side ([`par::alongside`]).
    pub fn freeze<'s>(
        &self,
        scene: &'s Scene,
        decoded: &Grid<f64>,
        residual_seed: Option<u64>,
    ) -> (Frozen<'s>, Option<Level>) {
        let (photons, spp) = (scene.render.photons, scene.render.spp);
        let (frozen, second) = par::alongside(
            || Frozen::new(scene, Some(&self.support)),
            || residual_seed.map(|seed| render_photon(&self.scene_at(decoded, photons, spp, seed)).images),
        );
        let shifted = second.map(|second| self.with_residual_from(&frozen.images, &second));
        (frozen, shifted)
    }

    /// `dL/d(decoder grid)` from `dL/d(this level's grid)`.
    pub fn pull_back(&self, grad: Vec<f64>, fine_shape: [usize; 3]) -> Vec<f64> {
        if !self.pooled {
            return grad;
        }
        let [nz, ny, nx] = fine_shape;
        let (cy, cx) = (ny / 2, nx / 2);
        let mut out = vec![0.0; nz * ny * nx];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    out[(k * ny + j) * nx + i] = grad[((k / 2) * cy + j / 2) * cx + i / 2] * 0.125;
                }
            }
        }
        out
    }
}

/// The 2x2x2 block means of an even-shaped grid (same box).
pub fn pool<R: Real>(g: &Grid<R>) -> Grid<R> {
    let [nz, ny, nx] = g.shape;
    let (cz, cy, cx) = (nz / 2, ny / 2, nx / 2);
    // Each block on its own (a dual grid is large): the same sums for any number of threads.
    let data = (0..cz * cy * cx)
        .into_par_iter()
        .with_min_len(256)
        .map(|b| {
            let (k, j, i) = (b / (cy * cx), b / cx % cy, b % cx);
            let mut s = R::cst(0.0);
            for c in 0..8 {
                s += g.data[g.index(2 * k + (c >> 2), 2 * j + ((c >> 1) & 1), 2 * i + (c & 1))];
            }
            s * 0.125
        })
        .collect();
    Grid::new(g.lo, g.hi, [cz, cy, cx], data)
}

/// The 2x2 block means of an even-sized image: what a camera of half the resolution sees.
pub fn halve(im: &Image) -> Image {
    let (w, h) = (im.width / 2, im.height / 2);
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let at = |dx: usize, dy: usize| im.data[(2 * y + dy) * im.width + 2 * x + dx];
            data.push(0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)));
        }
    }
    Image { width: w, height: h, data }
}

#[cfg(test)]
mod tests {
    use crate::image::Image;
    use crate::recon::param_grad::tests::tiny;

    fn map(t: &Image, f: impl Fn(f64) -> f64) -> Image {
        Image { width: t.width, height: t.height, data: t.data.iter().map(|&v| f(v)).collect() }
    }

    #[test]
    fn shifted_targets_give_the_second_renders_residual() {
        let (level, _, _) = tiny();
        let images = level.targets.iter().map(|t| map(t, |v| 2.0 * v + 0.5)).collect::<Vec<_>>();
        let second = level.targets.iter().map(|t| map(t, |v| v + 0.25)).collect::<Vec<_>>();
        let shifted = level.with_residual_from(&images, &second);
        for c in 0..images.len() {
            for p in 0..images[c].data.len() {
                let residual = images[c].data[p] - shifted.targets[c].data[p];
                let wanted = second[c].data[p] - level.targets[c].data[p];
                assert!((residual - wanted).abs() < 1e-12);
            }
        }
    }
}
