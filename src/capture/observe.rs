//! A capture's frames as a reconstruction sees them: downsampled by area
//! averaging (the cameras' intrinsics scaled with them), the visual hull
//! carved from real silhouettes, and a warning where a frame shows light
//! outside the smoke box (a background left in).
//!
//! Real silhouettes differ from rendered ones: the frames were
//! background-subtracted and thresholded (codes up to about 8 of 255 set to
//! 0) and carry faint codec ringing (codes 1-6) around the plume, and the
//! calibration places the same point up to a few tens of full-resolution
//! pixels apart in different cameras. So a pixel is in the silhouette where
//! its area average is above an absolute code value that ringing does not
//! reach, and the silhouette is dilated by a margin for the calibration.

use super::settings::FitSettings;
use super::{frames, Capture};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::math::{intersect_box, Vec3};
use crate::scene::Camera;

/// Code value (of 255) above which an area-averaged pixel shows smoke:
/// above the capture's threshold (8) and its ringing (1-6).
pub const SILHOUETTE_CODE: f64 = 12.0;

/// Dilation of the silhouettes, in full-resolution pixels, while the cameras
/// are as calibrated: the calibration's disagreement between cameras (up to
/// about 40 pixels for ScalarFlow's).
pub const SILHOUETTE_MARGIN_PX: f64 = 40.0;

/// The images of some cameras of a capture at one working resolution.
#[derive(Clone, Debug)]
pub struct Observed {
    /// The cameras, downsampled with the images.
    pub cameras: Vec<Camera>,
    /// Per frame (in the order asked for), one image per camera.
    pub images: Vec<Vec<Image>>,
    /// The same with every code below the capture's threshold raised to it
    /// before the average ([`area_ceiling`]): the most each pixel can have
    /// been before the threshold hid part of its area.
    pub ceilings: Vec<Vec<Image>>,
    /// The cameras' names.
    pub names: Vec<String>,
}

/// Frames `wanted` of cameras `views` of `capture`, downsampled by the
/// `factor` of `settings` ([`area_average`] under their response's
/// `gamma`; [`area_ceiling`] under their `threshold` too), and checked for
/// light outside the smoke box.
pub fn observe(capture: &Capture, views: &[usize], wanted: &[usize], settings: &FitSettings) -> Result<Observed> {
    let observed = downsampled(capture, views, wanted, settings)?;
    check_light_outside_box(capture, &observed, wanted)?;
    Ok(observed)
}

/// [`observe`] without the check: for frames read again beside one that
/// was checked, which would repeat its warning.
fn downsampled(capture: &Capture, views: &[usize], wanted: &[usize], settings: &FitSettings) -> Result<Observed> {
    let (factor, gamma) = (settings.factor, settings.gamma);
    let mut images = vec![Vec::with_capacity(views.len()); wanted.len()];
    let mut ceilings = images.clone();
    let mut cameras = Vec::with_capacity(views.len());
    for &v in views {
        let view = &capture.views[v];
        for ((per_frame, ceiling), full) in images.iter_mut().zip(&mut ceilings).zip(frames::read(view, wanted)?) {
            per_frame.push(area_average(&full, factor, gamma));
            ceiling.push(area_ceiling(&full, factor, gamma, settings.threshold));
        }
        cameras.push(view.camera.downsample(factor));
    }
    let names = views.iter().map(|&v| capture.views[v].name.clone()).collect();
    Ok(Observed { cameras, images, ceilings, names })
}

/// `photograph` (codes) downsampled by `factor` as a camera of larger
/// pixels would have seen it: a pixel's radiance is the mean of its area's,
/// and a code is radiance to the power 1/`gamma` (the response's curve), so
/// the codes are raised to `gamma`, averaged (a partial block at an edge
/// dropped) and returned as codes. Gamma 1 is the plain mean of the codes.
pub fn area_average(photograph: &Image, factor: usize, gamma: f64) -> Image {
    if gamma == 1.0 {
        return photograph.downsample(factor);
    }
    photograph.map(|v| v.powf(gamma)).downsample(factor).map(|v| v.powf(1.0 / gamma))
}

/// [`area_average`] of `photograph` with every code below `threshold`
/// raised to it: where the capture's processing set codes up to its
/// threshold to 0 (and its codec rang there), the most the area's mean can
/// have been. A pixel the threshold hid nothing of is its average.
pub fn area_ceiling(photograph: &Image, factor: usize, gamma: f64, threshold: f64) -> Image {
    area_average(&photograph.map(|v| v.max(threshold)), factor, gamma)
}

