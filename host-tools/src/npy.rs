//! NumPy `.npy` int8 arrays in and out (the `npyz` crate), for `orbfix embed` and the tools
//! that compare embeddings with other runtimes.

use anyhow::{bail, ensure, Context, Result};
use npyz::WriterBuilder;

/// A C-order int8 array.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct I8Array {
    /// Dimensions, outermost first.
    pub shape: Vec<usize>,
    /// Elements in C (row-major) order, `shape.iter().product()` of them.
    pub data: Vec<i8>,
}

/// Reads a `.npy` file's bytes as an int8 array; `what` names the file in errors.
///
/// Errors (sentences that say what to fix): not a `.npy` file, a dtype other than int8
/// (`|i1`), Fortran order, or fewer data bytes than the header declares.
pub fn read_i8(bytes: &[u8], what: &str) -> Result<I8Array> {
    let npy = npyz::NpyFile::new(bytes)
        .with_context(|| format!("{what} is not a NumPy .npy file (write it with numpy.save)"))?;
    let dtype = npy.dtype();
    let int8 = matches!(&dtype, npyz::DType::Plain(t) if t.type_char() == npyz::TypeChar::Int && t.size_field() == 1);
    if !int8 {
        bail!(
            "{what} has dtype {}, not int8: convert it with array.astype(numpy.int8)",
            dtype.descr()
        );
    }
    ensure!(
        npy.order() == npyz::Order::C || npy.shape().len() <= 1,
        "{what} is in Fortran order: save numpy.ascontiguousarray(array) instead"
    );
    let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let n: usize = shape.iter().product();
    let data: Vec<i8> = npy.into_vec().with_context(|| {
        format!("{what} is truncated: its header declares shape {shape:?} ({n} int8 values)")
    })?;
    ensure!(
        data.len() == n,
        "{what} holds {} values where its shape {shape:?} needs {n}",
        data.len()
    );
    Ok(I8Array { shape, data })
}

/// Encodes `data` (C order) with `shape` as `.npy` bytes (dtype `|i1`).
pub fn write_i8(shape: &[usize], data: &[i8]) -> Result<Vec<u8>> {
    let n: usize = shape.iter().product();
    ensure!(
        data.len() == n,
        "internal: {} values for shape {shape:?}",
        data.len()
    );
    let mut buf = Vec::with_capacity(n + 128);
    let dims: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
    let mut w = npyz::WriteOptions::<i8>::new()
        .default_dtype()
        .shape(&dims)
        .writer(&mut buf)
        .begin_nd()?;
    w.extend(data.iter().copied())?;
    w.finish()?;
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let data: Vec<i8> = (0..24).map(|v| (v * 11 - 128) as i8).collect();
        let bytes = write_i8(&[2, 3, 4], &data).unwrap();
        assert_eq!(&bytes[..6], b"\x93NUMPY");
        let back = read_i8(&bytes, "x.npy").unwrap();
        assert_eq!(back.shape, vec![2, 3, 4]);
        assert_eq!(back.data, data);
    }

    #[test]
    fn bad_files_are_clear_errors() {
        let bytes = write_i8(&[4, 8], &[3; 32]).unwrap();
        let e = read_i8(&bytes[..bytes.len() - 5], "t.npy").unwrap_err();
        assert!(format!("{e:#}").contains("truncated"), "{e:#}");
        let e = read_i8(b"not numpy at all", "t.npy").unwrap_err();
        assert!(format!("{e:#}").contains("not a NumPy"), "{e:#}");
        let mut buf = Vec::new();
        let mut w = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[2])
            .writer(&mut buf)
            .begin_nd()
            .unwrap();
        w.extend([1.0f32, 2.0]).unwrap();
        w.finish().unwrap();
        let e = read_i8(&buf, "f.npy").unwrap_err();
        assert!(format!("{e:#}").contains("not int8"), "{e:#}");
        let mut buf = Vec::new();
        let mut w = npyz::WriteOptions::<u8>::new()
            .default_dtype()
            .shape(&[2])
            .writer(&mut buf)
            .begin_nd()
            .unwrap();
        w.extend([1u8, 2]).unwrap();
        w.finish().unwrap();
        assert!(read_i8(&buf, "u.npy").is_err());
    }
}
