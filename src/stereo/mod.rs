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
//! 1. reduce both frames by `downsample` (box average; [`downsample_row`]) and pre-filter
//!    with a horizontal Sobel clipped to `±prefilter_cap` ([`prefilter`]), robust to the
//!    offset between the cameras;
//! 2. cost `|L(x) - R(x - d)|` aggregated over a `(2r + 1) x (2r + 1)` box by running sums
//!    (a vertical sum per column and disparity, updated by one row in and one row out, then
//!    a horizontal running sum);
//! 3. winner-take-all over the row's disparity range ([`geometry`]), rejected when the
//!    winner lies on the range's edge, when the runner-up (more than one disparity away) is
//!    not `uniqueness_pct` % worse, or when the gap is below `min_gap_per_px` per window
//!    pixel (textureless ground);
//! 4. left-right consistency: the right image's own winner (minimum of the same costs along
//!    the other diagonal) must agree within 1 px;
//! 5. sub-pixel disparity by a parabola through the three costs ([`crate::peak`]), Q4;
//! 6. speckle rejection: a disparity needs `min_support` of its 8 neighbours within 1 px;
//! 7. depth `Z = f B / d`, `u16` millimetres along the optical axis, 0 = no data: the
//!    layout [`crate::reproject::DepthView`] reads (at the reduced size,
//!    [`StereoRig::output_params`]).
//!
//! Only the rows and disparities that can hold ground inside the top-down square are
//! evaluated: [`geometry`] derives each row's disparity range from the rig (height, tilt,
//! attitude margin), the relief band and the largest ground range, and rows that can only
//! see sky are skipped.
//!
//! Memory: the caller's scratch of [`stereo_buffer_sizes`] (bytes and `u16` words, a few
//! tens of KB at the default 320 x 180 working size) plus the output band; frames are read
//! in place (they may live in external memory). A band of rows `y0..y1` costs `2r + 1`
//! extra rows of set-up: bands of 16 or more rows keep that below ~40 %.

mod band;
pub mod geometry;
mod prefilter;

pub use band::BandReport;
pub use prefilter::{downsample_row, prefilter};

use crate::camera::{CameraError, CameraParams};
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
    /// Aggregation radius `r`, pixels at the working size (1..=7; window `2r + 1` square).
    pub radius_px: u8,
    /// Clip of the Sobel pre-filter, gray levels (1..=63).
    pub prefilter_cap: u8,
    /// The runner-up cost must be at least this many percent above the winner's (0..=50).
    pub uniqueness_pct: u8,
    /// The runner-up must beat the winner by at least this many cost units per window pixel
    /// (0..=16; 0: off). Rejects textureless windows, where every disparity costs the same.
    pub min_gap_per_px: u8,
    /// Left-right consistency check (1 px tolerance).
    pub lr_check: bool,
    /// Speckle rejection: neighbours (of 8) that must agree within 1 px (0: off; 0..=8).
    pub min_support: u8,
    /// Largest ground distance from the rover that matters, metres (the top-down square's
    /// corner: 25 * sqrt(2) for 50 m x 50 m). Sets the smallest disparity searched.
    pub max_ground_range_m: f32,
    /// Highest relief above the ground under the rover, metres, in [0, camera height):
    /// sets the largest disparity of each row.
    pub relief_above_m: f32,
    /// Deepest relief below the ground under the rover, metres, >= 0: sets the smallest
    /// disparity of each row.
    pub relief_below_m: f32,
    /// Pitch and roll the ranges allow for, degrees, in [0, 30].
    pub attitude_margin_deg: f32,
}

