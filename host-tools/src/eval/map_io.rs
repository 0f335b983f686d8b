//! Map regions on disk: `MAP.png` + its georeference sidecar `MAP.json`, and the atomic
//! writes of eval's outputs.

use super::MapRegion;
use anyhow::{bail, Context};
use orbfix::geo::GeoRef;
use serde::{Deserialize, Serialize};

/// Map georeference sidecar (`MAP.json` next to `MAP.png`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MapMeta {
    /// World east of the map's west edge, metres.
    pub origin_x_m: f64,
    /// World north of the map's north edge, metres.
    pub origin_y_m: f64,
    /// Metres per pixel.
    pub m_per_px: f64,
    /// Width, pixels (checked against the PNG).
    pub width_px: usize,
    /// Height, pixels (checked against the PNG).
    pub height_px: usize,
    /// World seed the map was rendered from, if any.
    #[serde(default)]
    pub world_seed: Option<u64>,
    /// Sun elevation and azimuth of the render, degrees, if any.
    #[serde(default)]
    pub sun_deg: Option<(f64, f64)>,
    /// For a map of a DEM world (`orbfix map --dem`): what to add to world `(x, y)` to get
    /// the GeoTIFFs' CRS `(easting, northing)`, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs_offset_m: Option<(f64, f64)>,
}

/// Loads `MAP.png` + `MAP.json`, checking the georeference and sizes.
pub fn load_map(png: &std::path::Path, meta: &std::path::Path) -> anyhow::Result<MapRegion> {
    let text = std::fs::read_to_string(meta).with_context(|| {
        format!(
            "cannot read the map georeference {} (write one with `orbfix map`)",
            meta.display()
        )
    })?;
    let m: MapMeta = serde_json::from_str(&text).with_context(|| {
        format!(
            "{} is not a map georeference (needs origin_x_m, origin_y_m, m_per_px, width_px, height_px)",
            meta.display()
        )
    })?;
    let geo = GeoRef::new(m.origin_x_m as f32, m.origin_y_m as f32, m.m_per_px as f32)
        .map_err(|e| anyhow::anyhow!("{}: bad georeference: {e}", meta.display()))?;
    let img = image::open(png)
        .with_context(|| format!("cannot read the map image {}", png.display()))?
        .to_luma8();
    if img.width() as usize != m.width_px || img.height() as usize != m.height_px {
        bail!(
            "{} is {} x {} px but {} says {} x {}",
            png.display(),
            img.width(),
            img.height(),
            meta.display(),
            m.width_px,
            m.height_px
        );
    }
    Ok(MapRegion {
        width: img.width() as usize,
        height: img.height() as usize,
        image: img.into_raw(),
        geo,
    })
}

/// Writes `bytes` to `path` atomically, only to a regular file or `-` (the one
/// implementation: [`crate::fsutil::write_atomic`]); creates the parent folder first.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    crate::fsutil::write_atomic(path, bytes)
}

/// Saves a gray or RGB image as PNG atomically.
pub fn save_png_atomic<P, C>(
    img: &image::ImageBuffer<P, C>,
    path: &std::path::Path,
) -> anyhow::Result<()>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png)
        .with_context(|| format!("cannot encode {}", path.display()))?;
    write_atomic(path, buf.get_ref())
}
