//! The band matcher: running-sum SAD block matching of rows `y0..y1` (see the module docs
//! of [`super`] for the pipeline).

use super::swar::{absdiff_u8x4, min2_u16x2, min_u16x2, pair, split_u8x4, word};
use super::{Side, StereoBuffer, StereoError, StereoRig, DISPARITY_FRAC_BITS, MAX_RADIUS};
use crate::image::ImageView;
use crate::peak::parabola_min_offset;
use crate::reproject::{classify_frame, FrameStatus};

const ONE_Q: u16 = 1 << DISPARITY_FRAC_BITS;
const RING_MAX: usize = 2 * MAX_RADIUS as usize + 2;
/// A right pixel's winner index before any candidate.
const RB_NONE: u16 = u16::MAX;

/// Bytes of the byte scratch for a working width `w` and radius `r`: per image a ring of 3
/// reduced rows and a ring of `2r + 2` filtered rows.
pub(crate) fn bytes_len(w: usize, r: usize) -> usize {
    2 * w * (3 + 2 * r + 2)
}

/// `u16` elements of the word scratch for a working width `w` and `d` disparities, with
/// `d4` = `d` rounded up to a multiple of 4: the right image's winners (cost and index,
/// `2 w`), a ring of 3 disparity rows (`3 w`), then, on `u32` words (one element of slack
/// for the alignment), the column costs (`w d4`) and the row's aggregated costs (`d4`) in
/// the lane layout of [`lane`], and the same in disparity order (`d4`).
pub(crate) fn words_len(w: usize, d: usize) -> usize {
    let d4 = 4 * d.div_ceil(4);
    d4 + 5 * w + (w + 1) * d4 + 1
}

/// What one band did (sums over bands with [`BandReport::add`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BandReport {
    /// Rows matched (output rows and their one-row margins; sky rows are not matched).
    pub rows_matched: u64,
    /// Pixel-disparities of the winner-take-all (columns with a full window times each
    /// row's range): aggregation, winner search and the left-right bookkeeping.
    pub pixel_disparities: u64,
    /// Column-cost updates (one row in, one row out: two absolute differences each), the
    /// band's disparity union times the columns per row, the set-up rows included.
    pub cost_updates: u64,
    /// Output pixels with a disparity.
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

