//! Writing single-band GeoTIFFs: an f32 DEM (heights in metres) or a u8 orthoimage, Deflate
//! compressed, strips, georeferenced by ModelPixelScaleTag + ModelTiepointTag (PixelIsArea)
//! in the CRS of the procedural world ([`super::crs::world_crs_keys`]). Written atomically.

use super::crs::{
    world_crs_keys, TAG_GEO_ASCII_PARAMS, TAG_GEO_DOUBLE_PARAMS, TAG_GEO_KEY_DIRECTORY,
};
use super::georef::{Georeference, TAG_MODEL_PIXEL_SCALE, TAG_MODEL_TIEPOINT};
use crate::fsutil::write_atomic;
use anyhow::Context;
use std::io::Cursor;
use std::path::Path;
use tiff::encoder::colortype::{ColorType, Gray32Float, Gray8};
use tiff::encoder::{Compression, DeflateLevel, TiffEncoder};
use tiff::tags::Tag;

/// Writes a `width x height` DEM (heights in metres, row-major, row 0 north) as a
/// single-band f32 GeoTIFF with georeference `geo` in the world CRS.
pub fn write_dem_f32(
    path: &Path,
    width: usize,
    height: usize,
    heights_m: &[f32],
    geo: &Georeference,
) -> anyhow::Result<()> {
    let bytes = encode::<Gray32Float>(width, height, heights_m, geo)
        .with_context(|| format!("encoding the DEM {}", path.display()))?;
    write_atomic(path, &bytes)
}

/// Writes a `width x height` 8-bit orthoimage (row-major, row 0 north) as a single-band u8
/// GeoTIFF with georeference `geo` in the world CRS.
pub fn write_ortho_u8(
    path: &Path,
    width: usize,
    height: usize,
    gray: &[u8],
    geo: &Georeference,
) -> anyhow::Result<()> {
    let bytes = encode::<Gray8>(width, height, gray, geo)
        .with_context(|| format!("encoding the orthoimage {}", path.display()))?;
    write_atomic(path, &bytes)
}

fn encode<C: ColorType>(
    width: usize,
    height: usize,
    data: &[C::Inner],
    geo: &Georeference,
) -> anyhow::Result<Vec<u8>>
where
    [C::Inner]: tiff::encoder::TiffValue,
{
    anyhow::ensure!(
        width > 0 && height > 0 && data.len() == width * height,
        "raster of {} samples for {width} x {height} pixels",
        data.len()
    );
    let (w, h) = (u32::try_from(width)?, u32::try_from(height)?);
    let mut buf = Cursor::new(Vec::new());
    let mut enc =
        TiffEncoder::new(&mut buf)?.with_compression(Compression::Deflate(DeflateLevel::Balanced));
    let mut img = enc.new_image::<C>(w, h)?;
    let (scale, tie) = geo.to_tags();
    let (dir, doubles, ascii) = world_crs_keys();
    let d = img.encoder();
    d.write_tag(Tag::from_u16_exhaustive(TAG_MODEL_PIXEL_SCALE), &scale[..])?;
    d.write_tag(Tag::from_u16_exhaustive(TAG_MODEL_TIEPOINT), &tie[..])?;
    d.write_tag(Tag::from_u16_exhaustive(TAG_GEO_KEY_DIRECTORY), &dir[..])?;
    d.write_tag(
        Tag::from_u16_exhaustive(TAG_GEO_DOUBLE_PARAMS),
        &doubles[..],
    )?;
    d.write_tag(
        Tag::from_u16_exhaustive(TAG_GEO_ASCII_PARAMS),
        ascii.as_str(),
    )?;
    img.write_data(data)?;
    Ok(buf.into_inner())
}

#[cfg(test)]
mod tests {
    use super::super::{read_geotiff, Crs, SampleKind};
    use super::*;

    #[test]
    fn dem_and_ortho_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let geo = Georeference::new(1500.25, 2600.5, 0.5).unwrap();
        let (w, h) = (7, 5);
        let heights: Vec<f32> = (0..w * h).map(|i| i as f32 * 0.37 - 3.0).collect();
        let dem = dir.path().join("d.tif");
        write_dem_f32(&dem, w, h, &heights, &geo).unwrap();
        let r = read_geotiff(&dem).unwrap();
        assert_eq!((r.width, r.height, r.kind), (w, h, SampleKind::F32));
        assert_eq!(r.values, heights);
        assert_eq!(r.georef, geo);
        assert_eq!(r.crs, Crs::world());
        assert_eq!(r.nodata, None);
        let gray: Vec<u8> = (0..w * h).map(|i| (i * 7 % 256) as u8).collect();
        let ortho = dir.path().join("o.tif");
        write_ortho_u8(&ortho, w, h, &gray, &geo).unwrap();
        let r = read_geotiff(&ortho).unwrap();
        assert_eq!(r.kind, SampleKind::U8);
        assert_eq!(r.values, gray.iter().map(|&g| g as f32).collect::<Vec<_>>());
        assert_eq!(r.get(3, 2), Some(gray[2 * w + 3] as f32));
        assert_eq!(r.get(w, 0), None);
        assert!(write_dem_f32(&dem, w, h, &heights[1..], &geo).is_err());
    }
}
