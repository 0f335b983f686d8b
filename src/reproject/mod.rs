//! Integer lookup-table reprojection of the rover's four ground views into one north-up
//! top-down image (flat-ground assumption), and the range-aware path ([`reproject_range`]:
//! pixels with a depth image go to their true 3D points).
//!
//! Two steps, measured separately (`docs/reprojection.md`):
//! 1. [`Lut::build`] (once per stop, because the heading changes): for every cell of an
//!    `n x n` grid at `m_per_px` metres per cell centred on the rover, north-up, project the
//!    cell centre on the ground plane `z = ground_z_m` into each view (a 3x3 homography per
//!    view, `f32` set-up math) and store the view, the integer source pixel and a 5-bit x
//!    5-bit sub-pixel weight index, or "no data" (above the horizon, outside every view,
//!    beyond the maximum range). Where two views overlap both taps are kept and blended with
//!    a feather weight proportional to each tap's distance to its image's edge.
//! 2. [`Lut::apply`] (per frame set): integer-only bilinear sampling from the frames into a
//!    caller-provided top-down image and validity mask (255 valid, 0 no data).
//!
//! Memory: a primary [`Cell`] of 8 bytes per grid cell plus one 8-byte secondary [`Tap`] per
//! blended (overlap) cell, in caller-provided or static buffers ([`LutStorage`]). Nothing is
//! allocated and nothing panics; sizes are checked and reported as [`ReprojectError`].
//!
//! Fixed-point formats:
//! - sub-pixel position: 5 fractional bits (`1/32` pixel), weight index `fy << 5 | fx`;
//! - bilinear weights: Q10 (`(32 - fx)(32 - fy)`, ... summing to exactly 1024), from the
//!   1024-entry table [`BILINEAR_Q10`];
//! - feather weight of the secondary tap: Q8 (0..=255 of 256).
//!
//! Frames that are missing (`None`), black or saturated (see [`classify_frame`]) are not
//! sampled: their cells fall back to the overlapping view where there is one, else they are
//! marked "no data", and the [`ApplyReport`] says which frames were dropped.

mod apply;
mod lut;
mod range;
mod relief;
mod rings;

pub use apply::{classify_frame, ApplyReport, FrameStatus, BLACK_LEVEL, SATURATED_LEVEL};
pub use lut::{BuildStats, Lut};
pub use range::{
    range_scratch_bytes, range_scratch_len, reproject_range, reproject_range_relief, DepthBand,
    DepthExpander, DepthView, RangeAccumulator, RangeError, RangeOptions, RangeReport,
    DEFAULT_DEPTH_SCALE_M, DEFAULT_FILL_MIN, POS_FRAC_BITS,
};
pub use relief::{
    relief_template, relief_words, ReliefGrid, ReliefTemplate, MAX_BLOCK_PX, RELIEF_FRAC_BITS,
};
pub use rings::{equalize_rings, MAX_RINGS};

use crate::camera::{CameraError, CameraParams, RoverPose};
use crate::image::ImageView;

/// Fractional bits of the sub-pixel source position (as OpenCV's `INTER_BITS`).
pub const FRAC_BITS: u32 = 5;
/// Sub-pixel steps per pixel (`1 << FRAC_BITS`, as OpenCV's `INTER_TAB_SIZE`).
pub const FRAC_STEPS: u32 = 1 << FRAC_BITS;
/// Fractional bits of the bilinear weights (they sum to `1 << WEIGHT_BITS`).
pub const WEIGHT_BITS: u32 = 2 * FRAC_BITS;

/// Default grid side, cells (the satellite crop: 200 x 200).
pub const DEFAULT_N: usize = 200;
/// Default grid resolution, metres per cell (the satellite crop: 0.25 m/px, 50 m x 50 m).
pub const DEFAULT_M_PER_PX: f32 = 0.25;
/// Default capacity of the secondary-tap table for the default grid and rig, taps. The
/// default rig (640 x 360, 90 deg HFOV, 15 deg tilt) blends about 1 % of a 200 x 200 grid;
/// this leaves a wide margin. Overflowing it only drops feathering, never data.
pub const DEFAULT_EXTRA: usize = table_len(DEFAULT_N) / 8;

