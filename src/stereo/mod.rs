//! Depth from the rover's own rectified stereo pairs, integer block matching in row bands.
//!
//! Each view has a left camera (the view camera of [`crate::camera`]) and a right camera
//! `baseline_m` metres along the left camera's `+x` axis (right), same intrinsics, same
//! orientation: a rectified pair, so a point at depth `Z` (metres along the optical axis)
//! appears `d = f B / Z` pixels further left in the right image (`f`: focal length, pixels;
//! `B`: baseline, metres). `docs/stereo.md` has the method, the cost model and the
//! benchmark against OpenCV.
//!
//! Pipeline, per output row (all integer):
//! 1. reduce both frames by `downsample` (box average; [`downsample_row`]; rows by
//!    `row_factor` times more, [`downsample_row_by`]) and pre-filter with a horizontal
//!    Sobel clipped to `±prefilter_cap` ([`prefilter`]), robust to the offset between the
//!    cameras;
//! 2. cost `|L(x) - R'(x - d')|` aggregated over a `(2r + 1) x (2 rv + 1)` box (`r`:
//!    `radius_px`, `rv`: `radius_rows_px`) by running sums
//!    (a vertical sum per column and disparity, updated by one row in and one row out, then
//!    a horizontal running sum), where `R'` is the right row moved right by the flat
//!    ground's disparity of its row less a constant (`ground_shear`; Q8, linear
//!    interpolation, [`shear_row`]) and `d'` the residual disparity: the window follows the
//!    ground, whose disparity grows down the image, instead of spreading it over the
//!    window's rows; the residual plus the row's shear is the disparity;
//! 3. winner-take-all over the row's disparity range ([`geometry`]), rejected when the
//!    winner lies on the range's edge, when the runner-up (more than one disparity away) is
//!    not `uniqueness_pct` % worse, or when the gap is below `min_gap_per_px` per window
//!    pixel (textureless ground);
//! 4. left-right consistency: the right image's own winner (minimum of the same costs along
//!    the other diagonal) must agree within 1 px; with `column_step` 2 steps 3 to 5 are
//!    taken at every other column (every `near_column_step`-th in the near rows whose flat
//!    ground that many columns span at most `near_column_span_m`), the window still sliding
//!    over every column, and a column between two decided ones takes their linear blend
//!    where they agree within 1 px;
//! 5. sub-pixel disparity by a parabola through the three costs ([`crate::peak`]), Q4;
//! 6. speckle rejection: a disparity needs `min_support` of its 8 neighbours within 1 px;
//! 7. rows matched at a coarser scale (or with `row_factor` 2) are expanded onto the
//!    working rows they cover, each moved to its own distance (module `expand`);
//! 8. depth `Z = f B / d`, `u16` millimetres along the optical axis, 0 = no data: the
//!    layout [`crate::reproject::DepthView`] reads (at the reduced size,
//!    [`StereoRig::output_params`]).
//!
//! Only the rows and disparities that can hold ground inside the top-down square are
//! evaluated: [`geometry`] derives each row's disparity range from the rig (height, tilt,
//! attitude margin), the relief band and the largest ground range, and rows that can only
//! see sky are skipped. Near rows are matched at a coarser scale ([`scale`]) where a
//! quarter-pixel disparity error there still moves their ground by at most
//! `scale_error_m`; their output is expanded to the working size.
//!
//! Memory: the caller's scratch of [`stereo_buffer_sizes`] (bytes and `u16` words, a few
//! tens of KB at the default 320 x 180 working size) plus the output band; frames are read
//! in place (they may live in external memory). A view is one stream ([`StereoView`],
//! [`StereoRig::view`]): bands that follow each other cost no set-up rows and match no row
//! twice, so the band height only sets the output buffer; a band on its own
//! ([`StereoRig::depth_band`]) costs `2r + 1` rows of set-up.

mod band;
mod error;
mod expand;
mod fill;
pub mod geometry;
mod kernel;
mod params;
mod prefilter;
#[cfg(test)]
mod reference;
mod rig;
pub mod scale;
mod shear;
mod speckle;
mod swar;

pub use band::{BandReport, StereoView};
pub use error::{Side, StereoBuffer, StereoError};
pub use params::{StereoParams, SubPixel};
pub use prefilter::{downsample_row, downsample_row_by, prefilter};
pub use rig::{stereo_buffer_bound, stereo_buffer_sizes, StereoBufferSizes, StereoRig};
pub use shear::shear_row;

/// Default baseline, metres.
pub const DEFAULT_BASELINE_M: f32 = 0.30;
/// Fractional bits of the disparities ([`StereoRig::disparity_band`]): Q4, 1/16 pixel.
pub const DISPARITY_FRAC_BITS: u32 = 4;
/// Largest aggregation radius, pixels (window 15 x 15).
pub const MAX_RADIUS: u8 = 7;
