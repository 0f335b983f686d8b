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

use super::relief::{ReliefCells, ReliefGrid, RELIEF_FRAC_BITS};
use super::{classify_frame, Buffer, FrameStatus, GridSpec, ReprojectError};
use crate::camera::{Camera, CameraParams, RoverPose, View};
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

/// Rounds a Q32 ray component to `i32` (rays are bounded by [`RAY_LIMIT`]).
fn to_q(v: f32) -> Result<i32, RangeError> {
    if !(v.is_finite() && libm::fabsf(v) < RAY_LIMIT) {
        return Err(RangeError::Overflow);
    }
    Ok(libm::roundf(v) as i32)
}

/// Per-pixel limits of one view, in the fixed-point units of [`place_row`].
struct Limits {
    /// Largest depth, depth units (0 is always "no depth").
    max_depth: u16,
    /// Height band relative to the optical centre, metres Q32.
    h_lo: i64,
    h_hi: i64,
    /// Optical centre from the grid's west / north edge, cells Q32 (`n / 2`).
    c_q: i64,
    /// Grid side, cells (at most 65535).
    n: u32,
    /// `(2R / res)^2` for the range test on cell centres.
    range_lim: i64,
}

/// Per-view set-up of the row placement (fixed-point limits, camera axes, column steps).
struct ViewSetup {
    lim: Limits,
    height_band: bool,
    range_lim: Option<i64>,
    /// Camera right, down, forward axes in the world.
    ax: [[f32; 3]; 3],
    /// Focal length, pixels.
    f: f32,
    /// Normalized x of the first column's centre.
    u0: f32,
    /// Principal point row, pixels.
    cy: f32,
    /// Steps per column (east cells, south cells, metres up; Q32 per depth unit, `f32`).
    b: [f32; 3],
    /// The same, rounded.
    b_q: [i32; 3],
    scale_xy: f32,
    scale_z: f32,
}

/// Bits of the depth scale of an expanded row ([`DepthExpander`]): Q16.
const ROW_SCALE_BITS: u32 = 16;
/// 1.0 in that format.
const ROW_SCALE_ONE: u32 = 1 << ROW_SCALE_BITS;

/// Expands the rows of a depth image reduced by an integer factor `k` (e.g. on-board stereo
/// at half resolution) to the frame's rows, as [`RangeAccumulator::add_rows`] places them:
/// frame pixel `(i, j)` takes the depth of reduced pixel `(i / k, j / k)`, scaled by the
/// ratio of the flat-ground depths of frame row `j` and of the reduced row's centre row
/// (`(j / k + 0.5) k - 0.5`). A reduced pixel's depth belongs to its centre; without the
/// scale, the `k` frame rows of one reduced row would all fall at the centre row's
/// distance, leaving stripes with gaps between them far from the rover. The ratio is that
/// of the downward slopes of the two rows' rays at the centre column (`h / Z` on flat
/// ground): exact for ground parallel to the rover's, within 1 % elsewhere for `k <= 4`.
#[derive(Clone, Copy, Debug)]
pub struct DepthExpander {
    /// Upward component of the centre column's ray at the principal point row, per unit
    /// of camera depth.
    up0: f32,
    /// Its change per frame row.
    up_row: f32,
    /// Principal point row, pixels.
    cy: f32,
}

impl DepthExpander {
    /// The expander of `view` of the rig `params` at `pose` (checked as
    /// [`crate::camera::Camera::new`] checks them).
    pub fn new(params: &CameraParams, pose: &RoverPose, view: View) -> Result<Self, RangeError> {
        let cam = Camera::new(params, pose, view).map_err(ReprojectError::from)?;
        let r = cam.world_to_cam;
        let f = cam.focal_px;
        let up = [r[(0, 2)], r[(1, 2)], r[(2, 2)]];
        Ok(Self::from_axes(
            up,
            f,
            (0.5 - cam.cx) / f,
            cam.cy,
            params.width_px as usize,
        ))
    }

    /// From a view's set-up (the same axes, the same arithmetic).
    fn from_setup(s: &ViewSetup, w: usize) -> Self {
        let [ax_r, ax_d, ax_f] = s.ax;
        Self::from_axes([ax_r[2], ax_d[2], ax_f[2]], s.f, s.u0, s.cy, w)
    }

