//! A monochrome radiance image: row-major, row 0 at the top.

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
