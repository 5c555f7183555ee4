//! NumPy `.npy` files: read what `numpy.save` writes for float32, float64,
//! uint8 and bool arrays, write float32 and uint8. The format is small
//! enough to own
//! (<https://numpy.org/doc/stable/reference/generated/numpy.lib.format.html>).
//!
//! Read: format versions 1.0, 2.0 and 3.0; little- and big-endian (`<f4`,
//! `>f8`, ...); C order and Fortran order (`fortran_order: True`, what numpy
//! writes for a transposed array), the latter rearranged into C order on
//! load. A header whose shape does not match the data that follows, or
//! asks for more than [`MAX_ELEMENTS`], is an error before anything is
//! allocated for it; a path that is not a regular file (`/dev/zero`, a
//! directory, a pipe) is an error before anything is read, and no read
//! takes more bytes than the largest valid file ([`max_file_bytes`]).
//! Write: version 1.0, little-endian, C order.

use crate::bail;
use crate::error::{Error, Result};
use std::path::Path;

/// Most elements an array read may have: 2^28 (a 645^3 grid; 2 GiB once
/// widened to `f64`). The project's grids are at most 128^3 (2^21) and its
/// largest array, a prior's weights, under 2^20; a header asking for more
/// (a 4 MB compressed file claiming 1024^3) is refused before any allocation.
pub const MAX_ELEMENTS: usize = 1 << 28;
/// Longest header read (numpy's own loader refuses headers over 10 000 bytes by default).
pub const MAX_HEADER: usize = 1 << 20;

/// The element types read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Element {
    /// `f4`.
    F32,
    /// `f8`.
    F64,
    /// `u1`.
    U8,
    /// `b1` (read as 0 or 1).
    Bool,
}

impl Element {
    /// True for float32 and float64.
    pub fn is_float(self) -> bool {
        matches!(self, Element::F32 | Element::F64)
    }

    fn size(self) -> usize {
        match self {
            Element::F32 => 4,
            Element::F64 => 8,
            Element::U8 | Element::Bool => 1,
        }
    }
}

/// An array read from `.npy`: its shape and its values as `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct Array {
    /// Shape, outermost axis first.
    pub shape: Vec<usize>,
    /// Values in C order (last axis fastest), whatever the file's order.
    pub data: Vec<f64>,
    /// The stored element type, as in the header (`<f4`, `>f8`, `|u1`, `|b1`).
    pub dtype: String,
    /// The stored element type.
    pub element: Element,
}

/// The largest a valid `.npy` file can be: its prefix, the longest header
/// read and [`MAX_ELEMENTS`] 8-byte elements.
pub fn max_file_bytes() -> u64 {
    12 + MAX_HEADER as u64 + 8 * MAX_ELEMENTS as u64
}

/// Reads a `.npy` file. `what` names the field the file belongs to: every
/// error is `what: path: problem` (a long path shortened,
/// [`crate::error::show`]). The header is read first and its shape checked
/// against [`MAX_ELEMENTS`] and against the file's size before the data is read.
pub fn read(path: &Path, what: &str) -> Result<Array> {
    use std::io::Read;
    let fail = |msg: String| Error(format!("{what}: {}: {msg}", crate::error::show(path)));
    let (mut file, len, mut bytes) = open_header(path).map_err(fail)?;
    let cannot = |e: std::io::Error| fail(format!("cannot read: {e}"));
    // A header that does not parse is reported by `parse` below, with the whole file.
    if let Ok(d) = declared(&bytes) {
        if d.header_end as u64 + d.data_bytes as u64 != len {
            let body = len.saturating_sub(d.header_end as u64);
            return Err(fail(format!(
                "data is {body} bytes, shape {:?} of {} needs {}",
                d.shape, d.dtype, d.data_bytes
            )));
        }
    }
    file.read_to_end(&mut bytes).map_err(cannot)?;
    parse(&bytes).map_err(|e| fail(e.0))
}

/// What the `.npy` file at `path` declares, from its header alone (its
/// data is never read); errors as [`read`]'s.
pub fn read_declared(path: &Path, what: &str) -> Result<Declared> {
    let fail = |msg: String| Error(format!("{what}: {}: {msg}", crate::error::show(path)));
    let (_, _, bytes) = open_header(path).map_err(fail)?;
    declared(&bytes).map_err(|e| fail(e.0))
}

/// The regular file at `path` opened, its length, and its first bytes (as
/// many as the longest header read takes); the rest is left to read, at
/// most its length and one byte more (to notice a file that grows).
fn open_header(path: &Path) -> std::result::Result<(std::io::Take<std::fs::File>, u64, Vec<u8>), String> {
    use std::io::Read;
    let (file, len) = open_regular(path, max_file_bytes())?;
    let mut file = file.take(len + 1);
    let mut bytes = Vec::new();
    file.by_ref().take((12 + MAX_HEADER) as u64).read_to_end(&mut bytes).map_err(|e| format!("cannot read: {e}"))?;
    Ok((file, len, bytes))
}

