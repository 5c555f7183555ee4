//! Finite differences of the frozen estimator: the oracle that forward and
//! reverse mode are checked against. The estimator's decisions (photon
//! paths, kernel neighbourhoods) stay frozen at the scene's density, so the
//! loss is a smooth function of each voxel and its difference quotients
//! converge to the exact derivative that forward and reverse mode compute.

use crate::grad::loss::mse;
use crate::image::Image;
use crate::render::frozen::Frozen;

/// A difference quotient of the frozen loss in one voxel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FiniteDifference {
    /// The estimate of `dL/drho_v`.
    pub value: f64,
    /// Forward (one-sided) differences: the voxel's density is too close to
    /// 0 for a step below it. Error O(h^2) instead of O(h^4).
    pub one_sided: bool,
}

/// The frozen loss (mean squared error against `targets`, over as many
/// cameras as there are targets) with `delta` added to voxel `v`.
pub fn frozen_loss(frozen: &Frozen, targets: &[Image], v: usize, delta: f64) -> f64 {
    let mut p = frozen.scene.density.clone();
    p.data[v] += delta;
    mse(&frozen.images_with(&p, targets.len()), targets)
}

/// Richardson-extrapolated difference quotient of the frozen loss in voxel
/// `v`. The step keeps the voxel's optical thickness change near 1e-3
/// (stiff cases) and is relative to the density otherwise; extrapolating
/// from steps `h` and `h / 2` removes the leading error term. Central
/// differences (error O(h^4)) unless the density is within `h` of 0, where
/// the estimator is not defined below 0: then forward differences (O(h^2)).
///
/// ```
/// use dualphoton::eval::scenes::one_light_blob;
/// use dualphoton::grad::finite_diff::finite_difference;
/// use dualphoton::image::Image;
/// use dualphoton::render::frozen::Frozen;
///
/// let mut scene = one_light_blob(4, 4);
/// scene.render.photons = 200;
/// let frozen = Frozen::new(&scene, None);
/// let targets: Vec<_> = frozen.images.iter().map(|im| Image { data: vec![0.0; im.data.len()], ..im.clone() }).collect();
/// let d = finite_difference(&frozen, &targets, scene.density.index(2, 2, 2));
/// assert!(d.value.is_finite() && !d.one_sided);
/// ```
pub fn finite_difference(frozen: &Frozen, targets: &[Image], v: usize) -> FiniteDifference {
    let d = &frozen.scene.density;
    let rho = d.data[v];
    let thickness = frozen.scene.medium.sigma_t_scale * d.voxel_size().min();
    let h = 1e-3 * rho.max(0.01).min(1.0 / thickness.max(1e-300));
    let loss = |delta: f64| frozen_loss(frozen, targets, v, delta);
    if rho - h < 0.0 {
        let f0 = loss(0.0);
        let (d1, d2) = ((loss(h) - f0) / h, (loss(h / 2.0) - f0) / (h / 2.0));
        FiniteDifference { value: 2.0 * d2 - d1, one_sided: true }
    } else {
        let c1 = (loss(h) - loss(-h)) / (2.0 * h);
        let c2 = (loss(h / 2.0) - loss(-h / 2.0)) / h;
        FiniteDifference { value: (4.0 * c2 - c1) / 3.0, one_sided: false }
    }
}
