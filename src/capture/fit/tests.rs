//! A frame's fit on made views of a ball: each update rule, the cameras'
//! alignment, the image pyramid, the decoders' stages, the lighting of a
//! known density, and bit-identical results for any thread count.

use super::aligning::{align_cameras, at_scale, Moves, Seen};
use super::*;
use crate::capture::align::Free;
use crate::capture::density::{cube_around, grid_shape, in_box};
use crate::capture::lighting::candidate_lights;
use crate::capture::settings::ImageModel;
use crate::render::render_photon;
use crate::scene::{Medium, RenderSettings};

/// Three cameras of `size` pixels on a ring around the origin, each
/// seeing a disc of `radius` pixels at 0.3 in its middle: a ball's views.
fn ball_views(size: usize, radius: f64) -> ([Camera; 3], Vec<Image>) {
    let camera = |x: f64, z: f64| Camera {
        position: Vec3::new(x, 0.3, z),
        look_at: Vec3::zeros(),
        up: Vec3::y(),
        lens: crate::scene::Lens::FovY(40.0),
        width: size,
        height: size,
    };
    let centre = (size as f64 - 1.0) / 2.0;
    let disc = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64 - centre, (i / size) as f64 - centre);
            if x * x + y * y < radius * radius {
                0.3
            } else {
                0.0
            }
        })
        .collect();
    let cameras = [camera(2.5, 0.0), camera(0.0, 2.5), camera(-1.8, 1.8)];
    (cameras, vec![Image { width: size, height: size, data: disc }; 3])
}

