//! Reading one single-band GeoTIFF raster: u8, u16, i16 or f32 samples, in strips or tiles,
//! any compression the `tiff` crate decodes (none, LZW, Deflate, PackBits, JPEG), with its
//! georeference ([`super::georef`]), CRS ([`super::crs`]) and GDAL no-data value.

use super::crs::{GeoKeys, TAG_GEO_ASCII_PARAMS, TAG_GEO_DOUBLE_PARAMS, TAG_GEO_KEY_DIRECTORY};
use super::georef::{
    Georeference, TAG_MODEL_PIXEL_SCALE, TAG_MODEL_TIEPOINT, TAG_MODEL_TRANSFORMATION,
};
use super::{Crs, GeoTiffError};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

/// Largest raster read, pixels (2^28: 1 GiB of `f32`).
pub const MAX_PIXELS: u64 = 1 << 28;

/// The TIFF tag GDAL stores the no-data value in (ASCII).
const TAG_GDAL_NODATA: u16 = 42113;

/// Sample type of the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// Unsigned 8-bit (orthoimages).
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit (integer DEMs).
    I16,
    /// 32-bit float (DEMs).
    F32,
}

/// A single-band georeferenced raster, row-major, row 0 north.
#[derive(Clone, Debug)]
pub struct GeoRaster {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Sample values as `f32` (exact for every supported type), `height * width`.
    pub values: Vec<f32>,
    /// Sample type in the file.
    pub kind: SampleKind,
    /// North-west corner and pixel size, metres.
    pub georef: Georeference,
    /// The projected CRS.
    pub crs: Crs,
    /// GDAL's no-data value (TIFF tag 42113), if the file has one.
    pub nodata: Option<f64>,
}

impl GeoRaster {
    /// The value of pixel `(col, row)`, `None` outside or where it is no-data (or NaN).
    pub fn get(&self, col: usize, row: usize) -> Option<f32> {
        if col >= self.width || row >= self.height {
            return None;
        }
        let v = self.values[row * self.width + col];
        (!self.is_nodata(v)).then_some(v)
    }

    /// Whether `v` is the no-data value (NaN always is).
    pub fn is_nodata(&self, v: f32) -> bool {
        v.is_nan() || self.nodata.is_some_and(|n| v as f64 == n)
    }
}

