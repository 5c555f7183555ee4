//! The training cameras aligned between a fit's updates: each camera's
//! photograph warped onto its render ([`crate::capture::align::warp`]),
//! less what every camera shares, added to its corrections so far.

use crate::capture::align::{take_out_shared, warp, Free};
use crate::image::Image;
use crate::scene::Camera;

/// The training cameras' corrections so far, per camera: what
/// [`align_cameras`] adds to.
pub(super) struct Moves<'m> {
    pub(super) offsets: &'m mut [[f64; 2]],
    pub(super) zooms: &'m mut [f64],
    pub(super) rolls: &'m mut [f64],
}

/// What the cameras are aligned on: their views at one stage's scale.
pub(super) struct Seen<'s> {
    /// The cameras at 1/`scale` of the working resolution.
    pub(super) cameras: &'s [Camera],
    /// Their render before the move.
    pub(super) rendered: &'s [Image],
    /// Their photographs.
    pub(super) photos: &'s [Image],
    /// How many times coarser than the working resolution they are.
    pub(super) scale: usize,
}

/// `camera` (at the working resolution) at 1/`scale` of it: itself at 1.
pub(super) fn at_scale(camera: &Camera, scale: usize) -> Camera {
    if scale == 1 {
        camera.clone()
    } else {
        camera.downsample(scale)
    }
}

/// Moves every camera's principal point (and as `free` says scales its
/// focal lengths and turns it about its optical axis) so that its
/// photograph agrees with its render, as `seen` at one scale, keeping
/// the mean move and turn 0 and the magnifications' geometric mean 1: a
/// shift, turn or magnification shared by every camera is the density's to
/// explain, not the cameras'. `cameras` and `totals` are at the working
/// resolution: a move of one pixel at the scale is `scale` pixels there.
pub(super) fn align_cameras(cameras: &mut [Camera], totals: Moves, free: Free, seen: Seen) {
    let warps: Vec<_> = seen
        .rendered
        .iter()
        .zip(seen.photos)
        .zip(seen.cameras)
        .map(|((r, p), c)| {
            let [_, _, cx, cy] = c.intrinsics();
            warp(r, p, [cx, cy], free)
        })
        .collect();
    let mut moves: Vec<[f64; 2]> = warps.iter().map(|w| w.offset).collect();
    let mut factors: Vec<f64> = warps.iter().map(|w| 1.0 + w.zoom).collect();
    let mut turns: Vec<f64> = warps.iter().map(|w| w.roll).collect();
    take_out_shared(&mut moves, &mut factors, &mut turns);
    for (c, camera) in cameras.iter_mut().enumerate() {
        let [dx, dy] = moves[c].map(|d| d * seen.scale as f64);
        *camera = camera.shift(dx, dy).zoom(factors[c]).roll(turns[c]);
        totals.offsets[c] = [totals.offsets[c][0] + dx, totals.offsets[c][1] + dy];
        totals.zooms[c] *= factors[c];
        totals.rolls[c] += turns[c];
    }
}
