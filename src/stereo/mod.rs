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
mod expand;
mod fill;
pub mod geometry;
mod kernel;
mod prefilter;
#[cfg(test)]
mod reference;
pub mod scale;
mod shear;
mod speckle;
mod swar;

pub use band::{BandReport, StereoView};
pub use prefilter::{downsample_row, downsample_row_by, prefilter};
pub use shear::shear_row;

use crate::camera::{CameraError, CameraParams, RoverPose, View};
use crate::image::ImageView;
use crate::reproject::FrameStatus;
use core::fmt;

/// Default baseline, metres.
pub const DEFAULT_BASELINE_M: f32 = 0.30;
/// Fractional bits of the disparities ([`StereoRig::disparity_band`]): Q4, 1/16 pixel.
pub const DISPARITY_FRAC_BITS: u32 = 4;
/// Largest aggregation radius, pixels (window 15 x 15).
pub const MAX_RADIUS: u8 = 7;

/// Settings of the stereo matcher. Checked by [`StereoRig::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StereoParams {
    /// Baseline, metres: the right camera sits this far along the left camera's `+x` axis.
    /// Finite, in (0, 10].
    pub baseline_m: f32,
    /// Reduction of both frames before matching (1..=4; 2: 640 x 360 -> 320 x 180).
    pub downsample: u8,
    /// Aggregation radius `r` across, pixels at the working size (1..=7; window `2r + 1`
    /// wide).
    pub radius_px: u8,
    /// Further reduction of the rows (1..=2): every level's frames are reduced by
    /// `downsample * 2^L` across and `row_factor` times that down, so a matched row covers
    /// `row_factor * 2^L` working rows (each taking the matched depth scaled to its own
    /// flat-ground distance). 2 halves the rows matched; disparities keep their precision.
    pub row_factor: u8,
    /// Aggregation radius down, rows of the (row-reduced) level image (1..=7; window
    /// `2 radius_rows_px + 1` tall).
    pub radius_rows_px: u8,
    /// Working-size rows matched in pairs (the frames reduced twice as much down, the
    /// working size's columns and disparities) where the flat ground of a pair spans at most
    /// this many metres down the image (finite, >= 0; 0: never): the near rows, where the
    /// top-down image's 0.25 m cells hold several working rows; rows a coarser level takes
    /// stay there ([`scale`]). Default 1.5 (rows within about 16 m of level ground; 0.5
    /// until 2026-12-07, 0 until 2026-12-05: `docs/stereo.md`, "The stage within 40 M" and
    /// "Rising terrain in the horizon rows").
    pub pair_rows_m: f32,
    /// Aggregation radius down in the paired rows, rows of pairs (1..=`radius_rows_px`).
    pub pair_radius_rows_px: u8,
    /// Columns of a level row whose disparity is decided (1..=2): 2 decides every other
    /// column (`x - radius_px` even: winner, uniqueness, left-right check, sub-pixel), while
    /// the window still slides over every column; a column between two decided ones takes
    /// their mean where both have a disparity and they agree within 1 px, else no data.
    /// The right image's winners come from the decided columns only.
    pub column_step: u8,
    /// Columns decided in the near rows (1..=4, at least `column_step`): a level row whose
    /// flat ground (under its top edge, level rover) `near_column_step` level columns span
    /// at most `near_column_span_m` decides every `near_column_step`-th column instead of
    /// every `column_step`-th; a column between two decided ones takes their linear blend
    /// (Q4, rounded half up) where both have a disparity and they agree within 1 px.
    pub near_column_step: u8,
    /// Ground span, metres across, of `near_column_step` level columns up to which a row
    /// takes the near step (finite, >= 0; 0: never). Default 1.0 (every fourth column
    /// decided within about 40 m, so in every row the square needs; 0.5 until 2026-12-07,
    /// 0.25 until 2026-12-05).
    pub near_column_span_m: f32,
    /// Clip of the Sobel pre-filter, gray levels (1..=63).
    pub prefilter_cap: u8,
    /// The runner-up cost must be at least this many percent above the winner's (0..=50).
    pub uniqueness_pct: u8,
    /// The runner-up must beat the winner by at least this many cost units per window pixel
    /// (0..=16; 0: off). Rejects textureless windows, where every disparity costs the same.
    pub min_gap_per_px: u8,
    /// Left-right consistency check (1 px tolerance).
    pub lr_check: bool,
    /// The sub-pixel fit.
    pub subpixel: SubPixel,
    /// Windows that follow the flat ground down the image: each right row is moved by the
    /// flat ground's disparity of its row (less a constant; linear interpolation), so the
    /// ground, whose disparity grows by `B cos t / h` pixels per row (0.15 for the
    /// default rig), keeps one disparity over a window's rows instead of spreading over
    /// `2 rv + 1` of them ([`geometry::RowRanges::shear_q8`]).
    pub ground_shear: bool,
    /// Speckle rejection: neighbours (of 8) that must agree within 1 px (0: off; 0..=8).
    pub min_support: u8,
    /// Gaps of at most this many working pixels in an output row, between two pixels whose
    /// disparities agree within 1 px, take their linear blend (0..=64; 0: off): the holes
    /// of textureless ground, not those across a depth edge.
    pub gap_fill_px: u8,
    /// Largest ground distance from the rover that matters, metres (the top-down square's
    /// corner: 25 * sqrt(2) for 50 m x 50 m). Sets the smallest disparity searched.
    pub max_ground_range_m: f32,
    /// Highest relief above the ground under the rover, metres, in [0, camera height):
    /// sets the largest disparity of each row.
    pub relief_above_m: f32,
    /// Relief above the ground near the rover, metres (>= 0, not NaN; at or above
    /// `relief_above_m`: off): a point at depth `Z` metres is searched up to
    /// `min(relief_above_m, relief_above_near_m + relief_above_grade Z)` above the ground
    /// under the rover (terrain rising with distance, not rocks taller near the rover).
    /// Default 0.5 with a grade of 0.1: the rows within about 5 m search 14 % fewer
    /// pixel-disparities with the same fixes on the development seeds (`docs/stereo.md`).
    pub relief_above_near_m: f32,
    /// Grade of the relief above with depth, metres per metre (finite, in [0, 10]).
    pub relief_above_grade: f32,
    /// Grade of the terrain searched in the horizon rows, metres per metre of depth
    /// (finite, in [0, 10]; 0: off; default 0.3 since 2026-12-07): the rows whose flat
    /// ground lies beyond `max_ground_range_m` (or above the horizon) search every point
    /// within the range that stands at most `min(relief_above_near_m, relief_above_m) +
    /// horizon_grade Z` above the ground under the rover, with no cap at `relief_above_m`:
    /// terrain rising toward the skyline, seen above the flat ground's horizon. Costs
    /// pixel-disparities (0.3 at the working size: about +48 %; at level 1,
    /// `horizon_coarse`, far less: `docs/stereo.md`, "Rising terrain in the horizon rows");
    /// the sky next to the skyline matches the skyline's edge, so pair it with the range
    /// stage's `RangeOptions::sky_below_gray`.
    pub horizon_grade: f32,
    /// The horizon rows (with `horizon_grade` on) matched at level 1, the frames reduced by
    /// `2 downsample` both ways: half the columns, rows and disparities of the working size,
    /// `pair_radius_rows_px` rows down, every `column_step`-th column decided; both working
    /// rows of a level row take its depth unscaled (what those rows see is terrain rising
    /// toward the skyline, not flat ground). A quarter pixel there moves a point 20 m away
    /// by about 4 m: these rows place hills, not centimetres. On by default since
    /// 2026-12-07; cuts the horizon rows' work to about a third (`docs/stereo.md`, "Rising
    /// terrain in the horizon rows").
    pub horizon_coarse: bool,
    /// Deepest relief below the ground under the rover, metres, >= 0: sets the smallest
    /// disparity of each row.
    pub relief_below_m: f32,
    /// Uncertainty of the rover's pitch and of its roll that the ranges allow for,
    /// degrees, in [0, 30]: the ranges follow the attitude the rig is given
    /// ([`StereoRig::for_view`]; level for [`StereoRig::new`]) to within it.
    pub attitude_margin_deg: f32,
    /// Coarser scales near rows may be matched at (0..=2): level `L` reduces the frames by
    /// `downsample * 2^L` ([`scale`]); 0 matches every row at the working size.
    pub scale_levels: u8,
    /// A row is matched at a coarser level only where a quarter-pixel disparity error there
    /// moves its flat ground by at most this, metres (finite, >= 0). Default 0.45 (level 1
    /// within about 6.6 m, level 2 within 4.6 m; 0.25 until 2026-12-07, 0.175 until
    /// 2026-12-05).
    pub scale_error_m: f32,
}

