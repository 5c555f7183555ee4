//! The camera response both ways: a photograph to what a fit's renders
//! are fitted to (less the black level, over the gain; censored where the
//! capture's threshold hides a render's error), and a render to code
//! values (the gain and black level, the curve, the threshold).

use crate::capture::settings::FitSettings;
use crate::image::Image;
use crate::scene::Camera;

/// `targets` where the capture's threshold hides nothing, and `rendered`
/// itself (no error) where a target is 0 and the render is below the
/// threshold: there the photograph cannot tell the render is wrong. Where
/// a target is 0 and the render above the threshold, 0, or with
/// `to_threshold` the threshold itself (the most the hidden value can have
/// been). `threshold` is in linear units of the photographs; a camera's
/// render `r` meets it where `gain r + black` does. Without a render (none
/// yet), `targets` as they are.
pub(super) fn censored(
    targets: &[Image],
    rendered: Option<&[Image]>,
    threshold: f64,
    gains: &[f64],
    blacks: &[f64],
    to_threshold: bool,
) -> Vec<Image> {
    let Some(rendered) = rendered else { return targets.to_vec() };
    targets
        .iter()
        .zip(rendered)
        .zip(gains.iter().zip(blacks))
        .map(|((t, r), (gain, black))| Image {
            width: t.width,
            height: t.height,
            data: t
                .data
                .iter()
                .zip(&r.data)
                .map(|(&t, &r)| match t == 0.0 {
                    true if r * gain + black < threshold => r,
                    true if to_threshold => (threshold - black) / gain,
                    _ => t,
                })
                .collect(),
        })
        .collect()
}

/// Each of `rendered` where it lies between its photograph (`floors`) and
/// that photograph's ceiling (no error: the threshold hid where in between
/// it is), else the nearer of the two. Both through the response, as the
/// renders.
pub(super) fn within(floors: &[Image], ceilings: &[Image], rendered: &[Image]) -> Vec<Image> {
    floors
        .iter()
        .zip(ceilings)
        .zip(rendered)
        .map(|((floor, ceiling), r)| Image {
            width: r.width,
            height: r.height,
            data: (floor.data.iter().zip(&ceiling.data).zip(&r.data))
                .map(|((&lo, &hi), &v)| v.min(hi).max(lo))
                .collect(),
        })
        .collect()
}

/// `photographs` (linear) less each camera's black level where they are
/// not 0 (the threshold hid the rest), over its gain.
pub(super) fn over_response(photographs: &[Image], gains: &[f64], blacks: &[f64]) -> Vec<Image> {
    let cameras = photographs.iter().zip(gains.iter().zip(blacks));
    cameras.map(|(p, (g, b))| p.map(|v| if v > 0.0 { (v - b) / g } else { 0.0 })).collect()
}

/// The natural fall-off of an ideal thin lens through `camera`: per pixel,
/// cos^4 of the angle between the ray through its centre and the optical
/// axis (1 at the principal point). Turning the camera about its axis
/// leaves it unchanged.
pub fn lens_falloff(camera: &Camera) -> Image {
    let [fx, fy, cx, cy] = camera.intrinsics();
    let mut falloff = Image::zeros(camera.width, camera.height);
    for (i, v) in falloff.data.iter_mut().enumerate() {
        let x = ((i % camera.width) as f64 + 0.5 - cx) / fx;
        let y = ((i / camera.width) as f64 + 0.5 - cy) / fy;
        *v = (1.0 + x * x + y * y).powi(-2);
    }
    falloff
}

/// `image` as `camera` passes it: times its [`lens_falloff`] where
/// `settings` model it ([`FitSettings::lens_falloff`]), else as it is.
/// `divide` takes the fall-off out instead, as from a photograph.
pub fn through_lens(image: Image, camera: &Camera, settings: &FitSettings, divide: bool) -> Image {
    if !settings.lens_falloff {
        return image;
    }
    let falloff = lens_falloff(camera);
    let data = image.data.iter().zip(&falloff.data).map(|(v, f)| if divide { v / f } else { v * f }).collect();
    Image { data, ..image }
}

