//! The field's held-out-view evaluation on ScalarFlow's real capture, as
//! PINF and HyFluid report it: frames as code value / 255, downsampled to
//! half resolution by area averaging, cropped to rows 90..960 and columns
//! 45..540 of the 540 x 960 image, PSNR = -10 log10(mean squared error)
//! over the crop. Relative RMSE over the crop goes beside it: about 90 % of
//! the crop is black, so an all-black prediction already scores about 19 dB.

use super::align::sample;
use crate::image::Image;
use rayon::prelude::*;

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

    /// Its name in a sentence: "the field's protocol" for ScalarFlow's
    /// frames, which is no field's for images of other sizes.
    pub fn name(&self) -> &'static str {
        if *self == Protocol::SCALARFLOW {
            "the field's protocol"
        } else {
            "the whole-image protocol"
        }
    }

    /// What the metrics see, in words: "half resolution by area averaging,
    /// crop rows 90..960 and columns 45..540".
    pub fn describe(&self) -> String {
        let [x, y, w, h] = self.crop;
        let scale =
            if self.factor == 2 { "half resolution".to_string() } else { format!("1/{} resolution", self.factor) };
        format!("{scale} by area averaging, crop rows {y}..{} and columns {x}..{}", y + h, x + w)
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

/// Largest shift [`Oracle`] tries, in pixels of the protocol's view along
/// each axis (8 half-resolution pixels: about 16 of the capture's).
pub const ORACLE_SHIFT_PX: i64 = 8;

/// What a prediction would score with knowledge that only the held-out
/// photograph gives: the least-squares gain onto it, and the best whole-pixel
/// shift (at most [`ORACLE_SHIFT_PX`] each way, the prediction's own gain).
/// Never used to choose anything: it says how much of the held-out error is
/// the held-out camera's unknown response or misplacement, and so how much
/// is the reconstruction's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Oracle {
    /// The least-squares gain of the prediction onto the truth (1 for a black prediction).
    pub gain: f64,
    /// The score with that gain.
    pub with_gain: Score,
    /// The best shift (right, down), in the view's pixels.
    pub shift: [i64; 2],
    /// The score with that shift.
    pub with_shift: Score,
}

impl Oracle {
    /// The oracle scores of `prediction` against `truth` (the same size).
    pub fn of(prediction: &Image, truth: &Image) -> Oracle {
        let pt: f64 = prediction.data.iter().zip(&truth.data).map(|(p, t)| p * t).sum();
        let pp: f64 = prediction.data.iter().map(|p| p * p).sum();
        let gain = if pp > 0.0 { pt / pp } else { 1.0 };
        let with_gain = Score::of(&prediction.map(|p| p * gain), truth);
        let r = ORACLE_SHIFT_PX;
        let shifts: Vec<[i64; 2]> = (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| [dx, dy])).collect();
        let norm2 = squared_norm(truth);
        // Scored in parallel, chosen in order: the same choice on any number of threads.
        let scores: Vec<Score> = shifts.par_iter().map(|&s| shifted_score(prediction, s, truth, norm2)).collect();
        let (shift, with_shift) = shifts
            .into_iter()
            .zip(scores)
            .min_by(|a, b| mse_of(&a.1).total_cmp(&mse_of(&b.1)).then(norm(a.0).cmp(&norm(b.0))))
            .expect("at least the zero shift");
        Oracle { gain, with_gain, shift, with_shift }
    }
}

/// Magnifications [`Aligned`] tries, about the camera's principal point:
/// 0.95 to 1.05 in steps of 0.005, more than twice as wide as the training
/// cameras' fitted focal-length factors.
pub const ORACLE_MAGNIFICATIONS: [f64; 21] = [
    0.95, 0.955, 0.96, 0.965, 0.97, 0.975, 0.98, 0.985, 0.99, 0.995, 1.0, 1.005, 1.01, 1.015, 1.02, 1.025, 1.03, 1.035,
    1.04, 1.045, 1.05,
];

