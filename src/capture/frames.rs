//! Frames of a capture as images of code value / full scale (0..1 for
//! 8- and 16-bit data), grey: the mean of the colour channels.
//!
//! Videos are decoded by the `ffmpeg` program, as PINF and HyFluid decode
//! them (to 8-bit RGB; a limited-range video is stretched to full range).
//! No Rust crate decodes these H.264 files exactly: the `openh264` crate
//! was measured to decode their B-frames wrongly. PNG and JPEG (8 or 16
//! bit; JPEG 8 bit) are read by the `image` crate; `.npy` frames ((H, W) or
//! (H, W, C) with C of 1 to 4 as in a PNG, float values as they are,
//! `uint8` / 255) by the project's reader.

use super::{Frames, View};
use crate::bail;
use crate::error::{show, Error, Result};
use crate::image::Image;
use crate::io::npy;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};

/// What to tell a user without `ffmpeg`.
pub const NO_FFMPEG: &str = "the ffmpeg program decodes videos and was not found: install it (Debian/Ubuntu: \
                             apt install ffmpeg; macOS: brew install ffmpeg) or extract the frames as PNG images \
                             and give a transforms.json";

/// True if `ffmpeg` can be run.
pub fn have_ffmpeg() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// True for the image files a folder of frames may hold.
pub fn is_image(path: &Path) -> bool {
    path.is_file() && IMAGE_EXTENSIONS.contains(&extension(path).as_str())
}

/// The extension of `path` in lower case (`""` if none).
fn extension(path: &Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default()
}

/// The extensions of the image files a capture's frames may be, lower case.
pub const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "npy"];

/// Width and height of an image file, from its header.
pub fn image_size(path: &Path) -> Result<(usize, usize)> {
    if extension(path) == "npy" {
        let (height, width, _) = npy_frame_shape(path, &npy::read_declared(path, "frame")?.shape)?;
        return Ok((width, height));
    }
    let (w, h) = image::image_dimensions(path).map_err(|e| Error(format!("{}: {e}", show(path))))?;
    Ok((w as usize, h as usize))
}

/// Frames `wanted` (in that order) of `view`, each checked against the
/// camera's size. Errors: a frame out of range, no `ffmpeg`, a file that
/// does not decode, an image of another size.
pub fn read(view: &View, wanted: &[usize]) -> Result<Vec<Image>> {
    let count = view.frames.count();
    if let Some(&n) = wanted.iter().find(|&&n| n >= count) {
        bail!("camera {}: frame {n} is out of range (it has frames 0..{})", view.name, count.saturating_sub(1));
    }
    let (width, height) = (view.camera.width, view.camera.height);
    let images = match &view.frames {
        Frames::Video { path, .. } => decode_video(path, wanted)?,
        Frames::Images(paths) => wanted.iter().map(|&n| read_image(&paths[n])).collect::<Result<Vec<_>>>()?,
    };
    for image in &images {
        if (image.width, image.height) != (width, height) {
            bail!(
                "camera {}: its frames are {}x{} but the calibration says {width}x{height} (width x height): give \
                 the calibration the images' size and intrinsics, or images of the size it gives",
                view.name,
                image.width,
                image.height
            );
        }
    }
    Ok(images)
}

/// Pictures `wanted` of the video at `path`, at the size it has, in as few
/// passes of `ffmpeg` as its `select` filter allows (it keeps them in
/// stream order).
fn decode_video(path: &Path, wanted: &[usize]) -> Result<Vec<Image>> {
    let mut sorted = wanted.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut decoded = Vec::with_capacity(sorted.len());
    for (select, frames) in select_passes(&sorted, TERMS_PER_PASS) {
        decoded.extend(decode_selected(path, &select, &frames)?);
    }
    if sorted == wanted {
        return Ok(decoded);
    }
    Ok(wanted.iter().map(|n| decoded[sorted.binary_search(n).unwrap_or(0)].clone()).collect())
}

/// The most terms one `select` expression is given: `ffmpeg`'s expression
/// parser refuses a sum of more than 100.
const TERMS_PER_PASS: usize = 50;

/// One `select` expression per pass of `ffmpeg` over a video, with the
/// frames it keeps, for `sorted` frames (ascending, distinct): a run of
/// consecutive frames is one term, and a pass has at most `per_pass` terms.
fn select_passes(sorted: &[usize], per_pass: usize) -> Vec<(String, Vec<usize>)> {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for &n in sorted {
        match runs.last_mut() {
            Some((_, last)) if *last + 1 == n => *last = n,
            _ => runs.push((n, n)),
        }
    }
    let term = |&(a, b): &(usize, usize)| {
        if a == b {
            format!("eq(n\\,{a})")
        } else {
            format!("between(n\\,{a}\\,{b})")
        }
    };
    runs.chunks(per_pass.max(1))
        .map(|pass| {
            let select = pass.iter().map(term).collect::<Vec<_>>().join("+");
            (select, pass.iter().flat_map(|&(a, b)| a..=b).collect())
        })
        .collect()
}

