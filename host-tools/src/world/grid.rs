//! Sampled rasters of the world ([`HeightGrid`]) and the checks of a query rectangle.

use super::WorldError;

pub(super) fn check_rect(x0: f64, y0: f64, x1: f64, y1: f64, cell: f64) -> Result<(), WorldError> {
    if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) || x1 < x0 || y1 < y0
    {
        return Err(WorldError::BadQuery(format!(
            "rectangle [{x0}, {x1}) x [{y0}, {y1}) must be finite with x0 <= x1 and y0 <= y1"
        )));
    }
    let cells = ((x1 - x0) / cell + 2.0) * ((y1 - y0) / cell + 2.0);
    if cells > 1e8 {
        return Err(WorldError::BadQuery(format!(
            "rectangle [{x0}, {x1}) x [{y0}, {y1}) spans {cells:.0} cells of {cell} m: query smaller tiles"
        )));
    }
    Ok(())
}

/// A sampled north-up raster of height and albedo. Row-major, row 0 north, column 0 west;
/// georeference as `docs/frames.md` (north-west corner + metres per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct HeightGrid {
    /// World `x` of the west edge, metres.
    pub origin_x_m: f64,
    /// World `y` of the north edge, metres.
    pub origin_y_m: f64,
    /// Pixel size, metres per pixel.
    pub m_per_px: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// Elevation per pixel, metres, `ny * nx` row-major.
    pub height_m: Vec<f32>,
    /// Normal albedo per pixel, 0..1, `ny * nx` row-major.
    pub albedo: Vec<f32>,
}

impl HeightGrid {
    /// Index of pixel `(col, row)` in the row-major vectors, if inside.
    pub fn index(&self, col: usize, row: usize) -> Option<usize> {
        (col < self.nx && row < self.ny).then(|| row * self.nx + col)
    }

    /// World `(x, y)` metres of the centre of pixel `(col, row)`.
    pub fn pixel_centre(&self, col: usize, row: usize) -> (f64, f64) {
        (
            self.origin_x_m + (col as f64 + 0.5) * self.m_per_px,
            self.origin_y_m - (row as f64 + 0.5) * self.m_per_px,
        )
    }
}