/// The finest steps [`Aligned`] refines its grid's best to: a
/// magnification of 0.0005 (a tenth of the grid's step) and an eighth of a
/// pixel of the protocol's view. Its search starts at four times these.
pub const ORACLE_FINEST_STEPS: [f64; 2] = [0.0005, 0.125];

/// What a prediction would score had the held-out camera been aligned as
/// the training cameras are (its focal lengths scaled about its principal
/// point, and its principal point moved after it), found on its own
/// photograph: the best of a grid of magnifications and whole-pixel shifts
/// of the protocol's view, refined to [`ORACLE_FINEST_STEPS`]. A diagnostic
/// like [`Oracle`], never used to choose anything: it says how much of the
/// held-out error a calibration error of that camera, of the size the
/// training cameras' own corrections have, would explain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aligned {
    /// The best magnification, within [`ORACLE_MAGNIFICATIONS`]' range.
    pub magnification: f64,
    /// The best shift after it (right, down), in the view's pixels, at most
    /// [`ORACLE_SHIFT_PX`] each way.
    pub shift: [f64; 2],
    /// The score with both.
    pub score: Score,
}

impl Aligned {
    /// The best magnification of `prediction` (full resolution) about
    /// `principal` (its camera's principal point, in its pixels) and the best
    /// shift after it, scored under `protocol` against `truth_view` (the
    /// photograph's view under it). On the grid, ties go to the
    /// magnification nearest 1.
    pub fn of(prediction: &Image, principal: [f64; 2], protocol: &Protocol, truth_view: &Image) -> Aligned {
        let tried: Vec<(f64, Oracle)> = ORACLE_MAGNIFICATIONS
            .par_iter()
            .map(|&k| (k, Oracle::of(&protocol.view(&magnified(prediction, k, principal)), truth_view)))
            .collect();
        // Chosen in order, as the shifts are.
        let (k, grid) = tried
            .into_iter()
            .min_by(|(ka, a), (kb, b)| {
                mse_of(&a.with_shift)
                    .total_cmp(&mse_of(&b.with_shift))
                    .then((ka - 1.0).abs().total_cmp(&(kb - 1.0).abs()))
            })
            .expect("at least one magnification");
        refined(prediction, principal, protocol, truth_view, k, grid.shift)
    }
}

/// The grid's best (`magnification`, `shift`) refined by a pattern search:
/// each unknown moved up and down by its step, the best move taken while it
/// lowers the error, the steps halved from four times
/// [`ORACLE_FINEST_STEPS`] to them. The shift now moves the full-resolution
/// image with the magnification, so it may be a fraction of the view's
/// pixel; the grid's whole-pixel shifts of the view are the same but for
/// what they bring in across the crop's edge.
fn refined(
    prediction: &Image,
    principal: [f64; 2],
    protocol: &Protocol,
    truth_view: &Image,
    magnification: f64,
    shift: [i64; 2],
) -> Aligned {
    let [k_step, shift_step] = ORACLE_FINEST_STEPS;
    // Counted in finest steps from the grid's best: a value reached by two paths is one number.
    let at = |[nk, nx, ny]: [i64; 3]| {
        let shift = [shift[0] as f64 + nx as f64 * shift_step, shift[1] as f64 + ny as f64 * shift_step];
        (magnification + nk as f64 * k_step, shift)
    };
    let (k_min, k_max) = (ORACLE_MAGNIFICATIONS[0], ORACLE_MAGNIFICATIONS[ORACLE_MAGNIFICATIONS.len() - 1]);
    let within = |n: [i64; 3]| {
        let (k, [dx, dy]) = at(n);
        let r = ORACLE_SHIFT_PX as f64;
        k >= k_min - 1e-12 && k <= k_max + 1e-12 && dx.abs() <= r && dy.abs() <= r
    };
    let factor = protocol.factor as f64;
    let score_at = |n: [i64; 3]| {
        let (k, [dx, dy]) = at(n);
        Score::of(&protocol.view(&moved(prediction, k, [factor * dx, factor * dy], principal)), truth_view)
    };
    let (mut best, mut best_score) = ([0; 3], score_at([0; 3]));
    for stride in [4, 2, 1] {
        loop {
            let tried: Vec<[i64; 3]> = (0..3)
                .flat_map(|axis| {
                    [-stride, stride].map(|d| {
                        let mut n = best;
                        n[axis] += d;
                        n
                    })
                })
                .filter(|&n| within(n))
                .collect();
            // Scored in parallel, chosen in order: the first of equal ones.
            let scores: Vec<Score> = tried.par_iter().map(|&n| score_at(n)).collect();
            match tried.into_iter().zip(scores).min_by(|a, b| mse_of(&a.1).total_cmp(&mse_of(&b.1))) {
                Some((n, score)) if mse_of(&score) < mse_of(&best_score) => (best, best_score) = (n, score),
                _ => break,
            }
        }
    }
    let (magnification, shift) = at(best);
    Aligned { magnification, shift, score: best_score }
}

