//! Range-aware reprojection: forward projection of pixels with known depth (stereo, point
//! cloud) onto the north-up top-down grid, integer-only per pixel.
//!
//! The flat-ground table ([`super::Lut`]) places a point `dz` below or above the rover's
//! ground plane at range `d` at `d * h / (h + dz)`; on relief that smears the top-down image
//! beyond a few metres. Here each pixel goes to its true 3D point instead:
//!
//! `P = C + z * (a_row + i * b)`, with `C` the optical centre, `z` the pixel's depth along
//! the optical axis, `a_row = Z + Y (v - cy) / f + X (0.5 - cx) / f` (`X, Y, Z` the
//! camera's right, down and forward axes in the world, `v = row + 0.5`) and `b = X / f`:
//! the un-normalized ray is linear in the column `i` along a row.
//!
//! Per row (set-up, `f32`): `a_row` and `b` are scaled to grid cells (east, south) and
//! metres (up) per depth unit and rounded to Q32 in `i32`. Per pixel (integer): three
//! `i32` adds (the ray steps by `b`), three 32 x 32 -> 64 multiply-adds (`z * ray`: east,
//! south, up; `SMLAL` on Cortex-M), two shifts (cell = floor, `>> 32`),
//! compares, and per cell a sample count (`u8`, saturating at 255, kept in the caller's
//! mask until the end) and a gray sum (`u16` in the scratch: at most 255 samples of at most
//! 255, 65,025). Then per cell one division
//! (`out = sum / count`, rounded) and an optional hole-filling pass (a cell with no sample
//! and at least [`RangeOptions::fill_min_neighbours`] of its 8 neighbours sampled gets
//! their mean), so sampling gaps at range do not punch holes while the blind disc under
//! the mast and unseen areas stay "no data".
//!
//! Memory: the caller's scratch of [`range_scratch_len`] `u32` (2 bytes per cell, 80 KB
//! for the default 200 x 200 grid) plus the output and mask (`n * n` bytes each; the mask
//! holds the counts while pixels are placed). No heap, no panics, no floats per pixel.

mod accumulator;
mod depth_band;
mod place;
mod relief_pass;
mod setup;

pub use accumulator::RangeAccumulator;
pub use depth_band::{DepthBand, DepthExpander};

use super::relief::ReliefGrid;
use super::{Buffer, FrameStatus, GridSpec, ReprojectError};
use crate::camera::{CameraParams, RoverPose, View};
use crate::image::{ImageView, Plane};

/// Default depth unit: millimetres (`u16` depths up to 65.535 m).
pub const DEFAULT_DEPTH_SCALE_M: f32 = 0.001;
/// Default minimum number of sampled 8-neighbours for filling an empty cell.
pub const DEFAULT_FILL_MIN: u8 = 5;

/// Fractional bits of the fixed-point positions (grid cells, Q32 in `i64`).
pub const POS_FRAC_BITS: u32 = 32;
/// Sample count at which a cell saturates (later samples are not added).
const SATURATED: u8 = 255;
/// Largest magnitude of a Q32 ray component (per depth unit) along a row: `2^30`, so that
/// rays fit `i32` with margin for the per-column steps and `z * ray` is one 32 x 32 -> 64
/// multiply-accumulate (`SMLAL` on Cortex-M).
const RAY_LIMIT: f32 = 1_073_741_824.0;

/// `u32` elements of the scratch for an `n x n` grid (one `u16` gray sum per cell:
/// `ceil(n * n / 2)`; 0 on overflow).
pub const fn range_scratch_len(n: usize) -> usize {
    super::table_len(n).div_ceil(2)
}

/// Bytes of the scratch for an `n x n` grid (2 per cell, rounded up to a word).
pub const fn range_scratch_bytes(n: usize) -> usize {
    range_scratch_len(n) * core::mem::size_of::<u32>()
}

/// A borrowed depth image: `u16` depth along the optical axis per pixel, in units of
/// [`RangeOptions::depth_scale_m`] (millimetres by default), 0 = no depth. Row-major;
/// `stride` is in elements (`u16`), not bytes. The same view as the gray frames'
/// ([`Plane`]), with its checks.
pub type DepthView<'a> = Plane<'a, u16>;