    /// `up`: the world up components of the camera's right, down and forward axes; `u0`
    /// the normalized x of the first column's centre.
    fn from_axes(up: [f32; 3], f: f32, u0: f32, cy: f32, w: usize) -> Self {
        let [r, d, fw] = up;
        Self {
            up0: fw + r * (u0 + (0.5 * w as f32 - 0.5) / f),
            up_row: d / f,
            cy,
        }
    }

    #[inline]
    fn up_at(&self, row: f32) -> f32 {
        self.up0 + self.up_row * (row + 0.5 - self.cy)
    }

    /// Depth scale of frame row `j` (Q16); 1 where either ray does not point down, and
    /// bounded to `[1/4, 4]` near the horizon.
    fn scale(&self, j: usize, k: usize) -> u32 {
        let centre = ((j / k) as f32 + 0.5) * k as f32 - 0.5;
        let (uc, uj) = (self.up_at(centre), self.up_at(j as f32));
        if !(uc < -1e-4 && uj < -1e-4) {
            return ROW_SCALE_ONE;
        }
        let r = (uc / uj).clamp(0.25, 4.0);
        (r * ROW_SCALE_ONE as f32 + 0.5) as u32
    }

    /// Writes frame row `j` of the depth image reduced by `k` whose reduced row `j / k` is
    /// `src` into `out` (the frame's width; `src` at least `out.len() / k` long, rounded
    /// up, else the missing pixels get no depth). Depth 0 (no data) stays 0; a scaled depth
    /// beyond `u16::MAX` units is `u16::MAX`.
    pub fn expand_row(&self, j: usize, k: usize, src: &[u16], out: &mut [u16]) {
        let k = k.max(1);
        let scale = if k == 1 {
            ROW_SCALE_ONE
        } else {
            self.scale(j, k)
        };
        let mut chunks = out.chunks_mut(k);
        for (c, &o) in (&mut chunks).zip(src) {
            let d = if o == 0 || scale == ROW_SCALE_ONE {
                o
            } else {
                // In u64: a depth of up to 65,535 units times a scale of up to 4 in Q16
                // exceeds u32; a result beyond u16 saturates (the farthest depth).
                let v = (u64::from(o) * u64::from(scale) + u64::from(ROW_SCALE_ONE >> 1))
                    >> ROW_SCALE_BITS;
                u16::try_from(v).unwrap_or(u16::MAX).max(1)
            };
            c.fill(d);
        }
        for c in chunks {
            c.fill(0);
        }
    }
}

/// A band of a depth image at a reduced size, for [`RangeAccumulator::add_rows`].
#[derive(Clone, Copy, Debug)]
pub struct DepthBand<'a> {
    /// Depths (units of [`RangeOptions::depth_scale_m`], 0 = no depth), row-major,
    /// `width` per row, starting at reduced row `first_row`.
    pub data: &'a [u16],
    /// Reduced width, pixels (at least the frame width / `factor`, rounded up).
    pub width: usize,
    /// Reduced row of the band's first row.
    pub first_row: usize,
    /// Reduction factor (1..): frame pixel `(i, j)` reads reduced pixel `(i / factor, j /
    /// factor)`.
    pub factor: usize,
}

/// No depth (0) at the pixels of `frow` darker than `below` gray levels
/// ([`RangeOptions::sky_below_gray`]); `drow` the row's depths, as long as `frow` or shorter.
fn drop_sky(frow: &[u8], drow: &mut [u16], below: u8) {
    for (d, &g) in drow.iter_mut().zip(frow) {
        if g < below {
            *d = 0;
        }
    }
}

/// Places one row, every `stride`-th pixel from the first: the `k`-th pixel read has the
/// ray `ray + k * step` (`step` is already `stride` columns; Q32 per depth unit: cells
/// east, cells south, metres up). Returns the pixels accumulated. `HEIGHT` / `RANGE` switch the
/// height-band and range tests on.
#[inline(always)]
fn place_row<const HEIGHT: bool, const RANGE: bool>(
    frow: &[u8],
    drow: &[u16],
    stride: usize,
    ray: [i32; 3],
    step: [i32; 3],
    lim: &Limits,
    cells: &mut Cells<'_>,
) -> u32 {
    // Every pixel: a plain zip (a runtime `step_by` slows the common loop down).
    if stride <= 1 {
        let it = frow.iter().zip(drow);
        place_pixels::<HEIGHT, RANGE, _>(it, ray, step, lim, cells)
    } else {
        let it = frow.iter().zip(drow).step_by(stride);
        place_pixels::<HEIGHT, RANGE, _>(it, ray, step, lim, cells)
    }
}