/// Reads a single-band GeoTIFF. Refuses, saying what is supported: several bands or a
/// palette, sample types other than u8/u16/i16/f32, rasters without a georeference or with
/// rotation, non-projected or non-metric CRSs.
pub fn read_geotiff(path: &Path) -> Result<GeoRaster, GeoTiffError> {
    let p = path.display().to_string();
    let tiff_err = |source| GeoTiffError::Tiff {
        path: p.clone(),
        source,
    };
    let unsupported = |what: String| GeoTiffError::Unsupported {
        path: p.clone(),
        what,
    };
    let file = std::fs::File::open(path).map_err(|source| GeoTiffError::Io {
        path: p.clone(),
        source,
    })?;
    let mut limits = Limits::default();
    limits.decoding_buffer_size = (MAX_PIXELS * 4) as usize;
    limits.ifd_value_size = 16 << 20;
    let mut dec = Decoder::new(std::io::BufReader::new(file))
        .map_err(tiff_err)?
        .with_limits(limits);
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    if w as u64 * h as u64 > MAX_PIXELS {
        return Err(unsupported(format!(
            "{w} x {h} pixels is more than orbfix reads at once (2^28); cut a region with \
             gdal_translate -srcwin"
        )));
    }
    match dec.colortype().map_err(tiff_err)? {
        ColorType::Gray(_) => {}
        ColorType::Multiband { num_samples, .. } => {
            return Err(unsupported(format!(
                "{num_samples} bands: orbfix reads single-band rasters; extract one with \
                 gdal_translate -b 1"
            )))
        }
        other => {
            return Err(unsupported(format!(
                "colour type {other:?}: orbfix reads single-band gray rasters (DEM heights \
                 or an orthoimage); extract one band with gdal_translate -b 1"
            )))
        }
    }
    let f64s = |dec: &mut Decoder<_>, tag: u16| -> Result<Option<Vec<f64>>, GeoTiffError> {
        match dec.find_tag(Tag::from_u16_exhaustive(tag)) {
            Ok(Some(v)) => v.into_f64_vec().map(Some).map_err(tiff_err),
            Ok(None) => Ok(None),
            Err(e) => Err(tiff_err(e)),
        }
    };
    let scale = f64s(&mut dec, TAG_MODEL_PIXEL_SCALE)?;
    let ties = f64s(&mut dec, TAG_MODEL_TIEPOINT)?;
    let transform = f64s(&mut dec, TAG_MODEL_TRANSFORMATION)?;
    let dir = match dec.find_tag(Tag::from_u16_exhaustive(TAG_GEO_KEY_DIRECTORY)) {
        Ok(Some(v)) => v.into_u16_vec().map_err(tiff_err)?,
        Ok(None) => {
            return Err(unsupported(
                "no GeoKeyDirectoryTag (34735), so no CRS: orbfix reads GeoTIFFs in a \
                 projected CRS in metres; assign one with gdal_edit.py -a_srs"
                    .into(),
            ))
        }
        Err(e) => return Err(tiff_err(e)),
    };
    let doubles = f64s(&mut dec, TAG_GEO_DOUBLE_PARAMS)?.unwrap_or_default();
    let ascii = match dec.find_tag(Tag::from_u16_exhaustive(TAG_GEO_ASCII_PARAMS)) {
        Ok(Some(v)) => v.into_string().map_err(tiff_err)?,
        Ok(None) => String::new(),
        Err(e) => return Err(tiff_err(e)),
    };
    let keys = GeoKeys::parse(&dir, &doubles, &ascii).map_err(unsupported)?;
    let crs = Crs::from_keys(&keys).map_err(unsupported)?;
    let georef = Georeference::from_tags(
        scale.as_deref(),
        ties.as_deref(),
        transform.as_deref(),
        crs.raster_type,
    )
    .map_err(unsupported)?;
    let nodata =
        match dec.find_tag(Tag::from_u16_exhaustive(TAG_GDAL_NODATA)) {
            Ok(Some(v)) => {
                let s = v.into_string().map_err(tiff_err)?;
                let t = s.trim_matches(|c: char| c.is_whitespace() || c == '\0');
                Some(t.parse::<f64>().map_err(|_| {
                    unsupported(format!("GDAL no-data value '{t}' is not a number"))
                })?)
            }
            Ok(None) => None,
            Err(e) => return Err(tiff_err(e)),
        };
    let (values, kind) = match dec.read_image().map_err(tiff_err)? {
        DecodingResult::U8(v) => (v.into_iter().map(f32::from).collect(), SampleKind::U8),
        DecodingResult::U16(v) => (v.into_iter().map(f32::from).collect(), SampleKind::U16),
        DecodingResult::I16(v) => (v.into_iter().map(f32::from).collect(), SampleKind::I16),
        DecodingResult::F32(v) => (v, SampleKind::F32),
        other => {
            let name = match other {
                DecodingResult::U32(_) => "u32",
                DecodingResult::U64(_) => "u64",
                DecodingResult::F16(_) => "f16",
                DecodingResult::F64(_) => "f64",
                DecodingResult::I8(_) => "i8",
                DecodingResult::I32(_) => "i32",
                DecodingResult::I64(_) => "i64",
                _ => "this",
            };
            return Err(unsupported(format!(
                "{name} samples: orbfix reads u8, u16, i16 or f32 samples; convert with \
                 gdal_translate -ot Float32"
            )));
        }
    };
    let (width, height) = (w as usize, h as usize);
    if values.len() != width * height {
        return Err(unsupported(format!(
            "decoded {} samples for {width} x {height} pixels (one band expected)",
            values.len()
        )));
    }
    Ok(GeoRaster {
        width,
        height,
        values,
        kind,
        georef,
        crs,
        nodata,
    })
}
