//! Loads a real ScalarFlow density frame (Eckert et al. 2019) as ground
//! truth, in place of the built-in plume.
//!
//! A ScalarFlow frame is an `.npz` archive (`np.savez` or
//! `np.savez_compressed`: a zip, members stored or deflated) holding one
//! array under the key `data` (member `data.npy`): float32 or float64,
//! either byte order, C or Fortran order, shape `(z, y, x, 1)` or
//! `(z, y, x)`, y up, cubic cells, density in arbitrary units. The frames of the data set are 100 x 178 x 100
//! cells (x, y, z), stored as `(178, ...)` on axis 1.
//!
//! The frame's box is fitted into the unit cube `[-0.5, 0.5]^3` keeping its
//! aspect ratio: the longest axis spans `[-0.5, 0.5]`, the others are
//! centred (a 100 x 178 x 100 frame fills `|x|, |z| <= 0.281`). The frame is
//! resampled trilinearly at the voxel centres of a `(res, res, res)` grid,
//! both grids cell-centred like every density grid (no smoothing first, so below
//! the frame's resolution thin wisps may alias). Densities are then scaled
//! so that the largest voxel is exactly [`PLUME_MAX`] (1.36, the scale of
//! the built-in plume and of the paper's ground truth; the frame's own
//! units are arbitrary), and values below [`CUTOFF`] are set to 0.

use super::plume::{CUTOFF, PLUME_MAX};
use crate::error::{Error, Result};
use crate::io::npy::{self, Array};
use crate::math::Vec3;
use crate::volume::Grid;
use rayon::prelude::*;
use std::io::Read;
use std::path::Path;

/// The ScalarFlow frame at `path` on a `(res, res, res)` grid over
/// `[-0.5, 0.5]^3`: aspect kept, max exactly [`PLUME_MAX`], values below
/// [`CUTOFF`] set to 0 (see the module notes). Errors name the file and the
/// problem: unreadable, not a zip, no `data` member, not float32/float64, a
/// shape other than `(z, y, x[, 1])`, NaN/Inf or negative values, nothing
/// but zeros, `res = 0`.
///
/// ```no_run
/// use dualphoton::data::scalarflow::load_scalarflow;
/// let g = load_scalarflow(std::path::Path::new("density_000080.npz"), 64)?;
/// assert_eq!(g.shape, [64, 64, 64]);
/// # Ok::<(), dualphoton::Error>(())
/// ```
pub fn load_scalarflow(path: &Path, res: usize) -> Result<Grid<f64>> {
    let fail = |msg: String| Error(format!("ScalarFlow frame {}: {msg}", crate::error::show(path)));
    if res == 0 {
        return Err(fail("resolution 0 (need at least 1 voxel per axis)".into()));
    }
    if res.checked_pow(3).is_none_or(|n| n > npy::MAX_ELEMENTS) {
        return Err(fail(format!(
            "resolution {res}: a {res}^3 grid is more than the {} voxels allowed",
            npy::MAX_ELEMENTS
        )));
    }
    // A compressed archive is smaller than what it holds: no valid one is larger.
    let bytes = npy::read_bounded(path, npy::max_file_bytes()).map_err(fail)?;
    let frame = data_member(&bytes).and_then(frame_grid).map_err(fail)?;
    let mut grid = resample(&frame, res);
    let max = grid.max_value();
    if max <= 0.0 {
        return Err(fail(format!("no density at the voxel centres of a {res}^3 grid (try a finer resolution)")));
    }
    let scale = PLUME_MAX / max;
    for v in grid.data.iter_mut() {
        *v = if *v * scale < CUTOFF { 0.0 } else { *v * scale };
    }
    Ok(grid)
}

