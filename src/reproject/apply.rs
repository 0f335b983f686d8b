//! Applying the lookup table: integer-only bilinear sampling (per frame set).

use super::{
    Buffer, Lut, ReprojectError, Tap, BILINEAR_Q10, FRAC_BITS, NODATA, OFF_MASK, VIEW_SHIFT,
};
use crate::image::ImageView;

/// Gray level at or below which a sample counts as black.
pub const BLACK_LEVEL: u8 = 10;
/// Gray level at or above which a sample counts as saturated.
pub const SATURATED_LEVEL: u8 = 250;
/// Samples per side of the grid [`classify_frame`] reads (at most 32 x 32 = 1024 pixels).
const PROBE: usize = 32;
/// Percentage of black (or saturated) samples that makes a frame unusable.
const UNUSABLE_PERCENT: usize = 99;

/// State of one view's frame in an [`ApplyReport`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameStatus {
    /// Sampled.
    Ok,
    /// The caller passed `None`: not sampled.
    Missing,
    /// At least 99 % of a 32 x 32 sampling grid is at or below [`BLACK_LEVEL`]: not sampled.
    Black,
    /// At least 99 % of a 32 x 32 sampling grid is at or above [`SATURATED_LEVEL`]: not
    /// sampled.
    Saturated,
}

impl core::fmt::Display for FrameStatus {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Ok => "sampled",
            Self::Missing => "no frame given",
            Self::Black => "the frame is black",
            Self::Saturated => "the frame is saturated",
        })
    }
}

/// What [`Lut::apply`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ApplyReport {
    /// Per view (front, right, rear, left): sampled or why not.
    pub status: [FrameStatus; 4],
    /// Cells written with data (mask 255).
    pub valid_cells: usize,
    /// Cells with data in the table that became "no data" because their frames were not
    /// sampled.
    pub lost_cells: usize,
}

impl ApplyReport {
    /// Whether every frame was sampled.
    pub fn all_ok(&self) -> bool {
        self.status.iter().all(|s| *s == FrameStatus::Ok)
    }
}

/// Classifies a frame as usable, black or saturated from a sparse grid of at most
/// 32 x 32 samples (pixel centres of an even grid), so that a frame in slow external
/// memory is never read whole.
pub fn classify_frame(frame: &ImageView<'_>) -> FrameStatus {
    let (w, h) = (frame.width(), frame.height());
    let nx = w.min(PROBE);
    let ny = h.min(PROBE);
    let mut cols = [0usize; PROBE];
    for (i, c) in cols.iter_mut().enumerate().take(nx) {
        *c = (2 * i + 1) * w / (2 * nx);
    }
    let (mut dark, mut bright, mut total) = (0usize, 0usize, 0usize);
    for j in 0..ny {
        let y = (2 * j + 1) * h / (2 * ny);
        let Some(row) = frame.row(y) else { continue };
        for &x in cols.iter().take(nx) {
            if let Some(&p) = row.get(x) {
                total += 1;
                dark += usize::from(p <= BLACK_LEVEL);
                bright += usize::from(p >= SATURATED_LEVEL);
            }
        }
    }
    if total == 0 {
        return FrameStatus::Black;
    }
    if dark * 100 >= UNUSABLE_PERCENT * total {
        FrameStatus::Black
    } else if bright * 100 >= UNUSABLE_PERCENT * total {
        FrameStatus::Saturated
    } else {
        FrameStatus::Ok
    }
}

/// Q10 bilinear sum of the four taps at `off` (no view bits) of the frame starting at
/// `base`, with weight index `wi` (`fy << 5 | fx`, bits 10..=15 clear): the dot product of
/// the four pixels with the weights of [`BILINEAR_Q10_U32`].
///
/// Safety: `base + off + stride + 1` lies inside one frame buffer.
#[inline(always)]
unsafe fn tap_q10(base: *const u8, off: usize, stride: usize, wi: u16) -> u32 {
    let w = &BILINEAR_Q10_U32[usize::from(wi) & (WEIGHTS - 1)];
    // Safety: the caller guarantees `off + stride + 1` is inside the frame; the other
    // three offsets are smaller.
    let (p00, p01, p10, p11) = unsafe {
        let p = base.add(off);
        (
            u32::from(*p),
            u32::from(*p.add(1)),
            u32::from(*p.add(stride)),
            u32::from(*p.add(stride + 1)),
        )
    };
    p00 * w[0] + p01 * w[1] + p10 * w[2] + p11 * w[3]
}

const WEIGHTS: usize = 1 << (2 * FRAC_BITS);