/// Settings of the range reprojection.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RangeOptions {
    /// Metres per depth unit (0.001: millimetres). Finite, > 0.
    pub depth_scale_m: f32,
    /// Depths beyond this, metres along the optical axis, are ignored (`f32::INFINITY`:
    /// none).
    pub max_depth_m: f32,
    /// Points lower than this above the ground under the rover, metres, are ignored
    /// (`f32::NEG_INFINITY`: none).
    pub min_height_m: f32,
    /// Points higher than this above the ground under the rover, metres, are ignored (e.g.
    /// the camera height: nothing above the camera is ground; `f32::INFINITY`: none).
    pub max_height_m: f32,
    /// Empty cells with at least this many sampled 8-neighbours get their mean (0: no
    /// filling; 1..=8).
    pub fill_min_neighbours: u8,
    /// Largest column stride (1..=16; 1 = read every pixel, the default). With `k > 1` each
    /// row reads every `s`-th pixel, `s = clamp(floor(m_per_px f / (2 t)), 1, k)` with `t`
    /// the row's flat-ground depth at its centre column (metres) and `f` the focal length
    /// (pixels): the ground spacing of the pixels read stays at most half a cell on flat
    /// ground. Near the mast a cell gets hundreds of pixels, so this saves most of the
    /// per-pixel work for a small change of the image.
    pub max_column_stride: u8,
    /// Frame pixels darker than this, gray levels, get no depth in
    /// [`RangeAccumulator::add_rows`] (the on-board stereo's bands), so they are neither
    /// placed nor used for the relief (0: off; default 8 since 2026-12-07; depth images
    /// given to [`RangeAccumulator::add_view`] are placed as given). The lunar sky is black (0),
    /// the deepest shadow in the rendered frames about 29: the sky next to the skyline,
    /// whose window holds the skyline's edge, would otherwise be placed at the skyline's
    /// distance (`docs/stereo.md`, "Rising terrain in the horizon rows").
    pub sky_below_gray: u8,
}

impl RangeOptions {
    /// The check [`RangeAccumulator::new`] makes: a positive, finite depth unit,
    /// a positive largest depth, an ordered height band, `fill_min_neighbours` at most 8 and
    /// `max_column_stride` in 1..=16.
    pub fn validate(&self) -> Result<(), RangeError> {
        if !(self.depth_scale_m.is_finite() && self.depth_scale_m > 0.0)
            || self.max_depth_m.is_nan()
            || self.max_depth_m <= 0.0
        {
            return Err(RangeError::BadDepthScale);
        }
        if self.min_height_m.is_nan()
            || self.max_height_m.is_nan()
            || self.min_height_m > self.max_height_m
            || self.fill_min_neighbours > 8
            || !(1..=16).contains(&self.max_column_stride)
        {
            return Err(RangeError::BadOption);
        }
        Ok(())
    }
}

impl Default for RangeOptions {
    /// Millimetre depths, no depth or height limits, fill cells with >= 5 of 8 neighbours.
    fn default() -> Self {
        Self {
            depth_scale_m: DEFAULT_DEPTH_SCALE_M,
            max_depth_m: f32::INFINITY,
            min_height_m: f32::NEG_INFINITY,
            max_height_m: f32::INFINITY,
            fill_min_neighbours: DEFAULT_FILL_MIN,
            max_column_stride: 1,
            sky_below_gray: 8,
        }
    }
}

/// Errors of the range reprojection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RangeError {
    /// Camera, pose, grid, output buffer or frame size error (as the LUT path).
    Reproject(ReprojectError),
    /// A depth image's size differs from its frame's.
    DepthSize {
        /// View index (0 front, 1 right, 2 rear, 3 left).
        view: usize,
        /// The frame's `(width, height)`, pixels.
        expected: (usize, usize),
        /// The depth image's `(width, height)`, pixels.
        got: (usize, usize),
    },
    /// The scratch has the wrong length.
    ScratchSize {
        /// `u32` elements needed ([`range_scratch_len`]).
        needed: usize,
        /// Elements given.
        got: usize,
    },
    /// `depth_scale_m` not finite and > 0, or `max_depth_m` NaN or <= 0.
    BadDepthScale,
    /// Height band NaN or empty, `fill_min_neighbours` above 8, or `max_column_stride` not in
    /// 1..=16.
    BadOption,
    /// Grid resolution too fine for the depth scale: a ray component exceeds `2^30` in
    /// Q32 cells per depth unit, i.e. `m_per_px` below about `2 * |ray| * depth_scale_m`
    /// (about 3 mm per cell with millimetre depths and the default rig).
    Overflow,
}

impl core::fmt::Display for RangeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Reproject(e) => write!(f, "{e}"),
            Self::DepthSize {
                view,
                expected,
                got,
            } => write!(
                f,
                "depth image {view} is {} x {} pixels, its camera frame {} x {}; give depth images of the frames' size",
                got.0, got.1, expected.0, expected.1
            ),
            Self::ScratchSize { needed, got } => write!(
                f,
                "the range scratch has {got} elements, {needed} are needed; size it with range_scratch_len"
            ),
            Self::BadDepthScale => write!(
                f,
                "the depth scale must be a finite number of metres per unit above 0, and the maximum depth above 0"
            ),
            Self::BadOption => write!(
                f,
                "a range option is out of range: the height band must be a non-empty interval, the fill neighbours at most 8, the column stride 1 to 16"
            ),
            Self::Overflow => write!(
                f,
                "the grid resolution is too fine for the depth scale (a ray would overflow the fixed-point range); use coarser cells or a finer depth unit"
            ),
        }
    }
}

impl core::error::Error for RangeError {}

impl From<ReprojectError> for RangeError {
    fn from(e: ReprojectError) -> Self {
        RangeError::Reproject(e)
    }
}