/// Smallest camera frame side the reprojection can sample (bilinear taps need 2 x 2
/// pixels), pixels.
pub const MIN_FRAME_PX: u32 = 2;

/// Number of primary cells of an `n x n` grid (`n * n`; 0 on overflow).
pub const fn table_len(n: usize) -> usize {
    match n.checked_mul(n) {
        Some(c) => c,
        None => 0,
    }
}

/// Bytes of the primary table of an `n x n` grid (8 bytes per cell).
pub const fn table_bytes(n: usize) -> usize {
    table_len(n) * core::mem::size_of::<Cell>()
}

/// Bytes of a secondary-tap table holding `taps` taps (8 bytes per tap).
pub const fn extra_bytes(taps: usize) -> usize {
    taps * core::mem::size_of::<Tap>()
}

const VIEW_SHIFT: u32 = 30;
const OFF_MASK: u32 = (1 << VIEW_SHIFT) - 1;
const NODATA: u16 = 1 << 15;

/// One grid cell of the primary table (8 bytes).
///
/// Layout: `off` = source offset `y0 * stride + x0` of the top-left bilinear tap (bits
/// 0..=29) and the view index (bits 30..=31); `wi` = weight index `fy << 5 | fx` (bits
/// 0..=9), bit 15 set for "no data"; `w2` = Q8 weight of the secondary tap (0: none);
/// `run` = how many cells from this one on (itself included, at most 255) are valid,
/// single-tap and in the same view, so that [`Lut::apply`] can sample them with one frame
/// pointer (0 for no-data and blended cells).
/// Only [`Lut::build`] writes cells, which keeps every offset inside its frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Cell {
    off: u32,
    wi: u16,
    w2: u8,
    run: u8,
}

impl Cell {
    /// A "no data" cell.
    pub const EMPTY: Cell = Cell {
        off: 0,
        wi: NODATA,
        w2: 0,
        run: 0,
    };

    /// Whether the cell has data.
    pub fn is_valid(&self) -> bool {
        self.wi & NODATA == 0
    }

    /// View index (0 front, 1 right, 2 rear, 3 left) of the primary tap.
    pub fn view(&self) -> usize {
        (self.off >> VIEW_SHIFT) as usize
    }

    /// Q8 weight of the secondary tap (0 when the cell has one tap).
    pub fn secondary_weight_q8(&self) -> u8 {
        self.w2
    }
}

impl Default for Cell {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// A secondary bilinear tap of a blended cell (8 bytes), stored in grid order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Tap {
    off: u32,
    wi: u16,
    _pad: u16,
}

impl Tap {
    /// An unused tap.
    pub const EMPTY: Tap = Tap {
        off: 0,
        wi: 0,
        _pad: 0,
    };

    /// View index of this tap.
    pub fn view(&self) -> usize {
        (self.off >> VIEW_SHIFT) as usize
    }
}

impl Default for Tap {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// Static storage for one table: `CELLS` primary cells (`n * n`) and `EXTRA` secondary
/// taps, sized at compile time (e.g. in a `static` on the target).
pub struct LutStorage<const CELLS: usize, const EXTRA: usize> {
    /// Primary cells, `CELLS * 8` bytes.
    pub cells: [Cell; CELLS],
    /// Secondary taps, `EXTRA * 8` bytes.
    pub extra: [Tap; EXTRA],
}

impl<const CELLS: usize, const EXTRA: usize> LutStorage<CELLS, EXTRA> {
    /// Empty storage.
    pub const fn new() -> Self {
        Self {
            cells: [Cell::EMPTY; CELLS],
            extra: [Tap::EMPTY; EXTRA],
        }
    }

