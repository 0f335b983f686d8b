//! Georeference of north-up rasters (orbital maps, satellite crops, top-down grids).
//!
//! Pixel `(col, row)` has its centre at
//! `x = origin_x_m + (col + 0.5) * m_per_px`, `y = origin_y_m - (row + 0.5) * m_per_px`,
//! where `(origin_x_m, origin_y_m)` is the north-west corner of the raster, in metres.

/// Errors in a georeference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GeoError {
    /// The resolution is zero, negative or not finite.
    BadResolution,
    /// The origin is not finite or beyond [`MAX_ORIGIN_M`].
    BadOrigin,
}

impl core::fmt::Display for GeoError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BadResolution => write!(
                f,
                "the map resolution must be a finite number of metres per pixel above 0"
            ),
            Self::BadOrigin => write!(
                f,
                "the map origin must be finite and within {MAX_ORIGIN_M:.0} m of 0 on each axis"
            ),
        }
    }
}

impl core::error::Error for GeoError {}

/// Largest magnitude of an origin coordinate, metres (10,000 km: beyond any planetary map;
/// far larger values lose every metre of `f32` precision, so a fix there means nothing).
pub const MAX_ORIGIN_M: f32 = 1.0e7;

/// Georeference of a north-up raster: north-west corner and resolution.
///
/// Fields are private: [`GeoRef::new`] (or [`GeoRef::centred`]) is the only way to build
/// one, so the resolution is always finite and positive and the origin finite and within
/// [`MAX_ORIGIN_M`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GeoRef {
    origin_x_m: f32,
    origin_y_m: f32,
    m_per_px: f32,
}

impl GeoRef {
    /// A checked georeference.
    pub fn new(origin_x_m: f32, origin_y_m: f32, m_per_px: f32) -> Result<Self, GeoError> {
        if !(m_per_px.is_finite() && m_per_px > 0.0) {
            return Err(GeoError::BadResolution);
        }
        let ok = |v: f32| v.is_finite() && v.abs() <= MAX_ORIGIN_M;
        if !(ok(origin_x_m) && ok(origin_y_m)) {
            return Err(GeoError::BadOrigin);
        }
        Ok(Self {
            origin_x_m,
            origin_y_m,
            m_per_px,
        })
    }

    /// The georeference of a `width_px x height_px` raster centred on `(x_m, y_m)`.
    pub fn centred(
        x_m: f32,
        y_m: f32,
        width_px: usize,
        height_px: usize,
        m_per_px: f32,
    ) -> Result<Self, GeoError> {
        Self::new(
            x_m - 0.5 * width_px as f32 * m_per_px,
            y_m + 0.5 * height_px as f32 * m_per_px,
            m_per_px,
        )
    }

    /// World `x` (east) of the raster's west edge, metres.
    pub fn origin_x_m(&self) -> f32 {
        self.origin_x_m
    }

    /// World `y` (north) of the raster's north edge, metres.
    pub fn origin_y_m(&self) -> f32 {
        self.origin_y_m
    }

    /// Ground size of one pixel, metres per pixel (finite, positive).
    pub fn m_per_px(&self) -> f32 {
        self.m_per_px
    }

    /// World coordinates (metres) of continuous pixel coordinates `(col, row)`
    /// (pixel centres are at `+0.5`).
    pub fn to_world(&self, col: f32, row: f32) -> (f32, f32) {
        (
            self.origin_x_m + col * self.m_per_px,
            self.origin_y_m - row * self.m_per_px,
        )
    }

    /// Continuous pixel coordinates `(col, row)` of a world point (metres).
    pub fn to_pixel(&self, x_m: f32, y_m: f32) -> (f32, f32) {
        (
            (x_m - self.origin_x_m) / self.m_per_px,
            (self.origin_y_m - y_m) / self.m_per_px,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_centre() {
        let g = GeoRef::centred(100.0, 200.0, 200, 200, 0.25).unwrap();
        assert_eq!(g.origin_x_m(), 75.0);
        assert_eq!(g.origin_y_m(), 225.0);
        let (c, r) = g.to_pixel(100.0, 200.0);
        assert_eq!((c, r), (100.0, 100.0));
        let (x, y) = g.to_world(0.5, 0.5);
        assert_eq!((x, y), (75.125, 224.875));
        assert_eq!(GeoRef::new(0.0, 0.0, 0.0), Err(GeoError::BadResolution));
        assert_eq!(GeoRef::new(f32::NAN, 0.0, 1.0), Err(GeoError::BadOrigin));
        assert_eq!(GeoRef::new(1e38, 0.0, 1.0), Err(GeoError::BadOrigin));
        assert_eq!(GeoRef::new(0.0, -1e8, 1.0), Err(GeoError::BadOrigin));
        assert_eq!(GeoRef::new(0.0, 0.0, -0.25), Err(GeoError::BadResolution));
        assert!(GeoRef::new(-MAX_ORIGIN_M, MAX_ORIGIN_M, 0.25).is_ok());
    }
}