impl Default for StereoParams {
    /// 0.30 m baseline, 2x reduction, rows not reduced further, 7 x 7 window, every other
    /// column decided (every fourth where four columns span at most 0.5 m), rows in pairs
    /// where a pair spans at most 0.5 m, cap 31, 10 %
    /// uniqueness, gap 1 per pixel, left-right check, support 3, 25 sqrt(2) m range, relief
    /// +1 m / -2 m (+0.5 m until 2026-12-04; `docs/stereo.md`, "Relief searched 1 m above
    /// the ground"), above that only 0.5 m + 0.1 m per metre of depth (reaching 1 m at 5 m:
    /// `docs/stereo.md`, "Relief above that grows with depth"), 2 deg, up to two coarser scales where a quarter
    /// pixel moves the ground by at most 0.25 m. The scale error, the paired rows and the
    /// fourth columns (0.25 m, 0.5 m, 0.5 m; 0.175 m, none, 0.25 m until 2026-12-05) bring the stage
    /// within its 40 M instructions on the Cortex-M7; cross sun on the development seeds 1,
    /// 5 and 6 (300 stops) the fix's share within 5 m stays 0.937 and within 1 m goes from
    /// 0.903 to 0.897, and the OpenCV benchmark's bad-pixel rate (working-size pixels) is
    /// 1.38x SGBM's (`docs/stereo.md`, "The stage within 40 M"). Windows follow the
    /// ground (`ground_shear`, since 2026-12-06): 0.76x SGBM's bad-pixel rate, the stage
    /// at 39.66 M (`docs/stereo.md`, "Windows that follow the ground"). Since 2026-12-07
    /// the horizon rows search terrain rising 0.3 m per metre of depth, matched at level 1,
    /// and the near rows are coarser (quarter pixel 0.45 m, pairs where a pair spans 1.5 m,
    /// fourth columns where four span 1 m): the fix's accuracy with its own stereo comes
    /// within 0.03 of truth depth's, the stage at 39.1 M (`docs/stereo.md`, "Rising terrain
    /// in the horizon rows").
    fn default() -> Self {
        Self {
            baseline_m: DEFAULT_BASELINE_M,
            downsample: 2,
            radius_px: 3,
            row_factor: 1,
            radius_rows_px: 3,
            pair_rows_m: 1.5,
            pair_radius_rows_px: 2,
            column_step: 2,
            near_column_step: 4,
            near_column_span_m: 1.0,
            prefilter_cap: 31,
            uniqueness_pct: 10,
            min_gap_per_px: 1,
            lr_check: true,
            subpixel: SubPixel::Parabola,
            ground_shear: true,
            min_support: 3,
            gap_fill_px: 0,
            max_ground_range_m: 35.355_34,
            relief_above_m: 1.0,
            relief_above_near_m: 0.5,
            relief_above_grade: 0.1,
            horizon_grade: 0.3,
            horizon_coarse: true,
            relief_below_m: 2.0,
            attitude_margin_deg: 2.0,
            scale_levels: 2,
            scale_error_m: 0.45,
        }
    }
}

