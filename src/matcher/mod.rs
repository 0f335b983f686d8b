//! Matchers: score a top-down image (with a per-pixel weight mask) against map windows.
//!
//! Every matcher implements [`Matcher`]; its scores are **higher = more similar**, so a
//! localizer can treat all matchers alike:
//! - [`l1::L1`]: minus the weighted mean absolute difference (grey levels);
//! - [`l2::L2`]: minus the weighted mean squared difference (grey levels squared);
//! - [`ncc::Ncc`]: masked, weighted normalized cross-correlation in `[-1, 1]` (MARSAUTOLOCO).
//!
//! The weight mask is a `u8` image the size of the template: `0` marks a hole ("no data",
//! not seen by any camera), `1..=255` a pixel's relative weight. A binary reprojection
//! mask (0 / 255 or 0 / 1) is used as is; [`distance_weights`] turns it into MARSAUTOLOCO's
//! optional 1 / distance weighting around the rover (the template centre).
//!
//! All per-pixel arithmetic is integer (sums in `u64` / `i64`); floats are used once per
//! window to combine the sums.

pub mod l1;
pub mod l2;
pub mod ncc;
pub mod prep;

use crate::image::{ImageView, ImageViewMut};

/// Errors of a matcher.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MatchError {
    /// Template and weight mask differ in size.
    MaskSizeMismatch,
    /// The map window (or region) is smaller than the template.
    WindowTooSmall,
    /// The weight mask has no non-zero pixel: the top-down image is all "no data".
    NoValidPixels,
    /// The template has no contrast under its mask (all valid pixels equal): nothing to
    /// correlate.
    FeaturelessTemplate,
    /// The output slice is shorter than the response grid (`needed` scores).
    OutputTooSmall {
        /// Scores needed.
        needed: usize,
    },
    /// A step of zero pixels.
    ZeroStep,
    /// Sizes so large that a count or an index would not fit the machine's integers.
    TooLarge,
}

impl core::fmt::Display for MatchError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::MaskSizeMismatch => write!(
                f,
                "the top-down image and its weight mask differ in size; give both the same width and height"
            ),
            Self::WindowTooSmall => write!(
                f,
                "the map region is smaller than the top-down image (or the matcher cannot use this size); use a larger map or a smaller top-down image"
            ),
            Self::NoValidPixels => write!(
                f,
                "the weight mask has no valid pixel: the top-down image is all \"no data\"; check the camera frames and the reprojection"
            ),
            Self::FeaturelessTemplate => write!(
                f,
                "the top-down image has no contrast under its mask, there is nothing to match; check the camera exposure"
            ),
            Self::OutputTooSmall { needed } => write!(
                f,
                "the output buffer is too small: {needed} scores are needed; pass a larger buffer"
            ),
            Self::ZeroStep => write!(f, "a step of 0 pixels was given; use a step of at least 1"),
            Self::TooLarge => write!(
                f,
                "the sizes are too large for this machine's integers; use a smaller map region or a larger step"
            ),
        }
    }
}

impl core::error::Error for MatchError {}

/// Operation counts filled by matchers and the localizer, for benchmarks and the flight
/// budget. One "MAC" is one per-pixel multiply-accumulate (or absolute-difference
/// accumulate) of a correlation sum.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OpCounts {
    /// Per-pixel accumulate operations.
    pub macs: u64,
    /// Window positions scored.
    pub windows: u64,
    /// Pixels read while downsampling (building pyramid levels).
    pub downsample_px: u64,
}

impl OpCounts {
    /// Sum of two counts.
    pub fn add(&mut self, o: &OpCounts) {
        self.macs += o.macs;
        self.windows += o.windows;
        self.downsample_px += o.downsample_px;
    }
}

/// The size of a dense response grid: `cols x rows` positions, `step` template pixels apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Grid {
    cols: usize,
    rows: usize,
    step: usize,
}

impl Grid {
    /// The grid of a `tw x th` template slid over a `rw x rh` region every `step` pixels.
    /// Every grid has at least one position, and `cols * rows` fits a `usize`
    /// ([`MatchError::TooLarge`] otherwise).
    pub fn new(
        tw: usize,
        th: usize,
        rw: usize,
        rh: usize,
        step: usize,
    ) -> Result<Self, MatchError> {
        if step == 0 {
            return Err(MatchError::ZeroStep);
        }
        if rw < tw || rh < th || tw == 0 || th == 0 {
            return Err(MatchError::WindowTooSmall);
        }
        let (cols, rows) = ((rw - tw) / step + 1, (rh - th) / step + 1);
        if cols.checked_mul(rows).is_none() {
            return Err(MatchError::TooLarge);
        }
        Ok(Self { cols, rows, step })
    }

