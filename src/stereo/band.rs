//! The band matcher: running-sum SAD block matching of the rows of one view, streamed top
//! to bottom in bands (see the module docs of [`super`] for the pipeline).
//!
//! A [`StereoView`] holds one pair, the caller's scratch and where the stream stands: the
//! filtered rows, the column sums and the last three disparity rows stay in the scratch
//! between calls, so bands that follow each other cost no set-up rows, and the column sums
//! of each row hold only the groups of four disparities its own range needs (a group that
//! enters is summed over the window's rows once). The sums are exact, so a row's result
//! does not depend on where the stream started or how the rows are cut into bands.

use super::expand::{expand_row, Passed, RowPlace};
use super::fill::fill_gaps;
use super::kernel::{
    add_groups, column, decide, right_groups, slide, slide_min, unique, update_columns,
    ColumnParams, LaneMin, UpdateCols, EDGE, UNIQUE,
};
use super::speckle::finish_row;
use super::swar::{absdiff_u8x4, split_u8x4, word};
use super::{
    Side, StereoBuffer, StereoError, StereoRig, SubPixel, DISPARITY_FRAC_BITS, MAX_RADIUS,
};
use crate::image::ImageView;
use crate::reproject::{classify_frame, FrameStatus};

/// One pixel, Q4.
pub(crate) const ONE_Q: u16 = 1 << DISPARITY_FRAC_BITS;
const RING_MAX: usize = 2 * MAX_RADIUS as usize + 2;
/// A right pixel's winner index before any candidate.
const RB_NONE: u16 = u16::MAX;
/// "No row" in the stream's state.
const NONE: usize = usize::MAX;

/// Bytes of the byte scratch for a working width `w` and radius down `rv`: per image a ring
/// of 3 reduced rows and a ring of `2 rv + 2` filtered rows.
pub(crate) fn bytes_len(w: usize, rv: usize) -> usize {
    2 * w * (3 + 2 * rv + 2)
}

/// `u16` elements of the word scratch for a level width `w` and at most `groups` groups of
/// four disparities in a row: the right image's winners (costs and indices of the even and
/// of the odd right pixels, `4 ceil(w / 2)`), a ring of 3 disparity rows (`3 w`), then, on
/// `u32` words (one element of slack for the alignment), the column sums (`2 groups` words
/// per column) and the row's aggregated costs (`2 groups` words), in the lane layout of
/// [`lane`].
pub(crate) fn words_len(w: usize, groups: usize) -> usize {
    4 * w.div_ceil(2) + 3 * w + 4 * groups * (w + 1) + 1
}

/// What one call did (sums over calls with [`BandReport::add`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BandReport {
    /// Rows matched, at their level (output rows and the rows below them that the speckle
    /// test reads, each once per stream; sky rows are not matched).
    pub rows_matched: u64,
    /// Pixel-disparities of the winner-take-all (columns with a full window times each
    /// row's range): aggregation, winner search and the left-right bookkeeping.
    pub pixel_disparities: u64,
    /// Column-cost updates (one row in, one row out: two absolute differences each): each
    /// row's groups of four disparities times the columns, a group's set-up (its sums over
    /// the `2r + 1` rows of the window, when it enters) counted as `r + 1/2` updates.
    pub cost_updates: u64,
    /// Output pixels (working size) with a disparity.
    pub valid: u64,
    /// Rejected: winner on the range edge or window outside the right image.
    pub rejected_edge: u64,
    /// Rejected: not unique or textureless.
    pub rejected_unique: u64,
    /// Rejected by the left-right check.
    pub rejected_lr: u64,
    /// Rejected as speckle.
    pub rejected_speckle: u64,
}

impl BandReport {
    /// Adds another band's counts.
    pub fn add(&mut self, o: &BandReport) {
        self.rows_matched += o.rows_matched;
        self.pixel_disparities += o.pixel_disparities;
        self.cost_updates += o.cost_updates;
        self.valid += o.valid;
        self.rejected_edge += o.rejected_edge;
        self.rejected_unique += o.rejected_unique;
        self.rejected_lr += o.rejected_lr;
        self.rejected_speckle += o.rejected_speckle;
    }
}

/// What the band writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Output {
    /// Depth, millimetres.
    DepthMm,
    /// Disparity, Q4 pixels.
    DisparityQ4,
}

/// Which rows the row rings hold (`row + 1`, 0: none).
#[derive(Clone, Copy, Debug)]
struct RingTags {
    ds: [usize; 3],
    f: [usize; RING_MAX],
}

impl RingTags {
    const EMPTY: Self = Self {
        ds: [0; 3],
        f: [0; RING_MAX],
    };
}