/// The per-pixel loop of [`place_row`] over the pixels read.
#[inline(always)]
fn place_pixels<'p, const HEIGHT: bool, const RANGE: bool, I>(
    pixels: I,
    ray: [i32; 3],
    step: [i32; 3],
    lim: &Limits,
    cells: &mut Cells<'_>,
) -> u32
where
    I: Iterator<Item = (&'p u8, &'p u16)>,
{
    let [mut dx, mut dy, mut dz] = ray;
    let [bx, by, bz] = step;
    let (max_depth, n, c_q) = (lim.max_depth, lim.n, lim.c_q);
    // Both views cut to one length, so one bound check per pixel covers both.
    let len = cells.counts.len().min(cells.sums.len());
    let (Some(counts), Some(sums)) = (cells.counts.get_mut(..len), cells.sums.get_mut(..len))
    else {
        return 0;
    };
    let mut used = 0u32;
    for (&g, &z) in pixels {
        let (rx, ry, rz) = (dx, dy, dz);
        dx = dx.wrapping_add(bx);
        dy = dy.wrapping_add(by);
        if HEIGHT {
            dz = dz.wrapping_add(bz);
        }
        // One compare for "no depth" (0 wraps to 65535) and "too far".
        if z.wrapping_sub(1) >= max_depth {
            continue;
        }
        let zi = i64::from(z);
        if HEIGHT {
            let hz = zi * i64::from(rz);
            if hz < lim.h_lo || hz > lim.h_hi {
                continue;
            }
        }
        // Positions are below 2^46 (rays < 2^30, depths < 2^16), so the cell index (the
        // high word) fits i32; negative cells wrap to huge u32 and fail the bound.
        let col = ((c_q + zi * i64::from(rx)) >> POS_FRAC_BITS) as i32 as u32;
        let row = ((c_q + zi * i64::from(ry)) >> POS_FRAC_BITS) as i32 as u32;
        if col >= n || row >= n {
            continue;
        }
        if RANGE {
            let ec = 2 * i64::from(col) + 1 - i64::from(n);
            let er = 2 * i64::from(row) + 1 - i64::from(n);
            if ec * ec + er * er > lim.range_lim {
                continue;
            }
        }
        let k = row as usize * n as usize + col as usize;
        if let (Some(c), Some(sum)) = (counts.get_mut(k), sums.get_mut(k)) {
            if *c < SATURATED {
                *c += 1;
                // At most 255 samples of at most 255: the sum stays <= 65,025.
                *sum += u16::from(g);
            }
            used += 1;
        }
    }
    used
}

/// Points per block side the relief pass aims for, along and across the frame's rows.
const RELIEF_SAMPLES: f32 = 8.0;
/// Most frame rows between two rows of the relief pass (a power of two).
const RELIEF_MAX_ROW_STEP: usize = 16;
/// Most columns between two points of the relief pass.
const RELIEF_MAX_COL_STEP: usize = 64;

/// Frame rows between two rows of the relief pass where the flat ground lies beyond the
/// grid, or above the horizon (a power of two).
const RELIEF_FAR_ROW_STEP: usize = 4;

/// Row and column steps of the relief pass ([`relief_row`]) for a frame row whose
/// flat-ground depth at the centre column is `flat_m` metres (`None`: at or above the
/// horizon), for blocks `block_m` metres wide, focal length `f` pixels, camera `h` metres
/// up: about [`RELIEF_SAMPLES`] points per block side. On flat ground a row covers `t / f`
/// metres per column and `(h^2 + t^2) / (f h)` metres per row at depth `t`. Rows whose
/// flat ground lies beyond `reach_m` (the grid's half diagonal) see the grid only where the
/// terrain rises: every [`RELIEF_FAR_ROW_STEP`]-th row, columns as at `reach_m`. The row
/// step is a power of two, so the rows a step picks are also picked by every smaller step.
fn relief_steps(flat_m: Option<f32>, reach_m: f32, block_m: f32, f: f32, h: f32) -> (usize, usize) {
    let along = block_m / RELIEF_SAMPLES;
    let col_step = |t: f32| {
        let c = libm::floorf(along * f / t);
        if c >= 1.0 {
            (c as usize).min(RELIEF_MAX_COL_STEP)
        } else {
            1
        }
    };
    let t = match flat_m {
        Some(t) if t.is_finite() && t > 0.0 && t <= reach_m => t,
        _ => return (RELIEF_FAR_ROW_STEP, col_step(reach_m)),
    };
    let rows = libm::floorf(along * f * h / (h * h + t * t));
    let rows = if rows >= 1.0 {
        (rows as usize).min(RELIEF_MAX_ROW_STEP)
    } else {
        1
    };
    // The largest power of two not above `rows`.
    (
        1usize << (usize::BITS - 1 - rows.leading_zeros()),
        col_step(t),
    )
}