/// Row rings of both images: reduced rows (3) and filtered rows (`2r + 2`), tagged with
/// `row + 1` (0: empty).
struct Rings<'b> {
    ds: [&'b mut [u8]; 2],
    filt: [&'b mut [u8]; 2],
    ds_tag: [usize; 3],
    f_tag: [usize; RING_MAX],
    w: usize,
    h: usize,
    k: usize,
    ring: usize,
    cap: u8,
}

impl Rings<'_> {
    fn ensure_ds(&mut self, frames: [&ImageView<'_>; 2], q: usize) {
        let slot = q % 3;
        if self.ds_tag.get(slot) == Some(&(q + 1)) {
            return;
        }
        let w = self.w;
        for (buf, fr) in self.ds.iter_mut().zip(frames) {
            if let Some(o) = buf.get_mut(slot * w..slot * w + w) {
                super::downsample_row(fr, self.k, q, o);
            }
        }
        if let Some(t) = self.ds_tag.get_mut(slot) {
            *t = q + 1;
        }
    }

    /// Makes filtered row `k` (clamped to the image) present; returns its ring slot.
    fn ensure(&mut self, frames: [&ImageView<'_>; 2], k: isize) -> usize {
        let last = self.h - 1;
        let k = (k.max(0) as usize).min(last);
        // `checked_rem`: no division-by-zero panic path in the flight build (ring >= 4).
        let slot = k.checked_rem(self.ring).unwrap_or(0);
        if self.f_tag.get(slot) == Some(&(k + 1)) {
            return slot;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(last));
        self.ensure_ds(frames, a);
        self.ensure_ds(frames, k);
        self.ensure_ds(frames, b);
        let w = self.w;
        for (ds, f) in self.ds.iter().zip(self.filt.iter_mut()) {
            let row = |q: usize| ds.get((q % 3) * w..(q % 3) * w + w).unwrap_or(&[]);
            if let Some(o) = f.get_mut(slot * w..slot * w + w) {
                super::prefilter(row(a), row(k), row(b), self.cap, o);
            }
        }
        if let Some(t) = self.f_tag.get_mut(slot) {
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

/// Number of disparities `dmin + j` (`j < dn`) with the right pixel `x - dmin - j` inside.
#[inline(always)]
fn inside(x: usize, dmin: usize, dn: usize) -> usize {
    if x < dmin {
        0
    } else {
        (x - dmin + 1).min(dn)
    }
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
fn lane(j: usize) -> (usize, u32) {
    let g = 2 * (j / 4);
    match j % 4 {
        0 => (g + 1, 16),
        1 => (g, 16),
        2 => (g + 1, 0),
        _ => (g, 0),
    }
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

/// Adds one filtered row pair's costs to the column sums (`gw` words per column, the lane
/// layout of [`lane`]; a right pixel outside the image costs `oc`).
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
fn add_row(colsum: &mut [u32], gw: usize, dmin: usize, l: &[u8], r: &[u8], oc: u16) {
    let groups = gw / 2;
    let oc = u32::from(oc);
    for (x, (col, &lp)) in colsum.chunks_exact_mut(gw.max(1)).zip(l).enumerate() {
        let full = full_groups(x, dmin, groups);
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
        for j in 4 * full..2 * gw {
            let v = match hi.checked_sub(j + 1).and_then(|xr| r.get(xr)) {
                Some(&rp) => absdiff(lp, rp),
                None => oc,
            };
            lane_add_sub(col, j, v, 0);
        }
    }
}

/// One row in (`ln`, `rn`), one row out (`lo`, `ro`) of the column sums. Columns whose
/// right pixel is outside add and remove the same constant: unchanged.
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn update_rows(
    colsum: &mut [u32],
    gw: usize,
    dmin: usize,
    ln: &[u8],
    rn: &[u8],
    lo: &[u8],
    ro: &[u8],
) {
    let groups = gw / 2;
    let lanes = 2 * gw;
    // From column `x_full` on every group's right pixels lie inside the image: the right
    // pixels of column `x_full + i` are `i .. i + lanes` (`hi - 4 full .. hi` below).
    let x_full = dmin + lanes.max(1) - 1;
    if let (Some(cs), Some(lf), Some(of)) = (
        colsum.get_mut(x_full * gw..),
        ln.get(x_full..),
        lo.get(x_full..),
    ) {
        for ((col, (&a, &b)), (wn, wo)) in cs
            .chunks_exact_mut(gw.max(1))
            .zip(lf.iter().zip(of))
            .zip(rn.windows(lanes.max(1)).zip(ro.windows(lanes.max(1))))
        {
            let (a4, b4) = (u32::from(a) * 0x0101_0101, u32::from(b) * 0x0101_0101);
            for (pair, (cn, co)) in col
                .chunks_exact_mut(2)
                .zip(wn.chunks_exact(4).rev().zip(wo.chunks_exact(4).rev()))
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
    }
    // Columns `dmin .. x_full`: some groups partly outside.
    for (x, (col, (&a, &b))) in colsum
        .chunks_exact_mut(gw.max(1))
        .zip(ln.iter().zip(lo))
        .enumerate()
        .take(x_full)
        .skip(dmin)
    {
        let full = full_groups(x, dmin, groups);
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
        for j in 4 * full..(2 * gw).min(hi) {
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
    gw: usize,
    dmin: usize,
    /// Row range, as indices into the band's disparities.
    jl: usize,
    jh: usize,
    uniq: u32,
    gap: u32,
    lr: bool,
}

/// Winner-take-all of one row from the column sums into `disp` (Q4, 0 = none): `aggw`
/// holds the row's aggregated costs in the lane layout of [`lane`], `nat` the same in
/// disparity order, `rbc` and `rbd` the right image's winners (cost and index, right pixel
/// `xr` at `w - 1 - xr`).
///
/// Per column, one pass over the row's words slides the aggregation window one column on
/// and writes the costs in disparity order; the winner and the right image's winners are
/// then scanned two indices at a time ([`min_u16x2`]): each lane keeps its first strict
/// minimum, and of the two lanes the smaller cost, on a tie the smaller index, is the
/// first minimum of the whole range, what a scan in index order keeping strict
/// improvements finds. A right pixel sees its candidates in increasing index, so keeping
/// strict improvements per right pixel is the first of its smallest costs too. Indices are
/// below 2^15 (at most the working width, [`StereoRig::new`]), so [`RB_NONE`] is never one.
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn match_row(
    m: &RowMatch,
    colsum: &[u32],
    aggw: &mut [u32],
    nat: &mut [u16],
    rbc: &mut [u16],
    rbd: &mut [u16],
    disp: &mut [u16],
    rep: &mut BandReport,
) {
    disp.fill(0);
    let len = m.jh + 1 - m.jl;
    // The whole groups of four holding the row's range.
    let (w0, w1) = (2 * (m.jl / 4), 2 * (m.jh / 4) + 2);
    let nw = w1 - w0;
    let groups = nw / 2;
    let first = m.jl - 4 * (m.jl / 4);
    let (w, r, gw) = (m.w, m.r, m.gw);
    // Everything the column loop reads or writes through pointers, checked once per row.
    if gw == 0
        || w1 > gw
        || colsum.len() < w * gw
        || aggw.len() < nw
        || nat.len() < 2 * nw
        || first + len > 2 * nw
        || rbc.len() < w
        || rbd.len() < w
        || disp.len() < w
        || w < 2 * r + 1
    {
        return;
    }
    let aggw = aggw.get_mut(..nw).unwrap_or(&mut []);
    aggw.fill(0);
    for c in colsum.chunks_exact(gw).take(2 * r + 1) {
        for (a, &v) in aggw.iter_mut().zip(c.get(w0..w1).unwrap_or(&[])) {
            *a += v;
        }
    }
    if m.lr {
        rbc.fill(u16::MAX);
        rbd.fill(RB_NONE);
    }
    let d0 = m.dmin + m.jl;
    let (cs, ap, np) = (colsum.as_ptr(), aggw.as_mut_ptr(), nat.as_mut_ptr());
    let (rbc_p, rbd_p) = (rbc.as_mut_ptr(), rbd.as_mut_ptr());
    let (mut edge, mut uniq) = (0u64, 0u64);
    for x in r..w - r {
        // The right pixel x - d0 - j sees cost j at its own disparity d0 + j: for the
        // first `n` indices it lies inside the image, at `w - 1 - (x - d0) + j` of `rbc`
        // and `rbd`: both run forward with the costs (`n` is 0 for `x < d0`).
        let n = if m.lr { inside(x, d0, len) } else { 0 };
        let t0 = if n > 0 { w - 1 - (x - d0) } else { 0 };
        // Safety: checked above for the row: column `x + r < w` and column `x - r - 1`
        // (`x > r`) of `colsum` (at least `w gw` words) hold words `w0 .. w0 + nw <= gw`;
        // `aggw` has `nw` words and `nat` `2 nw` elements, aligned to 4 bytes (the words
        // it was split from), written as whole `u32` at even indices `4g`, `4g + 2`;
        // the costs read are `nat[first .. first + len]` (`first + len <= 2 nw`), two at a
        // time as one unaligned `u32`; `t0 + n <= w` (`n <= x - d0 + 1`), the length of
        // `rbc` and `rbd`. Nothing else refers to these buffers during the block, and the
        // slice `agg` made from `nat` lives only within it.
        let (best, bi, agg) = unsafe {
            if x > r {
                let ci = cs.add((x + r) * gw + w0);
                let co = cs.add((x - r - 1) * gw + w0);
                for g in 0..groups {
                    // Exact per lane (bounds: `lane`).
                    let e = *ap.add(2 * g) + *ci.add(2 * g) - *co.add(2 * g);
                    let d = *ap.add(2 * g + 1) + *ci.add(2 * g + 1) - *co.add(2 * g + 1);
                    *ap.add(2 * g) = e;
                    *ap.add(2 * g + 1) = d;
                    nat_group(np.add(4 * g), e, d);
                }
            } else {
                for g in 0..groups {
                    nat_group(np.add(4 * g), *ap.add(2 * g), *ap.add(2 * g + 1));
                }
            }
            let agg = np.add(first) as *const u16;
            let (rc, rd) = (rbc_p.add(t0), rbd_p.add(t0));
            let (mut bc, mut bj) = (u32::MAX, u32::MAX);
            let mut jj = 0x0001_0000u32;
            let mut k = 0;
            while k < n / 2 {
                let a = agg.add(2 * k).cast::<u32>().read_unaligned();
                let (cp, dp) = (rc.add(2 * k).cast::<u32>(), rd.add(2 * k).cast::<u32>());
                let (c, d) = min_u16x2(cp.read_unaligned(), dp.read_unaligned(), a, jj);
                cp.write_unaligned(c);
                dp.write_unaligned(d);
                (bc, bj) = min_u16x2(bc, bj, a, jj);
                // Two indices further in both lanes (below 2^15: no carry between them).
                jj += 0x0002_0002;
                k += 1;
            }
            while k < len / 2 {
                let a = agg.add(2 * k).cast::<u32>().read_unaligned();
                (bc, bj) = min_u16x2(bc, bj, a, jj);
                jj += 0x0002_0002;
                k += 1;
            }
            // Of the two lanes (even and odd indices), the smaller cost, then the first
            // index; then an odd range's last index.
            let (lo, hi) = ((bc & 0xffff, bj & 0xffff), (bc >> 16, bj >> 16));
            let (mut best, mut bi) = if hi.0 < lo.0 || (hi.0 == lo.0 && hi.1 < lo.1) {
                hi
            } else {
                lo
            };
            if len % 2 == 1 {
                let a = u32::from(*agg.add(len - 1));
                if a < best {
                    best = a;
                    bi = (len - 1) as u32;
                }
            }
            // An odd count's last right pixel.
            if n % 2 == 1 {
                let j = n - 1;
                let a = *agg.add(j);
                if a < *rc.add(j) {
                    *rc.add(j) = a;
                    *rd.add(j) = j as u16;
                }
            }
            (best, bi, core::slice::from_raw_parts(agg, len))
        };
        let best = best as u16;
        let bi = bi as usize;
        let d = d0 + bi;
        if bi == 0 || bi + 1 >= len || x < d + m.r {
            edge += 1;
            continue;
        }
        // The runner-up more than one index away (bi >= 1 here).
        let lo_min = agg.get(..bi - 1).map_or(u16::MAX, min_of);
        let hi_min = agg.get(bi + 2..).map_or(u16::MAX, min_of);
        let second = lo_min.min(hi_min);
        if second != u16::MAX {
            let (b, s) = (u32::from(best), u32::from(second));
            if s * (100 - m.uniq) < b * 100 || s < b + m.gap {
                uniq += 1;
                continue;
            }
        }
        let (Some(&lc), Some(&rc)) = (agg.get(bi - 1), agg.get(bi + 1)) else {
            continue;
        };
        let frac = parabola_min_offset(
            i32::from(lc),
            i32::from(best),
            i32::from(rc),
            i32::from(ONE_Q),
        );
        let q = (d as i32 * i32::from(ONE_Q) + frac).max(1);
        if let Some(o) = disp.get_mut(x) {
            *o = q.min(i32::from(u16::MAX)) as u16;
        }
    }
    rep.pixel_disparities += ((m.w - 2 * m.r) * len) as u64;
    rep.rejected_edge += edge;
    rep.rejected_unique += uniq;
    if m.lr {
        let mut lr = 0u64;
        for (x, o) in disp.iter_mut().enumerate() {
            if *o == 0 {
                continue;
            }
            let dl = usize::from((*o + ONE_Q / 2) >> DISPARITY_FRAC_BITS);
            // A right pixel no candidate reached has disparity 0.
            let dr = |j: u16| match j {
                RB_NONE => 0,
                j => d0 + usize::from(j),
            };
            let ok = x
                .checked_sub(dl)
                .and_then(|xr| rbd.get(m.w - 1 - xr))
                .is_some_and(|&j| dr(j).abs_diff(dl) <= 1);
            if !ok {
                *o = 0;
                lr += 1;
            }
        }
        rep.rejected_lr += lr;
    }
}

/// Writes a group's aggregated words `e` = (4g + 3 | 4g + 1) and `d` = (4g + 2 | 4g) to
/// `n[0..4]` as the costs of 4g, 4g + 1, 4g + 2, 4g + 3 (two `u32`, little-endian).
///
/// # Safety
/// `n` points at four writable `u16` aligned to 4 bytes.
#[inline(always)]
unsafe fn nat_group(n: *mut u16, e: u32, d: u32) {
    let n = n.cast::<u32>();
    // Safety: the caller's contract (four aligned, writable `u16`).
    unsafe {
        n.write((d >> 16) | (e & 0xffff_0000));
        n.add(1).write((d & 0xffff) | (e << 16));
    }
}

/// The smallest of `s` (`u16::MAX` when empty), two at a time ([`min2_u16x2`]).
#[inline(always)]
fn min_of(s: &[u16]) -> u16 {
    let pairs = s.chunks_exact(2);
    let tail = pairs.remainder().first().copied().unwrap_or(u16::MAX);
    let m = pairs.fold(u32::MAX, |m, c| min2_u16x2(m, pair(c)));
    (m as u16).min((m >> 16) as u16).min(tail)
}

/// Speckle filter and output of row `q` from the disparity rows above, at and below.
#[allow(clippy::too_many_arguments)]
fn finish_row(
    above: Option<&[u16]>,
    cur: &[u16],
    below: Option<&[u16]>,
    support: u8,
    mode: Output,
    depth_k: u32,
    out: &mut [u16],
    rep: &mut BandReport,
) {
    let near = |a: u16, b: u16| u32::from(b != 0 && a.abs_diff(b) <= ONE_Q);
    // Neighbours outside the row or the image count as "no data" (0), which is never near.
    let at = |row: Option<&[u16]>, i: Option<usize>| -> u16 {
        match (row, i) {
            (Some(r), Some(i)) => r.get(i).copied().unwrap_or(0),
            _ => 0,
        }
    };
    let (mut valid, mut speck) = (0u64, 0u64);
    for (x, (o, &d)) in out.iter_mut().zip(cur).enumerate() {
        *o = 0;
        if d == 0 {
            continue;
        }
        if support > 0 {
            let (l, r) = (x.checked_sub(1), Some(x + 1));
            let mut n = near(d, at(Some(cur), l)) + near(d, at(Some(cur), r));
            for row in [above, below] {
                n += near(d, at(row, l)) + near(d, at(row, Some(x))) + near(d, at(row, r));
            }
            if n < u32::from(support) {
                speck += 1;
                continue;
            }
        }
        let v = match mode {
            Output::DisparityQ4 => d,
            Output::DepthMm => {
                let z = (depth_k + u32::from(d) / 2)
                    .checked_div(u32::from(d))
                    .unwrap_or(0);
                if z == 0 || z > u32::from(u16::MAX) {
                    continue;
                }
                z as u16
            }
        };
        *o = v;
        valid += 1;
    }
    rep.valid += valid;
    rep.rejected_speckle += speck;
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

/// Rows `y0..y1` of the working-size output into `out` (`(y1 - y0) * width`, row-major).
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
    let frames = check_inputs(rig, left, right)?;
    let (w, h) = (rig.width, rig.height);
    if y0 >= y1 || y1 > h {
        return Err(StereoError::Rows { y0, y1, height: h });
    }
    let sizes = rig.buffer_sizes();
    for (buffer, needed, got) in [
        (StereoBuffer::Bytes, sizes.bytes, bytes.len()),
        (StereoBuffer::Words, sizes.words, words.len()),
        (StereoBuffer::Output, (y1 - y0) * w, out.len()),
    ] {
        if got < needed {
            return Err(StereoError::BufferSize {
                buffer,
                needed,
                got,
            });
        }
    }
    let p = &rig.params;
    let r = usize::from(p.radius_px);
    let ring = 2 * r + 2;
    // Lengths were checked above; `min` keeps the splits free of panic paths.
    let (ds_l, rest) = bytes.split_at_mut((3 * w).min(bytes.len()));
    let (ds_r, rest) = rest.split_at_mut((3 * w).min(rest.len()));
    let (f_l, rest) = rest.split_at_mut((ring * w).min(rest.len()));
    let (f_r, _) = rest.split_at_mut((ring * w).min(rest.len()));
    let mut rings = Rings {
        ds: [ds_l, ds_r],
        filt: [f_l, f_r],
        ds_tag: [0; 3],
        f_tag: [0; RING_MAX],
        w,
        h,
        k: usize::from(p.downsample),
        ring,
        cap: p.prefilter_cap,
    };
    let out = out.get_mut(..(y1 - y0) * w).unwrap_or(&mut []);
    out.fill(0);
    let mut rep = BandReport::default();

    let geo = &rig.geo;
    let c0 = y0.saturating_sub(1).max(geo.first_active());
    let c1 = (y1 + 1).min(h);
    if c0 >= c1 {
        return Ok(rep);
    }
    let Some((dmin, dmax)) = geo.union(c0, c1) else {
        return Ok(rep);
    };
    let dn = dmax + 1 - dmin;
    if dn > rig.max_disp {
        return Err(StereoError::TooSmall);
    }
    // Words per column: `dn` rounded up to groups of four lanes, two lanes per word.
    let gw = 2 * dn.div_ceil(4);
    let (rbc, rest) = words.split_at_mut(w.min(words.len()));
    let (rbd, rest) = rest.split_at_mut(w.min(rest.len()));
    let (disp, rest) = rest.split_at_mut((3 * w).min(rest.len()));
    // Safety: `u16` and `u32` are plain integers valid for every bit pattern, and
    // `align_to_mut` gives the aligned middle part as whole `u32` words (its prefix and
    // suffix, at most one `u16` each, stay unused: `words_len` has one element of slack).
    let (_, wide, _) = unsafe { rest.align_to_mut::<u32>() };
    let (colsum, rest) = wide.split_at_mut((w * gw).min(wide.len()));
    let (aggw, rest) = rest.split_at_mut(gw.min(rest.len()));
    let (natw, _) = rest.split_at_mut(gw.min(rest.len()));
    // Safety: `u16` has half the size and alignment of `u32` and every bit pattern is
    // valid, so the words read as `u16` give no prefix or suffix.
    let (_, nat, _) = unsafe { natw.align_to_mut::<u16>() };
    let mut disp_tag = [0usize; 3];
    let oc = out_cost(p.prefilter_cap);
    let ri = r as isize;

    colsum.fill(0);
    for k in c0 as isize - ri..=c0 as isize + ri {
        let s = rings.ensure(frames, k);
        let (l, rr) = rings.rows(s);
        add_row(colsum, gw, dmin, l, rr, oc);
    }
    rep.cost_updates += ((2 * r + 1) * w * dn) as u64 / 2;
    let area = ((2 * r + 1) * (2 * r + 1)) as u32;
    for y in c0..c1 {
        if y > c0 {
            let so = rings.ensure(frames, y as isize - ri - 1);
            let sn = rings.ensure(frames, y as isize + ri);
            let (lo, ro) = rings.rows(so);
            let (ln, rn) = rings.rows(sn);
            update_rows(colsum, gw, dmin, ln, rn, lo, ro);
            rep.cost_updates += (w * dn) as u64;
        }
        if let Some((lo, hi)) = geo.row(y) {
            let m = RowMatch {
                w,
                r,
                gw,
                dmin,
                jl: lo.saturating_sub(dmin),
                jh: hi.saturating_sub(dmin).min(dn - 1),
                uniq: u32::from(p.uniqueness_pct),
                gap: area * u32::from(p.min_gap_per_px),
                lr: p.lr_check,
            };
            if let Some(drow) = disp.get_mut((y % 3) * w..(y % 3) * w + w) {
                match_row(&m, colsum, aggw, nat, rbc, rbd, drow, &mut rep);
                if let Some(t) = disp_tag.get_mut(y % 3) {
                    *t = y + 1;
                }
                rep.rows_matched += 1;
            }
        }
        if y >= 1 && (y0..y1).contains(&(y - 1)) {
            finish(
                &disp_tag,
                disp,
                w,
                y - 1,
                y0,
                p.min_support,
                mode,
                rig.depth_k,
                out,
                &mut rep,
            );
        }
    }
    if (y0..y1).contains(&(c1 - 1)) {
        finish(
            &disp_tag,
            disp,
            w,
            c1 - 1,
            y0,
            p.min_support,
            mode,
            rig.depth_k,
            out,
            &mut rep,
        );
    }
    Ok(rep)
}

/// Finishes output row `q` from the disparity ring (rows not matched are "no data").
#[allow(clippy::too_many_arguments)]
fn finish(
    tag: &[usize; 3],
    disp: &[u16],
    w: usize,
    q: usize,
    y0: usize,
    support: u8,
    mode: Output,
    depth_k: u32,
    out: &mut [u16],
    rep: &mut BandReport,
) {
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
    let Some(o) = out.get_mut((q - y0) * w..(q - y0) * w + w) else {
        return;
    };
    finish_row(
        row(q.checked_sub(1)),
        cur,
        row(Some(q + 1)),
        support,
        mode,
        depth_k,
        o,
        rep,
    );
}