impl Default for StereoParams {
    /// 0.30 m baseline, 2x reduction, 7 x 7 window, cap 31, 10 % uniqueness, gap 1 per
    /// pixel, left-right check, support 3, 25 sqrt(2) m range, relief +0.5 m / -2 m, 2 deg.
    fn default() -> Self {
        Self {
            baseline_m: DEFAULT_BASELINE_M,
            downsample: 2,
            radius_px: 3,
            prefilter_cap: 31,
            uniqueness_pct: 10,
            min_gap_per_px: 1,
            lr_check: true,
            min_support: 3,
            max_ground_range_m: 35.355_34,
            relief_above_m: 0.5,
            relief_below_m: 2.0,
            attitude_margin_deg: 2.0,
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
                "the camera parameters are not usable ({e:?}): size must be > 0, HFOV in (0, 180) deg, tilt in [-89, 89] deg, height in (0, 100] m"
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
    /// Most disparities a band evaluates.
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

/// A checked stereo rig: the camera, the matcher settings and what follows from them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoRig {
    camera: CameraParams,
    params: StereoParams,
    geo: geometry::RowRanges,
    width: usize,
    height: usize,
    /// `f B * 1000 * 16` at the working size: depth mm = this / disparity Q4.
    depth_k: u32,
    max_disp: usize,
}

impl StereoRig {
    /// Checks the camera and the settings; the error names what is wrong.
    pub fn new(camera: &CameraParams, params: &StereoParams) -> Result<Self, StereoError> {
        camera.validate()?;
        let p = params;
        if !(p.baseline_m.is_finite() && p.baseline_m > 0.0 && p.baseline_m <= 10.0) {
            return Err(StereoError::Baseline);
        }
        let checks: [(bool, &'static str); 9] = [
            ((1..=4).contains(&p.downsample), "downsample must be 1..=4"),
            (
                (1..=MAX_RADIUS).contains(&p.radius_px),
                "radius_px must be 1..=7",
            ),
            (
                (1..=63).contains(&p.prefilter_cap),
                "prefilter_cap must be 1..=63",
            ),
            (p.uniqueness_pct <= 50, "uniqueness_pct must be 0..=50"),
            (p.min_gap_per_px <= 16, "min_gap_per_px must be 0..=16"),
            (p.min_support <= 8, "min_support must be 0..=8"),
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
        ];
        for (ok, what) in checks {
            if !ok {
                return Err(StereoError::Param(what));
            }
        }
        let k = usize::from(p.downsample);
        let width = (camera.width_px as usize).checked_div(k).unwrap_or(0);
        let height = (camera.height_px as usize).checked_div(k).unwrap_or(0);
        let r = usize::from(p.radius_px);
        if width < 2 * r + 4 || height < 2 * r + 2 {
            return Err(StereoError::TooSmall);
        }
        let geo = geometry::RowRanges::new(camera, p, width, height);
        let max_disp = geo.max_disparities();
        // The widest disparity must leave columns to match.
        if max_disp == 0 || geo.global_max() + 2 * r + 2 > width {
            return Err(StereoError::TooSmall);
        }
        let kq = geo.focal_px() * p.baseline_m * 1000.0 * (1u32 << DISPARITY_FRAC_BITS) as f32;
        if !(1.0..4.0e9).contains(&kq) {
            return Err(StereoError::Baseline);
        }
        Ok(Self {
            camera: *camera,
            params: *params,
            geo,
            width,
            height,
            depth_k: libm::roundf(kq) as u32,
            max_disp,
        })
    }

    /// The settings.
    pub fn params(&self) -> &StereoParams {
        &self.params
    }

    /// The row disparity ranges.
    pub fn ranges(&self) -> &geometry::RowRanges {
        &self.geo
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
        let r = usize::from(self.params.radius_px);
        StereoBufferSizes {
            bytes: band::bytes_len(w, r),
            words: band::words_len(w, self.max_disp),
            out_width: w,
            out_height: self.height,
            max_disparities: self.max_disp,
        }
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
        for (i, chunk) in out.chunks_mut(step * w).enumerate().take(h.div_ceil(step)) {
            let y0 = i * step;
            let y1 = (y0 + step).min(h);
            let r = band::run(self, left, right, y0, y1, bytes, words, chunk, mode)?;
            rep.add(&r);
        }
        Ok(rep)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;
    use std::vec::Vec;

    fn hash(x: i64, y: i64) -> f32 {
        let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        h ^= h >> 29;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 32;
        (h % 1000) as f32 / 1000.0
    }

    /// Value noise: a random grid every 3 px, bilinear, 40..215.
    fn texture(x: f32, y: f32) -> f32 {
        let (gx, gy) = (x / 3.0, y / 3.0);
        let (ix, iy) = (libm::floorf(gx), libm::floorf(gy));
        let (fx, fy) = (gx - ix, gy - iy);
        let (ix, iy) = (ix as i64, iy as i64);
        let a = hash(ix, iy) * (1.0 - fx) + hash(ix + 1, iy) * fx;
        let b = hash(ix, iy + 1) * (1.0 - fx) + hash(ix + 1, iy + 1) * fx;
        40.0 + 175.0 * (a * (1.0 - fy) + b * fy)
    }

    /// Full-resolution flat-ground disparity of row `v` (pixels), 0 above the horizon.
    fn flat_disparity(cam: &CameraParams, baseline: f32, v: usize) -> f32 {
        let f = cam.focal_px();
        let t = cam.tilt_deg.to_radians();
        let yn = (v as f32 + 0.5 - 0.5 * cam.height_px as f32) / f;
        let s = libm::sinf(t) + yn * libm::cosf(t);
        (f * baseline * s / cam.height_m).max(0.0)
    }

    /// A rectified pair of textured flat ground (sky rows textured too), with `flat` gray
    /// for columns below `flat_cols` of the left image (and their right counterparts).
    fn ground_pair(cam: &CameraParams, baseline: f32, flat_cols: usize) -> (Vec<u8>, Vec<u8>) {
        let (w, h) = (cam.width_px as usize, cam.height_px as usize);
        let mut l = vec![0u8; w * h];
        let mut r = vec![0u8; w * h];
        for v in 0..h {
            let d = flat_disparity(cam, baseline, v);
            for u in 0..w {
                let x = u as f32 + 0.5;
                let y = v as f32;
                let tl = if u < flat_cols { 128.0 } else { texture(x, y) };
                let xr = x + d;
                let tr = if xr < flat_cols as f32 {
                    128.0
                } else {
                    texture(xr, y)
                };
                l[v * w + u] = libm::roundf(tl) as u8;
                r[v * w + u] = libm::roundf(tr) as u8;
            }
        }
        (l, r)
    }

    struct Run {
        rig: StereoRig,
        bytes: Vec<u8>,
        words: Vec<u16>,
    }

    fn setup(params: &StereoParams) -> Run {
        let cam = CameraParams::default();
        let rig = StereoRig::new(&cam, params).unwrap();
        let s = rig.buffer_sizes();
        Run {
            rig,
            bytes: vec![0; s.bytes],
            words: vec![0; s.words],
        }
    }

    #[test]
    fn flat_ground_disparity_and_depth() {
        let cam = CameraParams::default();
        let p = StereoParams::default();
        let (l, r) = ground_pair(&cam, p.baseline_m, 0);
        let (lv, rv) = (
            ImageView::new(&l, 640, 360).unwrap(),
            ImageView::new(&r, 640, 360).unwrap(),
        );
        let mut run = setup(&p);
        let (w, h) = run.rig.output_size();
        assert_eq!((w, h), (320, 180));
        let mut disp = vec![0u16; w * h];
        let rep = run
            .rig
            .image(
                &lv,
                Some(&rv),
                16,
                true,
                &mut run.bytes,
                &mut run.words,
                &mut disp,
            )
            .unwrap();
        let first = run.rig.ranges().first_active();
        let (mut n, mut good, mut err_sum, mut cand) = (0usize, 0usize, 0.0f32, 0usize);
        for y in 0..h {
            // True disparity at the working size: the mean of the two full rows.
            let dt = 0.25
                * (flat_disparity(&cam, p.baseline_m, 2 * y)
                    + flat_disparity(&cam, p.baseline_m, 2 * y + 1));
            for x in 0..w {
                let d = disp[y * w + x];
                if y < first {
                    assert_eq!(d, 0, "sky row {y} matched");
                    continue;
                }
                // Ground within range, columns with a full window inside both images.
                if dt < 1.5 || x < 40 || x + 4 >= w {
                    continue;
                }
                cand += 1;
                if d == 0 {
                    continue;
                }
                n += 1;
                let e = (d as f32 / 16.0 - dt).abs();
                err_sum += e;
                good += usize::from(e <= 0.5);
            }
        }
        assert!(n as f32 > 0.85 * cand as f32, "coverage {n} of {cand}");
        assert!(good as f32 > 0.97 * n as f32, "{good} of {n} within 0.5 px");
        assert!(
            err_sum / (n as f32) < 0.15,
            "mean error {}",
            err_sum / n as f32
        );
        assert_eq!(rep.valid as usize, disp.iter().filter(|&&d| d != 0).count());
        assert!(rep.pixel_disparities > 0 && rep.cost_updates > rep.pixel_disparities / 2);

        // Depth: f B / d in millimetres at the bottom rows (~2.5 m).
        let mut depth = vec![0u16; w * 10];
        run.rig
            .depth_band(
                &lv,
                Some(&rv),
                170,
                180,
                &mut run.bytes,
                &mut run.words,
                &mut depth,
            )
            .unwrap();
        let y = 175;
        let t = 15f32.to_radians();
        let yn = (2.0 * y as f32 + 1.0 - 180.0) / 320.0;
        let z_true = 2000.0 / (libm::sinf(t) + yn * libm::cosf(t));
        let mut zs: Vec<u16> = depth[5 * w + 40..5 * w + 300]
            .iter()
            .copied()
            .filter(|&z| z > 0)
            .collect();
        zs.sort_unstable();
        assert!(zs.len() > 200);
        let med = zs[zs.len() / 2] as f32;
        assert!((med - z_true).abs() < 0.02 * z_true, "{med} vs {z_true}");
    }

    #[test]
    fn bands_do_not_change_the_result() {
        let cam = CameraParams::default();
        let p = StereoParams::default();
        let (l, r) = ground_pair(&cam, p.baseline_m, 0);
        let (lv, rv) = (
            ImageView::new(&l, 640, 360).unwrap(),
            ImageView::new(&r, 640, 360).unwrap(),
        );
        let mut run = setup(&p);
        let (w, h) = run.rig.output_size();
        let mut a = vec![0u16; w * h];
        let mut b = vec![0u16; w * h];
        run.rig
            .image(
                &lv,
                Some(&rv),
                h,
                true,
                &mut run.bytes,
                &mut run.words,
                &mut a,
            )
            .unwrap();
        run.rig
            .image(
                &lv,
                Some(&rv),
                7,
                true,
                &mut run.bytes,
                &mut run.words,
                &mut b,
            )
            .unwrap();
        assert!(a.iter().filter(|&&d| d != 0).count() > 10_000);
        assert!(a == b);
    }

    #[test]
    fn textureless_ground_gives_no_data() {
        let cam = CameraParams::default();
        let p = StereoParams::default();
        let (l, r) = ground_pair(&cam, p.baseline_m, 300);
        let (lv, rv) = (
            ImageView::new(&l, 640, 360).unwrap(),
            ImageView::new(&r, 640, 360).unwrap(),
        );
        let mut run = setup(&p);
        let (w, h) = run.rig.output_size();
        let mut d = vec![0u16; w * h];
        run.rig
            .image(
                &lv,
                Some(&rv),
                32,
                true,
                &mut run.bytes,
                &mut run.words,
                &mut d,
            )
            .unwrap();
        // Columns 0..150 (full 0..300) are uniform gray: nothing there (the window reaches
        // 3 px into the texture).
        let flat_hits = (0..h)
            .map(|y| d[y * w..y * w + 140].iter().filter(|&&v| v != 0).count())
            .sum::<usize>();
        assert_eq!(flat_hits, 0);
        let tex_hits = (0..h)
            .map(|y| {
                d[y * w + 160..y * w + 316]
                    .iter()
                    .filter(|&&v| v != 0)
                    .count()
            })
            .sum::<usize>();
        assert!(tex_hits > 5_000, "{tex_hits}");
    }

    #[test]
    fn bad_inputs_are_typed_errors() {
        let cam = CameraParams::default();
        for b in [0.0, f32::NAN, -0.3, f32::INFINITY] {
            let p = StereoParams {
                baseline_m: b,
                ..StereoParams::default()
            };
            assert_eq!(StereoRig::new(&cam, &p).err(), Some(StereoError::Baseline));
            assert!(stereo_buffer_sizes(&cam, &p).is_err());
        }
        let p = StereoParams {
            radius_px: 0,
            ..StereoParams::default()
        };
        assert!(matches!(
            StereoRig::new(&cam, &p),
            Err(StereoError::Param(_))
        ));

        let p = StereoParams::default();
        let mut run = setup(&p);
        let (w, _) = run.rig.output_size();
        let (l, r) = ground_pair(&cam, p.baseline_m, 0);
        let lv = ImageView::new(&l, 640, 360).unwrap();
        let rv = ImageView::new(&r, 640, 360).unwrap();
        let mut out = vec![0u16; w * 8];
        let mut go = |left: &ImageView<'_>, right: Option<&ImageView<'_>>, out: &mut [u16]| {
            run.rig
                .depth_band(left, right, 100, 108, &mut run.bytes, &mut run.words, out)
        };
        assert_eq!(
            go(&lv, None, &mut out).err(),
            Some(StereoError::MissingRight)
        );
        let black = vec![0u8; 640 * 360];
        let bv = ImageView::new(&black, 640, 360).unwrap();
        assert_eq!(
            go(&lv, Some(&bv), &mut out).err(),
            Some(StereoError::Frame {
                side: Side::Right,
                status: FrameStatus::Black
            })
        );
        let white = vec![255u8; 640 * 360];
        let wv = ImageView::new(&white, 640, 360).unwrap();
        assert_eq!(
            go(&wv, Some(&rv), &mut out).err(),
            Some(StereoError::Frame {
                side: Side::Left,
                status: FrameStatus::Saturated
            })
        );
        let small = ImageView::new(&r, 320, 360).unwrap();
        assert!(matches!(
            go(&lv, Some(&small), &mut out),
            Err(StereoError::PairSize { .. })
        ));
        let both_small = ImageView::new(&l, 320, 360).unwrap();
        assert!(matches!(
            go(&both_small, Some(&small), &mut out),
            Err(StereoError::FrameSize { .. })
        ));
        assert!(matches!(
            go(&lv, Some(&rv), &mut out[..w]),
            Err(StereoError::BufferSize {
                buffer: StereoBuffer::Output,
                ..
            })
        ));
        assert!(go(&lv, Some(&rv), &mut out).is_ok());
        let e = run.rig.depth_band(
            &lv,
            Some(&rv),
            10,
            5,
            &mut run.bytes,
            &mut run.words,
            &mut out,
        );
        assert!(matches!(e, Err(StereoError::Rows { .. })));
        let e = run
            .rig
            .depth_band(&lv, Some(&rv), 0, 8, &mut [], &mut run.words, &mut out);
        assert!(matches!(
            e,
            Err(StereoError::BufferSize {
                buffer: StereoBuffer::Bytes,
                ..
            })
        ));
        // Messages are sentences without type names.
        let msg = std::format!("{}", StereoError::MissingRight);
        assert!(msg.starts_with("no right image") && !msg.contains("StereoError"));
    }

    #[test]
    fn sizes_and_work_of_the_default_rig() {
        let cam = CameraParams::default();
        let s = stereo_buffer_sizes(&cam, &StereoParams::default()).unwrap();
        assert_eq!((s.out_width, s.out_height), (320, 180));
        assert!(
            s.max_disparities > 20 && s.max_disparities < 40,
            "{}",
            s.max_disparities
        );
        assert_eq!(s.bytes, 2 * 320 * 11);
        assert_eq!(
            s.words,
            320 * s.max_disparities + s.max_disparities + 5 * 320
        );
        assert!(s.working_bytes() < 32 * 1024, "{}", s.working_bytes());
    }
}
