//! Tests of the `.npy` reader on files built byte by byte the way numpy
//! writes them (header padded so the data starts on a 64-byte boundary).

use super::*;

/// A `.npy` file of format `version` with the given header fields and data.
fn npy(version: u8, descr: &str, fortran: bool, shape: &str, body: &[u8]) -> Vec<u8> {
    let order = if fortran { "True" } else { "False" };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': {shape}, }}");
    let prefix = if version == 1 { 10 } else { 12 };
    header.push_str(&" ".repeat((64 - (prefix + header.len() + 1) % 64) % 64));
    header.push('\n');
    let mut out = vec![0x93, b'N', b'U', b'M', b'P', b'Y', version, 0];
    match version {
        1 => out.extend_from_slice(&(header.len() as u16).to_le_bytes()),
        _ => out.extend_from_slice(&(header.len() as u32).to_le_bytes()),
    }
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(body);
    out
}

fn le8(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn be8(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_be_bytes()).collect()
}

fn be4(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| (*x as f32).to_be_bytes()).collect()
}

/// `a[k][j][i] = (k * 12 + j * 4 + i) / 2 - 3` of shape (2, 3, 4) in C order.
fn values() -> Vec<f64> {
    (0..24).map(|n| n as f64 * 0.5 - 3.0).collect()
}

/// The same array in Fortran order (first axis fastest).
fn fortran_values() -> Vec<f64> {
    let a = values();
    let mut out = vec![];
    for i in 0..4 {
        for j in 0..3 {
            for k in 0..2 {
                out.push(a[k * 12 + j * 4 + i]);
            }
        }
    }
    out
}