    /// Positions along a row (west to east).
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Positions along a column (north to south).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Pixels between neighbouring positions.
    pub fn step(&self) -> usize {
        self.step
    }

    /// The same positions `step` pixels apart (e.g. a coarse grid in full-resolution pixels).
    pub fn with_step(&self, step: usize) -> Result<Self, MatchError> {
        if step == 0 {
            return Err(MatchError::ZeroStep);
        }
        Ok(Self { step, ..*self })
    }

    /// Number of positions (`cols * rows`, checked by [`Grid::new`]).
    pub fn len(&self) -> usize {
        self.cols.saturating_mul(self.rows)
    }

    /// Whether the grid is empty (never, for a grid built by [`Grid::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The grid of a dense search: `template` slid over `region` every `step` pixels
    /// ([`Grid::new`]), and the first [`Grid::len`] scores of `out`, where the search
    /// writes them ([`MatchError::OutputTooSmall`] when `out` is shorter).
    pub fn dense<'o>(
        template: &ImageView<'_>,
        region: &ImageView<'_>,
        step: usize,
        out: &'o mut [f32],
    ) -> Result<(Self, &'o mut [f32]), MatchError> {
        let grid = Self::new(
            template.width(),
            template.height(),
            region.width(),
            region.height(),
            step,
        )?;
        let out = out
            .get_mut(..grid.len())
            .ok_or(MatchError::OutputTooSmall { needed: grid.len() })?;
        Ok((grid, out))
    }
}

/// A matcher: scores a template (top-down image + weight mask) against map windows.
///
/// Scores are higher-is-better and comparable between windows of one call (not between
/// matchers). Implementations must not allocate and must not panic.
pub trait Matcher {
    /// Short name (`"l1"`, `"l2"`, `"ncc"`, ...), used in reports.
    fn name(&self) -> &'static str;

    /// Score of `template` (weighted by `weight`, `0` = hole) against `window`, whose
    /// top-left `template.width() x template.height()` pixels are compared.
    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError>;

    /// Dense response: the score of the template at every `step`-th position of `region`
    /// (top-left corners `(c * step, r * step)`), written row-major into `out`.
    /// Returns the grid. The default calls [`Matcher::score`] per position; matchers
    /// override it when template statistics can be hoisted.
    fn dense(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        region: &ImageView<'_>,
        step: usize,
        out: &mut [f32],
        ops: &mut OpCounts,
    ) -> Result<Grid, MatchError> {
        let (grid, out) = Grid::dense(template, region, step, out)?;
        let cols = core::num::NonZeroUsize::new(grid.cols).ok_or(MatchError::WindowTooSmall)?;
        for (i, o) in out.iter_mut().enumerate() {
            let (c, r) = (i % cols, i / cols);
            let win = region
                .sub(c * step, r * step, template.width(), template.height())
                .ok_or(MatchError::WindowTooSmall)?;
            *o = self.score(template, weight, &win, ops)?;
        }
        Ok(grid)
    }
}

/// Minus the weighted mean of `cost(|t - m|)` over the template (holes, `w = 0`, ignored):
/// the shared body of the L1 and L2 baselines. Integer sums (u64), one float division.
#[inline(always)]
pub(crate) fn weighted_distance(
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
    window: &ImageView<'_>,
    ops: &mut OpCounts,
    cost: impl Fn(u32) -> u32,
) -> Result<f32, MatchError> {
    check_inputs(template, weight, window)?;
    let mut total = 0u64;
    let mut acc = 0u64;
    for y in 0..template.height() {
        let (Some(t), Some(w), Some(m)) = (template.row(y), weight.row(y), window.row(y)) else {
            return Err(MatchError::WindowTooSmall);
        };
        for ((&t, &w), &m) in t.iter().zip(w).zip(m) {
            acc += (w as u32 * cost(t.abs_diff(m) as u32)) as u64;
            total += w as u64;
        }
    }
    ops.macs += (template.width() * template.height()) as u64;
    ops.windows += 1;
    if total == 0 {
        return Err(MatchError::NoValidPixels);
    }
    Ok(-(acc as f32 / total as f32))
}

