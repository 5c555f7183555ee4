//! NumPy `.npy` files: read float32/float64/uint8/bool arrays in C order,
//! write float32 and uint8. The format is small enough to own
//! (https://numpy.org/doc/stable/reference/generated/numpy.lib.format.html).

use crate::bail;
use crate::error::{Error, Result};
use std::path::Path;

/// An array read from `.npy`: its shape and its values as `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct Array {
    /// Shape, outermost axis first.
    pub shape: Vec<usize>,
    /// Values in C order.
    pub data: Vec<f64>,
    /// The stored element type, as in the header (`<f4`, `<f8`, `|u1`, `|b1`).
    pub dtype: String,
}

/// Reads a `.npy` file. `what` names the field the file belongs to, for errors.
pub fn read(path: &Path, what: &str) -> Result<Array> {
    let bytes = std::fs::read(path).map_err(|e| Error(format!("{what}: cannot read {}: {e}", path.display())))?;
    parse(&bytes).map_err(|e| Error(format!("{what}: {}: {}", path.display(), e.0)))
}

/// Parses the bytes of a `.npy` file.
pub fn parse(bytes: &[u8]) -> Result<Array> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        bail!("not a .npy file (bad magic)");
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        v => bail!("unsupported .npy version {v}"),
    };
    let end = start + header_len;
    if bytes.len() < end {
        bail!("truncated .npy header");
    }
    let header = std::str::from_utf8(&bytes[start..end]).map_err(|_| Error::new("header is not text"))?;
    let dtype = header_value(header, "descr").ok_or_else(|| Error::new("header has no 'descr'"))?;
    let dtype = dtype.trim_matches(|c| c == '\'' || c == '"').to_string();
    let fortran = header_value(header, "fortran_order").ok_or_else(|| Error::new("header has no 'fortran_order'"))?;
    if fortran.trim() != "False" {
        bail!("Fortran-order arrays are not supported (save with C order)");
    }
    let shape_text = header_value(header, "shape").ok_or_else(|| Error::new("header has no 'shape'"))?;
    let shape = shape_text
        .trim_matches(|c| c == '(' || c == ')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>().map_err(|_| Error(format!("bad shape {shape_text}"))))
        .collect::<Result<Vec<_>>>()?;
    let count: usize = shape.iter().product();
    let body = &bytes[end..];
    let size = match dtype.as_str() {
        "<f4" => 4,
        "<f8" => 8,
        "|u1" | "<u1" | "|b1" => 1,
        other => bail!("dtype {other} is not supported (need float32 or float64, little-endian)"),
    };
    if body.len() < count * size {
        bail!("data is truncated: shape {shape:?} needs {} bytes, file has {}", count * size, body.len());
    }
    let data = match size {
        4 => body.chunks_exact(4).take(count).map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64).collect(),
        8 => body.chunks_exact(8).take(count).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect(),
        _ => body[..count].iter().map(|&b| b as f64).collect(),
    };
    Ok(Array { shape, data, dtype })
}

/// The text of `'key': value` in a header dict, up to the next top-level comma.
fn header_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{key}'"))? + key.len() + 2;
    let rest = header[at..].trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0;
    for (i, c) in rest.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
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

/// Writes `data` (C order) as a uint8 `.npy` of the given shape.
pub fn write_u8(path: &Path, shape: &[usize], data: &[u8]) -> Result<()> {
    assert_eq!(shape.iter().product::<usize>(), data.len());
    write_raw(path, "|u1", shape, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_f32() {
        let dir = std::env::temp_dir().join(format!("dualphoton-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.npy");
        write_f32(&p, &[2, 3], &[0.0, 1.0, 2.0, 3.0, 4.5, -1.0]).unwrap();
        let a = read(&p, "test").unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, vec![0.0, 1.0, 2.0, 3.0, 4.5, -1.0]);
        assert_eq!(a.dtype, "<f4");
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!((10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize) % 64, 0);
    }

    #[test]
    fn rejects_garbage_and_big_endian() {
        assert!(parse(b"hello world, not numpy").is_err());
        let mut v = b"\x93NUMPY\x01\x00".to_vec();
        let h = "{'descr': '>f8', 'fortran_order': False, 'shape': (1,), }\n";
        v.extend_from_slice(&(h.len() as u16).to_le_bytes());
        v.extend_from_slice(h.as_bytes());
        v.extend_from_slice(&[0u8; 8]);
        assert!(parse(&v).unwrap_err().0.contains(">f8"));
    }
}
