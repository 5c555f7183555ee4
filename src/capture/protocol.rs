//! The field's held-out-view evaluation on ScalarFlow's real capture, as
//! PINF and HyFluid report it: frames as code value / 255, downsampled to
//! half resolution by area averaging, cropped to rows 90..960 and columns
//! 45..540 of the 540 x 960 image, PSNR = -10 log10(mean squared error)
//! over the crop. Relative RMSE over the crop goes beside it: about 90 % of
//! the crop is black, so an all-black prediction already scores about 19 dB.

use crate::image::Image;

/// Downsampling, then a crop, then the metrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Protocol {
    /// Area-averaging factor.
    pub factor: usize,
    /// Crop of the downsampled image: first column, first row, width, height.
    pub crop: [usize; 4],
}

impl Protocol {
    /// The ScalarFlow protocol: half resolution, rows 90..960, columns 45..540.
    pub const SCALARFLOW: Protocol = Protocol { factor: 2, crop: [45, 90, 495, 870] };

    /// The protocol for a held-out image of `width` x `height`: the
    /// ScalarFlow one for its 1080 x 1920 frames, else half resolution and
    /// no crop.
    pub fn for_size(width: usize, height: usize) -> Protocol {
        if (width, height) == (1080, 1920) {
            Protocol::SCALARFLOW
        } else {
            Protocol { factor: 2, crop: [0, 0, width / 2, height / 2] }
        }
    }

    /// `image` downsampled and cropped, as the metrics see it.
    pub fn view(&self, image: &Image) -> Image {
        crop(&image.downsample(self.factor), self.crop)
    }

    /// PSNR and relative RMSE of `prediction` against `truth` (both at full
    /// resolution) under this protocol.
    pub fn score(&self, prediction: &Image, truth: &Image) -> Score {
        Score::of(&self.view(prediction), &self.view(truth))
    }
}

/// The metrics of one prediction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// -10 log10(MSE); `None` for a perfect prediction (infinite).
    pub psnr: Option<f64>,
    /// ||prediction - truth|| / ||truth||; `None` against a black truth.
    pub rel_rmse: Option<f64>,
}

impl Score {
    /// The metrics of `prediction` against `truth` over every pixel.
    pub fn of(prediction: &Image, truth: &Image) -> Score {
        assert_eq!(prediction.data.len(), truth.data.len(), "compared images differ in size");
        let err2: f64 = prediction.data.iter().zip(&truth.data).map(|(p, t)| (p - t) * (p - t)).sum();
        let norm2: f64 = truth.data.iter().map(|t| t * t).sum();
        let mse = err2 / truth.data.len().max(1) as f64;
        Score { psnr: (mse > 0.0).then(|| -10.0 * mse.log10()), rel_rmse: (norm2 > 0.0).then(|| (err2 / norm2).sqrt()) }
    }
}

/// The `[x0, y0, width, height]` window of `image` (clamped to the image).
pub fn crop(image: &Image, [x0, y0, w, h]: [usize; 4]) -> Image {
    let x0 = x0.min(image.width);
    let y0 = y0.min(image.height);
    let (w, h) = (w.min(image.width - x0), h.min(image.height - y0));
    let mut data = Vec::with_capacity(w * h);
    for y in y0..y0 + h {
        data.extend_from_slice(&image.data[y * image.width + x0..y * image.width + x0 + w]);
    }
    Image { width: w, height: h, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_and_relative_rmse_follow_their_definitions() {
        let truth = Image { width: 2, height: 2, data: vec![0.0, 0.5, 0.0, 0.5] };
        let pred = Image { width: 2, height: 2, data: vec![0.1, 0.5, 0.0, 0.4] };
        let s = Score::of(&pred, &truth);
        // MSE = (0.01 + 0.01) / 4 = 0.005.
        assert!((s.psnr.unwrap() - -10.0 * 0.005f64.log10()).abs() < 1e-12);
        assert!((s.rel_rmse.unwrap() - (0.02f64 / 0.5).sqrt()).abs() < 1e-12);
        assert_eq!(Score::of(&truth, &truth).psnr, None);
        assert_eq!(Score::of(&truth, &Image::zeros(2, 2)).rel_rmse, None);
    }

    #[test]
    fn the_scalarflow_view_is_half_resolution_then_the_crop() {
        // Pixel value = its full-resolution column, so a 2x2 mean is 2u + 0.5.
        let full = Image { width: 1080, height: 1920, data: (0..1080 * 1920).map(|i| (i % 1080) as f64).collect() };
        let v = Protocol::for_size(1080, 1920).view(&full);
        assert_eq!((v.width, v.height), (495, 870));
        assert_eq!(v.data[0], 2.0 * 45.0 + 0.5);
        assert_eq!(v.data[494], 2.0 * 539.0 + 0.5);
        assert_eq!(Protocol::for_size(64, 48).view(&Image::zeros(64, 48)).data.len(), 32 * 24);
    }
}