/// How the sub-pixel disparity is fitted through the winner's cost and its two
/// neighbours' ([`crate::peak`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SubPixel {
    /// The parabola's vertex ([`crate::peak::parabola_min_offset`]).
    Parabola,
    /// Equiangular (V) line fitting ([`crate::peak::equiangular_min_offset`]), the fit of
    /// sums of absolute differences.
    Equiangular,
}

impl SubPixel {
    /// The offset of the minimum of costs `l`, `c`, `r` in units of `1 / one`.
    #[inline(always)]
    pub(crate) fn offset(self, l: i32, c: i32, r: i32, one: i32) -> i32 {
        match self {
            SubPixel::Parabola => crate::peak::parabola_min_offset(l, c, r, one),
            SubPixel::Equiangular => crate::peak::equiangular_min_offset(l, c, r, one),
        }
    }
}

/// Which image of the pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Side {
    /// The left (view) camera.
    Left,
    /// The right camera, `baseline_m` to the right.
    Right,
}

/// Which caller buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StereoBuffer {
    /// The byte scratch.
    Bytes,
    /// The `u16` scratch.
    Words,
    /// The output band.
    Output,
}

/// Errors of the stereo matcher; `Display` says what to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StereoError {
    /// The camera parameters were rejected.
    Camera(CameraError),
    /// The baseline is not finite or not in (0, 10] metres.
    Baseline,
    /// Another setting is out of range (named).
    Param(&'static str),
    /// The reduced image is too small for the window and the disparity range.
    TooSmall,
    /// No right image was given.
    MissingRight,
    /// A frame is black or saturated.
    Frame {
        /// Which image.
        side: Side,
        /// Black or saturated.
        status: FrameStatus,
    },
    /// The two images differ in size.
    PairSize {
        /// Left `(width, height)`, pixels.
        left: (usize, usize),
        /// Right `(width, height)`, pixels.
        right: (usize, usize),
    },
    /// The frames are not the size the camera parameters give.
    FrameSize {
        /// `(width, height)` expected, pixels.
        expected: (usize, usize),
        /// `(width, height)` given, pixels.
        got: (usize, usize),
    },
    /// Rows `y0..y1` are empty or not inside the output image.
    Rows {
        /// First row.
        y0: usize,
        /// One past the last row.
        y1: usize,
        /// Output height, rows.
        height: usize,
    },
    /// A buffer is too short.
    BufferSize {
        /// Which buffer.
        buffer: StereoBuffer,
        /// Elements needed.
        needed: usize,
        /// Elements given.
        got: usize,
    },
}

