//! The stereo matcher's settings ([`StereoParams`], checked by [`super::StereoRig::new`]) and
//! the sub-pixel fit ([`SubPixel`]).

use super::DEFAULT_BASELINE_M;

/// Settings of the stereo matcher. Checked by [`StereoRig::new`](super::StereoRig::new).
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
    /// stay there ([`scale`](super::scale)). Default 1.5 (rows within about 16 m of level ground; 0.5
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
    /// `2 rv + 1` of them ([`geometry::RowRanges::shear_q8`](super::geometry::RowRanges::shear_q8)).
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
    /// ([`StereoRig::for_view`](super::StereoRig::for_view); level for [`StereoRig::new`](super::StereoRig::new)) to within it.
    pub attitude_margin_deg: f32,
    /// Coarser scales near rows may be matched at (0..=2): level `L` reduces the frames by
    /// `downsample * 2^L` ([`scale`](super::scale)); 0 matches every row at the working size.
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