    /// Total bytes.
    pub const fn bytes() -> usize {
        CELLS * core::mem::size_of::<Cell>() + EXTRA * core::mem::size_of::<Tap>()
    }
}

impl<const CELLS: usize, const EXTRA: usize> Default for LutStorage<CELLS, EXTRA> {
    fn default() -> Self {
        Self::new()
    }
}

/// Storage for the default grid (200 x 200 cells, [`DEFAULT_EXTRA`] secondary taps).
pub type DefaultLutStorage = LutStorage<{ table_len(DEFAULT_N) }, DEFAULT_EXTRA>;

/// Bilinear weights in Q10 for each weight index `fy << 5 | fx`: `[w00, w01, w10, w11]`
/// for the taps `(x0, y0)`, `(x0 + 1, y0)`, `(x0, y0 + 1)`, `(x0 + 1, y0 + 1)`.
pub static BILINEAR_Q10: [[u16; 4]; 1 << WEIGHT_BITS] = bilinear_table();

const fn bilinear_table() -> [[u16; 4]; 1 << WEIGHT_BITS] {
    let mut t = [[0u16; 4]; 1 << WEIGHT_BITS];
    let mut i = 0;
    while i < (1 << WEIGHT_BITS) {
        let fx = (i & (FRAC_STEPS as usize - 1)) as u16;
        let fy = (i >> FRAC_BITS) as u16;
        let s = FRAC_STEPS as u16;
        t[i] = [(s - fx) * (s - fy), fx * (s - fy), (s - fx) * fy, fx * fy];
        i += 1;
    }
    t
}

/// The top-down grid: `n x n` cells of `m_per_px` metres, north-up, centred on the rover
/// (`docs/frames.md`: cell `(col, row)` has its centre `(col + 0.5 - n/2) m_per_px` east and
/// `(n/2 - row - 0.5) m_per_px` north of the rover).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridSpec {
    /// Cells per side.
    pub n: usize,
    /// Ground size of a cell, metres.
    pub m_per_px: f32,
    /// Ground distance from the rover beyond which cells are "no data", metres
    /// (`f32::INFINITY`: no limit).
    pub max_range_m: f32,
}

impl Default for GridSpec {
    /// 200 x 200 cells at 0.25 m (50 m x 50 m, the satellite crop), no range limit.
    fn default() -> Self {
        Self {
            n: DEFAULT_N,
            m_per_px: DEFAULT_M_PER_PX,
            max_range_m: f32::INFINITY,
        }
    }
}

impl GridSpec {
    /// An `n x n` grid at `m_per_px` with no range limit.
    pub fn new(n: usize, m_per_px: f32) -> Self {
        Self {
            n,
            m_per_px,
            max_range_m: f32::INFINITY,
        }
    }

    /// Checks the grid; the error says what is wrong.
    pub fn validate(&self) -> Result<(), ReprojectError> {
        if self.n == 0 || table_len(self.n) == 0 || self.n > u16::MAX as usize {
            return Err(ReprojectError::BadGridSize);
        }
        if !(self.m_per_px.is_finite() && self.m_per_px > 0.0) {
            return Err(ReprojectError::BadResolution);
        }
        if self.max_range_m.is_nan() || self.max_range_m <= 0.0 {
            return Err(ReprojectError::BadMaxRange);
        }
        Ok(())
    }

    /// Cells in the grid (`n * n`).
    pub fn cells(&self) -> usize {
        table_len(self.n)
    }
}