/// [`light_outside_box`] on `observed` (frames `wanted` of `capture`), its
/// warning printed, where the capture has a smoke box.
pub fn check_light_outside_box(capture: &Capture, observed: &Observed, wanted: &[usize]) -> Result<()> {
    if let Some((lo, hi)) = capture.smoke_box {
        if let Some(warning) = light_outside_box(observed, wanted, &lo, &hi)? {
            eprintln!("warning: {warning}");
        }
    }
    Ok(())
}

/// Shares of a camera's pixels outside the smoke box brighter than
/// [`SILHOUETTE_CODE`] above which [`light_outside_box`] warns, and above
/// which it refuses the frames (the real clip's and the made captures'
/// share is 0; a background left in lights most of the image).
pub const LIGHT_OUTSIDE_BOX: [f64; 2] = [0.05, 0.5];

/// A warning if a camera of `observed` (frames `wanted`) shows light
/// where no density in the box `lo`..`hi` can explain it
/// ([`bright_outside_box`] above the first of [`LIGHT_OUTSIDE_BOX`] on
/// some frame): a background not subtracted, or smoke outside the box,
/// which the fit would take for smoke in the box. An error above the
/// second: no fit could explain those photographs.
pub fn light_outside_box(observed: &Observed, wanted: &[usize], lo: &Vec3, hi: &Vec3) -> Result<Option<String>> {
    let (mut cameras, mut most) = (Vec::new(), 0.0f64);
    for (c, (camera, name)) in observed.cameras.iter().zip(&observed.names).enumerate() {
        let shares = observed.images.iter().map(|per| bright_outside_box(&per[c], camera, lo, hi));
        let worst = shares.zip(wanted).filter_map(|(s, &f)| Some((s?, f))).max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((share, frame)) = worst.filter(|&(s, _)| s > LIGHT_OUTSIDE_BOX[0]) {
            cameras.push(format!("{:.0} % in {name} (frame {frame})", 100.0 * share));
            most = most.max(share);
        }
    }
    if cameras.is_empty() {
        return Ok(None);
    }
    let what = format!(
        "of the pixels whose rays miss the smoke box, {} are brighter than code {SILHOUETTE_CODE} of 255; the fit \
         renders smoke inside the box on black, so subtract the photographs' background first and give a box \
         that holds all the smoke",
        cameras.join(", ")
    );
    if most > LIGHT_OUTSIDE_BOX[1] {
        return Err(Error(what));
    }
    Ok(Some(format!("{what} (the fit goes on, taking that light for smoke)")))
}

/// The photographs' noise around `frame` at the working resolution of
/// `settings` ([`area_average`] under their curve): the root mean square over
/// every pixel of `views` (code value / 255) of [`noise_of_three`] on
/// three consecutive frames (the frame and its neighbours, shifted
/// inwards at the clip's ends). `None`
/// for a capture of fewer than three frames. Not checked for light outside
/// the box: `frame` is checked where it is fitted.
pub fn temporal_noise(capture: &Capture, views: &[usize], frame: usize, settings: &FitSettings) -> Result<Option<f64>> {
    let count = capture.frame_count();
    if count < 3 {
        return Ok(None);
    }
    let first = first_of_three(frame, count);
    let seen = downsampled(capture, views, &[first, first + 1, first + 2], settings)?;
    Ok(Some(noise_of_three([&seen.images[0], &seen.images[1], &seen.images[2]])))
}

/// The first of three consecutive frames of a clip of `count` (at least
/// 3) around `frame`: its neighbours', shifted inwards at the clip's ends.
fn first_of_three(frame: usize, count: usize) -> usize {
    frame.saturating_sub(1).min(count - 3)
}

/// Noise from three consecutive frames of the same cameras: where the
/// scene changes linearly over them, the middle frame minus the mean of
/// the other two is noise alone, of variance 1.5 sigma^2 for independent
/// noise of variance sigma^2 per frame. Change that is not linear in time
/// counts as noise too, so this is an upper bound on the photographs' own.
pub fn noise_of_three(frames: [&[Image]; 3]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for ((a, b), c) in frames[0].iter().zip(frames[1]).zip(frames[2]) {
        for ((x, y), z) in a.data.iter().zip(&b.data).zip(&c.data) {
            let d = y - 0.5 * (x + z);
            sum += d * d;
            n += 1;
        }
    }
    (sum / (1.5 * n.max(1) as f64)).sqrt()
}