/// What a prediction exact to the smoke (and in the camera's response)
/// would score through a held-out camera whose calibration is off by the
/// error [`Aligned`] found: its photograph moved back by that magnification
/// and shift, scored against itself; and moved back by the magnification
/// alone, a camera off by that only. A diagnostic like [`Aligned`], never
/// used to choose anything: what the camera's error leaves a reconstruction
/// that does not know it, however close to the smoke (a smoother one can
/// score more: blur hedges against a misplaced camera). The bilinear move
/// blurs the photograph a little, which flatters it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactSmoke {
    /// Moved back by the magnification and the shift.
    pub through_aligned: Score,
    /// Moved back by the magnification only.
    pub through_magnification: Score,
}

impl ExactSmoke {
    /// From the photograph `truth` (full resolution) and `truth_view`, its
    /// view under `protocol`, the camera's `principal` point and the error
    /// `aligned` that [`Aligned::of`] found under `protocol`.
    pub fn of(
        truth: &Image,
        truth_view: &Image,
        aligned: &Aligned,
        principal: [f64; 2],
        protocol: &Protocol,
    ) -> ExactSmoke {
        let factor = protocol.factor as f64;
        let score = |shift: [f64; 2]| {
            Score::of(&protocol.view(&moved_back(truth, aligned.magnification, shift, principal)), truth_view)
        };
        ExactSmoke { through_aligned: score(aligned.shift.map(|s| factor * s)), through_magnification: score([0.0; 2]) }
    }
}

/// The image that [`moved`]`(_, k, shift, principal)` takes to `image`:
/// `image` magnified `1 / k` times and moved by `-shift / k`.
fn moved_back(image: &Image, k: f64, [dx, dy]: [f64; 2], principal: [f64; 2]) -> Image {
    moved(image, 1.0 / k, [-dx / k, -dy / k], principal)
}

/// `image` magnified `k` times about `[cx, cy]` (pixel units, as a camera's
/// principal point), sampled bilinearly, black where nothing maps in: what
/// the same camera with focal lengths `k` times as long would see.
fn magnified(image: &Image, k: f64, principal: [f64; 2]) -> Image {
    moved(image, k, [0.0, 0.0], principal)
}

/// `image` magnified `k` times about `[cx, cy]`, then moved by `[dx, dy]`
/// pixels (right, down), sampled bilinearly, black where nothing maps in:
/// what the same camera would see with focal lengths `k` times as long and
/// its principal point moved by `[dx, dy]`.
pub fn moved(image: &Image, k: f64, [dx, dy]: [f64; 2], [cx, cy]: [f64; 2]) -> Image {
    let (w, h) = (image.width, image.height);
    let mut data = vec![0.0; w * h];
    data.par_chunks_mut(w.max(1)).enumerate().for_each(|(row, out)| {
        for (column, value) in out.iter_mut().enumerate() {
            *value = moved_pixel(image, k, [dx, dy], [cx, cy], [column, row]);
        }
    });
    Image { width: w, height: h, data }
}