/// The relief pass over one frame row: every `stride`-th depth of `drow` from the first,
/// with rays as [`place_row`]'s (`step` already `stride` columns), adds the point's height
/// (Q7 metres) to its block. Points without depth, beyond the depth limit or outside the
/// height band add nothing.
fn relief_row(
    drow: &[u16],
    stride: usize,
    ray: [i32; 3],
    step: [i32; 3],
    lim: &Limits,
    rc: &mut ReliefCells<'_>,
) {
    let [mut dx, mut dy, mut dz] = ray;
    let [bx, by, bz] = step;
    for &z in drow.iter().step_by(stride.max(1)) {
        let (rx, ry, rz) = (dx, dy, dz);
        dx = dx.wrapping_add(bx);
        dy = dy.wrapping_add(by);
        dz = dz.wrapping_add(bz);
        if z.wrapping_sub(1) >= lim.max_depth {
            continue;
        }
        let zi = i64::from(z);
        let hz = zi * i64::from(rz);
        if hz < lim.h_lo || hz > lim.h_hi {
            continue;
        }
        // As in `place_pixels`: the cell index fits i32; negative cells fail the bound.
        let col = ((lim.c_q + zi * i64::from(rx)) >> POS_FRAC_BITS) as i32 as u32;
        let row = ((lim.c_q + zi * i64::from(ry)) >> POS_FRAC_BITS) as i32 as u32;
        if let Some(b) = rc.grid.block_of(col, row) {
            // Q32 metres to Q7: heights within +-2^24 m fit i32.
            rc.add(b, (hz >> (POS_FRAC_BITS - RELIEF_FRAC_BITS)) as i32);
        }
    }
}

/// The per-cell accumulator: gray sums (`u16`, in the caller's scratch) and sample counts
/// (`u8`, in the caller's mask until [`RangeAccumulator::finish`]).
#[derive(Debug)]
struct Cells<'s> {
    sums: &'s mut [u16],
    counts: &'s mut [u8],
    /// The relief blocks, when asked for ([`RangeAccumulator::with_relief`]).
    relief: Option<ReliefCells<'s>>,
}

/// Incremental range reprojection for callers that produce one view (or one depth image)
/// at a time: [`RangeAccumulator::new`] clears the scratch, [`RangeAccumulator::add_view`]
/// places one view's pixels, [`RangeAccumulator::finish`] averages, fills holes and writes
/// the top-down image. [`reproject_range`] does all three for four views.
#[derive(Debug)]
pub struct RangeAccumulator<'s> {
    cells: Cells<'s>,
    params: CameraParams,
    pose: RoverPose,
    grid: GridSpec,
    opts: RangeOptions,
    report: RangeReport,
}

impl<'s> RangeAccumulator<'s> {
    /// Checks the parameters and clears `scratch` ([`range_scratch_len`]`(grid.n)`
    /// elements) and `mask` (`n * n` bytes, the sample counts until
    /// [`RangeAccumulator::finish`] writes the validity mask there).
    pub fn new(
        params: &CameraParams,
        pose: &RoverPose,
        grid: &GridSpec,
        opts: &RangeOptions,
        scratch: &'s mut [u32],
        mask: &'s mut [u8],
    ) -> Result<Self, RangeError> {
        grid.validate()?;
        params.validate().map_err(ReprojectError::from)?;
        pose.validate().map_err(ReprojectError::from)?;
        opts.validate()?;
        let cells = grid.cells();
        let needed = range_scratch_len(grid.n);
        if scratch.len() != needed {
            return Err(RangeError::ScratchSize {
                needed,
                got: scratch.len(),
            });
        }
        check_len(Buffer::Mask, mask.len(), cells)?;
        // Safety: `u16` is valid for every bit pattern and its alignment divides `u32`'s,
        // so `align_to_mut` views the whole word buffer as half-words (empty prefix and
        // suffix).
        let (_, sums, _) = unsafe { scratch.align_to_mut::<u16>() };
        let halves = sums.len();
        let sums = sums.get_mut(..cells).ok_or(RangeError::ScratchSize {
            needed,
            got: scratch_words(halves),
        })?;
        sums.fill(0);
        mask.fill(0);
        Ok(Self {
            cells: Cells {
                sums,
                counts: mask,
                relief: None,
            },
            params: *params,
            pose: *pose,
            grid: *grid,
            opts: *opts,
            report: RangeReport {
                status: [FrameStatus::Missing; 4],
                depth_missing: [false; 4],
                pixels_read: 0,
                points_used: 0,
                points_dropped: 0,
                cells_visited: 0,
                valid_cells: 0,
                filled_cells: 0,
            },
        })
    }