/// Checks template, mask and window sizes.
pub(crate) fn check_inputs(
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
    window: &ImageView<'_>,
) -> Result<(), MatchError> {
    if template.width() != weight.width() || template.height() != weight.height() {
        return Err(MatchError::MaskSizeMismatch);
    }
    if window.width() < template.width() || window.height() < template.height() {
        return Err(MatchError::WindowTooSmall);
    }
    Ok(())
}

/// Sum of all weights of a mask.
pub fn weight_sum(weight: &ImageView<'_>) -> u64 {
    let mut s = 0u64;
    for y in 0..weight.height() {
        if let Some(row) = weight.row(y) {
            s += row.iter().map(|&w| w as u64).sum::<u64>();
        }
    }
    s
}

/// Integer square root (floor) of a `u32`.
fn isqrt(n: u32) -> u32 {
    if n < 2 {
        return n;
    }
    let n = n as u64;
    let mut x = n;
    let mut y = x.div_ceil(2);
    while y < x {
        x = y;
        y = (x + n / x) / 2;
    }
    x as u32
}

/// MARSAUTOLOCO's optional 1 / distance weighting around the rover (the template centre):
/// `out = 0` where `mask == 0`, else `round(255 * r0 / max(d, r0))` (at least 1), with `d`
/// the distance of the pixel centre from the template centre and `r0 = min_radius_px`
/// (pixels; at least 1). Integer arithmetic only.
pub fn distance_weights(
    mask: &ImageView<'_>,
    out: &mut ImageViewMut<'_>,
    min_radius_px: u32,
) -> Result<(), MatchError> {
    if mask.width() != out.width() || mask.height() != out.height() {
        return Err(MatchError::MaskSizeMismatch);
    }
    let r0 = min_radius_px.max(1);
    // Doubled coordinates: pixel centre (2c + 1), template centre (w).
    let (cw, ch) = (mask.width() as i64, mask.height() as i64);
    for y in 0..mask.height() {
        let (Some(src), Some(dst)) = (mask.row(y), out.row_mut(y)) else {
            return Err(MatchError::MaskSizeMismatch);
        };
        let dy = 2 * y as i64 + 1 - ch;
        for (x, (s, d)) in src.iter().zip(dst.iter_mut()).enumerate() {
            if *s == 0 {
                *d = 0;
                continue;
            }
            let dx = 2 * x as i64 + 1 - cw;
            let d2 = (dx * dx + dy * dy) as u64; // (2 d)^2
            let dist2x = isqrt(d2.min(u32::MAX as u64) as u32).max(2 * r0); // 2 max(d, r0)
            let w = (2 * 255 * r0 + dist2x / 2) / dist2x;
            *d = w.clamp(1, 255) as u8;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isqrt_exact() {
        for n in 0..2000u32 {
            let r = isqrt(n);
            assert!(r * r <= n && (r + 1) * (r + 1) > n, "{n}");
        }
        assert_eq!(isqrt(u32::MAX), 65535);
    }

    #[test]
    fn grid_sizes() {
        let g = Grid::new(200, 200, 1200, 1200, 50).unwrap();
        assert_eq!((g.cols, g.rows, g.len()), (21, 21, 441));
        assert_eq!(Grid::new(10, 10, 5, 20, 1), Err(MatchError::WindowTooSmall));
        assert_eq!(Grid::new(1, 1, 5, 5, 0), Err(MatchError::ZeroStep));
        assert_eq!(
            Grid::new(1, 1, usize::MAX, usize::MAX, 1),
            Err(MatchError::TooLarge)
        );
        let g = Grid::new(1, 1, usize::MAX, 1, 1).unwrap();
        assert_eq!((g.cols(), g.rows(), g.len()), (usize::MAX, 1, usize::MAX));
    }

    #[test]
    fn distance_weights_fall_off() {
        let mask = [255u8; 100];
        let m = ImageView::new(&mask, 10, 10).unwrap();
        let mut buf = [0u8; 100];
        let mut o = ImageViewMut::new(&mut buf, 10, 10).unwrap();
        distance_weights(&m, &mut o, 2).unwrap();
        // Centre pixels (within r0) get full weight, corners less, holes stay 0.
        assert_eq!(buf[4 * 10 + 4], 255);
        assert!(buf[0] < 100 && buf[0] >= 1);
        let mut holes = [255u8; 100];
        holes[3] = 0;
        let m = ImageView::new(&holes, 10, 10).unwrap();
        let mut o = ImageViewMut::new(&mut buf, 10, 10).unwrap();
        distance_weights(&m, &mut o, 2).unwrap();
        assert_eq!(buf[3], 0);
    }
}