/// Pixel `[column, row]` of [`moved`]`(image, k, [dx, dy], [cx, cy])`.
#[inline]
pub fn moved_pixel(image: &Image, k: f64, [dx, dy]: [f64; 2], [cx, cy]: [f64; 2], [column, row]: [usize; 2]) -> f64 {
    let (x, y) = (column as f64 + 0.5, row as f64 + 0.5);
    sample(image, cx + (x - cx - dx) / k, cy + (y - cy - dy) / k)
}

/// The mean squared error behind a score (0 for a perfect one).
fn mse_of(score: &Score) -> f64 {
    score.psnr.map_or(0.0, |p| 10f64.powf(-p / 10.0))
}

/// Length of a shift, to prefer the smallest of equal ones.
fn norm([dx, dy]: [i64; 2]) -> i64 {
    dx.abs() + dy.abs()
}

/// `Score::of(image moved by [dx, dy] pixels (right, down), truth)`, black
/// where nothing moves in, without making the moved image; `norm2` is
/// [`squared_norm`]`(truth)`. The errors are added in the same order and
/// exact zeros (both black, most of a view) left out, which changes no sum
/// but a zero one's sign: the same score to the bit.
fn shifted_score(image: &Image, [dx, dy]: [i64; 2], truth: &Image, norm2: f64) -> Score {
    assert_eq!((image.width, image.height), (truth.width, truth.height), "compared images differ in size");
    let (w, h) = (image.width as i64, image.height as i64);
    let mut err2 = 0.0;
    for (y, truth_row) in (0..h).zip(truth.data.chunks(image.width.max(1))) {
        let sy = y - dy;
        let source = (0..h).contains(&sy).then(|| &image.data[(sy * w) as usize..((sy + 1) * w) as usize]);
        for (x, &t) in (0..w).zip(truth_row) {
            let sx = x - dx;
            let p = match source {
                Some(row) if (0..w).contains(&sx) => row[sx as usize],
                _ => 0.0,
            };
            if p != 0.0 || t != 0.0 {
                err2 += (p - t) * (p - t);
            }
        }
    }
    Score::of_sums(err2, norm2, truth.data.len())
}