/// A rendered view through a camera of `gain` and `black` level and the
/// response of `settings`: the gain and black level, the curve
/// ([`FitSettings::gamma`]), then the capture's processing (0 below its
/// threshold), in code value / full scale.
pub fn respond(image: &Image, gain: f64, black: f64, settings: &FitSettings) -> Image {
    image.map(|v| {
        let code = (gain * v + black).max(0.0).powf(1.0 / settings.gamma);
        if code < settings.threshold {
            0.0
        } else {
            code
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::scene::Lens;

    /// A dark pixel is no error where the render through the camera's gain
    /// and black level stays below the threshold: a black level lifting the
    /// render over it makes the photograph's 0 an error again, one
    /// lowering it hides a render above it.
    #[test]
    fn the_threshold_censors_through_the_black_level() {
        let target = [Image { width: 2, height: 1, data: vec![0.0, 0.5] }];
        let censor = |render: f64, black: f64| {
            let rendered = [Image { width: 2, height: 1, data: vec![render, 0.1] }];
            censored(&target, Some(&rendered), 0.03, &[1.0], &[black], false)[0].data.clone()
        };
        assert_eq!(censor(0.015, 0.0), vec![0.015, 0.5]);
        assert_eq!(censor(0.015, 0.02), vec![0.0, 0.5]);
        assert_eq!(censor(0.04, 0.0), vec![0.0, 0.5]);
        assert_eq!(censor(0.04, -0.02), vec![0.04, 0.5]);
        assert_eq!(censored(&target, None, 0.03, &[1.0], &[0.0], false)[0].data, target[0].data);
    }

    /// With `to_threshold`, a hidden pixel whose render through the gain and
    /// black level reaches the threshold is fitted to the threshold in the
    /// render's units, `(threshold - black) / gain`; one below it is still
    /// no error, and a pixel the photograph shows is its own target.
    #[test]
    fn a_hidden_pixel_above_the_threshold_is_fitted_to_it() {
        let target = [Image { width: 3, height: 1, data: vec![0.0, 0.0, 0.5] }];
        let rendered = [Image { width: 3, height: 1, data: vec![0.005, 0.04, 0.1] }];
        let (gain, black) = (2.0, 0.01);
        let fitted = censored(&target, Some(&rendered), 0.03, &[gain], &[black], true);
        assert_eq!(fitted[0].data, vec![0.005, (0.03 - black) / gain, 0.5]);
    }

    /// A render inside its photograph's interval is its own target; below
    /// it, the photograph; above it, the ceiling.
    #[test]
    fn a_render_is_fitted_to_the_nearer_end_of_its_interval() {
        let im = |data: Vec<f64>| Image { width: 3, height: 1, data };
        let (floors, ceilings) = ([im(vec![0.0, 0.2, 0.2])], [im(vec![0.03, 0.25, 0.25])]);
        let targets = within(&floors, &ceilings, &[im(vec![0.01, 0.1, 0.4])]);
        assert_eq!(targets[0].data, vec![0.01, 0.2, 0.25]);
    }

    /// The fall-off is 1 at the principal point and cos^4 of the angle off
    /// the axis elsewhere (a pixel whose centre is one focal length off
    /// axis passes a quarter); through the lens and back is the identity,
    /// and without the setting nothing changes.
    #[test]
    fn the_lens_falloff_is_cos4_of_the_angle_off_axis() {
        let camera = Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::zeros(),
            up: Vec3::new(0.0, 1.0, 0.0),
            lens: Lens::Pinhole { fx: 2.0, fy: 2.0, cx: 0.5, cy: 0.5 },
            width: 3,
            height: 1,
        };
        let falloff = lens_falloff(&camera);
        assert_eq!(falloff.data[0], 1.0);
        assert!((falloff.data[1] - 1.25f64.powi(-2)).abs() < 1e-15, "{falloff:?}");
        assert!((falloff.data[2] - 0.25).abs() < 1e-15, "{falloff:?}");
        let on = FitSettings { lens_falloff: true, ..FitSettings::default() };
        let image = Image { width: 3, height: 1, data: vec![0.2, 0.4, 0.8] };
        let seen = through_lens(image.clone(), &camera, &on, false);
        assert!((seen.data[2] - 0.2).abs() < 1e-15, "{seen:?}");
        let back = through_lens(seen, &camera, &on, true);
        assert!(back.data.iter().zip(&image.data).all(|(a, b)| (a - b).abs() < 1e-15), "{back:?}");
        assert_eq!(through_lens(image.clone(), &camera, &FitSettings::default(), false), image);
    }

    /// A photograph through the inverse response, over a camera's gain, comes
    /// back through `respond` as it was; below the threshold, as 0.
    #[test]
    fn the_response_inverts_what_the_fit_works_on() {
        let settings = FitSettings { gamma: 2.2, ..FitSettings::default() };
        let photo = Image { width: 4, height: 1, data: vec![0.0, 5.0 / 255.0, 0.1, 0.9] };
        let gain = 1.3;
        let linear = photo.map(|v| v.powf(settings.gamma) / gain);
        let back = respond(&linear, gain, 0.0, &settings);
        assert_eq!(back.data[..2], [0.0, 0.0]);
        for (b, p) in back.data[2..].iter().zip(&photo.data[2..]) {
            assert!((b - p).abs() < 1e-12, "{back:?}");
        }
        let raw = respond(&linear, gain, 0.0, &FitSettings::default());
        assert!((raw.data[3] - 0.9f64.powf(2.2)).abs() < 1e-12, "gamma 1 must pass radiance through: {raw:?}");
        // With a black level, through what the fit works on and back.
        let black = 0.0003; // below the threshold in linear units, (8 / 255)^2.2
        let linear = &over_response(&[photo.map(|v| v.powf(settings.gamma))], &[gain], &[black])[0];
        let back = respond(linear, gain, black, &settings);
        assert_eq!(back.data[..2], [0.0, 0.0]);
        for (b, p) in back.data[2..].iter().zip(&photo.data[2..]) {
            assert!((b - p).abs() < 1e-12, "{back:?}");
        }
    }
}