    /// Also accumulates the relief on `grid`'s blocks ([`super::ReliefGrid`]) into `words`
    /// ([`super::relief_words`] long, cleared here): the mean height of the points of each
    /// block, which [`super::relief_template`] reads once the accumulator is finished. The
    /// heights come from a sparse pass over the depths of each row, separate from the
    /// gray-level placement (about 8 points per block side at every distance), so the
    /// relief costs a few per cent of the reprojection; the image is the same with or
    /// without it.
    /// `grid` must be made for this accumulator's grid side.
    pub fn with_relief(
        mut self,
        grid: ReliefGrid,
        words: &'s mut [i32],
    ) -> Result<Self, RangeError> {
        if grid.offset_px() * 2 + grid.blocks() * grid.block_px() > self.grid.n {
            return Err(RangeError::BadOption);
        }
        self.cells.relief = Some(ReliefCells::new(grid, words)?);
        Ok(self)
    }

    /// Checks that `frame` and `depth` have the rig's size (errors as [`reproject_range`]).
    fn check_sizes(
        &self,
        view: View,
        frame: &ImageView<'_>,
        depth: Option<&DepthView<'_>>,
    ) -> Result<(), RangeError> {
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        if (frame.width(), frame.height()) != (w, h) {
            return Err(ReprojectError::FrameSize {
                view: view.index(),
                expected: (w, h),
                got: (frame.width(), frame.height()),
            }
            .into());
        }
        if let Some(d) = depth {
            if (d.width(), d.height()) != (w, h) {
                return Err(RangeError::DepthSize {
                    view: view.index(),
                    expected: (w, h),
                    got: (d.width(), d.height()),
                });
            }
        }
        Ok(())
    }

    /// Places the pixels of `view`'s `frame` at the points given by `depth` (same size as
    /// the frame, `params.width_px x params.height_px`). Returns the frame's status: a
    /// black or saturated frame, or a missing depth image, adds nothing (recorded in the
    /// report). Adding a view twice accumulates it twice.
    pub fn add_view(
        &mut self,
        view: View,
        frame: &ImageView<'_>,
        depth: Option<&DepthView<'_>>,
    ) -> Result<FrameStatus, RangeError> {
        self.check_sizes(view, frame, depth)?;
        let vi = view.index();
        let st = classify_frame(frame);
        if let Some(s) = self.report.status.get_mut(vi) {
            *s = st;
        }
        if st != FrameStatus::Ok {
            return Ok(st);
        }
        let Some(d) = depth else {
            if let Some(m) = self.report.depth_missing.get_mut(vi) {
                *m = true;
            }
            return Ok(st);
        };
        let setup = self.setup(view)?;
        let h = self.params.height_px as usize;
        for j in 0..h {
            let (Some(frow), Some(drow)) = (frame.row(j), d.row(j)) else {
                break;
            };
            self.place(&setup, j, frow, drow)?;
        }
        Ok(st)
    }

    /// Records `view`'s frame status (and that it has no depth) without placing pixels:
    /// for callers that place a view row by row ([`RangeAccumulator::add_rows`]).
    pub fn set_view_status(&mut self, view: View, status: FrameStatus, depth_missing: bool) {
        let vi = view.index();
        if let Some(s) = self.report.status.get_mut(vi) {
            *s = status;
        }
        if let Some(m) = self.report.depth_missing.get_mut(vi) {
            *m = depth_missing;
        }
    }