/// The silhouette of a real frame (code value / 255) at 1/`factor` of the
/// full resolution: pixels above [`SILHOUETTE_CODE`], dilated by
/// `margin_px` / `factor` pixels (a disc).
pub fn real_silhouette(image: &Image, factor: usize, margin_px: f64) -> Vec<bool> {
    let seen: Vec<bool> = image.data.iter().map(|&v| v * 255.0 > SILHOUETTE_CODE).collect();
    dilate(&seen, image.width, image.height, margin_px / factor as f64)
}

/// The share of the pixels of `image` (code value / 255, as `camera` sees
/// it) whose rays miss the box `lo`..`hi` that are brighter than
/// [`SILHOUETTE_CODE`]: light no density in the box can explain. Near 0 in
/// a photograph of smoke inside the box on a subtracted background; near
/// 1 where the background is still there. `None` if every ray meets the box.
pub fn bright_outside_box(image: &Image, camera: &Camera, lo: &Vec3, hi: &Vec3) -> Option<f64> {
    let (mut outside, mut bright) = (0usize, 0usize);
    for (p, &v) in image.data.iter().enumerate() {
        let (x, y) = ((p % image.width) as f64 + 0.5, (p / image.width) as f64 + 0.5);
        if intersect_box(&camera.ray(x, y), lo, hi).is_none() {
            outside += 1;
            bright += usize::from(v * 255.0 > SILHOUETTE_CODE);
        }
    }
    (outside > 0).then(|| bright as f64 / outside as f64)
}