/// The `data` array of an `.npz` archive.
fn data_member(bytes: &[u8]) -> std::result::Result<Array, String> {
    let mut zip =
        zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| format!("not an .npz (zip) archive: {e}"))?;
    let Some(name) = ["data.npy", "data"].into_iter().find(|n| zip.index_for_name(n).is_some()) else {
        let names: Vec<&str> = zip.file_names().take(8).collect();
        return Err(format!("no array 'data' in the archive (members: {})", names.join(", ")));
    };
    let mut member = zip.by_name(name).map_err(|e| format!("cannot open {name}: {e}"))?;
    // Decompress the header alone first: a 4 MB archive may claim a 1024^3
    // array (8 GB). Its declared size is checked against MAX_ELEMENTS before
    // the rest is decompressed, and no more than that size is ever taken.
    let mut npy_bytes = Vec::new();
    let prefix = (12 + npy::MAX_HEADER) as u64;
    let cannot = |e: std::io::Error| format!("cannot decompress {name}: {e}");
    member.by_ref().take(prefix).read_to_end(&mut npy_bytes).map_err(cannot)?;
    let d = npy::declared(&npy_bytes).map_err(|e| format!("{name}: {}", e.0))?;
    let total = d.header_end + d.data_bytes;
    let rest = (total as u64 + 1).saturating_sub(npy_bytes.len() as u64);
    member.take(rest).read_to_end(&mut npy_bytes).map_err(cannot)?;
    npy::parse(&npy_bytes).map_err(|e| format!("{name}: {}", e.0))
}

/// The checked frame as a grid on its box fitted into the unit cube.
fn frame_grid(array: Array) -> std::result::Result<Grid<f64>, String> {
    if !array.element.is_float() {
        return Err(format!("dtype {} is not float32 or float64", array.dtype));
    }
    let shape = match array.shape[..] {
        [z, y, x] | [z, y, x, 1] => [z, y, x],
        _ => return Err(format!("shape {:?} is not (z, y, x, 1) or (z, y, x)", array.shape)),
    };
    if shape.contains(&0) {
        return Err(format!("shape {:?} is empty", array.shape));
    }
    if let Some(n) = array.data.iter().position(|v| !v.is_finite() || *v < 0.0) {
        let (k, j, i) = (n / (shape[1] * shape[2]), (n / shape[2]) % shape[1], n % shape[2]);
        return Err(format!(
            "density at (z, y, x) = ({k}, {j}, {i}) is {}: densities must be finite and non-negative",
            array.data[n]
        ));
    }
    if array.data.iter().all(|&v| v == 0.0) {
        return Err("the frame is all zero".into());
    }
    let (lo, hi) = fitted_box(shape);
    Ok(Grid::new(lo, hi, shape, array.data))
}

/// The box of a frame of `shape = [nz, ny, nx]` cubic cells fitted into
/// `[-0.5, 0.5]^3`: the longest axis spans it, the others are centred.
fn fitted_box(shape: [usize; 3]) -> (Vec3, Vec3) {
    let longest = *shape.iter().max().unwrap() as f64;
    let half = Vec3::new(shape[2] as f64, shape[1] as f64, shape[0] as f64) / (2.0 * longest);
    (-half, half)
}