/// The sum of `image`'s squared values.
fn squared_norm(image: &Image) -> f64 {
    image.data.iter().map(|t| t * t).sum()
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
        Score::of_sums(err2, squared_norm(truth), truth.data.len())
    }

    /// The metrics from the sum of squared errors over `pixels` pixels and
    /// the truth's squared norm.
    fn of_sums(err2: f64, norm2: f64, pixels: usize) -> Score {
        let mse = err2 / pixels.max(1) as f64;
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

    /// The shifted score, made without the shifted image, is the score of
    /// that image to the bit: moves left, right, up, down, off the image.
    #[test]
    fn a_shifted_score_is_the_score_of_the_shifted_image() {
        let (w, h) = (7, 5);
        let wave = |i: usize, a: f64| if i.is_multiple_of(3) { 0.0 } else { (i as f64 * a).sin().abs() };
        let image = Image { width: w, height: h, data: (0..w * h).map(|i| wave(i, 0.7)).collect() };
        let truth = Image { width: w, height: h, data: (0..w * h).map(|i| wave(i + 1, 1.3)).collect() };
        let norm2 = squared_norm(&truth);
        for shift in [[0, 0], [2, -1], [-3, 2], [6, 0], [0, -4], [7, 5], [-9, 0]] {
            let mut moved = Image::zeros(w, h);
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    let (sx, sy) = (x - shift[0], y - shift[1]);
                    if (0..w as i64).contains(&sx) && (0..h as i64).contains(&sy) {
                        moved.data[(y * w as i64 + x) as usize] = image.data[(sy * w as i64 + sx) as usize];
                    }
                }
            }
            assert_eq!(shifted_score(&image, shift, &truth, norm2), Score::of(&moved, &truth), "shift {shift:?}");
        }
    }

    /// A blob dimmed, then a blob moved: the oracle finds the gain and the
    /// shift that undo each.
    #[test]
    fn the_oracle_finds_a_known_gain_and_a_known_shift() {
        let (w, h) = (40, 30);
        let blob = |cx: f64, cy: f64, a: f64| Image {
            width: w,
            height: h,
            data: (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    a * (-((x - cx).powi(2) + (y - cy).powi(2)) / 18.0).exp()
                })
                .collect(),
        };
        let truth = blob(20.0, 15.0, 0.8);
        let dim = Oracle::of(&blob(20.0, 15.0, 0.5), &truth);
        assert!((dim.gain - 1.6).abs() < 1e-9, "{dim:?}");
        assert!(dim.with_gain.psnr.is_none_or(|p| p > 200.0), "a gain that undoes the dimming is exact: {dim:?}");
        let moved = Oracle::of(&blob(17.0, 17.0, 0.8), &truth);
        assert_eq!(moved.shift, [3, -2], "{moved:?}");
        // Exact but for the blob's tail that the move takes past the edge.
        assert!(moved.with_shift.psnr.unwrap() > 60.0, "{moved:?}");
        let base = Score::of(&blob(17.0, 17.0, 0.8), &truth).psnr.unwrap();
        assert!(moved.with_gain.psnr.unwrap() >= base - 1e-9, "the least-squares gain never scores worse");
        let here = Oracle::of(&truth, &truth);
        assert_eq!((here.gain, here.shift), (1.0, [0, 0]));
    }

    /// A prediction that sees a blob 2.5 % too small and off centre: the
    /// aligned oracle finds the magnification that undoes it.
    #[test]
    fn the_aligned_oracle_finds_a_known_magnification() {
        let (w, h) = (160, 120);
        let principal = [80.0, 60.0];
        let blob = |scale: f64| Image {
            width: w,
            height: h,
            data: (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64 + 0.5 - principal[0], (i / w) as f64 + 0.5 - principal[1]);
                    let (x, y) = (x / scale - 30.0, y / scale - 20.0);
                    (-(x * x + y * y) / 60.0).exp()
                })
                .collect(),
        };
        let protocol = Protocol::for_size(w, h);
        let truth = protocol.view(&blob(1.025));
        let small = blob(1.0);
        let found = Aligned::of(&small, principal, &protocol, &truth);
        assert!(near(&found, 1.025, [0.0, 0.0], 0.0005, 0.125), "{found:?}");
        let plain = Score::of(&protocol.view(&small), &truth).psnr.unwrap();
        assert!(found.score.psnr.unwrap() > plain + 20.0, "{found:?} against {plain}");
        assert_eq!(Aligned::of(&blob(1.0), principal, &protocol, &protocol.view(&blob(1.0))).magnification, 1.0);
        assert_eq!(magnified(&small, 1.0, principal), small, "a magnification of 1 changes nothing");
    }

    /// Whether `found` is within `k_tol` of magnification `k` and within
    /// `shift_tol` view pixels of `shift` along each axis.
    fn near(found: &Aligned, k: f64, shift: [f64; 2], k_tol: f64, shift_tol: f64) -> bool {
        (found.magnification - k).abs() <= k_tol + 1e-9
            && found.shift.iter().zip(shift).all(|(a, b)| (a - b).abs() <= shift_tol + 1e-9)
    }

    /// A `w` x `h` image of Gaussian blobs of height 1 at `centres` (pixel units).
    fn blobs(w: usize, h: usize, centres: &[[f64; 2]]) -> Image {
        let value = |x: f64, y: f64| -> f64 {
            centres.iter().map(|[cx, cy]| (-((x - cx).powi(2) + (y - cy).powi(2)) / 60.0).exp()).sum()
        };
        Image {
            width: w,
            height: h,
            data: (0..w * h).map(|i| value((i % w) as f64 + 0.5, (i / w) as f64 + 0.5)).collect(),
        }
    }

    /// An error between the grid's points, a magnification of 1.0215 and a
    /// shift of (1.375, -0.625) view pixels: the refinement finds it closer
    /// than the grid's nearest point (1.02 and (1, -1)) could be. Two blobs
    /// apart, as a plume's foot and top are: one alone could trade the
    /// magnification for a shift.
    #[test]
    fn the_aligned_oracle_refines_between_its_grid_points() {
        let (w, h) = (160, 120);
        let principal = [80.0, 60.0];
        let blob = blobs(w, h, &[[110.0, 85.0], [50.0, 30.0]]);
        let protocol = Protocol::for_size(w, h);
        let photographed = protocol.view(&moved(&blob, 1.0215, [2.75, -1.25], principal));
        let found = Aligned::of(&blob, principal, &protocol, &photographed);
        assert!(near(&found, 1.0215, [1.375, -0.625], 0.001, 0.25), "{found:?}");
        assert!(found.score.psnr.is_none_or(|p| p > 50.0), "{found:?}");
    }

    /// A photograph of a blob seen 2.5 % magnified and moved by (2, -3)
    /// pixels of the view: moved back by the error the aligned oracle finds,
    /// it is the blob as the calibrated camera sees it, and the exact
    /// smoke's score is that of the blob against the photograph.
    #[test]
    fn the_exact_smoke_is_the_photograph_moved_back() {
        let (w, h) = (160, 120);
        let principal = [80.0, 60.0];
        let blob = blobs(w, h, &[[110.0, 80.0]]);
        let protocol = Protocol::for_size(w, h);
        let photograph = moved(&blob, 1.025, [4.0, -6.0], principal);
        let photographed = protocol.view(&photograph);
        let found = Aligned::of(&blob, principal, &protocol, &photographed);
        assert!(near(&found, 1.025, [2.0, -3.0], 0.0005, 0.125), "{found:?}");
        let back = moved_back(&photograph, found.magnification, [4.0, -6.0], principal);
        let worst = back.data.iter().zip(&blob.data).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 0.02, "moved back, the photograph is the blob: worst pixel {worst}");
        let exact = ExactSmoke::of(&photograph, &photographed, &found, principal, &protocol);
        let blob_score = protocol.score(&blob, &photograph).psnr.unwrap();
        assert!((exact.through_aligned.psnr.unwrap() - blob_score).abs() < 0.5, "{exact:?} against {blob_score}");
        // Far from perfect, and the magnification alone leaves the shift's error.
        assert!(blob_score < 30.0, "{blob_score}");
        assert!(exact.through_magnification.psnr.unwrap() > blob_score + 1.0, "{exact:?}");
        let none = Aligned { magnification: 1.0, shift: [0.0, 0.0], score: found.score };
        assert_eq!(ExactSmoke::of(&photograph, &photographed, &none, principal, &protocol).through_aligned.psnr, None);
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
        // Described as it is applied: rows and columns of the half-resolution view.
        let scalarflow = "half resolution by area averaging, crop rows 90..960 and columns 45..540";
        assert_eq!(Protocol::for_size(1080, 1920).describe(), scalarflow);
        assert_eq!(Protocol::for_size(64, 48).describe().split(", ").nth(1), Some("crop rows 0..24 and columns 0..32"));
        // Only ScalarFlow's frames are scored as the field scores them.
        assert_eq!(Protocol::for_size(1080, 1920).name(), "the field's protocol");
        assert_eq!(Protocol::for_size(64, 48).name(), "the whole-image protocol");
    }
}