#[test]
fn round_trip_f32() {
    let dir = std::env::temp_dir().join(format!("dualphoton-npy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("a.npy");
    write_f32(&p, &[2, 3], &[0.0, 1.0, 2.0, 3.0, 4.5, -1.0]).unwrap();
    let a = read(&p, "test").unwrap();
    assert_eq!(a.shape, vec![2, 3]);
    assert_eq!(a.data, vec![0.0, 1.0, 2.0, 3.0, 4.5, -1.0]);
    assert_eq!((a.dtype.as_str(), a.element), ("<f4", Element::F32));
    let bytes = std::fs::read(&p).unwrap();
    let start = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!(start % 64, 0);
    assert_eq!(bytes, npy(1, "<f4", false, "(2, 3)", &bytes[start..]), "the writer writes what numpy writes");
}

#[test]
fn round_trip_f64_is_exact() {
    let dir = std::env::temp_dir().join(format!("dualphoton-npy64-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("a.npy");
    let v = vec![0.1, -1e-300, f64::MAX, 1.0 / 3.0];
    write_f64(&p, &[4], &v).unwrap();
    let a = read(&p, "test").unwrap();
    assert_eq!((a.shape, a.data, a.element), (vec![4], v, Element::F64));
}

#[test]
fn fortran_order_is_transposed_into_c_order() {
    let c = parse(&npy(1, "<f8", false, "(2, 3, 4)", &le8(&values()))).unwrap();
    let f = parse(&npy(1, "<f8", true, "(2, 3, 4)", &le8(&fortran_values()))).unwrap();
    assert_eq!(c.data, values());
    assert_eq!((f.shape.clone(), f.data.clone()), (c.shape.clone(), c.data.clone()));
    // `np.save(a.T)` writes a's C-order bytes with shape (4, 3, 2), Fortran order.
    let t = parse(&npy(1, "<f8", true, "(4, 3, 2)", &le8(&values()))).unwrap();
    assert_eq!(t.shape, vec![4, 3, 2]);
    for (i, j, k) in (0..4).flat_map(|i| (0..3).flat_map(move |j| (0..2).map(move |k| (i, j, k)))) {
        assert_eq!(t.data[(i * 3 + j) * 2 + k], values()[k * 12 + j * 4 + i]);
    }
    // One axis, or none: Fortran and C order are the same bytes.
    let v = parse(&npy(1, "<f8", true, "(3,)", &le8(&[1.0, 2.0, 3.0]))).unwrap();
    assert_eq!(v.data, vec![1.0, 2.0, 3.0]);
    let s = parse(&npy(1, "<f8", true, "()", &le8(&[2.5]))).unwrap();
    assert_eq!((s.shape, s.data), (vec![], vec![2.5]));
}

#[test]
fn big_endian_reads_the_same_values() {
    let a = parse(&npy(1, ">f8", false, "(2, 3, 4)", &be8(&values()))).unwrap();
    assert_eq!((a.data, a.dtype.as_str(), a.element), (values(), ">f8", Element::F64));
    let b = parse(&npy(1, ">f4", true, "(2, 3, 4)", &be4(&fortran_values()))).unwrap();
    assert_eq!((b.data, b.element), (values(), Element::F32));
    let little = parse(&npy(1, "<f4", false, "(1,)", &0.1f32.to_le_bytes())).unwrap();
    let big = parse(&npy(1, ">f4", false, "(1,)", &0.1f32.to_be_bytes())).unwrap();
    assert_eq!(little.data, big.data);
}

#[test]
fn versions_one_two_and_three_read_alike() {
    let one = parse(&npy(1, "<f8", false, "(2, 3, 4)", &le8(&values()))).unwrap();
    for version in [2, 3] {
        let bytes = npy(version, "<f8", false, "(2, 3, 4)", &le8(&values()));
        assert_eq!(bytes.len() % 8, 0);
        assert_eq!(parse(&bytes).unwrap(), one);
    }
    let mut four = npy(1, "<f8", false, "(1,)", &le8(&[1.0]));
    four[6] = 4;
    assert!(parse(&four).unwrap_err().0.contains("version 4.0"));
}

#[test]
fn bytes_and_booleans() {
    let u = parse(&npy(1, "|u1", false, "(2, 2)", &[0, 1, 7, 255])).unwrap();
    assert_eq!((u.data, u.element), (vec![0.0, 1.0, 7.0, 255.0], Element::U8));
    let b = parse(&npy(1, "|b1", true, "(2, 2)", &[0, 1, 1, 0])).unwrap();
    assert_eq!((b.data, b.element), (vec![0.0, 1.0, 1.0, 0.0], Element::Bool));
    assert!(!b.element.is_float() && Element::F64.is_float());
    let empty = parse(&npy(1, "<f4", false, "(0, 3)", &[])).unwrap();
    assert_eq!((empty.shape, empty.data), (vec![0, 3], vec![]));
}

#[test]
fn sizes_that_do_not_fit_are_errors_not_panics() {
    let huge = npy(1, "<f8", false, "(4294967296, 4294967296, 4294967296)", &[0; 8]);
    assert!(parse(&huge).unwrap_err().0.contains("more elements than"), "product overflows usize");
    let absurd = npy(1, "<f8", false, "(1099511627776,)", &[0; 8]);
    assert!(parse(&absurd).unwrap_err().0.contains("more elements than"), "2^40 elements");
    let short = parse(&npy(1, "<f8", false, "(2, 3)", &le8(&[1.0; 5]))).unwrap_err().0;
    assert!(short.contains("data is 40 bytes") && short.contains("needs 48"), "{short}");
    let long = parse(&npy(1, "<f4", false, "(2,)", &[0; 12])).unwrap_err().0;
    assert!(long.contains("data is 12 bytes") && long.contains("needs 8"), "{long}");
    let mut header = npy(2, "<f8", false, "(1,)", &le8(&[1.0]));
    header[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(parse(&header).unwrap_err().0.contains("header of 4294967295 bytes"));
    let mut cut = npy(1, "<f8", false, "(1,)", &[]);
    cut.truncate(40);
    assert!(parse(&cut).unwrap_err().0.contains("truncated"));
}

#[test]
fn bad_headers_are_errors() {
    assert!(parse(b"hello world, not numpy").unwrap_err().0.contains("not a .npy"));
    for descr in ["<i8", "<f2", "<c16", "|O", "<U3"] {
        let e = parse(&npy(1, descr, false, "(1,)", &[0; 16])).unwrap_err().0;
        assert!(e.contains(descr) && e.contains("not supported"), "{e}");
    }
    let e = parse(&npy(1, "<f8", false, "(2, x)", &[])).unwrap_err().0;
    assert!(e.contains("bad shape (2, x)"), "{e}");
    let mut no_order = b"\x93NUMPY\x01\x00".to_vec();
    let h = "{'descr': '<f8', 'shape': (1,), }\n";
    no_order.extend_from_slice(&(h.len() as u16).to_le_bytes());
    no_order.extend_from_slice(h.as_bytes());
    assert!(parse(&no_order).unwrap_err().0.contains("'fortran_order'"));
}

#[test]
fn read_errors_name_the_field_and_the_file() {
    let dir = std::env::temp_dir().join(format!("dualphoton-npy-read-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("short.npy");
    std::fs::write(&p, npy(1, "<f4", false, "(2, 3, 4)", &[0; 8])).unwrap();
    let e = read(&p, "volume.density").unwrap_err().0;
    assert!(e.starts_with(&format!("volume.density: {}: data is 8 bytes", p.display())), "{e}");
    assert_eq!(e.lines().count(), 1);
    let e = read(&dir.join("missing.npy"), "--target").unwrap_err().0;
    assert!(e.starts_with("--target: ") && e.contains("missing.npy: cannot read"), "{e}");
}
