//! The orbital map region of a query: rendered under the map's sun, or a DEM site's
//! orthoimage resampled to the grid.

use crate::eval::MapRegion;
use crate::render::{self, RenderOptions, Sun};
use crate::world::World;
use anyhow::Context;
use orbfix::geo::GeoRef;

/// The `size_px x size_px` orbital map region centred on `(cx, cy)` metres: rendered under
/// `sun`, or for a DEM world whose map source is [`crate::world::dem::MapSource::Ortho`] (the
/// default) the orthoimage itself resampled to the grid (`sun` and `opts` then unused).
pub fn map_region(
    world: &World,
    cx: f64,
    cy: f64,
    size_px: usize,
    m_per_px: f64,
    sun: Sun,
    opts: &RenderOptions,
) -> anyhow::Result<MapRegion> {
    if let Some(dem) = world
        .dem()
        .filter(|d| d.map_source() == crate::world::dem::MapSource::Ortho)
    {
        let geo = GeoRef::centred(cx as f32, cy as f32, size_px, size_px, m_per_px as f32)
            .map_err(|e| {
                anyhow::anyhow!("bad map georeference around ({cx:.1}, {cy:.1}) m: {e}")
            })?;
        return Ok(MapRegion {
            width: size_px,
            height: size_px,
            image: dem.ortho_map(&geo, size_px, size_px),
            geo,
        });
    }
    let (img, geo) =
        render::render_satellite_crop(world, cx, cy, size_px as u32, m_per_px, sun, opts)
            .with_context(|| format!("rendering the map around ({cx:.1}, {cy:.1}) m"))?;
    Ok(MapRegion {
        width: img.width() as usize,
        height: img.height() as usize,
        image: img.into_raw(),
        geo,
    })
}
