//! A monochrome radiance image: row-major, row 0 at the top. Every layer
//! shares this type: renderers make it, losses and metrics compare it,
//! `io` writes it.

/// Radiance per pixel (W/(sr m^2) in the scene's units).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Values, row-major, row 0 at the top; `len = width * height`.
    pub data: Vec<f64>,
}

impl Image {
    /// A black image.
    pub fn zeros(width: usize, height: usize) -> Self {
        Image { width, height, data: vec![0.0; width * height] }
    }

    /// The image with `f` applied to every value.
    pub fn map(&self, f: impl Fn(f64) -> f64) -> Image {
        Image { width: self.width, height: self.height, data: self.data.iter().map(|&v| f(v)).collect() }
    }

    /// The image averaged over `factor x factor`-pixel blocks (area
    /// downsampling; partial blocks at the right and bottom edges dropped).
    pub fn downsample(&self, factor: usize) -> Image {
        Image { width: self.width / factor, height: self.height / factor, data: self.block_means(factor) }
    }

    /// Means over `b x b`-pixel blocks (partial blocks at the edges dropped).
    pub fn block_means(&self, b: usize) -> Vec<f64> {
        let (bw, bh) = (self.width / b, self.height / b);
        let mut out = Vec::with_capacity(bw * bh);
        for by in 0..bh {
            for bx in 0..bw {
                let mut s = 0.0;
                for y in by * b..(by + 1) * b {
                    for x in bx * b..(bx + 1) * b {
                        s += self.data[y * self.width + x];
                    }
                }
                out.push(s / (b * b) as f64);
            }
        }
        out
    }
}

/// The mean square of every pixel of `images`: the scale a penalty on
/// their mean squared error is set against (0 for no pixels).
pub fn mean_square(images: &[Image]) -> f64 {
    let pixels = images.iter().map(|i| i.data.len()).sum::<usize>().max(1) as f64;
    images.iter().flat_map(|i| &i.data).map(|v| v * v).sum::<f64>() / pixels
}

/// The 99.5th percentile of the positive finite values, or 1 if there are
/// none: the white point of a PNG preview and the scale of a silhouette.
pub fn auto_white(values: &[f64]) -> f64 {
    let mut pos: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0 && v.is_finite()).collect();
    if pos.is_empty() {
        return 1.0;
    }
    pos.sort_by(|a, b| a.total_cmp(b));
    pos[((pos.len() - 1) as f64 * 0.995).round() as usize]
}
