//! Satellite crops: a square orthographic north-up image centred on a point, with its
//! georeference.

use super::{ortho, terrain, RenderError, RenderOptions, Sun, Surface};
use image::GrayImage;
use orbfix::geo::GeoRef;

/// A satellite crop `size_px x size_px` centred on `(x_m, y_m)` (`docs/frames.md`).
pub fn render_satellite_crop(
    world: &dyn Surface,
    x_m: f64,
    y_m: f64,
    size_px: u32,
    m_per_px: f64,
    sun: Sun,
    opts: &RenderOptions,
) -> Result<(GrayImage, GeoRef), RenderError> {
    render_satellite_crop_cached(world, x_m, y_m, size_px, m_per_px, sun, opts, None)
}

/// As [`render_satellite_crop`], sharing coarse terrain through `cache` (identical results).
#[allow(clippy::too_many_arguments)]
pub fn render_satellite_crop_cached(
    world: &dyn Surface,
    x_m: f64,
    y_m: f64,
    size_px: u32,
    m_per_px: f64,
    sun: Sun,
    opts: &RenderOptions,
    cache: Option<&terrain::TileCache>,
) -> Result<(GrayImage, GeoRef), RenderError> {
    let geo = GeoRef::centred(
        x_m as f32,
        y_m as f32,
        size_px as usize,
        size_px as usize,
        m_per_px as f32,
    )
    .map_err(|e| RenderError::Option(format!("bad satellite georeference: {e}")))?;
    let img = ortho::render_ortho_cached(world, &geo, size_px, size_px, sun, opts, cache)?;
    Ok((img, geo))
}
