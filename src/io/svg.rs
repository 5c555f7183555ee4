//! A small hand-written SVG document: RGB bitmaps embedded as base64 PNG,
//! text and rectangles. Figures that are mostly images (Fig. 6, Fig. 8) use
//! it: plotters' SVG backend embeds bitmaps only with a feature that pulls a
//! second copy of the `image` crate, and SVG text needs no font file.

use crate::error::{Error, Result};
use std::fmt::Write as _;
use std::path::Path;

/// An 8-bit RGB bitmap, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `3 * width * height` bytes: red, green, blue per pixel.
    pub data: Vec<u8>,
}

impl Rgb {
    /// This bitmap enlarged `factor` times by pixel replication (nearest
    /// neighbour), so that viewers cannot blur the pixels.
    pub fn upscale(&self, factor: usize) -> Rgb {
        let f = factor.max(1);
        let (w, h) = (self.width * f, self.height * f);
        let mut data = Vec::with_capacity(3 * w * h);
        for y in 0..h {
            for x in 0..w {
                let i = 3 * ((y / f) * self.width + x / f);
                data.extend_from_slice(&self.data[i..i + 3]);
            }
        }
        Rgb { width: w, height: h, data }
    }

    /// The bitmap as PNG file bytes.
    pub fn png(&self) -> Result<Vec<u8>> {
        let im = image::RgbImage::from_raw(self.width as u32, self.height as u32, self.data.clone())
            .ok_or_else(|| Error::new("bitmap size does not match its data"))?;
        let mut bytes = std::io::Cursor::new(vec![]);
        im.write_to(&mut bytes, image::ImageFormat::Png).map_err(|e| Error(format!("PNG encoding: {e}")))?;
        Ok(bytes.into_inner())
    }
}

/// Horizontal anchor of a text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    /// `x` is the left end.
    Start,
    /// `x` is the middle.
    Middle,
    /// `x` is the right end.
    End,
}

/// An SVG document being drawn; coordinates in pixels, y down.
pub struct Svg {
    width: usize,
    height: usize,
    body: String,
}

impl Svg {
    /// An empty white canvas of `width x height` pixels.
    pub fn new(width: usize, height: usize) -> Svg {
        let body = format!("<rect x=\"0\" y=\"0\" width=\"{width}\" height=\"{height}\" fill=\"#ffffff\"/>\n");
        Svg { width, height, body }
    }

    /// Places `bitmap` with its top-left corner at `(x, y)`, one pixel per pixel.
    pub fn image(&mut self, x: usize, y: usize, bitmap: &Rgb) -> Result<()> {
        let data = base64(&bitmap.png()?);
        let (w, h) = (bitmap.width, bitmap.height);
        let _ = writeln!(
            self.body,
            "<image x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" style=\"image-rendering:pixelated\" \
             href=\"data:image/png;base64,{data}\" xlink:href=\"data:image/png;base64,{data}\"/>"
        );
        Ok(())
    }

    /// Writes `text` (escaped) at `(x, y)` (the baseline), `size` pixels high.
    pub fn text(&mut self, x: f64, y: f64, size: f64, anchor: Anchor, text: &str) {
        let anchor = match anchor {
            Anchor::Start => "start",
            Anchor::Middle => "middle",
            Anchor::End => "end",
        };
        let _ = writeln!(
            self.body,
            "<text x=\"{x:.1}\" y=\"{y:.1}\" font-family=\"sans-serif\" font-size=\"{size:.1}\" \
             text-anchor=\"{anchor}\" fill=\"#000000\">{}</text>",
            escape(text)
        );
    }

    /// A line from `(x0, y0)` to `(x1, y1)`, one pixel wide, black.
    pub fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64)) {
        let _ = writeln!(
            self.body,
            "<line x1=\"{x0:.1}\" y1=\"{y0:.1}\" x2=\"{x1:.1}\" y2=\"{y1:.1}\" stroke=\"#000000\" stroke-width=\"1\"/>"
        );
    }

    /// The outline of a rectangle, one pixel wide, black.
    pub fn frame(&mut self, x: f64, y: f64, w: f64, h: f64) {
        let _ = writeln!(
            self.body,
            "<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"none\" stroke=\"#000000\" stroke-width=\"1\"/>"
        );
    }

    /// Writes the document to `path`.
    pub fn save(&self, path: &Path) -> Result<()> {
        let (w, h) = (self.width, self.height);
        let text = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" \
             width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n{}</svg>\n",
            self.body
        );
        std::fs::write(path, text).map_err(|e| Error(format!("cannot write {}: {e}", path.display())))
    }
}

/// `text` with the characters XML reserves escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Standard base64 (RFC 4648, with `=` padding).
pub fn base64(bytes: &[u8]) -> String {
    const TABLE: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(TABLE[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_examples() {
        for (plain, coded) in
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("foobar", "Zm9vYmFy")]
        {
            assert_eq!(base64(plain.as_bytes()), coded);
        }
    }

    #[test]
    fn upscaling_replicates_pixels() {
        let im = Rgb { width: 2, height: 1, data: vec![1, 2, 3, 4, 5, 6] };
        let big = im.upscale(2);
        assert_eq!((big.width, big.height), (4, 2));
        assert_eq!(&big.data[..12], &[1, 2, 3, 1, 2, 3, 4, 5, 6, 4, 5, 6]);
        assert_eq!(big.data[..12], big.data[12..]);
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }
}