/// Row rings of both images at one level: reduced rows (3) and filtered rows (`2r + 2`).
struct Rings<'b> {
    ds: [&'b mut [u8]; 2],
    filt: [&'b mut [u8]; 2],
    tags: &'b mut RingTags,
    w: usize,
    h: usize,
    /// Reduction of the frames across and down.
    k: (usize, usize),
    ring: usize,
    cap: u8,
    /// The ground shear's terms ([`super::shear::shear_at`]).
    shear: (i32, i32),
}

impl<'b> Rings<'b> {
    /// The rings of a level of width `w` (level image height `h`, frames reduced by `k`
    /// across and down, `ring = 2 rv + 2` filtered rows) in `bytes` ([`bytes_len`] of the
    /// working width bounds every level's).
    #[allow(clippy::too_many_arguments)]
    fn new(
        bytes: &'b mut [u8],
        tags: &'b mut RingTags,
        w: usize,
        h: usize,
        k: (usize, usize),
        ring: usize,
        cap: u8,
        shear: (i32, i32),
    ) -> Self {
        // Lengths were checked by the caller; `min` keeps the splits free of panic paths.
        let (ds_l, rest) = bytes.split_at_mut((3 * w).min(bytes.len()));
        let (ds_r, rest) = rest.split_at_mut((3 * w).min(rest.len()));
        let (f_l, rest) = rest.split_at_mut((ring * w).min(rest.len()));
        let (f_r, _) = rest.split_at_mut((ring * w).min(rest.len()));
        Self {
            ds: [ds_l, ds_r],
            filt: [f_l, f_r],
            tags,
            w,
            h,
            k,
            ring,
            cap,
            shear,
        }
    }

    fn ensure_ds(&mut self, frames: [&ImageView<'_>; 2], q: usize) {
        let slot = q % 3;
        if self.tags.ds.get(slot) == Some(&(q + 1)) {
            return;
        }
        let w = self.w;
        for (buf, fr) in self.ds.iter_mut().zip(frames) {
            if let Some(o) = buf.get_mut(slot * w..slot * w + w) {
                super::downsample_row_by(fr, self.k.0, self.k.1, q, o);
            }
        }
        if let Some(t) = self.tags.ds.get_mut(slot) {
            *t = q + 1;
        }
    }

    /// Makes filtered row `k` (clamped to the image) present; returns its ring slot.
    fn ensure(&mut self, frames: [&ImageView<'_>; 2], k: isize) -> usize {
        let last = self.h - 1;
        let k = (k.max(0) as usize).min(last);
        // `checked_rem`: no division-by-zero panic path in the flight build (ring >= 4).
        let slot = k.checked_rem(self.ring).unwrap_or(0);
        if self.tags.f.get(slot) == Some(&(k + 1)) {
            return slot;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(last));
        self.ensure_ds(frames, a);
        self.ensure_ds(frames, k);
        self.ensure_ds(frames, b);
        let w = self.w;
        for (i, (ds, f)) in self.ds.iter().zip(self.filt.iter_mut()).enumerate() {
            let row = |q: usize| ds.get((q % 3) * w..(q % 3) * w + w).unwrap_or(&[]);
            if let Some(o) = f.get_mut(slot * w..slot * w + w) {
                super::prefilter(row(a), row(k), row(b), self.cap, o);
                if i == 1 {
                    // The right image follows the ground down the window.
                    super::shear_row(o, super::shear::shear_at(self.shear, k));
                }
            }
        }
        if let Some(t) = self.tags.f.get_mut(slot) {
            *t = k + 1;
        }
        slot
    }

    fn rows(&self, slot: usize) -> (&[u8], &[u8]) {
        let (a, b) = (slot * self.w, slot * self.w + self.w);
        let [l, r] = &self.filt;
        (l.get(a..b).unwrap_or(&[]), r.get(a..b).unwrap_or(&[]))
    }
}

/// Cost of a column whose right pixel is outside the image (the largest difference).
fn out_cost(cap: u8) -> u16 {
    2 * u16::from(cap)
}

#[inline(always)]
fn absdiff(a: u8, b: u8) -> u32 {
    u32::from(a.abs_diff(b))
}

/// Where the column cost of disparity index `j` lies in a column's words: `(word, shift)`.
///
/// Indices `4g .. 4g + 4` share words `2g` (index `4g + 3` in the low `u16` lane, `4g + 1`
/// in the high one) and `2g + 1` (`4g + 2` low, `4g` high): what [`split_u8x4`] makes of
/// the right pixels `x - dmin - 4g - 3 ..= x - dmin - 4g` loaded as one little-endian word
/// (lowest address, the largest disparity, in byte 0). Lane bounds: a column cost is at
/// most `(2r + 1) 2 cap` <= 15 * 126 = 1,890 and an aggregated cost at most
/// `(2r + 1)^2 2 cap` <= 28,350; adding one more column before removing one stays below
/// 30,240 < 2^16, and what is removed is part of the sum, so no lane ever carries into or
/// borrows from the other and plain `u32` adds and subtracts are exact lane by lane.
#[inline(always)]
pub(crate) fn lane(j: usize) -> (usize, u32) {
    // Word 2g + 1 for j % 4 in {0, 2}, 2g for {1, 3}; the high lane for {0, 1}.
    (2 * (j >> 2) + ((j & 1) ^ 1), (((j & 2) ^ 2) as u32) << 3)
}

/// Adds `add` to and subtracts `sub` from lane `j` of a column's words (bounds: [`lane`]).
#[inline(always)]
fn lane_add_sub(col: &mut [u32], j: usize, add: u32, sub: u32) {
    let (i, s) = lane(j);
    if let Some(c) = col.get_mut(i) {
        *c = *c + (add << s) - (sub << s);
    }
}

/// Groups of four disparity indices (of `groups`) whose right pixels `x - dmin - j` all
/// lie inside the image at column `x`: `4g + 3 <= x - dmin`.
#[inline(always)]
fn full_groups(x: usize, dmin: usize, groups: usize) -> usize {
    if x < dmin + 3 {
        0
    } else {
        ((x - dmin - 3) / 4 + 1).min(groups)
    }
}

/// Column sums of `n` groups of four disparities from `dmin` on: `cs` holds column `x`'s
/// words at `x * stride .. x * stride + 2 n` (the lane layout of [`lane`]).
#[derive(Clone, Copy)]
struct Sums {
    stride: usize,
    n: usize,
    dmin: usize,
}

/// Adds one filtered row pair's costs to the column sums (a right pixel outside the image
/// costs `oc`).
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
fn add_row(cs: &mut [u32], s: Sums, l: &[u8], r: &[u8], oc: u16) {
    let oc = u32::from(oc);
    let lanes = 4 * s.n;
    let w = l.len().min(r.len());
    let (n, stride, dmin) = (s.n, s.stride, s.dmin);
    if n == 0 || w == 0 || 2 * n > stride || cs.len() < (w - 1) * stride + 2 * n {
        return;
    }
    // From column `x_full` on every group's right pixels lie inside the image.
    let x_full = (dmin + 4 * n - 1).min(w);
    let (pc0, pr0, pl) = (cs.as_mut_ptr(), r.as_ptr(), l.as_ptr());
    for x in x_full..w {
        // Safety: as in `update_rows`: column x's `2 n` words lie inside `cs`, the right
        // bytes `x - dmin - 4n + 1 ..= x - dmin` inside `r`.
        unsafe {
            let l4 = u32::from(*pl.add(x)) * 0x0101_0101;
            add_groups(pc0.add(x * stride), pr0.add(x - dmin - 3), l4, n);
        }
    }
    // Columns `0 .. x_full`: some groups partly or wholly outside (those cost `oc`).
    for (x, &lp) in l.iter().enumerate().take(x_full) {
        let Some(col) = cs.get_mut(x * stride..x * stride + 2 * n) else {
            break;
        };
        let full = full_groups(x, dmin, n);
        // `hi >= 4 full`: the right pixels of the full groups are `hi - 4 full .. hi`.
        let hi = (x + 1).saturating_sub(dmin);
        let l4 = u32::from(lp) * 0x0101_0101;
        let (fast, _) = col.split_at_mut((2 * full).min(col.len()));
        if let Some(rs) = r.get(hi.saturating_sub(4 * full)..hi) {
            for (pair, c) in fast.chunks_exact_mut(2).zip(rs.chunks_exact(4).rev()) {
                let (e, o) = split_u8x4(absdiff_u8x4(l4, word(c)));
                if let [pe, po] = pair {
                    *pe += e;
                    *po += o;
                }
            }
        }
        for j in 4 * full..lanes {
            let v = match hi.checked_sub(j + 1).and_then(|xr| r.get(xr)) {
                Some(&rp) => absdiff(lp, rp),
                None => oc,
            };
            lane_add_sub(col, j, v, 0);
        }
    }
}

/// One row in (`ln`, `rn`), one row out (`lo`, `ro`) of the column sums. Lanes whose right
/// pixel is outside add and remove the same constant: unchanged.
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
fn update_rows(cs: &mut [u32], s: Sums, ln: &[u8], rn: &[u8], lo: &[u8], ro: &[u8]) {
    let w = ln.len().min(rn.len()).min(lo.len()).min(ro.len());
    let (n, stride, dmin) = (s.n, s.stride, s.dmin);
    if n == 0 || w == 0 || 2 * n > stride || cs.len() < (w - 1) * stride + 2 * n {
        return;
    }
    // From column `x_full` on every group's right pixels lie inside the image: the right
    // pixels of group k at column x are `x - dmin - 4k - 3 ..= x - dmin - 4k`.
    let x_full = (dmin + 4 * n - 1).min(w);
    if x_full < w {
        let x = x_full;
        let mut u = UpdateCols {
            pl: ln.as_ptr().wrapping_add(x),
            pm: lo.as_ptr().wrapping_add(x),
            pn: rn.as_ptr().wrapping_add(x - dmin - 3),
            po: ro.as_ptr().wrapping_add(x - dmin - 3),
            pc: cs.as_mut_ptr().wrapping_add(x * stride),
            stride: 4 * stride,
            cols: w - x,
            n,
        };
        // Safety: for every column `x_full <= x < w`: its `2 n` words lie inside `cs`
        // (checked above), its left bytes inside `ln` and `lo`, and its right bytes `x -
        // dmin - 4n + 1 ..= x - dmin` (>= 0 as x >= x_full) inside `rn` and `ro` (`w` bytes
        // each); the column sums' bounds are those of `lane`.
        unsafe { update_columns(&mut u) };
    }
    // Columns `dmin .. x_full`: some groups partly outside.
    for x in dmin..x_full {
        let (Some(col), Some(&a), Some(&b)) = (
            cs.get_mut(x * stride..x * stride + 2 * n),
            ln.get(x),
            lo.get(x),
        ) else {
            break;
        };
        let full = full_groups(x, dmin, n);
        // x >= dmin: the right pixel of index j is hi - 1 - j, inside for j < hi.
        let hi = x + 1 - dmin;
        let (a4, b4) = (u32::from(a) * 0x0101_0101, u32::from(b) * 0x0101_0101);
        let span = hi.saturating_sub(4 * full)..hi;
        let (fast, _) = col.split_at_mut((2 * full).min(col.len()));
        if let (Some(rsn), Some(rso)) = (rn.get(span.clone()), ro.get(span)) {
            for (pair, (cn, co)) in fast
                .chunks_exact_mut(2)
                .zip(rsn.chunks_exact(4).rev().zip(rso.chunks_exact(4).rev()))
            {
                let (en, on) = split_u8x4(absdiff_u8x4(a4, word(cn)));
                let (eo, oo) = split_u8x4(absdiff_u8x4(b4, word(co)));
                if let [pe, po] = pair {
                    // Add first, then subtract: exact per lane (bounds: `lane`).
                    *pe = *pe + en - eo;
                    *po = *po + on - oo;
                }
            }
        }
        for j in 4 * full..(4 * n).min(hi) {
            let xr = hi - 1 - j;
            if let (Some(&pn), Some(&po)) = (rn.get(xr), ro.get(xr)) {
                lane_add_sub(col, j, absdiff(a, pn), absdiff(b, po));
            }
        }
    }
}

/// Per-row settings of the winner-take-all.
struct RowMatch {
    w: usize,
    r: usize,
    /// Words per column of the column sums.
    stride: usize,
    /// First word of the row's groups in a column.
    w0: usize,
    /// Groups of four disparities holding the row's range.
    groups: usize,
    /// Disparity of the first group's index 0.
    d0: usize,
    /// The row's range, indices relative to `d0`.
    lo: usize,
    hi: usize,
    uniq: u32,
    gap: u32,
    lr: bool,
    sub: SubPixel,
    /// Columns decided: every `step`-th (1..=4, `Scales::column_step`).
    step: usize,
    /// The row's ground shear, Q8 pixels: added (rounded to Q4) to every disparity found,
    /// which are residuals until then ([`super::shear::add_shear`]).
    shear_q8: i32,
}

/// Added to the row's aggregated costs of indices outside its range (and, for one pass, to
/// the runner-up's excluded indices): every aggregated cost is below it (at most
/// `(2r + 1)^2 2 cap` <= 28,350, [`lane`]), and a biased one stays below 2^16 while the
/// window slides (28,350 + 2^15 + 1,890 < 2^16), so a biased lane never wins a minimum
/// that an unbiased one takes part in. The right image's winners start at this cost, so a
/// biased lane never replaces one either.
const BIAS: u32 = 0x8000;

/// Adds `v` to the lane of index `j` (relative to the row's first group) of the row's words.
#[inline(always)]
fn lane_add(ap: &mut [u32], j: usize, v: u32) {
    let (i, s) = lane(j);
    if let Some(a) = ap.get_mut(i) {
        *a += v << s;
    }
}

/// The cost of index `j` (relative to the row's first group) in the row's words.
#[inline(always)]
fn lane_cost(ap: &[u32], j: usize) -> u32 {
    let (i, s) = lane(j);
    ap.get(i).map_or(u32::MAX, |&v| (v >> s) & 0xffff)
}

/// The slide and lane minima of a column before the steady ones ([`match_row`]): `x == r`
/// (the first window, no slide) or right pixels partly outside the image.
#[inline(never)]
fn first_columns(
    ap: &mut [u32],
    cs: *const u32,
    gw: usize,
    w0: usize,
    x: usize,
    r: usize,
    groups: usize,
) -> LaneMin {
    let ap_ptr = ap.as_mut_ptr();
    // Safety: as in [`match_row`] (checked once per row): columns `x + r` and `x - r - 1`
    // (`x > r`) of the column sums hold words `w0 .. w0 + 2 groups`; `ap` has `2 groups`
    // words and is not part of them.
    unsafe {
        if x > r {
            let ci = cs.add((x + r) * gw + w0);
            let co = cs.add((x - r - 1) * gw + w0);
            slide_min::<true>(ap_ptr, ci, co, groups)
        } else {
            slide_min::<false>(ap_ptr, cs, cs, groups)
        }
    }
}

/// The right image's winners of a column before the steady ones, `base = x - d0`: the
/// groups whose four right pixels are all inside (`4k + 3 <= base`), then the inside lanes
/// of the next one at a time.
#[inline(never)]
fn right_first_columns(
    ap: &[u32],
    rb: &mut [u16],
    half: usize,
    base: usize,
    groups: usize,
    lo: usize,
    hi: usize,
) {
    if rb.len() < 4 * half || ap.len() < 2 * groups {
        return;
    }
    let n = if base >= 3 {
        ((base - 3) / 4 + 1).min(groups)
    } else {
        0
    };
    if n > 0 {
        let b = base - 3;
        let rbp = rb.as_mut_ptr();
        // Safety: `ap` has `2 groups >= 2 n` words; for `k < n` the pixels `b - 4k ..= b -
        // 4k + 3` lie in `0..=base`, `base < w <= 2 half`, so their costs (`(p & 1) half +
        // (p >> 1)`, two at a time) and indices (`4 half` bytes further) lie inside `rb`.
        unsafe {
            let pe = rbp.add((b & 1) * half + (b >> 1));
            let pd = rbp.add(((b + 1) & 1) * half + ((b + 1) >> 1));
            right_groups(ap.as_ptr(), pe, pd, 4 * half, n);
        }
    }
    if n < groups {
        for j in (4 * n).max(lo)..=hi.min(base) {
            let a = lane_cost(ap, j);
            let xr = base - j;
            let p = (xr & 1) * half + (xr >> 1);
            if let Some(&c) = rb.get(p) {
                if a < u32::from(c) {
                    if let Some(c) = rb.get_mut(p) {
                        *c = a as u16;
                    }
                    if let Some(i) = rb.get_mut(p + 2 * half) {
                        *i = j as u16;
                    }
                }
            }
        }
    }
}

/// The sub-pixel disparity (Q4, at least 1) of a unique winner `key` (`cost << 16 |
/// index`, index from `d0`) whose neighbours' costs are `costs` (index - 1 low, index + 1
/// high).
#[inline(always)]
fn sub_pixel(key: u32, costs: u32, d0: usize, sub: SubPixel) -> u16 {
    let (best, j) = (key >> 16, (key & 0xffff) as usize);
    let frac = sub.offset(
        (costs & 0xffff) as i32,
        best as i32,
        (costs >> 16) as i32,
        i32::from(ONE_Q),
    );
    let q = ((d0 + j) as i32 * i32::from(ONE_Q) + frac).max(1);
    q.min(i32::from(u16::MAX)) as u16
}

/// The right winners' pointers of a steady column ([`match_row`]): at the first one
/// (`last` is `None`) the costs of pixels `b` and `b + 1` (pixel `p` at element
/// `(p & 1) half + p / 2`), else `step` columns on from the last decided column's `(pe,
/// pd)`, pixels `b - step` and `b - step + 1`: for an even step both move `step / 2`
/// elements on in their arrays; for an odd one the parities swap, so pixel `b` is
/// `(step - 1) / 2` elements past the last pixel `b - step + 1` and pixel `b + 1` is
/// `(step + 1) / 2` past the last pixel `b - step`.
#[inline(always)]
fn right_ptrs(
    rbp: *mut u16,
    half: usize,
    b: usize,
    step: usize,
    last: Option<(*mut u16, *mut u16)>,
) -> (*mut u16, *mut u16) {
    match last {
        None => (
            rbp.wrapping_add((b & 1) * half + (b >> 1)),
            rbp.wrapping_add(((b + 1) & 1) * half + ((b + 1) >> 1)),
        ),
        Some((pe, pd)) if step & 1 == 0 => (pe.wrapping_add(step / 2), pd.wrapping_add(step / 2)),
        Some((pe, pd)) => (pd.wrapping_add(step / 2), pe.wrapping_add(step / 2 + 1)),
    }
}

/// Winner-take-all of one row from the column sums into `disp` (Q4, 0 = none): `aggw`
/// holds the row's aggregated costs (the whole groups of four holding its range, the lane
/// layout of [`lane`], indices outside the range biased by [`BIAS`]), `rb` the right
/// image's winners ([`right_groups`]).
///
/// Per column, one pass over the row's words slides the aggregation window one column on
/// and keeps, per lane, its first strict minimum ([`min_u16x2`]): every lane sees its
/// indices in increasing order, so of the four lanes the smaller cost, on a tie the smaller
/// index, is the first minimum of the whole range, what a scan in index order keeping
/// strict improvements finds. A second pass gives every right pixel its candidate of this
/// column; a right pixel sees its candidates in increasing index (one per column), so
/// keeping strict improvements is the first of its smallest costs too. The runner-up more
/// than one index from the winner is first bounded by the other lanes' minima (enough to
/// reject most textureless windows) and only computed exactly when that does not decide
/// ([`unique`]; on Armv7E-M inside the column's assembly block).
/// Indices are below 2^15 (at most the working width, [`StereoRig::new`]), so [`RB_NONE`]
/// is never one.
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
fn match_row(
    m: &RowMatch,
    colsum: &[u32],
    aggw: &mut [u32],
    rb: &mut [u16],
    disp: &mut [u16],
    rep: &mut BandReport,
) {
    disp.fill(0);
    let groups = m.groups;
    let (w0, nw) = (m.w0, 2 * groups);
    let (w, r, gw) = (m.w, m.r, m.stride);
    let half = w.div_ceil(2);
    let (lo, hi) = (m.lo, m.hi);
    // Everything the column loop reads or writes through pointers, checked once per row.
    if gw == 0
        || groups == 0
        || lo > hi
        || hi >= 4 * groups
        || w0 + nw > gw
        || colsum.len() < w * gw
        || aggw.len() < nw
        || rb.len() < 4 * half
        || disp.len() < w
        || w < 2 * r + 1
    {
        return;
    }
    let ap = aggw.get_mut(..nw).unwrap_or(&mut []);
    ap.fill(0);
    for c in colsum.chunks_exact(gw).take(2 * r + 1) {
        for (a, &v) in ap.iter_mut().zip(c.get(w0..w0 + nw).unwrap_or(&[])) {
            *a += v;
        }
    }
    for j in (0..lo).chain(hi + 1..4 * groups) {
        lane_add(ap, j, BIAS);
    }
    if m.lr {
        let (c, i) = rb.split_at_mut((2 * half).min(rb.len()));
        c.fill(BIAS as u16);
        i.iter_mut().take(2 * half).for_each(|v| *v = RB_NONE);
    }
    let dmin = m.d0;
    let lr_on = m.lr;
    let cs = colsum.as_ptr();
    let rbp = rb.as_mut_ptr();
    // From column `x_full` on, every group's right pixels lie inside the image; from
    // `x_steady` on (also past the first column, which has no slide) each column is one
    // [`column`] call.
    let x_full = dmin + 4 * groups - 1;
    let x_steady = x_full.max(r + 1);
    // The right winners' pointers of the last decided steady column.
    let mut last: Option<(*mut u16, *mut u16)> = None;
    let mut prm = ColumnParams {
        n: groups as u32,
        off: (4 * half) as u32,
        lo: lo as u32,
        hi: hi as u32,
        lim: 0,
        um1: 99 - m.uniq,
        den: 100 - m.uniq,
        gap: m.gap,
    };
    let (mut edge, mut uniq) = (0u64, 0u64);
    let step = m.step.max(1);
    // The decided columns `x` (`x - r` a multiple of `step`); after each, the window
    // slides over the `step - 1` columns that are not decided in one call.
    let mut x = r;
    // Column `x + r`'s and column `x - r - 1`'s words of the row's groups (the latter before
    // `colsum` at `x = r`: not read there), moved on with `x`.
    let mut ci = cs.wrapping_add(2 * r * gw + w0);
    let mut co = cs.wrapping_add(w0).wrapping_sub(gw);
    while x < w - r {
        let ap_ptr = ap.as_mut_ptr();
        // The largest index whose window lies inside the right image (x >= d + r).
        prm.lim = (x - r) as i32 - dmin as i32;
        // The verdict and, for a unique winner, its neighbours' costs.
        let (res, costs) = if lr_on && x >= x_steady {
            // Every group's right pixels inside: pixels `b - 4k ..= b - 4k + 3`, `b = x -
            // dmin - 3`.
            // The decided columns are `step` apart.
            let (pe, pd) = right_ptrs(rbp, half, x - dmin - 3, step, last);
            last = Some((pe, pd));
            // Safety: checked above for the row: columns `x + r < w` and `x - r - 1`
            // (`x > r`; `ci`, `co`) of `colsum` (at least `w gw` words) hold words `w0 .. w0 + nw <=
            // gw`; `ap` has `nw` words and is not part of `colsum`; `pe`, `pd` point at the
            // costs of pixels `b` and `b + 1` (`(p & 1) half + (p >> 1)`), and for `k <
            // groups` the pixels `b - 4k ..= b - 4k + 3` lie in `0..=x - dmin` (x >= x_full)
            // and below `w <= 2 half`, so their costs (two at a time) and indices (`2 half`
            // elements, `4 half` bytes further) lie inside `rb`'s `4 half` elements.
            unsafe { column(ap_ptr, ci, co, pe, pd, &prm) }
        } else {
            let acc = first_columns(ap, cs, gw, w0, x, r, groups);
            if lr_on && x >= dmin {
                right_first_columns(ap, rb, half, x - dmin, groups, lo, hi);
            }
            match decide(&acc, &prm) {
                key @ (EDGE | UNIQUE) => (key, 0),
                key => unique(ap, key, &prm),
            }
        };
        match res {
            EDGE => edge += 1,
            UNIQUE => uniq += 1,
            key => {
                if let Some(o) = disp.get_mut(x) {
                    *o = sub_pixel(key, costs, dmin, m.sub);
                }
            }
        }
        // The columns up to the next decided one (not past the row's last): the window
        // slides on.
        let n = (step - 1).min(w - r - 1 - x);
        if n > 0 {
            // Safety: checked above for the row: columns `x + 1 + r ..= x + n + r < w` and
            // `x - r ..= x + n - r - 1` (from `ci`, `co` one column on) of `colsum` (at least `w gw` words) hold words `w0 ..
            // w0 + nw <= gw`; `ap` has `nw` words and is not part of `colsum`.
            unsafe {
                slide(
                    ap_ptr,
                    ci.wrapping_add(gw),
                    co.wrapping_add(gw),
                    groups,
                    gw,
                    n,
                );
            }
        }
        x += n + 1;
        ci = ci.wrapping_add((n + 1) * gw);
        co = co.wrapping_add((n + 1) * gw);
    }
    rep.pixel_disparities += ((w - 2 * r) * (hi + 1 - lo)) as u64;
    rep.rejected_edge += edge;
    rep.rejected_unique += uniq;
    // Residuals to disparities ([`super::shear::add_shear`]), at the decided columns.
    let g4 = super::shear::shear_q4(m.shear_q8);
    let shifted = |v: u16| super::shear::sheared(v, g4);
    if lr_on {
        let mut lr = 0u64;
        // Only the decided columns (`x - r` a multiple of `step`) can hold a disparity yet.
        let mut x = r;
        while let Some(o) = disp.get_mut(x).filter(|_| x < w - r) {
            let v = *o;
            x += step;
            if v == 0 {
                continue;
            }
            let dl = usize::from((v + ONE_Q / 2) >> DISPARITY_FRAC_BITS);
            // A right pixel no candidate reached has disparity 0.
            let ok = (x - step)
                .checked_sub(dl)
                .and_then(|xr| rb.get(2 * half + (xr & 1) * half + (xr >> 1)))
                .is_some_and(|&j| {
                    let dr = match j {
                        RB_NONE => 0,
                        j => dmin + usize::from(j),
                    };
                    dr.abs_diff(dl) <= 1
                });
            if !ok {
                *o = 0;
                lr += 1;
            } else if g4 != 0 {
                *o = shifted(v);
            }
        }
        rep.rejected_lr += lr;
    } else if g4 != 0 {
        let mut x = r;
        while let Some(o) = disp.get_mut(x).filter(|_| x < w - r) {
            if *o != 0 {
                *o = shifted(*o);
            }
            x += step;
        }
    }
    // The blend of two decided columns moves with them: the shear could be added to the
    // decided columns alone.
    if step > 1 {
        super::fill::fill_between(disp, r, w - r, step);
    }
}

/// Checks the inputs of a band; returns the two frames.
pub(crate) fn check_inputs<'f, 'a>(
    rig: &StereoRig,
    left: &'f ImageView<'a>,
    right: Option<&'f ImageView<'a>>,
) -> Result<[&'f ImageView<'a>; 2], StereoError> {
    let right = right.ok_or(StereoError::MissingRight)?;
    let ls = (left.width(), left.height());
    let rs = (right.width(), right.height());
    if ls != rs {
        return Err(StereoError::PairSize {
            left: ls,
            right: rs,
        });
    }
    let expected = (rig.camera.width_px as usize, rig.camera.height_px as usize);
    if ls != expected {
        return Err(StereoError::FrameSize { expected, got: ls });
    }
    for (side, f) in [(Side::Left, left), (Side::Right, right)] {
        let status = classify_frame(f);
        if status != FrameStatus::Ok {
            return Err(StereoError::Frame { side, status });
        }
    }
    Ok([left, right])
}

/// Which column sums the scratch holds: those of row `row` ([`NONE`]: none) for groups
/// `g_lo..g_hi`, group `g` at words `2 (g - base)` of each column.
#[derive(Clone, Copy, Debug)]
struct SumsState {
    row: usize,
    g_lo: usize,
    g_hi: usize,
    base: usize,
}

/// Where a view's stream stands; the scratch holds the rows and sums it names.
#[derive(Clone, Copy, Debug)]
struct Stream {
    /// Level of the rows matched so far ([`NONE`]: nothing yet).
    level: usize,
    /// The next row (of the level's image) to match; rows `next - 3 .. next` are in the
    /// disparity ring where `disp_tag` says so.
    next: usize,
    rings: RingTags,
    disp_tag: [usize; 3],
    sums: SumsState,
}

impl Stream {
    const START: Self = Self {
        level: NONE,
        next: 0,
        rings: RingTags::EMPTY,
        disp_tag: [0; 3],
        sums: SumsState {
            row: NONE,
            g_lo: 0,
            g_hi: 0,
            base: 0,
        },
    };
}

/// One view's stereo pair matched row band by row band, top to bottom, in the caller's
/// scratch ([`StereoRig::view`]). Consecutive bands continue where the last one stopped;
/// any other band starts afresh (its set-up rows once more): the output is the same.
pub struct StereoView<'a> {
    rig: &'a StereoRig,
    frames: [&'a ImageView<'a>; 2],
    bytes: &'a mut [u8],
    words: &'a mut [u16],
    st: Stream,
}

/// How rows are finished: level width `w`, speckle support, output kind, depth constant
/// (working size) and the level (disparities are scaled by `2^level`, pixels expanded).
pub(super) struct Finish<'s> {
    w: usize,
    /// Neighbours (of 8) a disparity needs within 1 px (`StereoParams::min_support`).
    pub(super) support: u8,
    /// What the output holds.
    pub(super) mode: Output,
    /// Depth constant at the working size (`depth = depth_k / disparity`, Q4).
    pub(super) depth_k: u32,
    /// The slot ([`super::scale::SLOTS`]) of the rows.
    level: usize,
    /// Its working columns per column, as a shift.
    pub(super) shift: usize,
    /// Longest gap of a working row filled ([`super::fill::fill_gaps`]), pixels (0: off).
    gap: usize,
    /// The rig's levels (rows per level row, the flat-ground row scales).
    scales: &'s super::scale::Scales,
}

/// Working rows `rows` (all of level `level`) of a band whose output starts at working row
/// `y0`, `w` working pixels per row.
struct Band {
    level: usize,
    rows: core::ops::Range<usize>,
    y0: usize,
    w: usize,
}

impl<'a> StereoView<'a> {
    /// Checks the pair and the scratch sizes ([`StereoRig::buffer_sizes`]).
    pub(crate) fn new(
        rig: &'a StereoRig,
        left: &'a ImageView<'a>,
        right: Option<&'a ImageView<'a>>,
        bytes: &'a mut [u8],
        words: &'a mut [u16],
    ) -> Result<Self, StereoError> {
        let frames = check_inputs(rig, left, right)?;
        let sizes = rig.buffer_sizes();
        for (buffer, needed, got) in [
            (StereoBuffer::Bytes, sizes.bytes, bytes.len()),
            (StereoBuffer::Words, sizes.words, words.len()),
        ] {
            if got < needed {
                return Err(StereoError::BufferSize {
                    buffer,
                    needed,
                    got,
                });
            }
        }
        Ok(Self {
            rig,
            frames,
            bytes,
            words,
            st: Stream::START,
        })
    }

    /// Depth of output rows `y0..y1` (working size) into `out` (at least `(y1 - y0) *
    /// width` elements, row-major, `u16` millimetres along the optical axis, 0 = no data;
    /// rows that only see sky are 0). A band that starts where the last one stopped costs
    /// no set-up rows; the result of a row is the same however the image is cut.
    pub fn depth_rows(
        &mut self,
        y0: usize,
        y1: usize,
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        self.rows(y0, y1, out, Output::DepthMm)
    }

    /// As [`StereoView::depth_rows`], writing disparities instead: Q4 pixels at the
    /// working size ([`DISPARITY_FRAC_BITS`]), 0 = no data.
    pub fn disparity_rows(
        &mut self,
        y0: usize,
        y1: usize,
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        self.rows(y0, y1, out, Output::DisparityQ4)
    }

    /// Rows `y0..y1` of the working-size output into `out` (`(y1 - y0) * width`,
    /// row-major): the rows of each level ([`super::scale`]) matched at that level and
    /// expanded.
    pub(crate) fn rows(
        &mut self,
        y0: usize,
        y1: usize,
        out: &mut [u16],
        mode: Output,
    ) -> Result<BandReport, StereoError> {
        let (w, h) = (self.rig.width, self.rig.height);
        if y0 >= y1 || y1 > h {
            return Err(StereoError::Rows { y0, y1, height: h });
        }
        if out.len() < (y1 - y0) * w {
            return Err(StereoError::BufferSize {
                buffer: StereoBuffer::Output,
                needed: (y1 - y0) * w,
                got: out.len(),
            });
        }
        let out = out.get_mut(..(y1 - y0) * w).unwrap_or(&mut []);
        out.fill(0);
        let mut rep = BandReport::default();
        let sc = &self.rig.scales;
        // Runs of rows of one level.
        let mut ya = y0.max(sc.first_active());
        while ya < y1 {
            let l = sc.level_of_row(ya);
            let mut yb = ya + 1;
            while yb < y1 && sc.level_of_row(yb) == l {
                yb += 1;
            }
            let band = Band {
                level: l,
                rows: ya..yb,
                y0,
                w,
            };
            self.level_rows(&band, out, mode, &mut rep)?;
            ya = yb;
        }
        Ok(rep)
    }

    /// Matches (or takes from the stream) the rows of `band.level` that hold working rows
    /// `band.rows`, with the rows the speckle test reads around them, and writes them,
    /// expanded, into the band's output.
    fn level_rows(
        &mut self,
        band: &Band,
        out: &mut [u16],
        mode: Output,
        rep: &mut BandReport,
    ) -> Result<(), StereoError> {
        let l = band.level;
        let rig = self.rig;
        let geo = rig.scales.level(l);
        let (w, h) = geo.size();
        if band.rows.is_empty() || w == 0 || h == 0 {
            return Ok(());
        }
        let p = &rig.params;
        let r = usize::from(p.radius_px);
        let rv = rig.scales.radius_rows(l);
        let m = rig.scales.rows_per(l);
        // Level rows holding the band's rows; rows `c0..end` must be matched.
        // `checked_div`: no panic path (`m >= 1`).
        let div = |y: usize| y.checked_div(m).unwrap_or(0);
        let (qa, qb) = (div(band.rows.start), div(band.rows.end - 1) + 1);
        let c0 = qa.saturating_sub(1).max(rig.scales.first_active_of(l));
        let end = (qb + 1).min(h);
        // Continue the stream when it holds (or is about to match) exactly what is needed.
        let st = &mut self.st;
        if !(st.level == l && c0 <= st.next && st.next <= c0 + 3) {
            *st = Stream {
                level: l,
                next: c0,
                ..Stream::START
            };
        }
        let fin = Finish {
            w,
            support: p.min_support,
            mode,
            depth_k: rig.depth_k,
            level: l,
            shift: rig.scales.col_shift(l),
            gap: usize::from(p.gap_fill_px),
            scales: &rig.scales,
        };
        let Stream {
            next,
            rings: tags,
            disp_tag,
            sums,
            ..
        } = st;
        let mut rings = Rings::new(
            self.bytes,
            tags,
            w,
            h,
            rig.scales.reduction(l, usize::from(p.downsample)),
            2 * rv + 2,
            p.prefilter_cap,
            geo.shear_terms(),
        );
        // The word scratch of this level: right winners, disparity ring, column sums (a
        // stride of the level's most groups per row), the row's words.
        let stride = 2 * rig.scales.max_groups(l);
        let words = &mut *self.words;
        let (rb, rest) = words.split_at_mut((4 * w.div_ceil(2)).min(words.len()));
        let (disp, rest) = rest.split_at_mut((3 * w).min(rest.len()));
        // Safety: `u16` and `u32` are plain integers valid for every bit pattern, and
        // `align_to_mut` gives the aligned middle part as whole `u32` words (its prefix and
        // suffix, at most one `u16` each, stay unused: `words_len` has one element of slack).
        let (_, wide, _) = unsafe { rest.align_to_mut::<u32>() };
        let (colsum, rest) = wide.split_at_mut((w * stride).min(wide.len()));
        let (aggw, _) = rest.split_at_mut(stride.min(rest.len()));
        let area = ((2 * r + 1) * (2 * rv + 1)) as u32;
        let oc = out_cost(p.prefilter_cap);
        let mut q_fin = qa;
        loop {
            // Finish every row whose neighbours are matched (or cannot be).
            while q_fin < qb && q_fin < *next && (q_fin + 1 < *next || q_fin + 1 >= h) {
                finish(disp_tag, disp, q_fin, band, &fin, out, rep);
                q_fin += 1;
            }
            if *next >= end {
                break;
            }
            let q = *next;
            *next += 1;
            let Some((dlo, dhi)) = geo.row(q) else {
                sums.row = NONE;
                continue;
            };
            let (ga, gb) = (dlo / 4, dhi / 4 + 1);
            if gb - ga > stride / 2 {
                return Err(StereoError::TooSmall);
            }
            sums_to_row(
                sums,
                &mut rings,
                self.frames,
                colsum,
                stride,
                q,
                (ga, gb),
                rv,
                oc,
                rep,
            );
            let m = RowMatch {
                w,
                r,
                stride,
                w0: 2 * (ga - sums.base),
                groups: gb - ga,
                d0: 4 * ga,
                lo: dlo - 4 * ga,
                hi: dhi - 4 * ga,
                uniq: u32::from(p.uniqueness_pct),
                gap: area * u32::from(p.min_gap_per_px),
                lr: p.lr_check,
                sub: p.subpixel,
                step: rig.scales.column_step(l, q),
                shear_q8: geo.shear_q8(q),
            };
            if let Some(drow) = disp.get_mut((q % 3) * w..(q % 3) * w + w) {
                match_row(&m, colsum, aggw, rb, drow, rep);
                if let Some(t) = disp_tag.get_mut(q % 3) {
                    *t = q + 1;
                }
                rep.rows_matched += 1;
            }
        }
        Ok(())
    }
}

/// Brings the column sums to row `q` for groups `ga..gb`: groups the sums of row `q - 1`
/// hold are updated by one row in and one row out, the others set up over the window's
/// `2 rv + 1` rows; the groups kept move to the front of each column when the window would
/// run past the stride.
#[allow(clippy::too_many_arguments)]
fn sums_to_row(
    st: &mut SumsState,
    rings: &mut Rings<'_>,
    frames: [&ImageView<'_>; 2],
    colsum: &mut [u32],
    stride: usize,
    q: usize,
    (ga, gb): (usize, usize),
    rv: usize,
    oc: u16,
    rep: &mut BandReport,
) {
    let w = rings.w;
    let ri = rv as isize;
    // Groups kept from row q - 1.
    let (ka, kb) = if st.row != NONE && st.row + 1 == q {
        (ga.max(st.g_lo), gb.min(st.g_hi))
    } else {
        (ga, ga)
    };
    let (ka, kb) = if ka < kb { (ka, kb) } else { (ga, ga) };
    // Rebase when a group would lie before the base or past the stride.
    if ga < st.base || 2 * (gb - st.base) > stride {
        let (from, to, len) = (2 * (ka - st.base.min(ka)), 2 * (ka - ga), 2 * (kb - ka));
        for col in colsum.chunks_exact_mut(stride.max(1)).take(w) {
            move_words(col, from, to, len);
        }
        st.base = ga;
    }
    let sums = |g0: usize, g1: usize| Sums {
        stride,
        n: g1 - g0,
        dmin: 4 * g0,
    };
    let base = st.base;
    if kb > ka {
        let so = rings.ensure(frames, q as isize - ri - 1);
        let sn = rings.ensure(frames, q as isize + ri);
        let (lo, ro) = rings.rows(so);
        let (ln, rn) = rings.rows(sn);
        let cs = colsum.get_mut(2 * (ka - base)..).unwrap_or(&mut []);
        update_rows(cs, sums(ka, kb), ln, rn, lo, ro);
        rep.cost_updates += (w * 4 * (kb - ka)) as u64;
    }
    // New groups: below the kept ones and above them.
    for (g0, g1) in [(ga, ka), (kb, gb)] {
        if g1 <= g0 {
            continue;
        }
        let (off, n) = (2 * (g0 - base), 2 * (g1 - g0));
        for col in colsum.chunks_exact_mut(stride.max(1)).take(w) {
            if let Some(c) = col.get_mut(off..off + n) {
                c.fill(0);
            }
        }
        for k in q as isize - ri..=q as isize + ri {
            let sl = rings.ensure(frames, k);
            let (lr, rr) = rings.rows(sl);
            add_row(
                colsum.get_mut(off..).unwrap_or(&mut []),
                sums(g0, g1),
                lr,
                rr,
                oc,
            );
        }
        rep.cost_updates += ((2 * rv + 1) * w * 2 * n) as u64 / 2;
    }
    st.row = q;
    st.g_lo = ga;
    st.g_hi = gb;
}

/// Moves `len` words of `col` from `from` to `to` (the ranges may overlap; nothing moves
/// when either lies outside).
fn move_words(col: &mut [u32], from: usize, to: usize, len: usize) {
    if from + len > col.len() || to + len > col.len() || from == to {
        return;
    }
    if to < from {
        for i in 0..len {
            if let Some(&v) = col.get(from + i) {
                if let Some(d) = col.get_mut(to + i) {
                    *d = v;
                }
            }
        }
    } else {
        for i in (0..len).rev() {
            if let Some(&v) = col.get(from + i) {
                if let Some(d) = col.get_mut(to + i) {
                    *d = v;
                }
            }
        }
    }
}

/// Finishes level row `q` from the disparity ring (rows not matched are "no data") into
/// the band's working rows it covers.
fn finish(
    tag: &[usize; 3],
    disp: &[u16],
    q: usize,
    band: &Band,
    fin: &Finish,
    out: &mut [u16],
    rep: &mut BandReport,
) {
    let w = fin.w;
    let row = |y: Option<usize>| -> Option<&[u16]> {
        let y = y?;
        if tag.get(y % 3) != Some(&(y + 1)) {
            return None;
        }
        disp.get((y % 3) * w..(y % 3) * w + w)
    };
    let Some(cur) = row(Some(q)) else {
        return;
    };
    let l = fin.level;
    let m = fin.scales.rows_per(l);
    // The working rows of level row `q` inside the band's rows.
    let ya = (q * m).max(band.rows.start);
    let yb = ((q + 1) * m).min(band.rows.end);
    if ya >= yb || ya < band.y0 {
        return;
    }
    let bw = band.w;
    let first = (ya - band.y0) * bw;
    let Some(o) = out.get_mut(first..first + bw) else {
        return;
    };
    let above = row(q.checked_sub(1));
    let below = row(Some(q + 1));
    let valid = finish_row(above, cur, below, fin, o, rep);
    if m <= 1 {
        // Working-size pixels with data: each level pixel covers 2^l across.
        rep.valid += valid << fin.shift;
    } else {
        expand_rows(cur, above, below, q, m, first, ya, yb, bw, fin, out, rep);
    }
    // Short gaps of the finished working rows (`StereoParams::gap_fill_px`).
    for row in out
        .get_mut(first..first + (yb - ya) * bw)
        .unwrap_or(&mut [])
        .chunks_exact_mut(bw.max(1))
    {
        rep.valid += fill_gaps(row, fin.gap, fin.mode, fin.depth_k);
    }
}

/// Working rows `ya..yb` (the first at `first` in `out`, `bw` apart) of level row `q` (`m`
/// working rows per level row) from its disparities `cur` and its neighbours'
/// ([`super::expand`]): the later rows first (the first row, finished, tells which pixels
/// passed), then the first in place.
#[allow(clippy::too_many_arguments)]
fn expand_rows(
    cur: &[u16],
    above: Option<&[u16]>,
    below: Option<&[u16]>,
    q: usize,
    m: usize,
    first: usize,
    ya: usize,
    yb: usize,
    bw: usize,
    fin: &Finish,
    out: &mut [u16],
    rep: &mut BandReport,
) {
    let place = |y: usize| RowPlace {
        level: fin.shift,
        rows: m,
        offset: y - q * m,
        flat_q15: fin.scales.row_scale_q15(fin.level, q, y, false),
    };
    let side = |y: usize| {
        if 2 * (y - q * m) + 1 < m {
            above
        } else {
            below
        }
    };
    let (head, tail) = out.split_at_mut((first + bw).min(out.len()));
    let first_row = head.get_mut(first..).unwrap_or(&mut []);
    let mut written = 0;
    for (i, dst) in tail
        .chunks_exact_mut(bw.max(1))
        .take(yb - ya - 1)
        .enumerate()
    {
        let y = ya + 1 + i;
        let passed = Passed::Row(first_row, 1 << fin.shift);
        written += expand_row(cur, side(y), passed, dst, &place(y), fin.mode, fin.depth_k);
    }
    written += expand_row(
        cur,
        side(ya),
        Passed::InPlace,
        first_row,
        &place(ya),
        fin.mode,
        fin.depth_k,
    );
    rep.valid += written;
}

/// Rows `y0..y1` of the working-size output into `out` (`(y1 - y0) * width`, row-major),
/// on a fresh stream.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run(
    rig: &StereoRig,
    left: &ImageView<'_>,
    right: Option<&ImageView<'_>>,
    y0: usize,
    y1: usize,
    bytes: &mut [u8],
    words: &mut [u16],
    out: &mut [u16],
    mode: Output,
) -> Result<BandReport, StereoError> {
    StereoView::new(rig, left, right, bytes, words)?.rows(y0, y1, out, mode)
}
