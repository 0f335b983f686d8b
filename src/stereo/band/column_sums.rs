//! The column sums of the band matcher: per column, the SAD costs of groups of four
//! disparities summed over the window's rows, two disparities per `u32` word ([`lane`]),
//! one row in and one row out as the band moves down.

use super::super::kernel::{add_groups, update_columns, UpdateCols};
use super::super::swar::{absdiff_u8x4, split_u8x4, word};

/// Cost of a column whose right pixel is outside the image (the largest difference).
pub(super) fn out_cost(cap: u8) -> u16 {
    2 * u16::from(cap)
}

#[inline(always)]
pub(super) fn absdiff(a: u8, b: u8) -> u32 {
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
pub(super) fn lane_add_sub(col: &mut [u32], j: usize, add: u32, sub: u32) {
    let (i, s) = lane(j);
    if let Some(c) = col.get_mut(i) {
        *c = *c + (add << s) - (sub << s);
    }
}

/// Groups of four disparity indices (of `groups`) whose right pixels `x - dmin - j` all
/// lie inside the image at column `x`: `4g + 3 <= x - dmin`.
#[inline(always)]
pub(super) fn full_groups(x: usize, dmin: usize, groups: usize) -> usize {
    if x < dmin + 3 {
        0
    } else {
        ((x - dmin - 3) / 4 + 1).min(groups)
    }
}

/// Column sums of `n` groups of four disparities from `dmin` on: `cs` holds column `x`'s
/// words at `x * stride .. x * stride + 2 n` (the lane layout of [`lane`]).
#[derive(Clone, Copy)]
pub(super) struct Sums {
    pub(super) stride: usize,
    pub(super) n: usize,
    pub(super) dmin: usize,
}

/// Adds one filtered row pair's costs to the column sums (a right pixel outside the image
/// costs `oc`).
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
pub(super) fn add_row(cs: &mut [u32], s: Sums, l: &[u8], r: &[u8], oc: u16) {
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
pub(super) fn update_rows(cs: &mut [u32], s: Sums, ln: &[u8], rn: &[u8], lo: &[u8], ro: &[u8]) {
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
