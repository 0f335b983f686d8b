//! The per-view set-up of the range placement: the camera's axes, the column steps and the
//! per-pixel limits in the fixed-point units the placement loop uses.

use super::{RangeError, RAY_LIMIT};

/// Rounds a Q32 ray component to `i32` (rays are bounded by [`RAY_LIMIT`]).
pub(super) fn to_q(v: f32) -> Result<i32, RangeError> {
    if !(v.is_finite() && libm::fabsf(v) < RAY_LIMIT) {
        return Err(RangeError::Overflow);
    }
    Ok(libm::roundf(v) as i32)
}

/// Per-pixel limits of one view, in the fixed-point units of [`place_row`].
pub(super) struct Limits {
    /// Largest depth, depth units (0 is always "no depth").
    pub(super) max_depth: u16,
    /// Height band relative to the optical centre, metres Q32.
    pub(super) h_lo: i64,
    pub(super) h_hi: i64,
    /// Optical centre from the grid's west / north edge, cells Q32 (`n / 2`).
    pub(super) c_q: i64,
    /// Grid side, cells (at most 65535).
    pub(super) n: u32,
    /// `(2R / res)^2` for the range test on cell centres.
    pub(super) range_lim: i64,
}

/// Per-view set-up of the row placement (fixed-point limits, camera axes, column steps).
pub(super) struct ViewSetup {
    pub(super) lim: Limits,
    pub(super) height_band: bool,
    pub(super) range_lim: Option<i64>,
    /// Camera right, down, forward axes in the world.
    pub(super) ax: [[f32; 3]; 3],
    /// Focal length, pixels.
    pub(super) f: f32,
    /// Normalized x of the first column's centre.
    pub(super) u0: f32,
    /// Principal point row, pixels.
    pub(super) cy: f32,
    /// Steps per column (east cells, south cells, metres up; Q32 per depth unit, `f32`).
    pub(super) b: [f32; 3],
    /// The same, rounded.
    pub(super) b_q: [i32; 3],
    pub(super) scale_xy: f32,
    pub(super) scale_z: f32,
}