/// [`read`], then a check that every value is finite and fits in float32
/// (`|v| <= f32::MAX`): for data that is used or written as float32
/// (densities, images), where a float64 1e300 would become an infinity.
pub fn read_f32_range(path: &Path, what: &str) -> Result<Array> {
    let array = read(path, what)?;
    check_f32_range(&array.data).map_err(|msg| Error(format!("{what}: {}: {msg}", crate::error::show(path))))?;
    Ok(array)
}

/// `Err` naming the first value that is NaN, infinite or beyond the float32
/// range, with its flat index.
pub fn check_f32_range(data: &[f64]) -> std::result::Result<(), String> {
    match data.iter().position(|v| !(v.is_finite() && v.abs() <= f32::MAX as f64)) {
        None => Ok(()),
        Some(n) => Err(format!(
            "value {:e} at flat index {n} is not a finite float32 (|v| <= {:e}); NaN, infinities and larger \
             values are refused",
            data[n],
            f32::MAX
        )),
    }
}

/// The bytes of the regular file at `path`, at most `most` of them: a path
/// that is not a regular file (`/dev/zero`, a directory, a FIFO) or a file
/// longer than `most` is an error before (or instead of) reading it all.
pub fn read_bounded(path: &Path, most: u64) -> std::result::Result<Vec<u8>, String> {
    use std::io::Read;
    let (file, len) = open_regular(path, most)?;
    let mut bytes = Vec::with_capacity(len as usize);
    // The file may grow while read: never take more than `most` (+1 to notice).
    file.take(most + 1).read_to_end(&mut bytes).map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > most {
        return Err(format!("more than the {most} bytes this reader accepts"));
    }
    Ok(bytes)
}

/// The regular file at `path`, opened, and its length, at most `most`.
fn open_regular(path: &Path, most: u64) -> std::result::Result<(std::fs::File, u64), String> {
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read: {e}"))?;
    if !meta.is_file() {
        return Err("not a regular file (a device, directory or pipe); give a file".into());
    }
    if meta.len() > most {
        return Err(format!("{} bytes is more than the {most} this reader accepts", meta.len()));
    }
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    Ok((file, meta.len()))
}

/// What a `.npy` header declares ([`declared`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Declared {
    /// Shape, outermost axis first.
    pub shape: Vec<usize>,
    /// The element type as written (`<f4`).
    pub dtype: String,
    /// Bytes before the data: magic, version, header length and header.
    pub header_end: usize,
    /// Bytes of data the shape and element type need.
    pub data_bytes: usize,
}

/// What a `.npy` header declares, from the file's first bytes (the header
/// is enough): lets a caller check a file's size, or a compressed member's,
/// before reading or decompressing its data. A shape of more than
/// [`MAX_ELEMENTS`] is an error.
pub fn declared(bytes: &[u8]) -> Result<Declared> {
    let (header, body) = split(bytes)?;
    let header_end = bytes.len() - body.len();
    let value = |key: &str| header_value(header, key).ok_or_else(|| Error(format!("header has no '{key}'")));
    let dtype = value("descr")?.trim_matches(|c| c == '\'' || c == '"').to_string();
    let (element, _) = element_of(&dtype)?;
    let shape = parse_shape(value("shape")?)?;
    let data_bytes = element_count(&shape)? * element.size();
    Ok(Declared { shape, dtype, header_end, data_bytes })
}

/// The number of elements of `shape`, at most [`MAX_ELEMENTS`].
fn element_count(shape: &[usize]) -> Result<usize> {
    shape
        .iter()
        .try_fold(1usize, |n, &axis| n.checked_mul(axis))
        .filter(|&n| n <= MAX_ELEMENTS)
        .ok_or_else(|| Error(format!("shape {shape:?} has more elements than the {MAX_ELEMENTS} this reader accepts")))
}

/// Parses the bytes of a `.npy` file.
pub fn parse(bytes: &[u8]) -> Result<Array> {
    let (header, body) = split(bytes)?;
    let value = |key: &str| header_value(header, key).ok_or_else(|| Error(format!("header has no '{key}'")));
    let dtype = value("descr")?.trim_matches(|c| c == '\'' || c == '"').to_string();
    let (element, big_endian) = element_of(&dtype)?;
    let fortran = match value("fortran_order")? {
        "True" => true,
        "False" => false,
        other => bail!("header's 'fortran_order' is {other}, not True or False"),
    };
    let shape = parse_shape(value("shape")?)?;
    let count = element_count(&shape)?;
    let need = count * element.size();
    if body.len() != need {
        bail!("data is {} bytes, shape {shape:?} of {dtype} needs {need}", body.len());
    }
    let data = decode(body, element, big_endian);
    let data = if fortran { fortran_to_c(&data, &shape) } else { data };
    Ok(Array { shape, data, dtype, element })
}