    /// Places rows `rows` of `view`'s `frame` (the rig's size) with depth from `band`, a
    /// depth image at the size reduced by `band.factor` (e.g. on-board stereo at half
    /// resolution): full-resolution pixel `(i, j)` takes the depth of reduced pixel
    /// `(i / factor, j / factor)`, which must lie in the band, scaled to row `j`. `row_buf` (at least the
    /// frame width, `u16`) holds the expanded depth row ([`DepthExpander`]: each depth
    /// scaled to its frame row). Does not classify the frame (see
    /// [`RangeAccumulator::set_view_status`]); the result of a row does not depend on how
    /// the rows are cut into calls.
    pub fn add_rows(
        &mut self,
        view: View,
        frame: &ImageView<'_>,
        rows: core::ops::Range<usize>,
        band: &DepthBand<'_>,
        row_buf: &mut [u16],
    ) -> Result<(), RangeError> {
        self.check_sizes(view, frame, None)?;
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        let k = band.factor.max(1);
        let bad = RangeError::DepthSize {
            view: view.index(),
            expected: (w.div_ceil(k), h.div_ceil(k)),
            got: (
                band.width,
                band.data.len().checked_div(band.width).unwrap_or(0),
            ),
        };
        if band.width * k < w || row_buf.len() < w {
            return Err(bad);
        }
        let setup = self.setup(view)?;
        let expander = DepthExpander::from_setup(&setup, w);
        for j in rows.start..rows.end.min(h) {
            let Some(frow) = frame.row(j) else { break };
            let y = (j / k).checked_sub(band.first_row).ok_or(bad)?;
            let src = band
                .data
                .get(y * band.width..(y + 1) * band.width)
                .ok_or(bad)?;
            let sky = self.opts.sky_below_gray;
            let drow = if k == 1 && sky == 0 {
                src.get(..w).ok_or(bad)?
            } else {
                let out = row_buf.get_mut(..w).ok_or(bad)?;
                if k == 1 {
                    out.copy_from_slice(src.get(..w).ok_or(bad)?);
                } else {
                    // Each frame row at its own distance ([`DepthExpander`]).
                    expander.expand_row(j, k, src, out);
                }
                if sky > 0 {
                    drop_sky(frow, out, sky);
                }
                &*out
            };
            self.place(&setup, j, frow, drow)?;
        }
        Ok(())
    }

    /// Fixed-point set-up of one view (limits, camera axes, column steps).
    fn setup(&self, view: View) -> Result<ViewSetup, RangeError> {
        let (params, grid, opts) = (&self.params, &self.grid, &self.opts);
        let n = grid.n;
        // Limits in the fixed-point units.
        let max_depth_units = {
            let q = opts.max_depth_m / opts.depth_scale_m;
            if q >= u16::MAX as f32 {
                u16::MAX
            } else {
                libm::floorf(q) as u16
            }
        };
        let one = (1u64 << POS_FRAC_BITS) as f32;
        let scale_z = opts.depth_scale_m * one;
        let scale_xy = scale_z / grid.m_per_px;
        // Heights relative to the optical centre, metres Q32 (saturating casts keep
        // infinities).
        let h_lo = ((opts.min_height_m - params.height_m) * one) as i64;
        let h_hi = ((opts.max_height_m - params.height_m) * one) as i64;
        // Ground range limit on cell centres: (2c + 1 - n)^2 + (2r + 1 - n)^2 <= (2 R/res)^2.
        let range_lim: Option<i64> = if grid.max_range_m.is_finite() {
            let r = 2.0 * grid.max_range_m / grid.m_per_px;
            if r * r < 4.0e18 {
                Some((r * r) as i64)
            } else {
                None
            }
        } else {
            None
        };
        // The optical centre is straight above the rover: n / 2 cells from the west and
        // north edges.
        let height_band = h_lo > i64::MIN || h_hi < i64::MAX;
        let lim = Limits {
            max_depth: max_depth_units,
            h_lo,
            h_hi,
            c_q: (n as i64) << (POS_FRAC_BITS - 1),
            n: n as u32,
            range_lim: range_lim.unwrap_or(i64::MAX),
        };

        let cam = Camera::new(params, &self.pose, view).map_err(ReprojectError::from)?;
        let r = cam.world_to_cam;
        // Camera right, down, forward axes in the world.
        let ax_r = [r[(0, 0)], r[(0, 1)], r[(0, 2)]];
        let ax_d = [r[(1, 0)], r[(1, 1)], r[(1, 2)]];
        let ax_f = [r[(2, 0)], r[(2, 1)], r[(2, 2)]];
        let f = cam.focal_px;
        let u0 = (0.5 - cam.cx) / f;
        // Steps per column, Q32 per depth unit: east (cells), south (cells), up (metres).
        let bx = ax_r[0] / f * scale_xy;
        let by = -ax_r[1] / f * scale_xy;
        let bz = ax_r[2] / f * scale_z;
        let b_q = [to_q(bx)?, to_q(by)?, to_q(bz)?];
        Ok(ViewSetup {
            lim,
            height_band,
            range_lim,
            ax: [ax_r, ax_d, ax_f],
            f,
            u0,
            cy: cam.cy,
            b: [bx, by, bz],
            b_q,
            scale_xy,
            scale_z,
        })
    }

