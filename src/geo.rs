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
    /// The origin is not finite.
    BadOrigin,
}

/// Georeference of a north-up raster: north-west corner and resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GeoRef {
    /// World `x` (east) of the raster's west edge, metres.
    pub origin_x_m: f32,
    /// World `y` (north) of the raster's north edge, metres.
    pub origin_y_m: f32,
    /// Ground size of one pixel, metres per pixel.
    pub m_per_px: f32,
}

impl GeoRef {
    /// A checked georeference.
    pub fn new(origin_x_m: f32, origin_y_m: f32, m_per_px: f32) -> Result<Self, GeoError> {
        if !(m_per_px.is_finite() && m_per_px > 0.0) {
            return Err(GeoError::BadResolution);
        }
        if !(origin_x_m.is_finite() && origin_y_m.is_finite()) {
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
        assert_eq!(g.origin_x_m, 75.0);
        assert_eq!(g.origin_y_m, 225.0);
        let (c, r) = g.to_pixel(100.0, 200.0);
        assert_eq!((c, r), (100.0, 100.0));
        let (x, y) = g.to_world(0.5, 0.5);
        assert_eq!((x, y), (75.125, 224.875));
        assert_eq!(GeoRef::new(0.0, 0.0, 0.0), Err(GeoError::BadResolution));
        assert_eq!(GeoRef::new(f32::NAN, 0.0, 1.0), Err(GeoError::BadOrigin));
    }
}
