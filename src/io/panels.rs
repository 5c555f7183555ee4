//! Figures made of images: a strip of one camera's images (Fig. 6) and the
//! held-out comparison truth | estimate | signed error (Fig. 8). Each comes
//! as a plain PNG (the pixels, nothing else) and as an SVG with the images
//! enlarged by pixel replication, labels and, for the error, a colour bar.

use super::plot::significant;
use super::png::tone_map;
use super::svg::{Anchor, Rgb, Svg};
use crate::error::{Error, Result};
use crate::image::{auto_white, Image};
use std::path::Path;

/// Pixels between panels of a PNG strip.
const PNG_GAP: usize = 2;

/// An SVG panel is enlarged to about this many pixels across (at least 1x).
const SVG_PANEL: usize = 256;

/// The signed error `e` in [-1, 1] as a colour: white at 0, full blue at -1
/// (estimate too dark), full red at +1 (estimate too bright), linear between.
pub fn signed_error_colour(e: f64) -> [u8; 3] {
    let e = e.clamp(-1.0, 1.0);
    let fade = (255.0 * (1.0 - e.abs())) as u8;
    if e >= 0.0 {
        [255, fade, fade]
    } else {
        [fade, fade, 255]
    }
}

/// Images side by side (with a 2-pixel gap), all under one white point, as grey PNG.
pub fn image_strip(images: &[&Image], white: f64, out: &Path) -> Result<()> {
    let h = images.iter().map(|i| i.height).max().unwrap_or(1);
    let w: usize = images.iter().map(|i| i.width).sum::<usize>() + PNG_GAP * images.len().saturating_sub(1);
    let mut canvas = image::GrayImage::from_pixel(w as u32, h as u32, image::Luma([255]));
    let mut x0 = 0;
    for im in images {
        let grey = tone_map(&im.data, white);
        for y in 0..im.height {
            for x in 0..im.width {
                canvas.put_pixel((x0 + x) as u32, y as u32, image::Luma([grey[y * im.width + x]]));
            }
        }
        x0 += im.width + PNG_GAP;
    }
    canvas.save(out).map_err(|e| Error(format!("cannot write {}: {e}", out.display())))
}

/// Fig. 8 as one RGB PNG: ground truth | estimate (shared white point,
/// grey) | signed error ([`signed_error_colour`], full colour at `white / 4`).
pub fn held_out_panel(truth: &Image, estimate: &Image, out: &Path) -> Result<()> {
    let white = auto_white(&truth.data);
    let panels = [grey(truth, white), grey(estimate, white), signed_error(truth, estimate, white)];
    let (w, h) = (truth.width, truth.height);
    let mut canvas = image::RgbImage::from_pixel((3 * w + 2 * PNG_GAP) as u32, h as u32, image::Rgb([255; 3]));
    for (k, p) in panels.iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                let i = 3 * (y * w + x);
                let c = [p.data[i], p.data[i + 1], p.data[i + 2]];
                canvas.put_pixel((k * (w + PNG_GAP) + x) as u32, y as u32, image::Rgb(c));
            }
        }
    }
    canvas.save(out).map_err(|e| Error(format!("cannot write {}: {e}", out.display())))
}

/// A labelled strip as SVG: `panels` (image, label under it) side by side
/// under one white point, enlarged by pixel replication, `title` above.
pub fn labelled_strip(panels: &[(&Image, String)], white: f64, title: &str, out: &Path) -> Result<()> {
    let f = factor(panels.iter().map(|(im, _)| im.width).max().unwrap_or(1));
    let (gap, top, label) = (8, 36, 28);
    let w = panels.iter().map(|(im, _)| im.width * f + gap).sum::<usize>() + gap;
    let h = panels.iter().map(|(im, _)| im.height * f).max().unwrap_or(0);
    let mut svg = Svg::new(w, top + h + label);
    svg.text(w as f64 / 2.0, 24.0, 16.0, Anchor::Middle, title);
    let mut x = gap;
    for (im, text) in panels {
        let bitmap = grey(im, white).upscale(f);
        svg.image(x, top, &bitmap)?;
        svg.text((x + bitmap.width / 2) as f64, (top + h + 20) as f64, 14.0, Anchor::Middle, text);
        x += bitmap.width + gap;
    }
    svg.save(out)
}