    /// Places frame row `j` (`frow`, its depths `drow`, both the frame's width).
    fn place(
        &mut self,
        s: &ViewSetup,
        j: usize,
        frow: &[u8],
        drow: &[u16],
    ) -> Result<(), RangeError> {
        let (params, grid, opts) = (&self.params, &self.grid, &self.opts);
        let w = params.width_px as usize;
        let [ax_r, ax_d, ax_f] = s.ax;
        let (f, u0) = (s.f, s.u0);
        let [bx, by, bz] = s.b;
        let [bx_q, by_q, bz_q] = s.b_q;
        let vv = (j as f32 + 0.5 - s.cy) / f;
        let a = [
            ax_f[0] + ax_d[0] * vv + ax_r[0] * u0,
            ax_f[1] + ax_d[1] * vv + ax_r[1] * u0,
            ax_f[2] + ax_d[2] * vv + ax_r[2] * u0,
        ];
        let ax = a[0] * s.scale_xy;
        let ay = -a[1] * s.scale_xy;
        let az = a[2] * s.scale_z;
        // The ray at both ends of the row must stay inside RAY_LIMIT (so i32 steps
        // cannot overflow: the rounding drift over a row is below `w` units).
        let end = w as f32;
        for (a0, b0) in [(ax, bx), (ay, by), (az, bz)] {
            if libm::fabsf(a0) + libm::fabsf(b0) * end >= RAY_LIMIT {
                return Err(RangeError::Overflow);
            }
        }
        let ray = [to_q(ax)?, to_q(ay)?, to_q(az)?];
        // The row's flat-ground depth at its centre column, metres (`None` at or above the
        // horizon).
        let up_mid = a[2] + ax_r[2] * (0.5 * w as f32 - 0.5) / f;
        let flat_m = (up_mid < 0.0).then(|| params.height_m / -up_mid);
        // Column stride from that depth.
        let mut stride = 1usize;
        if let (true, Some(t)) = (opts.max_column_stride > 1, flat_m) {
            let st = libm::floorf(grid.m_per_px * f / (2.0 * t));
            if st >= 2.0 {
                stride = (st as usize).min(usize::from(opts.max_column_stride));
            }
        }
        stride = stride.min(w.max(1));
        let k = stride as i32;
        let step = [
            bx_q.wrapping_mul(k),
            by_q.wrapping_mul(k),
            bz_q.wrapping_mul(k),
        ];
        let read = w.div_ceil(stride.max(1)) as u64;
        let lim = &s.lim;
        let scratch = &mut self.cells;
        // The relief: a sparse pass of its own, about RELIEF_SAMPLES points per block side.
        if let Some(rc) = scratch.relief.as_mut() {
            let block_m = grid.m_per_px * rc.grid.block_px() as f32;
            // Half the grid's diagonal: beyond it, only terrain that rises lands in a block.
            let reach_m = grid.n as f32 * grid.m_per_px * core::f32::consts::FRAC_1_SQRT_2;
            let (rows, cols) = relief_steps(flat_m, reach_m, block_m, f, params.height_m);
            if j % rows == 0 {
                let c = cols.min(w.max(1));
                let kc = c as i32;
                let rstep = [
                    bx_q.wrapping_mul(kc),
                    by_q.wrapping_mul(kc),
                    bz_q.wrapping_mul(kc),
                ];
                relief_row(drow, c, ray, rstep, lim, rc);
            }
        }
        // Monomorphized per limit set so the default (no height band, no range limit)
        // loop keeps its state in registers.
        macro_rules! row {
            ($h:literal, $r:literal) => {
                place_row::<$h, $r>(frow, drow, stride, ray, step, lim, scratch)
            };
        }
        let used = match (s.height_band, s.range_lim.is_some()) {
            (false, false) => row!(false, false),
            (true, false) => row!(true, false),
            (false, true) => row!(false, true),
            (true, true) => row!(true, true),
        };
        self.report.pixels_read += read;
        self.report.points_used += u64::from(used);
        self.report.points_dropped += read - u64::from(used);
        Ok(())
    }

