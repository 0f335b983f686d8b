//! GeoTIFF in and out: single-band rasters (DEMs, orthoimages) georeferenced in a projected
//! CRS in metres, mapped to the core's [`orbfix::geo::GeoRef`] (north-west corner, metres per
//! pixel). What is supported and what is refused: `docs/interop.md`.
//!
//! - [`georef`]: the raster-to-model tags (ModelPixelScale + ModelTiepoint, or
//!   ModelTransformation without rotation; PixelIsArea / PixelIsPoint).
//! - [`crs`]: the GeoKey directory and the CRS it describes (projected, metres), and the CRS
//!   orbfix writes for its procedural world (IAU_2015:30110, Moon equirectangular).
//! - [`read`]: one single-band raster (u8, u16, i16, f32 samples; strips or tiles).
//! - [`write`]: a single-band f32 DEM or u8 orthoimage with those tags.

pub mod crs;
pub mod georef;
pub mod read;
pub mod write;

pub use crs::Crs;
pub use georef::Georeference;
pub use read::{read_geotiff, GeoRaster, SampleKind};
pub use write::{write_dem_f32, write_ortho_u8};

/// What was wrong with a GeoTIFF, and what orbfix supports instead.
#[derive(Debug, thiserror::Error)]
pub enum GeoTiffError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The TIFF decoder or encoder failed.
    #[error("{path}: not a readable TIFF ({source})")]
    Tiff {
        /// The file.
        path: String,
        /// The cause.
        source: tiff::TiffError,
    },
    /// A TIFF or GeoTIFF feature orbfix does not support.
    #[error("{path}: {what}")]
    Unsupported {
        /// The file.
        path: String,
        /// What is unsupported and what is supported instead.
        what: String,
    },
}