/// [`BILINEAR_Q10`] widened to `u32` (16 KiB) so the inner loop needs no conversions.
static BILINEAR_Q10_U32: [[u32; 4]; WEIGHTS] = widen();

const fn widen() -> [[u32; 4]; WEIGHTS] {
    let mut t = [[0u32; 4]; WEIGHTS];
    let mut i = 0;
    while i < WEIGHTS {
        let w = BILINEAR_Q10[i];
        t[i] = [w[0] as u32, w[1] as u32, w[2] as u32, w[3] as u32];
        i += 1;
    }
    t
}

const ROUND10: u32 = 1 << 9;
const ROUND18: u32 = 1 << 17;

impl Lut<'_> {
    /// Samples `frames` (front, right, rear, left; `None` for a missing camera) into `out`
    /// (`n * n` gray levels, north-up; 0 where no data) and `mask` (`n * n`; 255 valid,
    /// 0 no data). Frames must have the size and stride the table was built for. Black or
    /// saturated frames ([`classify_frame`]) are treated as missing and reported.
    pub fn apply(
        &self,
        frames: &[Option<ImageView<'_>>; 4],
        out: &mut [u8],
        mask: &mut [u8],
    ) -> Result<ApplyReport, ReprojectError> {
        self.apply_inner(frames, None, out, mask)
    }

    /// [`Lut::apply`] with the frames' states given (from [`classify_frame`], or
    /// [`FrameStatus::Missing`] to leave a view out) instead of classified again: for
    /// banded tables ([`Lut::build_rows`]), whose bands all sample the same frames. Views
    /// whose status is not [`FrameStatus::Ok`] or whose frame is `None` are not sampled;
    /// sizes and strides are checked as in [`Lut::apply`].
    pub fn apply_with_status(
        &self,
        frames: &[Option<ImageView<'_>>; 4],
        status: &[FrameStatus; 4],
        out: &mut [u8],
        mask: &mut [u8],
    ) -> Result<ApplyReport, ReprojectError> {
        self.apply_inner(frames, Some(status), out, mask)
    }

    fn apply_inner(
        &self,
        frames: &[Option<ImageView<'_>>; 4],
        given: Option<&[FrameStatus; 4]>,
        out: &mut [u8],
        mask: &mut [u8],
    ) -> Result<ApplyReport, ReprojectError> {
        let cells_n = self.cells.len();
        for (buffer, got) in [(Buffer::Output, out.len()), (Buffer::Mask, mask.len())] {
            if got != cells_n {
                return Err(ReprojectError::BufferSize {
                    buffer,
                    needed: cells_n,
                    got,
                });
            }
        }
        let mut status = [FrameStatus::Missing; 4];
        let mut data: [*const u8; 4] = [core::ptr::null(); 4];
        for (view, (f, (st, d))) in frames
            .iter()
            .zip(status.iter_mut().zip(data.iter_mut()))
            .enumerate()
        {
            let Some(f) = f else { continue };
            if (f.width(), f.height()) != (self.width, self.height) {
                return Err(ReprojectError::FrameSize {
                    view,
                    expected: (self.width, self.height),
                    got: (f.width(), f.height()),
                });
            }
            if f.stride() != self.stride {
                return Err(ReprojectError::FrameStride {
                    view,
                    expected: self.stride,
                    got: f.stride(),
                });
            }
            *st = match given {
                Some(g) => g.get(view).copied().unwrap_or(FrameStatus::Missing),
                None => classify_frame(f),
            };
            if *st == FrameStatus::Ok {
                // ImageView guarantees len >= stride * (height - 1) + width, which with the
                // table invariant keeps every tap inside the frame.
                *d = f.data().as_ptr();
            }
        }
        let ok = status.map(|s| s == FrameStatus::Ok);
        let (valid, lost) = if ok.iter().all(|&o| o) {
            self.apply_all(&data, out, mask)
        } else {
            self.apply_some(&data, &ok, out, mask)
        };
        Ok(ApplyReport {
            status,
            valid_cells: valid,
            lost_cells: lost,
        })
    }

    /// Every frame present: runs of single-tap cells in one view go through a tight
    /// loop with one frame pointer; other cells (no data, blended) one by one.
    fn apply_all(&self, data: &[*const u8; 4], out: &mut [u8], mask: &mut [u8]) -> (usize, usize) {
        let stride = self.stride;
        let mut extra = self.extra.iter();
        let mut i = 0usize;
        while let Some(c) = self.cells.get(i) {
            let run = usize::from(c.run);
            if run > 0 {
                let base = data[(c.off >> VIEW_SHIFT) as usize];
                let end = i + run;
                if let (Some(cs), Some(os), Some(ms)) = (
                    self.cells.get(i..end),
                    out.get_mut(i..end),
                    mask.get_mut(i..end),
                ) {
                    ms.fill(255);
                    for (c, o) in cs.iter().zip(os.iter_mut()) {
                        // Safety: the table invariant (Lut::build) with the size and stride
                        // checked in `apply` keeps `off + stride + 1` inside the frame; all
                        // cells of a run are in the view of `base`.
                        let a = unsafe { tap_q10(base, (c.off & OFF_MASK) as usize, stride, c.wi) };
                        *o = ((a + ROUND10) >> 10) as u8;
                    }
                    i = end;
                    continue;
                }
            }
            let (Some(o), Some(m)) = (out.get_mut(i), mask.get_mut(i)) else {
                break;
            };
            i += 1;
            if c.wi & NODATA != 0 {
                *o = 0;
                *m = 0;
                continue;
            }
            let frame = data[(c.off >> VIEW_SHIFT) as usize];
            let off = (c.off & OFF_MASK) as usize;
            // Safety: the table invariant (Lut::build) with the size and stride checked in
            // `apply` keeps `off + stride + 1` inside the frame.
            let a = unsafe { tap_q10(frame, off, stride, c.wi) };
            let v = if c.w2 == 0 {
                (a + ROUND10) >> 10
            } else {
                match extra.next() {
                    Some(t) => {
                        let f2 = data[(t.off >> VIEW_SHIFT) as usize];
                        // Safety: as above, for the secondary tap.
                        let b = unsafe { tap_q10(f2, (t.off & OFF_MASK) as usize, stride, t.wi) };
                        let w2 = u32::from(c.w2);
                        (a * (256 - w2) + b * w2 + ROUND18) >> 18
                    }
                    None => (a + ROUND10) >> 10,
                }
            };
            *o = v.min(255) as u8;
            *m = 255;
        }
        (self.stats.valid_cells, 0)
    }

    /// Some frames not sampled: cells fall back to the other tap or become "no data".
    fn apply_some(
        &self,
        data: &[*const u8; 4],
        ok: &[bool; 4],
        out: &mut [u8],
        mask: &mut [u8],
    ) -> (usize, usize) {
        let stride = self.stride;
        let mut extra = self.extra.iter();
        let (mut valid, mut lost) = (0usize, 0usize);
        for ((c, o), m) in self.cells.iter().zip(out.iter_mut()).zip(mask.iter_mut()) {
            *o = 0;
            *m = 0;
            if c.wi & NODATA != 0 {
                continue;
            }
            let second: Option<&Tap> = if c.w2 == 0 { None } else { extra.next() };
            let v1 = (c.off >> VIEW_SHIFT) as usize;
            let ok1 = ok[v1];
            let ok2 = second.filter(|t| ok[t.view()]);
            let sample = |view: usize, off: u32, wi: u16| {
                // Safety: the table invariant (Lut::build) with the size and stride
                // checked in `apply` keeps `off + stride + 1` inside the frame, and only
                // views whose frame was accepted are sampled.
                unsafe { tap_q10(data[view], (off & OFF_MASK) as usize, stride, wi) }
            };
            let v = match (ok1, ok2) {
                (true, Some(t)) => {
                    let a = sample(v1, c.off, c.wi);
                    let b = sample(t.view(), t.off, t.wi);
                    let w2 = u32::from(c.w2);
                    (a * (256 - w2) + b * w2 + ROUND18) >> 18
                }
                (true, None) => (sample(v1, c.off, c.wi) + ROUND10) >> 10,
                (false, Some(t)) => (sample(t.view(), t.off, t.wi) + ROUND10) >> 10,
                (false, None) => {
                    lost += 1;
                    continue;
                }
            };
            *o = v.min(255) as u8;
            *m = 255;
            valid += 1;
        }
        (valid, lost)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tap_equals_weight_table() {
        let stride = 5;
        let frame: [u8; 10] = [0, 255, 17, 3, 99, 255, 254, 1, 128, 77];
        for off in 0..3 {
            for wi in 0..1024u16 {
                let w = BILINEAR_Q10[wi as usize];
                let p = |k: usize| u32::from(frame[k]);
                let want = p(off) * u32::from(w[0])
                    + p(off + 1) * u32::from(w[1])
                    + p(off + stride) * u32::from(w[2])
                    + p(off + stride + 1) * u32::from(w[3]);
                // Safety: off + stride + 1 <= 8 < 10.
                let got = unsafe { tap_q10(frame.as_ptr(), off, stride, wi) };
                assert_eq!(got, want, "off {off} wi {wi}");
            }
        }
    }
}
