//! A stereo rig ([`StereoRig`]): the checked settings of one view's pair, the disparity
//! ranges and scales its rows need, the buffers it asks for ([`stereo_buffer_sizes`]), and
//! the calls that match a band of rows.

use super::{
    band, geometry, scale, BandReport, StereoBuffer, StereoError, StereoParams, StereoView,
    DISPARITY_FRAC_BITS, MAX_RADIUS,
};
use crate::camera::{CameraParams, RoverPose, View};
use crate::image::ImageView;

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
    pub(super) camera: CameraParams,
    pub(super) params: StereoParams,
    pub(super) scales: scale::Scales,
    pub(super) width: usize,
    pub(super) height: usize,
    /// `f B * 1000 * 16` at the working size: depth mm = this / disparity Q4.
    pub(super) depth_k: u32,
    /// Lanes of the column sums per column ([`StereoBufferSizes::max_disparities`]).
    pub(super) max_disp: usize,
    /// `u16` scratch elements: the most any level in use needs.
    pub(super) words: usize,
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
    /// reproject the depth with these and the left frame reduced by [`downsample_row`](super::downsample_row).
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