/// What [`reproject_range`] did (also the operation counts for the flight budget).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RangeReport {
    /// Per view (front, right, rear, left): sampled or why not (a view whose depth image
    /// is missing keeps `Ok` here and is flagged in `depth_missing`).
    pub status: [FrameStatus; 4],
    /// Views with a usable frame but no depth image (not sampled).
    pub depth_missing: [bool; 4],
    /// Pixels read (frames sampled x their pixels): the per-pixel work.
    pub pixels_read: u64,
    /// Pixels that landed in a grid cell and were accumulated.
    pub points_used: u64,
    /// Pixels with no depth, beyond the depth or height limits, or outside the grid.
    pub points_dropped: u64,
    /// Cells visited by the per-cell passes (average and hole filling).
    pub cells_visited: u64,
    /// Cells with data (mask 255), filled cells included.
    pub valid_cells: usize,
    /// Cells filled from their neighbours.
    pub filled_cells: usize,
}

/// Reprojects `frames` (front, right, rear, left; `None` for a missing camera) with their
/// `depths` (same order and sizes) into `out` (`n * n` gray levels, north-up, 0 where no
/// data) and `mask` (`n * n`; 255 valid, 0 no data), using `scratch`
/// ([`range_scratch_len`]`(grid.n)` elements, overwritten). Frames must be
/// `params.width_px x params.height_px` (any stride); black or saturated frames
/// ([`classify_frame`](crate::reproject::classify_frame)) are treated as missing and reported. `grid.max_range_m` limits the
/// ground distance of a cell centre from the rover. Every size is checked before any
/// pixel is read.
#[allow(clippy::too_many_arguments)]
pub fn reproject_range(
    frames: &[Option<ImageView<'_>>; 4],
    depths: &[Option<DepthView<'_>>; 4],
    params: &CameraParams,
    pose: &RoverPose,
    grid: &GridSpec,
    opts: &RangeOptions,
    scratch: &mut [u32],
    out: &mut [u8],
    mask: &mut [u8],
) -> Result<RangeReport, RangeError> {
    reproject_range_relief(
        frames, depths, params, pose, grid, opts, scratch, out, mask, None,
    )
}

/// [`reproject_range`] that also accumulates the relief on `relief`'s grid into its words
/// ([`RangeAccumulator::with_relief`]; `None`: as [`reproject_range`]).
#[allow(clippy::too_many_arguments)]
pub fn reproject_range_relief(
    frames: &[Option<ImageView<'_>>; 4],
    depths: &[Option<DepthView<'_>>; 4],
    params: &CameraParams,
    pose: &RoverPose,
    grid: &GridSpec,
    opts: &RangeOptions,
    scratch: &mut [u32],
    out: &mut [u8],
    mask: &mut [u8],
    relief: Option<(ReliefGrid, &mut [i32])>,
) -> Result<RangeReport, RangeError> {
    let mut acc = RangeAccumulator::new(params, pose, grid, opts, scratch, mask)?;
    if let Some((g, words)) = relief {
        acc = acc.with_relief(g, words)?;
    }
    // Checked here too (not only in `finish`), so that no pixel is read for nothing.
    check_len(Buffer::Output, out.len(), grid.cells())?;
    for ((f, d), view) in frames.iter().zip(depths).zip(View::ALL) {
        if let Some(f) = f {
            acc.check_sizes(view, f, d.as_ref())?;
        }
    }
    for ((f, d), view) in frames.iter().zip(depths).zip(View::ALL) {
        if let Some(f) = f {
            acc.add_view(view, f, d.as_ref())?;
        }
    }
    acc.finish(out)
}

/// `Ok` when `buffer` has the `needed` length (`got`), else its `BufferSize` error.
fn check_len(buffer: Buffer, got: usize, needed: usize) -> Result<(), RangeError> {
    if got == needed {
        Ok(())
    } else {
        Err(ReprojectError::BufferSize {
            buffer,
            needed,
            got,
        }
        .into())
    }
}

/// `u32` words that hold `halves` `u16` values.
const fn scratch_words(halves: usize) -> usize {
    halves.div_ceil(2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::ImageError;

    #[test]
    fn accumulator_saturates_and_averages() {
        // The per-pixel update of `place_pixels` at its worst: white samples beyond the
        // saturating count (an overflowing sum panics here, in a debug test build).
        let (mut c, mut sum) = (0u8, 0u16);
        for _ in 0..300 {
            if c < SATURATED {
                c += 1;
                sum += 255;
            }
        }
        assert_eq!(c, 255);
        assert_eq!(sum, 65_025);
        assert_eq!(u32::from(sum) / u32::from(c), 255);
    }

    #[test]
    fn depth_view_checks_sizes() {
        let d = [0u16; 10];
        assert!(DepthView::new(&d, 5, 2).is_ok());
        assert_eq!(
            DepthView::new(&d, 5, 3).err(),
            Some(ImageError::BufferTooSmall {
                needed: 15,
                got: 10
            })
        );
        assert_eq!(
            DepthView::with_stride(&d, 5, 2, 4).err(),
            Some(ImageError::StrideTooSmall {
                stride: 4,
                width: 5
            })
        );
        assert_eq!(DepthView::new(&d, 0, 2).err(), Some(ImageError::ZeroSize));
    }
}
