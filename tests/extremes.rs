//! Stiff and extreme scenes: values and derivatives stay finite.

mod common;

use dualphoton::grad::forward::{random_gradient, Directions};
use dualphoton::grad::reverse::{reverse_gradient, Subset};
use dualphoton::math::Vec3;
use dualphoton::render::frozen::Frozen;
use dualphoton::rng::Rng;
use dualphoton::scene::{Light, Scene};

fn base() -> Scene {
    let lights = vec![Light { position: Vec3::new(1.2, 0.5, 1.5), intensity: 50.0 }];
    let mut s = common::scene(common::blob(8), common::medium(0.9, 0.6, 3), lights, vec![common::camera(2.0, 35.0, 5)]);
    s.render.photons = 3000;
    s
}

fn cases() -> Vec<(&'static str, Scene)> {
    let mut out = vec![];
    let mut s = base();
    // sigma_t = 20 * 500 = 1e4 per unit: optical depth 1e4 across the box.
    s.density.data.iter_mut().for_each(|v| *v = 500.0);
    out.push(("optical depth 1e4", s));
    let mut s = base();
    s.density.data.iter_mut().for_each(|v| *v = 0.0);
    out.push(("zero density", s));
    for albedo in [0.0, 1.0] {
        let mut s = base();
        s.medium.albedo = albedo;
        out.push((if albedo == 0.0 { "albedo 0" } else { "albedo 1" }, s));
    }
    for g in [-0.99, 0.99, 0.9999] {
        let mut s = base();
        s.medium.g = g;
        out.push(("extreme g", s));
    }
    let mut s = base();
    s.lights[0].position = Vec3::new(0.5, 0.0, 0.0);
    out.push(("light on the box face", s));
    let mut s = base();
    s.lights[0].position = Vec3::new(0.0, 0.0, 0.0);
    out.push(("light inside the medium", s));
    let mut s = base();
    s.lights[0].intensity = 1e12;
    out.push(("intensity 1e12", s));
    out
}

#[test]
fn values_and_derivatives_are_finite() {
    for (name, scene) in cases() {
        let frozen = Frozen::new(&scene, None);
        for im in &frozen.images {
            assert!(im.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{name}: image not finite");
        }
        let targets: Vec<_> = frozen
            .images
            .iter()
            .map(|i| dualphoton::image::Image { data: vec![0.01; i.data.len()], ..i.clone() })
            .collect();
        let rev = reverse_gradient(&frozen, &targets, Subset::full());
        assert!(rev.loss.is_finite() && rev.grad.iter().all(|g| g.is_finite()), "{name}: reverse gradient not finite");
        let all: Vec<usize> = (0..scene.density.len()).collect();
        let fwd = random_gradient::<4>(&frozen, &all, &targets, Directions::Gaussian, &mut Rng::from_seed(1));
        assert!(fwd.iter().all(|g| g.is_finite()), "{name}: forward gradient not finite");
    }
}