/// Errors of the reprojection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReprojectError {
    /// Camera or pose parameters are invalid (zero, NaN, tilt or FOV out of range, ...).
    Camera(CameraError),
    /// Grid side is zero or too large (`n * n` must fit, `n <= 65535`).
    BadGridSize,
    /// Grid resolution is zero, negative or not finite.
    BadResolution,
    /// Maximum range is zero, negative or NaN.
    BadMaxRange,
    /// A band of grid rows is empty or reaches past the grid ([`Lut::build_rows`]).
    BadBand,
    /// Frames must be at least 2 x 2 pixels with `stride >= width`.
    FrameTooSmall,
    /// A frame's `stride * height` does not fit the table's 30-bit offsets.
    FrameTooLarge,
    /// A caller buffer has the wrong length.
    BufferSize {
        /// Which buffer.
        buffer: Buffer,
        /// Length needed, elements.
        needed: usize,
        /// Length given, elements.
        got: usize,
    },
    /// A frame's size is not the one the table was built for.
    FrameSize {
        /// View index (0 front, 1 right, 2 rear, 3 left).
        view: usize,
        /// Expected `(width, height)`, pixels.
        expected: (usize, usize),
        /// Given `(width, height)`, pixels.
        got: (usize, usize),
    },
    /// A frame's row stride is not the one the table was built for.
    FrameStride {
        /// View index.
        view: usize,
        /// Expected stride, bytes.
        expected: usize,
        /// Given stride, bytes.
        got: usize,
    },
}

/// Names a caller buffer in [`ReprojectError::BufferSize`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Buffer {
    /// The primary table (`n * n` cells).
    Cells,
    /// The top-down output image (`n * n` bytes).
    Output,
    /// The validity mask (`n * n` bytes).
    Mask,
}

impl core::fmt::Display for ReprojectError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Camera(e) => write!(f, "{e}"),
            Self::BadGridSize => write!(f, "the top-down grid side must be 1 to 65535 cells"),
            Self::BadResolution => write!(
                f,
                "the top-down grid resolution must be a finite number of metres per cell above 0"
            ),
            Self::BadMaxRange => write!(f, "the maximum range must be a number of metres above 0"),
            Self::BadBand => write!(
                f,
                "the band of grid rows is empty or reaches past the grid; give rows inside the grid"
            ),
            Self::FrameTooSmall => write!(
                f,
                "the camera frames must be at least 2 x 2 pixels, with a row stride of at least the width"
            ),
            Self::FrameTooLarge => write!(
                f,
                "the camera frames are too large for the lookup table (stride x height must stay below 2^30 bytes); use smaller frames"
            ),
            Self::BufferSize {
                buffer,
                needed,
                got,
            } => {
                let name = match buffer {
                    Buffer::Cells => "lookup-table",
                    Buffer::Output => "top-down image",
                    Buffer::Mask => "mask",
                };
                write!(
                    f,
                    "the {name} buffer has {got} elements, {needed} are needed; size it for the grid"
                )
            }
            Self::FrameSize {
                view,
                expected,
                got,
            } => write!(
                f,
                "camera frame {view} is {} x {} pixels, the table was built for {} x {}; rebuild the table or pass frames of that size",
                got.0, got.1, expected.0, expected.1
            ),
            Self::FrameStride {
                view,
                expected,
                got,
            } => write!(
                f,
                "camera frame {view} has a row stride of {got} bytes, the table was built for {expected}; rebuild the table for this stride"
            ),
        }
    }
}

impl core::error::Error for ReprojectError {}

impl From<CameraError> for ReprojectError {
    fn from(e: CameraError) -> Self {
        ReprojectError::Camera(e)
    }
}

/// One-shot reprojection for callers that do not keep the table: builds the table for
/// `pose` into `cells` / `extra`, then samples `frames` (front, right, rear, left; `None`
/// for a missing camera) into `out` (n x n, north-up, gray levels) and `mask` (255 valid,
/// 0 no data). The frames' stride must equal their width.
///
/// `cells` must hold exactly `grid.n * grid.n` cells; `extra` may hold any number of taps
/// ([`DEFAULT_EXTRA`] for the default grid).
#[allow(clippy::too_many_arguments)]
pub fn reproject_top_down(
    frames: &[Option<ImageView<'_>>; 4],
    params: &CameraParams,
    pose: &RoverPose,
    grid: &GridSpec,
    cells: &mut [Cell],
    extra: &mut [Tap],
    out: &mut [u8],
    mask: &mut [u8],
) -> Result<ApplyReport, ReprojectError> {
    let stride = params.width_px as usize;
    let lut = Lut::build(cells, extra, params, pose, grid, stride)?;
    lut.apply(frames, out, mask)
}
