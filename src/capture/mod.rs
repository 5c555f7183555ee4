//! Real captures: calibrated cameras, their frames, and the box the smoke
//! is in, read as other projects distribute them.
//!
//! - [`calibration`] reads the camera calibration: PINF/HyFluid's
//!   `info.json` or a NeRF-style `transforms.json`;
//!   [`scalarflow_cameras`] reads ScalarFlow's own camera file, a second
//!   calibration of its rig (its focal lengths differ).
//! - [`frames`] decodes frames from videos (through the `ffmpeg` program)
//!   or image files into images of code value / full scale.
//! - [`observe`] gives the frames at a working resolution and the real
//!   silhouettes a visual hull is carved from ([`crate::recon::hull::carve`]).
//! - [`align`] finds how far a photograph must move to agree with a render
//!   (a camera's principal point, corrected).
//! - [`fit`] fits one frame: the density, the lights' intensities and the
//!   emission, under one of three image models; [`settings`] holds every
//!   setting of it and its defaults; [`density`] is what its steps move
//!   and where it starts.
//! - [`lighting`] is the fit's lighting and the cameras' gains: candidate
//!   lights and an ambient term, fitted by least squares on their renders;
//!   [`lights`] gives the image's derivatives in a light's place.
//! - [`priors`] are what the fit asks of a density beside the images;
//!   [`learned_filter`] is a linear filter from a fitted density to the
//!   true one, learned on made captures.
//! - [`rig`] aligns the training cameras once for every frame of a capture;
//!   [`reuse`] says when a later run may take a rig or fits an earlier one made.
//! - [`temporal`] brings neighbouring frames' densities onto one frame's.
//! - [`frame`] is one frame end to end: checks, images, fit, held-out views;
//!   [`outputs`] writes what `dualphoton fit --capture` leaves in its folder.
//! - [`protocol`] is the field's held-out-view evaluation: area
//!   downsampling, a fixed crop, PSNR and relative RMSE;
//!   [`expected_view`] averages a held-out view over the calibration error
//!   the training cameras show.

pub mod align;
pub mod calibration;
pub mod density;
pub mod expected_view;
pub mod fit;
pub mod frame;
pub mod frames;
pub mod learned_filter;
pub mod lighting;
pub mod lights;
pub mod observe;
pub mod outputs;
pub mod priors;
pub mod protocol;
pub mod reuse;
pub mod rig;
pub mod scalarflow_cameras;
pub mod settings;
pub mod temporal;

use crate::math::Vec3;
use crate::scene::Camera;
use std::path::PathBuf;

/// Where one camera's frames are.
#[derive(Clone, Debug, PartialEq)]
pub enum Frames {
    /// A video; frame `n` is its `n`-th decoded picture.
    Video {
        /// The video file.
        path: PathBuf,
        /// Its number of frames, as the calibration gives it.
        count: usize,
    },
    /// One image file (PNG, JPEG or `.npy`) per frame, in frame order.
    Images(Vec<PathBuf>),
}

impl Frames {
    /// Number of frames.
    pub fn count(&self) -> usize {
        match self {
            Frames::Video { count, .. } => *count,
            Frames::Images(paths) => paths.len(),
        }
    }
}

/// One calibrated camera of a capture.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Its name: the file name of its video or first image, without extension.
    pub name: String,
    /// The camera at the frames' full resolution.
    pub camera: Camera,
    /// Its frames.
    pub frames: Frames,
    /// True for a camera the calibration sets aside for testing
    /// (`test_videos` of an `info.json`); never fitted.
    pub held_out: bool,
}

/// The first item that repeats an earlier one: (earlier, later) index.
pub(crate) fn first_repeat<T: PartialEq>(items: &[T]) -> Option<(usize, usize)> {
    (0..items.len()).find_map(|i| items[..i].iter().position(|x| *x == items[i]).map(|j| (j, i)))
}