/// Both updates fit three views of a bright disc (a ball) that fills
/// only part of the box, so the hull leaves some voxels out. The
/// multiplicative one takes other steps and keeps every voxel of the
/// hull positive (the additive one's projection may zero some), and
/// both lower the images' error.
#[test]
fn the_log_density_update_fits_a_ball() {
    let (cameras, images) = ball_views(64, 16.0);
    let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
    let run = |log_density: bool| {
        let settings = FitSettings {
            model: ImageModel::EmissionAbsorption,
            // The silhouettes' margin (40 pixels of the capture) is 10 at 1/4.
            factor: 4,
            resolution: 8,
            updates: vec![10, 20],
            align: false,
            gains: false,
            threshold: 0.0,
            log_density,
            ..FitSettings::default()
        };
        fit(&cameras, &images, None, smoke_box, &settings, None, &mut |_| {}).unwrap()
    };
    let (additive, multiplicative) = (run(false), run(true));
    for done in [&additive, &multiplicative] {
        let first = done.log[0].image_mse;
        let last = done.log.last().unwrap().image_mse;
        assert!(last < first / 2.0, "the images' error fell from {first} to only {last}");
        assert!(done.scene.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
    }
    assert_ne!(additive.scene.density.data, multiplicative.scene.density.data, "log_density changed no step");
    // Outside the hull both are 0; inside it the multiplicative density never is.
    let zero = |d: &Grid<f64>| d.data.iter().map(|&v| v == 0.0).collect::<Vec<bool>>();
    let (zero_add, zero_mul) = (zero(&additive.scene.density), zero(&multiplicative.scene.density));
    assert!(zero_mul.iter().any(|&z| z), "the hull left no voxel out: the test exercises nothing");
    assert!(zero_mul.iter().zip(&zero_add).all(|(&m, &a)| !m || a), "a voxel of the hull went to 0");
    assert!(zero_mul.iter().any(|&z| !z), "the multiplicative fit left no density");
}

/// One photograph of a ball moved 3 pixels down, which no density
/// explains (the cameras share their vertical). One fit's alignment
/// finds part of it, the density having taken up the rest; fitted again
/// from its own corrections, the cameras move on towards the 3 pixels.
#[test]
fn a_fit_aligning_from_its_own_corrections_finds_more_of_a_moved_camera() {
    let (cameras, mut images) = ball_views(64, 12.0);
    let down = |i: usize| if i < 3 * 64 { 0.0 } else { images[0].data[i - 3 * 64] };
    images[0] = Image { data: (0..64 * 64).map(down).collect(), ..images[0].clone() };
    let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
    let settings = FitSettings {
        model: ImageModel::EmissionAbsorption,
        factor: 4,
        resolution: 16,
        updates: vec![80, 20, 20],
        zoom: false,
        shared_alignment: false,
        gains: false,
        threshold: 0.0,
        ..FitSettings::default()
    };
    // Camera 0's move against the other two's, in working pixels.
    let moved = |f: &Fit| f.offsets[0][1] - (f.offsets[1][1] + f.offsets[2][1]) / 2.0;
    let corrections = |f: &Fit| Corrections {
        offsets_px: f.offsets_px(),
        zooms: f.zooms.clone(),
        rolls: f.rolls.clone(),
        gains: None,
    };
    let first = fit(&cameras, &images, None, smoke_box, &settings, None, &mut |_| {}).unwrap();
    let second =
        fit_aligning_from(&cameras, &images, None, smoke_box, &settings, &corrections(&first), &mut |_| {}).unwrap();
    let third =
        fit_aligning_from(&cameras, &images, None, smoke_box, &settings, &corrections(&second), &mut |_| {}).unwrap();
    let found = [moved(&first), moved(&second), moved(&third)];
    assert!(found[0] > 0.5 && found[0] < 2.0, "{found:?}");
    assert!(found[1] > found[0] + 0.4 && found[2] > found[1] && found[2] < 3.5, "{found:?}");
    // Held by the same corrections (a rig's), the cameras do not move again.
    let held = fit(&cameras, &images, None, smoke_box, &settings, Some(&corrections(&second)), &mut |_| {}).unwrap();
    assert_eq!(held.offsets, corrections(&second).apply(&cameras, 4).unwrap().1);
}

/// With the image pyramid a coarse stage aligns the cameras on images
/// at half the working resolution: a photograph one pixel off there is
/// two pixels off at the working resolution, where the cameras move.
#[test]
fn a_coarse_stage_moves_the_cameras_in_working_pixels() {
    let (cameras, _) = ball_views(64, 12.0);
    let blob = |dx: f64| Image {
        width: 32,
        height: 32,
        data: (0..32 * 32)
            .map(|i| {
                let (x, y) = ((i % 32) as f64 - 15.5 - dx, (i / 32) as f64 - 15.5);
                (-(x * x + y * y) / 18.0).exp()
            })
            .collect(),
    };
    let rendered = vec![blob(0.0); 3];
    let photos = vec![blob(1.0), blob(0.0), blob(0.0)];
    let coarse: Vec<Camera> = cameras.iter().map(|c| at_scale(c, 2)).collect();
    let mut working = cameras.to_vec();
    let (mut offsets, mut zooms, mut rolls) = (vec![[0.0; 2]; 3], vec![1.0; 3], vec![0.0; 3]);
    let moves = Moves { offsets: &mut offsets, zooms: &mut zooms, rolls: &mut rolls };
    let seen = Seen { cameras: &coarse, rendered: &rendered, photos: &photos, scale: 2 };
    align_cameras(&mut working, moves, Free { zoom: false, roll: false }, seen);
    // Camera 0 against the other two: one coarse pixel, two working ones.
    let apart = offsets[0][0] - offsets[1][0];
    assert!((apart.abs() - 2.0).abs() < 0.2, "{offsets:?}");
    assert!((offsets[1][0] - offsets[2][0]).abs() < 1e-9 && offsets.iter().all(|o| o[1].abs() < 0.05));
    let moved = working[0].intrinsics()[2] - cameras[0].intrinsics()[2];
    assert!((moved - offsets[0][0]).abs() < 1e-9, "the camera moved {moved}, its total {}", offsets[0][0]);
    assert_eq!(working[0].width, 64, "the working camera was downsampled");
}

/// With the image pyramid a fit of three views of a ball runs its
/// coarse levels on coarser images, still lowers the error, and ends
/// with its cameras at the working resolution.
#[test]
fn a_fit_on_the_image_pyramid_fits_a_ball() {
    let (cameras, images) = ball_views(64, 16.0);
    let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
    let run = |image_pyramid: bool| {
        let settings = FitSettings {
            model: ImageModel::EmissionAbsorption,
            factor: 4,
            resolution: 16,
            updates: vec![10, 10, 20],
            gains: false,
            shared_alignment: false,
            threshold: 0.0,
            image_pyramid,
            ..FitSettings::default()
        };
        fit(&cameras, &images, None, smoke_box, &settings, None, &mut |_| {}).unwrap()
    };
    let (flat, pyramid) = (run(false), run(true));
    assert_ne!(flat.log[0].image_mse, pyramid.log[0].image_mse, "the pyramid changed nothing");
    let first = pyramid.log[0].image_mse;
    let last = pyramid.log.last().unwrap().image_mse;
    assert!(last < first / 2.0, "the images' error fell from {first} to only {last}");
    assert!(pyramid.scene.cameras.iter().all(|c| (c.width, c.height) == (64, 64)));
    assert!(pyramid.offsets.iter().all(|o| o.iter().all(|v| v.is_finite() && v.abs() < 3.0)), "{:?}", pyramid.offsets);
    // The finest level works at the same resolution either way: its errors are comparable.
    assert!(last < 2.0 * flat.log.last().unwrap().image_mse, "{last} against {:?}", flat.log.last());
}

/// A box longer along y (a decoder's cube holds voxels outside it).
const TALL_BOX: (Vec3, Vec3) = (Vec3::new(-0.4, -0.5, -0.4), Vec3::new(0.4, 0.5, 0.4));

/// Three views of a ball in [`TALL_BOX`] fitted under emission-absorption
/// on the images alone, with `settings`' grid, updates and start: the
/// fit, and each update's image error in its first and second stage.
fn decoded_ball_fit(settings: &FitSettings) -> (Fit, Vec<f64>, Vec<f64>) {
    let (cameras, images) = ball_views(64, 10.0);
    let settings = FitSettings {
        model: ImageModel::EmissionAbsorption,
        // The silhouettes' margin is 10 pixels at 1/4: the hull leaves voxels out.
        factor: 4,
        // The images alone: in so small a scene the smoothness term pulls
        // a decoder's rough density back up the images' error.
        smoothness: 0.0,
        align: false,
        gains: false,
        threshold: 0.0,
        ..settings.clone()
    };
    let done = fit(&cameras, &images, None, TALL_BOX, &settings, None, &mut |_| {}).unwrap();
    let stage = |s: usize| done.log.iter().filter(|r| r.level == s).map(|r| r.image_mse).collect::<Vec<f64>>();
    let (first, second) = (stage(0), stage(1));
    (done, first, second)
}

/// The paper's model fits three views of a ball, then the finest level
/// goes on from its density; settings it cannot run with are refused.
#[test]
fn the_decoder_stage_fits_a_ball_before_the_finest_level() {
    let settings = FitSettings { resolution: 8, updates: vec![10, 15], decoder: 30, ..FitSettings::default() };
    let (done, decoder, finest) = decoded_ball_fit(&settings);
    let smoke_box = TALL_BOX;
    // The decoder's updates, then the finest level's only.
    assert_eq!((decoder.len(), finest.len(), done.log.len()), (30, 15, 45));
    assert!(
        decoder[29] < decoder[0] / 2.0,
        "the decoder's stage lowered the error from {} to only {}",
        decoder[0],
        decoder[29]
    );
    assert!(finest[0] < decoder[0] / 2.0, "the finest level did not start from the decoder's fit");
    assert!(finest[14] < decoder[29], "the finest level did not go on from the decoder's fit");
    assert!(done.scene.density.data.contains(&0.0), "the hull left no voxel out");
    assert_eq!(done.scene.density.shape, grid_shape(&smoke_box.0, &smoke_box.1, 8));
    assert!(done.scene.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
    // The cube's voxels past the box: centres at +-0.4375 along x and z.
    let inside = in_box(&cube_around(&smoke_box.0, &smoke_box.1, 8), &smoke_box.0, &smoke_box.1);
    assert_eq!(inside.iter().filter(|&&i| i).count(), 6 * 8 * 6);
    let cube = FitSettings { resolution: 12, ..settings };
    assert!(cube.validate().unwrap_err().0.contains("decoder"), "a decoder needs a cube of 4 * 2^n voxels");
    let per_frame = FitSettings { align: true, shared_alignment: false, ..cube };
    assert!(FitSettings { resolution: 8, ..per_frame }.validate().unwrap_err().0.contains("shared_alignment"));
}

/// A fit is the seed's alone: every update (multiple scattering's photon
/// map, the reverse-mode gradient, the lights' and gains' refits, the
/// cameras' alignment) gives the same bits with one thread and with three.
#[test]
fn a_fit_is_bit_identical_for_any_thread_count() {
    let (cameras, images) = ball_views(48, 9.0);
    let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
    let settings = FitSettings {
        model: ImageModel::Multiple,
        factor: 4,
        resolution: 8,
        updates: vec![10, 10],
        photons: 2_000,
        shared_alignment: false,
        threshold: 0.0,
        ..FitSettings::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| fit(&cameras, &images, None, smoke_box, &settings, None, &mut |_| {}).unwrap())
    };
    let (one, three) = (run(1), run(3));
    assert!(one.offsets.iter().any(|o| o[0] != 0.0), "the cameras never moved: the test exercises no alignment");
    assert_eq!(one.scene.density.data, three.scene.density.data);
    let losses = |f: &Fit| f.log.iter().map(|r| r.image_mse).collect::<Vec<f64>>();
    assert_eq!(losses(&one), losses(&three));
    assert_eq!((&one.gains, &one.offsets, &one.zooms), (&three.gains, &three.offsets, &three.zooms));
    assert_eq!(one.scene.lights, three.scene.lights);
}

/// The learned prior's latent fits three views of a ball from the
/// training plumes' mean, then the finest level goes on from its
/// density; a prior together with the paper's decoder, or on a grid it
/// does not decode, is refused.
#[test]
fn the_learned_prior_stage_fits_a_ball_before_the_finest_level() {
    let settings = FitSettings { resolution: 64, updates: vec![10, 5], prior: 20, ..FitSettings::default() };
    let (done, prior, finest) = decoded_ball_fit(&settings);
    let smoke_box = TALL_BOX;
    assert_eq!((prior.len(), finest.len()), (20, 5));
    assert!(prior[19] < 0.7 * prior[0], "the prior's stage lowered the error from {} to only {}", prior[0], prior[19]);
    assert!(finest[0] < 0.7 * prior[0], "the finest level did not start from the prior's fit");
    assert!(finest[4] < prior[19], "the finest level did not go on from the prior's fit");
    assert_eq!(done.scene.density.shape, grid_shape(&smoke_box.0, &smoke_box.1, 64));
    assert!(done.scene.density.data.iter().all(|d| d.is_finite() && *d >= 0.0));
    // Stretched over the box, the prior's grid has the box's proportions.
    let stretched = FitSettings { prior_stretched: true, ..settings.clone() };
    let (_, prior_stage, _) = decoded_ball_fit(&stretched);
    assert!(prior_stage[19] < 0.7 * prior_stage[0], "stretched, the prior's stage fitted nothing");
    assert_ne!(prior_stage, prior, "prior_stretched changed nothing");
    let alone = FitSettings { prior: 0, ..stretched };
    assert!(alone.validate().unwrap_err().0.contains("needs prior"));
    let both = FitSettings { decoder: 10, ..settings.clone() };
    assert!(both.validate().unwrap_err().0.contains("set one of them"));
    let coarse = FitSettings { resolution: 32, ..settings };
    assert!(coarse.validate().unwrap_err().0.contains("decodes 64^3 grids"), "{:?}", coarse.validate());
}

/// With the density held at the truth's, the lighting comes back: two
/// candidates' intensities, no emission, the gains 1. A camera made
/// twice as bright gets the largest gain, and the images are fitted as
/// closely (on a ball the lights' view-dependent light can stand in for
/// part of a gain, so the split is not asked).
#[test]
fn the_lighting_of_a_known_density_comes_back() {
    let (cameras, _) = ball_views(24, 6.0);
    let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
    let settings = FitSettings { model: ImageModel::Single, threshold: 0.0, ..FitSettings::default() };
    let mut density = Grid::new(smoke_box.0, smoke_box.1, [8, 8, 8], vec![0.0; 512]);
    for v in 0..512 {
        if density.voxel_center(v / 64, (v / 8) % 8, v % 8).norm() < 0.3 {
            density.data[v] = 4.0;
        }
    }
    let mut truth = Scene {
        density: density.clone(),
        medium: Medium { sigma_t_scale: 1.0, albedo: 1.0, g: settings.g, max_order: 1, emission: 0.0 },
        lights: candidate_lights(&smoke_box.0, &smoke_box.1, 0.0),
        cameras: cameras.to_vec(),
        render: RenderSettings { photons: 0, spp: 8, seed: 99, ..RenderSettings::default() },
    };
    truth.lights[0].intensity = 2.0;
    truth.lights[3].intensity = 1.0;
    let images = render_photon(&truth).images;
    let done = fit_lighting(&cameras, &images, smoke_box, density.clone(), &settings, None).unwrap();
    assert_eq!(done.scene.density.data, density.data, "the density moved");
    let lights: Vec<f64> = done.scene.lights.iter().map(|l| l.intensity).collect();
    // A ball's views tell its lights apart by their shading alone: the
    // truth's two the strongest, near their intensities, the rest small.
    assert!((lights[0] / 2.0 - 1.0).abs() < 0.1 && (lights[3] - 1.0).abs() < 0.15, "lights {lights:?}");
    let others: f64 = lights.iter().enumerate().filter(|(l, _)| ![0, 3].contains(l)).map(|(_, w)| w).sum();
    assert!(others < 0.15 * (lights[0] + lights[3]), "lights {lights:?}");
    assert!(done.scene.medium.emission < 0.02, "emission {}", done.scene.medium.emission);
    assert!(done.gains.iter().all(|g| (g - 1.0).abs() < 0.05), "gains {:?}", done.gains);
    let error = training_rmse(&done, &images);
    let scale = (images.iter().flat_map(|im| &im.data).map(|v| v * v).sum::<f64>() / (3.0 * 576.0)).sqrt();
    // The renders' own noise (2 camera samples a pixel) is most of it.
    assert!(error < 0.15 * scale, "RMSE {error} against the images' {scale}");
    let mut brighter = images.clone();
    brighter[1] = brighter[1].map(|v| 2.0 * v);
    let done = fit_lighting(&cameras, &brighter, smoke_box, density, &settings, None).unwrap();
    assert!(done.gains[1] > 1.3 * done.gains[0].max(done.gains[2]), "gains {:?}", done.gains);
    let brighter_error = training_rmse(&done, &brighter);
    assert!(brighter_error < 2.0 * error, "RMSE {brighter_error}, against {error} at gains 1");
    // The held-out camera's gain is the training gains' geometric mean,
    // which the lights absorb: 1, its render the same whatever the gains.
    let product: f64 = done.gains.iter().product();
    assert!((product - 1.0).abs() < 1e-12, "gains {:?}", done.gains);
    let unit_gains = Fit { gains: vec![1.0; 3], ..done.clone() };
    assert_eq!(render_view(&done, &cameras[0]).data, render_view(&unit_gains, &cameras[0]).data);
    // Its black level is the training cameras' mean.
    let blacks = Fit { black_levels: vec![0.02, 0.03, -0.02], ..done };
    assert!((held_out_black(&blacks) - 0.01).abs() < 1e-15);
    // A rig's gains are held where the settings say so, fitted where not.
    let rig = Corrections {
        offsets_px: vec![[0.0; 2]; 3],
        zooms: vec![1.0; 3],
        rolls: vec![0.0; 3],
        gains: Some(vec![0.8, 1.25, 1.0]),
    };
    let held_settings = FitSettings { rig_gains: true, ..settings.clone() };
    let held = fit_lighting(&cameras, &brighter, smoke_box, truth.density.clone(), &held_settings, Some(&rig)).unwrap();
    assert_eq!(held.gains, vec![0.8, 1.25, 1.0]);
    let fitted = fit_lighting(&cameras, &brighter, smoke_box, truth.density, &settings, Some(&rig)).unwrap();
    assert!(fitted.gains[1] > 1.3 * fitted.gains[0].max(fitted.gains[2]), "gains {:?}", fitted.gains);
}

/// A ball's small views and a short emission-absorption fit of them that
/// hides nothing (threshold 0) and leaves the cameras as they are.
fn small_ball_fit() -> ([Camera; 3], Vec<Image>, (Vec3, Vec3), FitSettings) {
    let (cameras, images) = ball_views(32, 8.0);
    let smoke_box = (Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5));
    let settings = FitSettings {
        model: ImageModel::EmissionAbsorption,
        factor: 8,
        resolution: 8,
        updates: vec![5, 5],
        align: false,
        threshold: 0.0,
        ..FitSettings::default()
    };
    (cameras, images, smoke_box, settings)
}