/// The header text and the data after it.
fn split(bytes: &[u8]) -> Result<(&str, &[u8])> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        bail!("not a .npy file (bad magic)");
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        2 | 3 => bail!("truncated .npy header"),
        v => bail!("unsupported .npy format version {v}.{} (1.0, 2.0 and 3.0 are read)", bytes[7]),
    };
    if header_len > MAX_HEADER {
        bail!("header of {header_len} bytes is longer than the {MAX_HEADER} this reader accepts");
    }
    let end = start + header_len;
    if bytes.len() < end {
        bail!("truncated .npy header");
    }
    // Versions 1 and 2 are latin-1, 3 is UTF-8; the keys read are ASCII either way.
    let header = std::str::from_utf8(&bytes[start..end]).map_err(|_| Error::new("header is not text"))?;
    Ok((header, &bytes[end..]))
}

/// The element type of a `descr` and whether it is big-endian.
fn element_of(descr: &str) -> Result<(Element, bool)> {
    let native_big = cfg!(target_endian = "big");
    let (big, code) = match descr.as_bytes().first() {
        Some(b'<') => (false, &descr[1..]),
        Some(b'>') => (true, &descr[1..]),
        Some(b'|' | b'=') => (native_big, &descr[1..]),
        _ => (native_big, descr),
    };
    let element = match code {
        "f4" => Element::F32,
        "f8" => Element::F64,
        "u1" => Element::U8,
        "b1" => Element::Bool,
        _ => bail!("dtype {descr} is not supported (float32, float64, uint8 or bool, either byte order)"),
    };
    Ok((element, big))
}

/// The axes of a shape tuple: `(2, 3)`, `(3,)`, `()`; Python 2's `3L` too.
fn parse_shape(text: &str) -> Result<Vec<usize>> {
    text.trim_matches(|c| c == '(' || c == ')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<usize>().map_err(|_| Error(format!("bad shape {text}"))))
        .collect()
}

/// The values of `body` (whole elements, already length-checked) as `f64`.
fn decode(body: &[u8], element: Element, big: bool) -> Vec<f64> {
    match element {
        Element::F32 => body
            .chunks_exact(4)
            .map(|c| {
                let b = c.try_into().unwrap();
                (if big { f32::from_be_bytes(b) } else { f32::from_le_bytes(b) }) as f64
            })
            .collect(),
        Element::F64 => body
            .chunks_exact(8)
            .map(|c| {
                let b = c.try_into().unwrap();
                if big {
                    f64::from_be_bytes(b)
                } else {
                    f64::from_le_bytes(b)
                }
            })
            .collect(),
        Element::U8 => body.iter().map(|&b| b as f64).collect(),
        Element::Bool => body.iter().map(|&b| f64::from(u8::from(b != 0))).collect(),
    }
}

/// `data` stored in Fortran order (first axis fastest) rearranged into C
/// order (last axis fastest): walk the C-order index like an odometer and
/// keep the Fortran offset of the same element.
fn fortran_to_c(data: &[f64], shape: &[usize]) -> Vec<f64> {
    let mut stride = vec![1usize; shape.len()];
    for a in 1..shape.len() {
        stride[a] = stride[a - 1] * shape[a - 1];
    }
    let mut index = vec![0usize; shape.len()];
    let mut offset = 0;
    let mut out = Vec::with_capacity(data.len());
    for _ in 0..data.len() {
        out.push(data[offset]);
        for a in (0..shape.len()).rev() {
            index[a] += 1;
            offset += stride[a];
            if index[a] < shape[a] {
                break;
            }
            offset -= stride[a] * shape[a];
            index[a] = 0;
        }
    }
    out
}

/// The text of `'key': value` in a header dict, up to the next top-level comma.
fn header_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{key}'")).or_else(|| header.find(&format!("\"{key}\"")))? + key.len() + 2;
    let rest = header[at..].trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0;
    for (i, c) in rest.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(rest[..i].trim()),
            _ => {}
        }
    }
    None
}

fn write_raw(path: &Path, descr: &str, shape: &[usize], body: &[u8]) -> Result<()> {
    let shape_text = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!("({})", shape.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_text}, }}");
    // Pad so that the data starts on a 64-byte boundary, ending with a newline.
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + body.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(body);
    std::fs::write(path, out).map_err(|e| Error(format!("cannot write {}: {e}", path.display())))
}

/// Writes `data` (C order) as a float32 `.npy` of the given shape.
pub fn write_f32(path: &Path, shape: &[usize], data: &[f64]) -> Result<()> {
    assert_eq!(shape.iter().product::<usize>(), data.len());
    let body: Vec<u8> = data.iter().flat_map(|&v| (v as f32).to_le_bytes()).collect();
    write_raw(path, "<f4", shape, &body)
}

/// Writes `data` (C order) as a float64 `.npy` of the given shape: exact
/// (weights and checkpoints).
pub fn write_f64(path: &Path, shape: &[usize], data: &[f64]) -> Result<()> {
    assert_eq!(shape.iter().product::<usize>(), data.len());
    let body: Vec<u8> = data.iter().flat_map(|&v| v.to_le_bytes()).collect();
    write_raw(path, "<f8", shape, &body)
}

/// Writes `data` (C order) as a uint8 `.npy` of the given shape.
pub fn write_u8(path: &Path, shape: &[usize], data: &[u8]) -> Result<()> {
    assert_eq!(shape.iter().product::<usize>(), data.len());
    write_raw(path, "|u1", shape, data)
}

#[cfg(test)]
mod tests;