impl From<CameraError> for StereoError {
    fn from(e: CameraError) -> Self {
        StereoError::Camera(e)
    }
}

impl fmt::Display for StereoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            StereoError::Camera(e) => write!(
                f,
                "the camera parameters are not usable ({e}): size must be > 0, HFOV in (0, 180) deg, tilt in [-89, 89] deg, height in (0, 100] m"
            ),
            StereoError::Baseline => f.write_str(
                "the stereo baseline must be a finite distance in (0, 10] metres; without one the pair gives no depth",
            ),
            StereoError::Param(what) => write!(f, "stereo setting out of range: {what}"),
            StereoError::TooSmall => f.write_str(
                "the reduced image is too small for the matching window and the disparity range; use a smaller downsample or radius",
            ),
            StereoError::MissingRight => f.write_str(
                "no right image for this view: the view gets no stereo depth (give the pair's right frame)",
            ),
            StereoError::Frame { side, status } => write!(
                f,
                "the {} image is {}: the view gets no stereo depth",
                match side {
                    Side::Left => "left",
                    Side::Right => "right",
                },
                match status {
                    FrameStatus::Black => "black",
                    FrameStatus::Saturated => "saturated",
                    FrameStatus::Missing => "missing",
                    FrameStatus::Ok => "usable",
                }
            ),
            StereoError::PairSize { left, right } => write!(
                f,
                "the stereo pair's images differ in size: left {} x {}, right {} x {} pixels; both cameras must have the same size",
                left.0, left.1, right.0, right.1
            ),
            StereoError::FrameSize { expected, got } => write!(
                f,
                "the frames are {} x {} pixels but the camera parameters say {} x {}",
                got.0, got.1, expected.0, expected.1
            ),
            StereoError::Rows { y0, y1, height } => write!(
                f,
                "rows {y0}..{y1} are not a non-empty range inside the {height} output rows"
            ),
            StereoError::BufferSize {
                buffer,
                needed,
                got,
            } => write!(
                f,
                "the stereo {} buffer has {got} elements but needs {needed} (size it with stereo_buffer_sizes)",
                match buffer {
                    StereoBuffer::Bytes => "byte scratch",
                    StereoBuffer::Words => "u16 scratch",
                    StereoBuffer::Output => "output band",
                }
            ),
        }
    }
}

impl core::error::Error for StereoError {}

/// Buffer sizes of the matcher for one rig ([`stereo_buffer_sizes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StereoBufferSizes {
    /// Byte scratch, bytes (row rings of both images).
    pub bytes: usize,
    /// `u16` scratch, elements (column costs, winners, disparity rows).
    pub words: usize,
    /// Output width, pixels (the working size).
    pub out_width: usize,
    /// Output height, rows.
    pub out_height: usize,
    /// Disparity lanes the column sums hold per column: the most groups of four
    /// disparities (`4g .. 4g + 4`) any row's range touches, at any level, times 4.
    pub max_disparities: usize,
}

impl StereoBufferSizes {
    /// Working memory of the scratch, bytes (`bytes + 2 words`), without the output band.
    pub fn working_bytes(&self) -> usize {
        self.bytes + 2 * self.words
    }