/// Fig. 8 as SVG: ground truth | estimate | signed error, titled, enlarged
/// by pixel replication, with a colour bar giving the error in radiance.
pub fn held_out_figure(truth: &Image, estimate: &Image, title: &str, out: &Path) -> Result<()> {
    let white = auto_white(&truth.data);
    let f = factor(truth.width);
    let panels = [
        (grey(truth, white), "ground truth"),
        (grey(estimate, white), "estimate"),
        (signed_error(truth, estimate, white), "signed error (estimate - truth)"),
    ];
    let (gap, top, bar_w, bar_label) = (12, 56, 16, 96);
    let (pw, ph) = (truth.width * f, truth.height * f);
    let w = gap + 3 * (pw + gap) + bar_w + bar_label;
    let mut svg = Svg::new(w, top + ph + gap);
    svg.text(w as f64 / 2.0, 22.0, 16.0, Anchor::Middle, title);
    for (k, (bitmap, name)) in panels.iter().enumerate() {
        let x = gap + k * (pw + gap);
        svg.image(x, top, &bitmap.upscale(f))?;
        svg.text((x + pw / 2) as f64, (top - 10) as f64, 14.0, Anchor::Middle, name);
    }
    // Colour bar: +white/4 at the top, -white/4 at the bottom, as the error panel colours them.
    let bar_x = gap + 3 * (pw + gap);
    let bar = Rgb {
        width: bar_w,
        height: ph,
        data: (0..ph)
            .flat_map(|y| {
                let e = 1.0 - 2.0 * (y as f64 + 0.5) / ph as f64;
                std::iter::repeat_n(signed_error_colour(e), bar_w).flatten()
            })
            .collect(),
    };
    svg.image(bar_x, top, &bar)?;
    svg.frame(bar_x as f64, top as f64, bar_w as f64, ph as f64);
    // Errors beyond the ends are clipped to the end colours.
    let (end, half) = (significant(0.25 * white), significant(0.125 * white));
    let labels =
        [format!("\u{2265} +{end}"), format!("+{half}"), "0".into(), format!("-{half}"), format!("\u{2264} -{end}")];
    for (k, label) in labels.iter().enumerate() {
        let (x, y) = ((bar_x + bar_w) as f64, top as f64 + ph as f64 * k as f64 / 4.0);
        svg.line((x, y), (x + 4.0, y));
        svg.text(x + 7.0, y + 4.0, 12.0, Anchor::Start, label);
    }
    svg.text((bar_x + bar_w / 2) as f64, (top - 10) as f64, 12.0, Anchor::Middle, "radiance");
    svg.save(out)
}

/// A grid of panels as SVG: `rows` (a label, then its panels in column
/// order), `columns` named above the first row, `title` and `caption` (one
/// line each) above everything. Panels are placed as they are (no
/// enlargement); a row's label is written at its left.
pub fn labelled_grid(
    rows: &[(String, Vec<Rgb>)],
    columns: &[String],
    title: &str,
    caption: &str,
    out: &Path,
) -> Result<()> {
    let (gap, left, top) = (6, 84, 76);
    let pw = rows.iter().flat_map(|(_, p)| p.iter().map(|b| b.width)).max().unwrap_or(0);
    let ph = rows.iter().flat_map(|(_, p)| p.iter().map(|b| b.height)).max().unwrap_or(0);
    // Text about 0.55 of its size wide per character: the canvas is wide enough for both lines.
    let text = |chars: usize, size: f64| (chars as f64 * size * 0.55) as usize + 2 * gap;
    // The last column's label may be wider than its panel: room for its half past the panel.
    let overhang = columns.last().map_or(0, |name| text(name.len(), 12.0).saturating_sub(pw) / 2);
    let w = (left + columns.len() * (pw + gap) + overhang).max(text(title.len(), 16.0)).max(text(caption.len(), 12.0));
    let mut svg = Svg::new(w, top + rows.len() * (ph + gap));
    svg.text(w as f64 / 2.0, 20.0, 16.0, Anchor::Middle, title);
    svg.text(w as f64 / 2.0, 40.0, 12.0, Anchor::Middle, caption);
    for (c, name) in columns.iter().enumerate() {
        svg.text((left + c * (pw + gap) + pw / 2) as f64, (top - 10) as f64, 12.0, Anchor::Middle, name);
    }
    for (r, (label, panels)) in rows.iter().enumerate() {
        let y = top + r * (ph + gap);
        svg.text(6.0, (y + ph / 2) as f64, 13.0, Anchor::Start, label);
        for (c, bitmap) in panels.iter().enumerate() {
            svg.image(left + c * (pw + gap), y, bitmap)?;
        }
    }
    svg.save(out)
}

/// Pixel replication factor that makes a panel of `width` pixels about [`SVG_PANEL`] wide.
fn factor(width: usize) -> usize {
    (SVG_PANEL / width.max(1)).max(1)
}

/// `im` tone-mapped with `white` ([`tone_map`]), grey as RGB.
pub fn grey(im: &Image, white: f64) -> Rgb {
    Rgb { width: im.width, height: im.height, data: tone_map(&im.data, white).iter().flat_map(|&g| [g; 3]).collect() }
}

/// `estimate - truth` per pixel in units of `white / 4`, as [`signed_error_colour`].
pub fn signed_error(truth: &Image, estimate: &Image, white: f64) -> Rgb {
    let data = truth
        .data
        .iter()
        .zip(&estimate.data)
        .flat_map(|(t, e)| signed_error_colour((e - t) / (0.25 * white)))
        .collect();
    Rgb { width: truth.width, height: truth.height, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_colours_run_from_blue_through_white_to_red() {
        assert_eq!(signed_error_colour(-1.0), [0, 0, 255]);
        assert_eq!(signed_error_colour(0.0), [255, 255, 255]);
        assert_eq!(signed_error_colour(1.0), [255, 0, 0]);
        assert_eq!(signed_error_colour(7.0), [255, 0, 0]);
    }
}