    /// Averages the samples per cell into `out` (`n * n` gray levels, north-up, 0 where no
    /// data) and the mask given to [`RangeAccumulator::new`] (255 valid, 0 no data), fills
    /// holes, and returns the report of the whole reprojection.
    pub fn finish(self, out: &mut [u8]) -> Result<RangeReport, RangeError> {
        let n = self.grid.n;
        let cells = self.grid.cells();
        check_len(Buffer::Output, out.len(), cells)?;
        let Cells {
            sums, counts: mask, ..
        } = self.cells;
        let mut report = self.report;
        // Per cell: mean of the samples; the sum's slot then keeps whether the cell was
        // sampled (1) or not (0), the validity the hole filling reads.
        let mut valid = 0usize;
        for ((s, o), m) in sums.iter_mut().zip(out.iter_mut()).zip(mask.iter_mut()) {
            let cnt = u32::from(*m);
            match (u32::from(*s) + cnt / 2).checked_div(cnt) {
                Some(v) => {
                    *o = v.min(255) as u8;
                    *m = 255;
                    *s = 1;
                    valid += 1;
                }
                None => {
                    *o = 0;
                    *m = 0;
                    *s = 0;
                }
            }
        }
        let scratch = &*sums;
        report.cells_visited += cells as u64;
        // Hole filling: validity from the accumulator (unchanged), values from sampled
        // cells.
        let mut filled = 0usize;
        if self.opts.fill_min_neighbours > 0 {
            let need = u32::from(self.opts.fill_min_neighbours);
            for r in 0..n {
                for c in 0..n {
                    let k = r * n + c;
                    if scratch.get(k).is_none_or(|&a| a != 0) {
                        continue;
                    }
                    let (mut nv, mut sum) = (0u32, 0u32);
                    for rr in r.saturating_sub(1)..(r + 2).min(n) {
                        for cc in c.saturating_sub(1)..(c + 2).min(n) {
                            let kk = rr * n + cc;
                            if kk == k {
                                continue;
                            }
                            if let (Some(&a), Some(&v)) = (scratch.get(kk), out.get(kk)) {
                                if a != 0 {
                                    nv += 1;
                                    sum += u32::from(v);
                                }
                            }
                        }
                    }
                    if nv >= need {
                        if let (Some(o), Some(m)) = (out.get_mut(k), mask.get_mut(k)) {
                            *o = ((sum + nv / 2) / nv).min(255) as u8;
                            *m = 255;
                            filled += 1;
                        }
                    }
                }
            }
            report.cells_visited += cells as u64;
        }
        report.valid_cells = valid + filled;
        report.filled_cells = filled;
        Ok(report)
    }
}

/// Reprojects `frames` (front, right, rear, left; `None` for a missing camera) with their
/// `depths` (same order and sizes) into `out` (`n * n` gray levels, north-up, 0 where no
/// data) and `mask` (`n * n`; 255 valid, 0 no data), using `scratch`
/// ([`range_scratch_len`]`(grid.n)` elements, overwritten). Frames must be
/// `params.width_px x params.height_px` (any stride); black or saturated frames
/// ([`classify_frame`]) are treated as missing and reported. `grid.max_range_m` limits the
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
    fn relief_pass_samples_evenly_on_the_ground() {
        // 4 m blocks, f = 320 px, camera 2 m up, grid reach 35.4 m.
        let at = |t: Option<f32>| relief_steps(t, 35.4, 4.0, 320.0, 2.0);
        // Near: 0.5 m is 32 columns at 5 m; rows cover ~4.5 cm each, so the step is capped
        // to a power of two (11 -> 8).
        assert_eq!(at(Some(5.0)), (8, 32));
        // Far: every row, a few columns apart.
        assert_eq!(at(Some(30.0)), (1, 5));
        // Beyond the grid's reach, above the horizon or not finite: sparse rows, columns as
        // at the reach.
        for t in [
            Some(80.0),
            None,
            Some(f32::INFINITY),
            Some(f32::NAN),
            Some(-1.0),
        ] {
            assert_eq!(at(t), (RELIEF_FAR_ROW_STEP, 4), "{t:?}");
        }
        // Every row step is a power of two within its cap, every column step at least 1.
        for t in (1..400).map(|k| k as f32 * 0.1) {
            let (r, c) = at(Some(t));
            assert!(r.is_power_of_two() && r <= RELIEF_MAX_ROW_STEP, "{t}: {r}");
            assert!((1..=RELIEF_MAX_COL_STEP).contains(&c), "{t}: {c}");
        }
    }

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