    /// Elements of an output band of `rows` rows (`rows * out_width`).
    pub fn band_len(&self, rows: usize) -> usize {
        rows.saturating_mul(self.out_width)
    }
}

/// Scratch sizes of the matcher for `camera` and `params` (errors as [`StereoRig::new`]).
pub fn stereo_buffer_sizes(
    camera: &CameraParams,
    params: &StereoParams,
) -> Result<StereoBufferSizes, StereoError> {
    Ok(StereoRig::new(camera, params)?.buffer_sizes())
}

/// Upper bound of the scratch of any rig with a working width of at most `width` pixels,
/// aggregation radius down `radius_rows_px` and column sums of at most `max_disparities` lanes
/// (rounded up to groups of four; a rig's [`StereoBufferSizes::max_disparities`]), for
/// callers that size buffers before they know the rig ([`crate::fix::fix_buffer_sizes`]);
/// the output fields give `width` and 0 rows.
pub fn stereo_buffer_bound(
    width: usize,
    radius_rows_px: u8,
    max_disparities: usize,
) -> StereoBufferSizes {
    let groups = max_disparities.div_ceil(4);
    StereoBufferSizes {
        bytes: band::bytes_len(width, usize::from(radius_rows_px)),
        words: band::words_len(width, groups),
        out_width: width,
        out_height: 0,
        max_disparities: 4 * groups,
    }
}

/// A checked stereo rig: the camera, the matcher settings and what follows from them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoRig {
    camera: CameraParams,
    params: StereoParams,
    scales: scale::Scales,
    width: usize,
    height: usize,
    /// `f B * 1000 * 16` at the working size: depth mm = this / disparity Q4.
    depth_k: u32,
    /// Lanes of the column sums per column ([`StereoBufferSizes::max_disparities`]).
    max_disp: usize,
    /// `u16` scratch elements: the most any level in use needs.
    words: usize,
}

impl StereoRig {
    /// Checks the camera and the settings; the error names what is wrong. The row ranges
    /// are those of a level rover (pitch and roll within `attitude_margin_deg` of 0).
    pub fn new(camera: &CameraParams, params: &StereoParams) -> Result<Self, StereoError> {
        camera.validate()?;
        Self::with_attitude(camera, params, &geometry::Attitude::level(camera.tilt_deg))
    }

    /// As [`StereoRig::new`] for the camera of `view` on a rover with the pitch and roll
    /// of `pose` (degrees; known, say from the rover's inertial unit, to within
    /// `attitude_margin_deg`): the row ranges follow the ground as that camera sees it.
    pub fn for_view(
        camera: &CameraParams,
        params: &StereoParams,
        pose: &RoverPose,
        view: View,
    ) -> Result<Self, StereoError> {
        camera.validate()?;
        let att = geometry::Attitude::of_view(camera, pose, view)?;
        Self::with_attitude(camera, params, &att)
    }