/// The box of `corners` (lower x, y, z, then upper x, y, z, in a capture's
/// units), or an error: six finite numbers, each lower below its upper.
pub fn box_of(corners: &[f64]) -> crate::Result<(Vec3, Vec3)> {
    let bad = || {
        crate::Error(format!("{corners:?}: give six finite numbers, x0,y0,z0,x1,y1,z1 with x0 < x1, y0 < y1, z0 < z1"))
    };
    let [x0, y0, z0, x1, y1, z1] = <[f64; 6]>::try_from(corners).map_err(|_| bad())?;
    let (lo, hi) = (Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1));
    if corners.iter().all(|v| v.is_finite()) && lo.x < hi.x && lo.y < hi.y && lo.z < hi.z {
        Ok((lo, hi))
    } else {
        Err(bad())
    }
}

/// The `--box` option of the commands that fit a capture: the smoke box
/// given on the command line, in place of the calibration's.
#[derive(Clone, Debug, Default, clap::Args, serde::Serialize)]
pub struct BoxChoice {
    /// The smoke box, where the density lives, in the capture's units: x0,y0,z0,x1,y1,z1 (lower corner,
    /// upper corner). Default: the calibration's (info.json's voxel_matrix and voxel_scale); a
    /// transforms.json has none.
    #[arg(
        long = "box",
        value_delimiter = ',',
        allow_hyphen_values = true,
        action = clap::ArgAction::Set,
        value_name = "X0,Y0,Z0,X1,Y1,Z1"
    )]
    pub smoke_box: Option<Vec<f64>>,
}

impl BoxChoice {
    /// The box given ([`box_of`]), or `None`; errors name `--box`.
    pub fn corners(&self) -> crate::Result<Option<(Vec3, Vec3)>> {
        self.smoke_box.as_deref().map(box_of).transpose().map_err(|e| crate::Error(format!("--box: {e}")))
    }
}

/// A capture: its cameras and, where the calibration gives it, the box the
/// smoke is in (world units of the calibration).
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    /// The cameras, training ones first, in file order.
    pub views: Vec<View>,
    /// Lower and upper corner of the smoke box, if the calibration has one.
    pub smoke_box: Option<(Vec3, Vec3)>,
}

impl Capture {
    /// Frames every camera has.
    pub fn frame_count(&self) -> usize {
        self.views.iter().map(|v| v.frames.count()).min().unwrap_or(0)
    }

    /// The smoke box, or an error: the density's grid needs one.
    pub fn grid_box(&self) -> crate::Result<(Vec3, Vec3)> {
        self.smoke_box.ok_or_else(|| {
            crate::Error(
                "the calibration gives no smoke box (an info.json's voxel_matrix and voxel_scale; a transforms.json \
                 has none): give --box x0,y0,z0,x1,y1,z1 in its units"
                    .into(),
            )
        })
    }

    /// The view called `name`, or an error listing the names.
    pub fn view(&self, name: &str) -> crate::Result<usize> {
        self.views.iter().position(|v| v.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.views.iter().map(|v| v.name.as_str()).collect();
            crate::Error(format!("the capture has no camera '{name}' (it has: {})", names.join(", ")))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_six_finite_numbers_lower_corner_first() {
        let (lo, hi) = box_of(&[-1.0, 0.0, 2.0, 1.0, 0.5, 3.0]).unwrap();
        assert_eq!((lo, hi), (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.5, 3.0)));
        for bad in
            [&[0.0, 0.0, 0.0, 1.0, 1.0][..], &[0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0], &[1.0, 0.0, 0.0, 0.0, 1.0, 1.0]]
        {
            assert!(box_of(bad).is_err(), "{bad:?}");
        }
        assert!(box_of(&[0.0, 0.0, 0.0, 1.0, f64::NAN, 1.0]).is_err());
        assert!(box_of(&[0.0, 0.0, f64::NEG_INFINITY, 1.0, 1.0, 1.0]).is_err());
    }
}