/// Photographs that hide nothing (threshold 0) are their own ceilings:
/// fitted to the interval between them, a fit is the plain fit to the
/// bit. Without ceilings the setting is refused, not ignored.
#[test]
fn an_interval_of_no_width_is_the_plain_fit() {
    let (cameras, images, smoke_box, settings) = small_ball_fit();
    let interval = FitSettings { interval_censoring: true, ..settings.clone() };
    let plain = fit(&cameras, &images, None, smoke_box, &settings, None, &mut |_| {}).unwrap();
    let within = fit(&cameras, &images, Some(&images), smoke_box, &interval, None, &mut |_| {}).unwrap();
    assert_eq!(plain.scene.density.data, within.scene.density.data);
    assert_eq!(plain.gains, within.gains);
    let refused = fit(&cameras, &images, None, smoke_box, &interval, None, &mut |_| {}).unwrap_err().0;
    assert!(refused.contains("interval_censoring needs the photographs' ceilings"), "{refused}");
}

/// Photographs seen through a lens, fitted with its fall-off modelled, give
/// the fit of the same photographs without the lens: the fall-off is taken
/// out of the photographs before the fit and put back into every rendered
/// view, the training cameras' and any other's.
#[test]
fn a_fit_through_the_lens_takes_its_falloff_out_and_puts_it_back() {
    use super::response::{lens_falloff, through_lens};
    let (cameras, images, smoke_box, settings) = small_ball_fit();
    let lens = FitSettings { lens_falloff: true, ..settings.clone() };
    let seen: Vec<Image> = images.iter().zip(&cameras).map(|(i, c)| through_lens(i.clone(), c, &lens, false)).collect();
    let falloff = lens_falloff(&cameras[0]);
    assert!(falloff.data.iter().any(|&f| f < 0.9), "the lens passes nearly everything: the test exercises nothing");
    let plain = fit(&cameras, &images, None, smoke_box, &settings, None, &mut |_| {}).unwrap();
    let through = fit(&cameras, &seen, None, smoke_box, &lens, None, &mut |_| {}).unwrap();
    let near = |a: &[f64], b: &[f64]| {
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-6 * scale)
    };
    assert!(near(&through.scene.density.data, &plain.scene.density.data), "the fall-off was not taken out");
    for ((view, plain_view), camera) in training_views(&through).iter().zip(training_views(&plain)).zip(&cameras) {
        let expected = through_lens(plain_view, camera, &lens, false);
        assert!(near(&view.data, &expected.data), "a training view lacks the fall-off");
    }
    let other = Camera { width: 48, height: 40, ..cameras[1].clone() };
    let expected = through_lens(render_view(&plain, &other), &other, &lens, false);
    assert!(near(&render_view(&through, &other).data, &expected.data), "another camera's view lacks the fall-off");
}