    fn with_attitude(
        camera: &CameraParams,
        params: &StereoParams,
        att: &geometry::Attitude,
    ) -> Result<Self, StereoError> {
        let p = params;
        if !(p.baseline_m.is_finite() && p.baseline_m > 0.0 && p.baseline_m <= 10.0) {
            return Err(StereoError::Baseline);
        }
        let checks: [(bool, &'static str); 21] = [
            ((1..=4).contains(&p.downsample), "downsample must be 1..=4"),
            (
                (1..=MAX_RADIUS).contains(&p.radius_px),
                "radius_px must be 1..=7",
            ),
            ((1..=2).contains(&p.row_factor), "row_factor must be 1 or 2"),
            (
                (1..=2).contains(&p.column_step),
                "column_step must be 1 or 2",
            ),
            (
                (1..=4).contains(&p.near_column_step) && p.near_column_step >= p.column_step,
                "near_column_step must be 1..=4 and at least column_step",
            ),
            (
                p.near_column_span_m.is_finite() && p.near_column_span_m >= 0.0,
                "near_column_span_m must be finite and >= 0",
            ),
            (
                p.pair_rows_m.is_finite() && p.pair_rows_m >= 0.0,
                "pair_rows_m must be finite and >= 0",
            ),
            (
                (1..=p.radius_rows_px).contains(&p.pair_radius_rows_px),
                "pair_radius_rows_px must be 1..=radius_rows_px",
            ),
            (
                (1..=MAX_RADIUS).contains(&p.radius_rows_px),
                "radius_rows_px must be 1..=7",
            ),
            (
                (1..=63).contains(&p.prefilter_cap),
                "prefilter_cap must be 1..=63",
            ),
            (p.uniqueness_pct <= 50, "uniqueness_pct must be 0..=50"),
            (p.min_gap_per_px <= 16, "min_gap_per_px must be 0..=16"),
            (p.min_support <= 8, "min_support must be 0..=8"),
            (p.gap_fill_px <= 64, "gap_fill_px must be 0..=64"),
            (
                !p.relief_above_near_m.is_nan()
                    && p.relief_above_near_m >= 0.0
                    && p.relief_above_grade.is_finite()
                    && (0.0..=10.0).contains(&p.relief_above_grade),
                "relief_above_near_m must be >= 0 and relief_above_grade in [0, 10]",
            ),
            (
                p.horizon_grade.is_finite() && (0.0..=10.0).contains(&p.horizon_grade),
                "horizon_grade must be finite and in [0, 10]",
            ),
            (
                p.max_ground_range_m.is_finite() && p.max_ground_range_m > 0.0,
                "max_ground_range_m must be finite and > 0",
            ),
            (
                p.relief_above_m.is_finite()
                    && p.relief_above_m >= 0.0
                    && p.relief_above_m < 0.95 * camera.height_m
                    && p.relief_below_m.is_finite()
                    && p.relief_below_m >= 0.0,
                "relief_above_m must be in [0, 0.95 camera height) and relief_below_m finite and >= 0",
            ),
            (
                p.attitude_margin_deg.is_finite()
                    && (0.0..=30.0).contains(&p.attitude_margin_deg),
                "attitude_margin_deg must be in [0, 30]",
            ),
            (
                usize::from(p.scale_levels) < scale::LEVELS,
                "scale_levels must be 0..=2",
            ),
            (
                p.scale_error_m.is_finite() && p.scale_error_m >= 0.0,
                "scale_error_m must be finite and >= 0",
            ),
        ];
        for (ok, what) in checks {
            if !ok {
                return Err(StereoError::Param(what));
            }
        }
        let r = usize::from(p.radius_px);
        let rv = usize::from(p.radius_rows_px);
        // A level can be matched when its image leaves the window room, its disparity
        // indices fit the matcher's 16-bit halves (`band`), and its widest disparity leaves
        // columns to match.
        let usable = |g: &geometry::RowRanges| {
            let (w, h) = g.size();
            w >= 2 * r + 4
                && h >= 2 * rv + 2
                && w <= 32_767
                && matches!(g.union(0, h), Some((_, hi)) if hi + 2 * r + 2 <= w)
        };
        let level0 = geometry::RowRanges::with_rows(camera, p, 0, 1, att);
        let (width, level0_rows) = level0.size();
        // The working size: the frames reduced by `downsample` both ways.
        let height = camera
            .height_px
            .checked_div(u32::from(p.downsample))
            .unwrap_or(0) as usize;
        if width < 2 * r + 4 || level0_rows < 2 * rv + 2 {
            return Err(StereoError::TooSmall);
        }
        if width > 32_767 {
            return Err(StereoError::Param(
                "downsample must reduce the frames to at most 32767 pixels wide",
            ));
        }
        if !usable(&level0) {
            return Err(StereoError::TooSmall);
        }
        let scales = scale::Scales::new(camera, p, att, usable);
        // Each level's widest row once (set-up math, one scan of its rows).
        let (mut max_disp, mut words) = (0, 0);
        for l in scales.slots() {
            let g = scales.level(l);
            let groups = g.max_groups();
            max_disp = max_disp.max(4 * groups);
            words = words.max(band::words_len(g.size().0, groups));
        }
        let kq = level0.focal_px() * p.baseline_m * 1000.0 * (1u32 << DISPARITY_FRAC_BITS) as f32;
        if !(1.0..4.0e9).contains(&kq) {
            return Err(StereoError::Baseline);
        }
        Ok(Self {
            camera: *camera,
            params: *params,
            scales,
            width,
            height,
            depth_k: libm::roundf(kq) as u32,
            max_disp,
            words,
        })
    }

    /// The settings.
    pub fn params(&self) -> &StereoParams {
        &self.params
    }

    /// The row disparity ranges at the working size (level 0).
    pub fn ranges(&self) -> &geometry::RowRanges {
        self.scales.level(0)
    }

    /// The matching level of each row and every level's disparity ranges.
    pub fn scales(&self) -> &scale::Scales {
        &self.scales
    }

    /// Output `(width, height)`, pixels (the working size: frame size / `downsample`).
    pub fn output_size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The camera parameters of the output (the working size, same HFOV, height and tilt):
    /// reproject the depth with these and the left frame reduced by [`downsample_row`].
    pub fn output_params(&self) -> CameraParams {
        CameraParams {
            width_px: self.width as u32,
            height_px: self.height as u32,
            ..self.camera
        }
    }

    /// `f B` at the working size times 16000: depth (mm) = this / disparity (Q4).
    pub fn depth_constant(&self) -> u32 {
        self.depth_k
    }

    /// Scratch sizes.
    pub fn buffer_sizes(&self) -> StereoBufferSizes {
        let w = self.width;
        let rv = usize::from(self.params.radius_rows_px);
        StereoBufferSizes {
            bytes: band::bytes_len(w, rv),
            words: self.words,
            out_width: w,
            out_height: self.height,
            max_disparities: self.max_disp,
        }
    }

    /// A stream over one view's pair in the caller's scratch (sizes of
    /// [`StereoRig::buffer_sizes`]): [`StereoView::depth_rows`] band by band, top to
    /// bottom, costs each row once. A missing right image, a black or saturated frame, or
    /// frames of the wrong size are errors (the view then has no stereo depth).
    pub fn view<'a>(
        &'a self,
        left: &'a ImageView<'a>,
        right: Option<&'a ImageView<'a>>,
        bytes: &'a mut [u8],
        words: &'a mut [u16],
    ) -> Result<StereoView<'a>, StereoError> {
        StereoView::new(self, left, right, bytes, words)
    }

    /// Depth of output rows `y0..y1` (working size) of the pair `left`, `right` into `out`
    /// (at least `(y1 - y0) * width` elements, row-major, `u16` millimetres along the
    /// optical axis, 0 = no data), using the scratch of [`StereoRig::buffer_sizes`]. A
    /// missing right image, a black or saturated frame, or frames of the wrong size are
    /// errors (the view then has no stereo depth); rows that only see sky are 0. The result
    /// of a row does not depend on how the image is cut into bands.
    #[allow(clippy::too_many_arguments)]
    pub fn depth_band(
        &self,
        left: &ImageView<'_>,
        right: Option<&ImageView<'_>>,
        y0: usize,
        y1: usize,
        bytes: &mut [u8],
        words: &mut [u16],
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        band::run(
            self,
            left,
            right,
            y0,
            y1,
            bytes,
            words,
            out,
            band::Output::DepthMm,
        )
    }

    /// As [`StereoRig::depth_band`], writing disparities instead: Q4 pixels at the working
    /// size ([`DISPARITY_FRAC_BITS`]), 0 = no data.
    #[allow(clippy::too_many_arguments)]
    pub fn disparity_band(
        &self,
        left: &ImageView<'_>,
        right: Option<&ImageView<'_>>,
        y0: usize,
        y1: usize,
        bytes: &mut [u8],
        words: &mut [u16],
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        band::run(
            self,
            left,
            right,
            y0,
            y1,
            bytes,
            words,
            out,
            band::Output::DisparityQ4,
        )
    }

    /// The whole output image (`width * height` elements) in bands of `band_rows` rows:
    /// depth in millimetres, or Q4 disparities with `disparity`.
    #[allow(clippy::too_many_arguments)]
    pub fn image(
        &self,
        left: &ImageView<'_>,
        right: Option<&ImageView<'_>>,
        band_rows: usize,
        disparity: bool,
        bytes: &mut [u8],
        words: &mut [u16],
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        let (w, h) = (self.width, self.height);
        if out.len() < w * h {
            return Err(StereoError::BufferSize {
                buffer: StereoBuffer::Output,
                needed: w * h,
                got: out.len(),
            });
        }
        let step = band_rows.clamp(1, h);
        let mode = if disparity {
            band::Output::DisparityQ4
        } else {
            band::Output::DepthMm
        };
        let mut rep = BandReport::default();
        let mut view = self.view(left, right, bytes, words)?;
        for (i, chunk) in out.chunks_mut(step * w).enumerate().take(h.div_ceil(step)) {
            let y0 = i * step;
            let y1 = (y0 + step).min(h);
            let r = view.rows(y0, y1, chunk, mode)?;
            rep.add(&r);
        }
        Ok(rep)
    }
}