/// `frame` sampled trilinearly at the voxel centres of a `(res, res, res)`
/// grid over `[-0.5, 0.5]^3` (0 outside the frame's box).
fn resample(frame: &Grid<f64>, res: usize) -> Grid<f64> {
    let lo = Vec3::from_element(-0.5);
    let mut grid = Grid::new(lo, -lo, [res; 3], vec![0.0; res * res * res]);
    let h = 1.0 / res as f64;
    grid.data.par_chunks_mut(res).enumerate().for_each(|(row, out)| {
        let (k, j) = (row / res, row % res);
        for (i, v) in out.iter_mut().enumerate() {
            *v = frame.at(&(lo + Vec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * h));
        }
    });
    grid
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use zip::write::SimpleFileOptions;
    use zip::CompressionMethod;

    /// A fresh path in the temp directory for this test process.
    fn temp(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("dualphoton-scalarflow-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    /// The bytes of a float32 `.npy` written by the crate's own writer.
    fn npy_f32(shape: &[usize], data: &[f64]) -> Vec<u8> {
        let p = temp(&format!("a-{}.npy", shape.iter().map(|s| s.to_string()).collect::<Vec<_>>().join("x")));
        npy::write_f32(&p, shape, data).unwrap();
        std::fs::read(&p).unwrap()
    }

    /// The bytes of a float64 `.npy` (format version 1.0).
    fn npy_f64(shape: &[usize], data: &[f64]) -> Vec<u8> {
        let dims: Vec<String> = shape.iter().map(|s| s.to_string()).collect();
        let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({}), }}", dims.join(", "));
        header.push_str(&" ".repeat((64 - (10 + header.len() + 1) % 64) % 64));
        header.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        data.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        out
    }

    /// Writes an `.npz` holding `members` (name, bytes) and returns its path.
    fn npz(name: &str, members: &[(&str, &[u8])], method: CompressionMethod) -> std::path::PathBuf {
        let path = temp(name);
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
        for (member, bytes) in members {
            zip.start_file(*member, SimpleFileOptions::default().compression_method(method)).unwrap();
            zip.write_all(bytes).unwrap();
        }
        zip.finish().unwrap();
        path
    }

    /// A ScalarFlow-shaped frame (z, y, x) = (10, 18, 10) holding a Gaussian
    /// blob at its centre plus a faint spot near the top corner.
    fn frame() -> ([usize; 4], Vec<f64>) {
        let (nz, ny, nx) = (10, 18, 10);
        let mut data = vec![0.0; nz * ny * nx];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let d = Vec3::new(i as f64 + 0.5 - 5.0, j as f64 + 0.5 - 9.0, k as f64 + 0.5 - 5.0);
                    data[(k * ny + j) * nx + i] = 3.0 * (-d.norm_squared() / 4.0).exp();
                }
            }
        }
        data[(ny - 2) * nx] = 0.5; // (k, j, i) = (0, 16, 0)
        ([nz, ny, nx, 1], data)
    }

    #[test]
    fn fits_the_frame_and_keeps_its_centre() {
        let (shape, data) = frame();
        let bytes = npy_f32(&shape, &data);
        let stored =
            load_scalarflow(&npz("stored.npz", &[("data.npy", &bytes)], CompressionMethod::Stored), 18).unwrap();
        let deflated =
            load_scalarflow(&npz("deflated.npz", &[("data.npy", &bytes)], CompressionMethod::Deflated), 18).unwrap();
        assert_eq!(stored.shape, [18, 18, 18]);
        assert_eq!(stored.data, deflated.data);
        // At res 18 the output voxels are the frame's (cubic cells, 1/18 wide),
        // shifted by 4 in x and z: values are the frame's, scaled to PLUME_MAX.
        let scale = PLUME_MAX / 3.0 / (-3.0f64 * 0.25 / 4.0).exp();
        for (n, v) in data.iter().enumerate() {
            let (k, j, i) = (n / 180, (n / 10) % 18, n % 10);
            let want = if v * scale < CUTOFF { 0.0 } else { v * scale };
            let got = stored.data[stored.index(k + 4, j, i + 4)];
            assert!((got - want).abs() < 1e-6 * PLUME_MAX, "({k}, {j}, {i}): {got} vs {want}");
        }
        assert!((stored.max_value() - PLUME_MAX).abs() < 1e-9);
        // Outside the frame's box (|x| or |z| > 5/18) everything is 0.
        for k in 0..18 {
            for j in 0..18 {
                for i in 0..18 {
                    if !(4..14).contains(&i) || !(4..14).contains(&k) {
                        assert_eq!(stored.data[stored.index(k, j, i)], 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn blob_at_the_frames_centre_lands_at_the_grids_centre() {
        let (shape, mut data) = frame();
        data[16 * 10] = 0.0; // drop the faint spot: only the symmetric blob
        let path = npz("blob.npz", &[("data.npy", &npy_f64(&shape[..3], &data))], CompressionMethod::Deflated);
        let g = load_scalarflow(&path, 31).unwrap();
        let (mut sum, mut mass) = (Vec3::zeros(), 0.0);
        for k in 0..31 {
            for j in 0..31 {
                for i in 0..31 {
                    let v = g.data[g.index(k, j, i)];
                    sum += g.voxel_center(k, j, i) * v;
                    mass += v;
                }
            }
        }
        assert!((sum / mass).norm() < 1e-9, "{:?}", sum / mass);
        assert!((g.data[g.index(15, 15, 15)] - PLUME_MAX).abs() < 1e-12);
        assert!(g.data.iter().all(|&v| v == 0.0 || (CUTOFF..=PLUME_MAX).contains(&v)));
    }

    /// The error for an archive holding `members`, which must name the file and contain `what`.
    fn fails_with(name: &str, members: &[(&str, &[u8])], what: &str) {
        let path = npz(name, members, CompressionMethod::Deflated);
        let e = load_scalarflow(&path, 8).unwrap_err().0;
        assert!(e.contains(&path.display().to_string()) && e.contains(what), "{e}");
    }

    #[test]
    fn errors_name_the_file_and_the_problem() {
        let good = npy_f32(&[2, 3, 4, 1], &[1.0; 24]);
        let mut nan = vec![1.0; 24];
        nan[5] = f64::NAN;
        let mut negative = vec![1.0; 24];
        negative[7] = -0.5;
        let mut inf = vec![1.0; 24];
        inf[0] = f64::INFINITY;
        let u8_path = temp("u8.npy");
        npy::write_u8(&u8_path, &[2, 3, 4], &[1; 24]).unwrap();
        let u8_bytes = std::fs::read(&u8_path).unwrap();

        fails_with("other.npz", &[("density.npy", &good)], "no array 'data'");
        fails_with("ndim.npz", &[("data.npy", &npy_f32(&[6, 4], &[1.0; 24]))], "shape [6, 4]");
        fails_with("channels.npz", &[("data.npy", &npy_f32(&[2, 3, 2, 2], &[1.0; 24]))], "shape [2, 3, 2, 2]");
        fails_with("empty.npz", &[("data.npy", &npy_f32(&[2, 0, 4], &[]))], "empty");
        fails_with("dtype.npz", &[("data.npy", &u8_bytes)], "dtype |u1");
        fails_with("nan.npz", &[("data.npy", &npy_f32(&[2, 3, 4, 1], &nan))], "(0, 1, 1) is NaN");
        fails_with("inf.npz", &[("data.npy", &npy_f32(&[2, 3, 4, 1], &inf))], "is inf");
        fails_with("negative.npz", &[("data.npy", &npy_f32(&[2, 3, 4], &negative))], "is -0.5");
        fails_with("zero.npz", &[("data.npy", &npy_f32(&[2, 3, 4], &[0.0; 24]))], "all zero");
        fails_with("garbage.npz", &[("data.npy", b"not numpy")], "data.npy: not a .npy");

        let not_zip = temp("not-zip.npz");
        std::fs::write(&not_zip, b"PK but not really a zip archive").unwrap();
        let e = load_scalarflow(&not_zip, 8).unwrap_err().0;
        assert!(e.contains("not-zip.npz") && e.contains("not an .npz (zip) archive"), "{e}");
        let e = load_scalarflow(&temp("missing.npz"), 8).unwrap_err().0;
        assert!(e.contains("missing.npz") && e.contains("cannot read"), "{e}");
        let ok = npz("ok.npz", &[("data.npy", &good)], CompressionMethod::Stored);
        assert!(load_scalarflow(&ok, 0).unwrap_err().0.contains("resolution 0"));
        assert_eq!(load_scalarflow(&ok, 4).unwrap().max_value(), PLUME_MAX);
    }
}