/// The `frames` (ascending) that the `select` expression keeps of the video
/// at `path`, in one pass of `ffmpeg` that stops after the last of them.
fn decode_selected(path: &Path, select: &str, frames: &[usize]) -> Result<Vec<Image>> {
    // `file:` so that a path with a colon is never read as a protocol.
    let mut input = std::ffi::OsString::from("file:");
    input.push(path);
    let child = Command::new("ffmpeg")
        .args(["-nostdin", "-v", "error", "-i"])
        .arg(input)
        .args(["-vf", &format!("select={select}"), "-vsync", "passthrough"])
        .args(["-frames:v", &frames.len().to_string()])
        // PPM: each picture's header gives its size, so that a video of
        // another size than the calibration's (width and height swapped
        // have as many bytes) is refused rather than read scrambled.
        .args(["-f", "image2pipe", "-c:v", "ppm", "-pix_fmt", "rgb24", "pipe:1"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn();
    let mut child = match child {
        Ok(child) => child,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!("{}: {NO_FFMPEG}", show(path)),
        Err(e) => bail!("{}: cannot run ffmpeg: {e}", show(path)),
    };
    // Its messages are read beside its frames, so that neither pipe fills
    // while the other is waited on.
    let messages = child.stderr.take().map(|mut e| {
        std::thread::spawn(move || {
            let mut text = String::new();
            e.read_to_string(&mut text).ok();
            text
        })
    });
    let stdout = child.stdout.take().ok_or_else(|| Error("ffmpeg gave no output".into()))?;
    let mut stdout = std::io::BufReader::new(stdout);
    // Frame by frame, so that only one frame's bytes are ever held.
    let mut images = Vec::with_capacity(frames.len());
    while images.len() < frames.len() {
        let Some((width, height)) = read_ppm_header(&mut stdout) else { break };
        let mut bytes = vec![0u8; width * height * 3];
        if stdout.read_exact(&mut bytes).is_err() {
            break;
        }
        images.push(Image {
            width,
            height,
            data: bytes.chunks_exact(3).map(|p| (p[0] as f64 + p[1] as f64 + p[2] as f64) / (3.0 * 255.0)).collect(),
        });
    }
    // A byte more than the frames asked for: the video's frames are larger.
    let more = images.len() == frames.len() && stdout.read(&mut [0u8]).is_ok_and(|n| n > 0);
    drop(stdout);
    let status = child.wait()?;
    let stderr = messages.and_then(|m| m.join().ok()).unwrap_or_default();
    if !status.success() || images.len() != frames.len() || more {
        // Fewer pictures and no complaint: the video ended before them.
        let short = (status.success() && images.len() < frames.len()).then(|| {
            format!(
                "the video ends before frame {} (it has fewer frames than its calibration's frame_num says)",
                frames[images.len()]
            )
        });
        let what = stderr.lines().next().map(str::to_string).or(short);
        let what = what.unwrap_or_else(|| "its output is not the frames asked for".to_string());
        bail!(
            "{}: ffmpeg could not decode frames {}: {}",
            show(path),
            show_frames(frames),
            crate::error::shorten(&what)
        );
    }
    Ok(images)
}

/// The width and height in the header of a binary 8-bit PPM picture
/// (`P6 width height 255` and one whitespace byte), or `None` at the end
/// of the stream or on a header that is not one (of at most 2^28 pixels).
fn read_ppm_header(r: &mut impl std::io::BufRead) -> Option<(usize, usize)> {
    let mut fields = Vec::new();
    let mut field = Vec::new();
    while fields.len() < 4 {
        let mut byte = [0u8];
        r.read_exact(&mut byte).ok()?;
        if !byte[0].is_ascii_whitespace() {
            field.push(byte[0]);
        } else if !field.is_empty() {
            fields.push(String::from_utf8(std::mem::take(&mut field)).ok()?);
        }
        if field.len() > 16 {
            return None;
        }
    }
    let number = |s: &str| s.parse::<usize>().ok().filter(|&n| n > 0);
    let (width, height) = (number(&fields[1])?, number(&fields[2])?);
    (fields[0] == "P6" && fields[3] == "255" && width.checked_mul(height)? <= 1 << 28).then_some((width, height))
}

/// `frames` for a message: all of them where they are few.
fn show_frames(frames: &[usize]) -> String {
    match frames {
        [first, .., last] if frames.len() > 8 => format!("[{first}, ..., {last}] ({} frames)", frames.len()),
        _ => format!("{frames:?}"),
    }
}

/// One image file as grey code value / full scale; one with an alpha
/// channel composited over black (the fit's smoke is rendered on black).
fn read_image(path: &Path) -> Result<Image> {
    if extension(path) == "npy" {
        return read_npy(path);
    }
    let image = image::open(path).map_err(|e| Error(format!("{}: {e}", show(path))))?;
    let (width, height) = (image.width() as usize, image.height() as usize);
    // Exact code values for integer images: code / full scale in f64 (an
    // opaque pixel's alpha is full scale, a factor of exactly 1).
    let grey = |p: [f64; 4], full: f64| (p[0] + p[1] + p[2]) / (3.0 * full) * (p[3] / full);
    let color = image.color();
    let data: Vec<f64> = match color.bytes_per_pixel() / color.channel_count() {
        1 => image.to_rgba8().pixels().map(|p| grey(p.0.map(f64::from), 255.0)).collect(),
        2 => image.to_rgba16().pixels().map(|p| grey(p.0.map(f64::from), 65535.0)).collect(),
        _ => image.to_rgba32f().pixels().map(|p| grey(p.0.map(f64::from), 1.0)).collect(),
    };
    if data.iter().any(|v| !v.is_finite()) {
        bail!("{}: holds NaN or infinity", show(path));
    }
    Ok(Image { width, height, data })
}

/// A `.npy` frame: (H, W) grey, or (H, W, C) with the channels of a PNG:
/// grey, grey and alpha, RGB, RGBA; the colours averaged, alpha
/// composited over black. Its values are brightness: none below 0, none
/// beyond float32's range.
fn read_npy(path: &Path) -> Result<Image> {
    let a = npy::read_f32_range(path, "frame")?;
    let (height, width, channels) = npy_frame_shape(path, &a.shape)?;
    if let Some((n, v)) = a.data.iter().enumerate().find(|(_, v)| **v < 0.0) {
        bail!(
            "{}: value {v} at pixel {} (row-major) is negative: a frame is brightness, 0 or more; clip it at 0 first",
            show(path),
            n / channels
        );
    }
    let scale = if a.element == npy::Element::U8 { 255.0 } else { 1.0 };
    let colours = if channels % 2 == 0 { channels - 1 } else { channels };
    let data: Vec<f64> = a
        .data
        .chunks_exact(channels)
        .map(|p| {
            let alpha = if channels % 2 == 0 { p[channels - 1] / scale } else { 1.0 };
            p[..colours].iter().sum::<f64>() / (colours as f64 * scale) * alpha
        })
        .collect();
    Ok(Image { width, height, data })
}

/// Height, width and channels of a `.npy` frame of `shape`.
fn npy_frame_shape(path: &Path, shape: &[usize]) -> Result<(usize, usize, usize)> {
    match shape[..] {
        [h, w] => Ok((h, w, 1)),
        [h, w, c] if (1..=4).contains(&c) => Ok((h, w, c)),
        _ => bail!(
            "{}: shape {shape:?} is not (H, W) or (H, W, C) with C of 1 (grey), 2 (grey, alpha), 3 (RGB) or 4 (RGBA)",
            show(path)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_of_frames_is_one_term_and_a_pass_has_at_most_its_terms() {
        let passes = select_passes(&[0, 1, 2, 5, 7, 8], 50);
        assert_eq!(passes, vec![(r"between(n\,0\,2)+eq(n\,5)+between(n\,7\,8)".into(), vec![0, 1, 2, 5, 7, 8])]);
        let passes = select_passes(&[0, 1, 2, 5, 7, 8], 2);
        assert_eq!(passes.len(), 2);
        assert_eq!(passes[1], (r"between(n\,7\,8)".into(), vec![7, 8]));
        let odd: Vec<usize> = (1..240).step_by(2).collect();
        let passes = select_passes(&odd, TERMS_PER_PASS);
        assert_eq!(passes.iter().map(|(_, f)| f.len()).collect::<Vec<_>>(), vec![50, 50, 20]);
        assert_eq!(passes.iter().flat_map(|(_, f)| f.clone()).collect::<Vec<_>>(), odd);
        assert!(select_passes(&[], TERMS_PER_PASS).is_empty());
    }

    #[test]
    fn a_ppm_header_gives_the_size_and_leaves_the_pixels() {
        let mut stream: &[u8] = b"P6\n3 2\n255\nabcdefghijklmnopqr";
        assert_eq!(read_ppm_header(&mut stream), Some((3, 2)));
        assert_eq!(stream, b"abcdefghijklmnopqr");
        for bad in [&b""[..], b"P6\n3 2\n", b"P5\n3 2\n255\n", b"P6\n3 0\n255\n", b"P6\n3 2\n65535\n", b"P6 x 2 255 "] {
            assert_eq!(read_ppm_header(&mut { bad }), None, "{}", String::from_utf8_lossy(bad));
        }
    }
}