/// `mask` grown by a disc of `radius` pixels.
fn dilate(mask: &[bool], width: usize, height: usize, radius: f64) -> Vec<bool> {
    let r = radius.floor() as i64;
    let offsets: Vec<(i64, i64)> = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| ((dx * dx + dy * dy) as f64) <= radius * radius)
        .collect();
    let mut out = vec![false; mask.len()];
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            if !mask[(y as usize) * width + x as usize] {
                continue;
            }
            for (dx, dy) in &offsets {
                let (u, v) = (x + dx, y + dy);
                if u >= 0 && v >= 0 && u < width as i64 && v < height as i64 {
                    out[(v as usize) * width + u as usize] = true;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block of half black, half full code is half the radiance: under
    /// gamma 2 its code is sqrt(1/2), not the codes' mean 1/2.
    #[test]
    fn an_area_average_is_the_mean_of_the_radiance_under_the_response() {
        let photograph = Image { width: 4, height: 2, data: vec![0.0, 1.0, 0.2, 0.2, 1.0, 0.0, 0.2, 0.2] };
        let seen = area_average(&photograph, 2, 2.0);
        assert_eq!((seen.width, seen.height), (2, 1));
        assert!((seen.data[0] - 0.5f64.sqrt()).abs() < 1e-12, "{:?}", seen.data);
        assert!((seen.data[1] - 0.2).abs() < 1e-12, "{:?}", seen.data);
        assert_eq!(area_average(&photograph, 2, 1.0).data, vec![0.5, 0.2]);
    }

    /// A block the threshold (0.1) hid half of can have been as bright as
    /// its mean with the hidden half at the threshold; codes below it
    /// (ringing) count as hidden; a block above it is its mean.
    #[test]
    fn an_area_ceiling_raises_what_the_threshold_hid_to_it() {
        let photograph = Image { width: 4, height: 2, data: vec![0.0, 0.5, 0.2, 0.3, 0.05, 0.5, 0.2, 0.3] };
        let ceiling = area_ceiling(&photograph, 2, 1.0, 0.1);
        let near = |a: &[f64], b: [f64; 2]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(near(&ceiling.data, [0.3, 0.25]), "{:?}", ceiling.data);
        assert!(near(&area_average(&photograph, 2, 1.0).data, [0.2625, 0.25]));
    }

    #[test]
    fn the_noise_frames_are_a_frame_and_its_neighbours_inside_the_clip() {
        assert_eq!([0, 1, 5, 118, 119].map(|f| first_of_three(f, 120)), [0, 0, 4, 117, 117]);
        assert_eq!(first_of_three(2, 3), 0);
    }

    #[test]
    fn the_noise_of_three_frames_is_the_noise_added_to_a_linear_change() {
        let mut rng = crate::rng::Rng::new(7, crate::rng::Purpose::Pixel, 0);
        let sigma = 0.02;
        let frame = |t: f64, rng: &mut crate::rng::Rng| Image {
            width: 100,
            height: 100,
            data: (0..10_000)
                .map(|p| {
                    // Box-Muller: one normal number from two uniform ones.
                    let normal =
                        (-2.0 * (1.0 - rng.uniform()).ln()).sqrt() * (std::f64::consts::TAU * rng.uniform()).cos();
                    (p % 100) as f64 * 0.01 * (1.0 + t) + sigma * normal
                })
                .collect(),
        };
        let frames: Vec<Vec<Image>> = (0..3).map(|t| vec![frame(t as f64, &mut rng)]).collect();
        let noise = noise_of_three([&frames[0], &frames[1], &frames[2]]);
        assert!((noise / sigma - 1.0).abs() < 0.05, "{noise} against {sigma}");
    }

    /// Light where every ray misses the box is a background (or smoke
    /// outside the box), ringing below the silhouette's code is not, and
    /// light inside the box's image is smoke.
    #[test]
    fn light_outside_the_box_is_named_by_camera_and_frame() {
        let camera = Camera {
            position: Vec3::new(0.0, 0.0, 3.0),
            look_at: Vec3::zeros(),
            up: Vec3::y(),
            lens: crate::scene::Lens::FovY(40.0),
            width: 40,
            height: 40,
        };
        let (lo, hi) = (Vec3::from_element(-0.3), Vec3::from_element(0.3));
        let lit = |inside: f64, outside: f64| Image {
            width: 40,
            height: 40,
            data: (0..1600)
                .map(|p| {
                    let ray = camera.ray((p % 40) as f64 + 0.5, (p / 40) as f64 + 0.5);
                    (if intersect_box(&ray, &lo, &hi).is_some() { inside } else { outside }) / 255.0
                })
                .collect(),
        };
        let smoke = lit(200.0, 0.0);
        assert_eq!(bright_outside_box(&smoke, &camera, &lo, &hi), Some(0.0));
        assert_eq!(bright_outside_box(&lit(200.0, 6.0), &camera, &lo, &hi), Some(0.0));
        assert_eq!(bright_outside_box(&lit(200.0, 20.0), &camera, &lo, &hi), Some(1.0));
        let inside = Camera { position: Vec3::zeros(), look_at: Vec3::z(), ..camera.clone() };
        assert_eq!(bright_outside_box(&smoke, &inside, &lo, &hi), None);

        let observed = Observed {
            cameras: vec![camera.clone(), camera.clone()],
            images: vec![vec![smoke.clone(), smoke.clone()], vec![smoke.clone(), lit(200.0, 20.0)]],
            ceilings: vec![vec![smoke.clone(), smoke.clone()], vec![smoke.clone(), lit(200.0, 20.0)]],
            names: vec!["a".into(), "b".into()],
        };
        // Over half the pixels: an error; a tenth: a warning.
        let error = light_outside_box(&observed, &[4, 9], &lo, &hi).unwrap_err().0;
        assert!(error.starts_with("of the pixels whose rays miss the smoke box, 100 % in b (frame 9) are"), "{error}");
        let mut tenth = lit(200.0, 0.0);
        let outside: Vec<usize> = (0..1600).filter(|&p| tenth.data[p] == 0.0).collect();
        outside.iter().step_by(10).for_each(|&p| tenth.data[p] = 20.0 / 255.0);
        let some = Observed { images: vec![vec![smoke.clone(), tenth]], ..observed.clone() };
        let warning = light_outside_box(&some, &[4], &lo, &hi).unwrap().unwrap();
        assert!(
            warning.contains(" 10 % in b (frame 4)") && warning.ends_with("taking that light for smoke)"),
            "{warning}"
        );
        let clean = Observed { images: vec![vec![smoke.clone(), smoke]], ..observed };
        assert_eq!(light_outside_box(&clean, &[4], &lo, &hi).unwrap(), None);
    }

    #[test]
    fn ringing_is_not_smoke_and_the_margin_is_a_disc() {
        let mut image = Image::zeros(21, 21);
        image.data[10 * 21 + 10] = 100.0 / 255.0;
        image.data[0] = 6.0 / 255.0; // ringing
        let sil = real_silhouette(&image, 10, 40.0);
        // Radius 4 pixels at a tenth of the resolution: (10 +- 4, 10) in, (13, 13) out (4.2 from the centre).
        assert!(sil[10 * 21 + 14] && sil[6 * 21 + 10] && !sil[10 * 21 + 15]);
        assert!(!sil[13 * 21 + 13] && sil[12 * 21 + 12]);
        assert!(!sil[0]);
        assert_eq!(sil.iter().filter(|&&s| s).count(), 49);
    }
}
