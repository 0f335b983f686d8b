//! A matched level row finished: the speckle test (`StereoParams::min_support`: a disparity
//! stays only where enough of its 8 neighbours agree with it within 1 px), then the output
//! value of each pixel (disparity or depth), spread over the working columns it covers.

use super::band::{BandReport, Finish, Output, ONE_Q};

/// Speckle filter and output of a row from the disparity rows above, at and below (level
/// pixels) into `out` (working size: each level pixel covers `2^level` pixels, disparities
/// scaled to working-size pixels; `out` holds zeros where there is no data). Returns the
/// level pixels with data.
// A function of its own (called once per row): its loop keeps its state in registers.
#[inline(never)]
pub(super) fn finish_row(
    above: Option<&[u16]>,
    cur: &[u16],
    below: Option<&[u16]>,
    fin: &Finish,
    out: &mut [u16],
    rep: &mut BandReport,
) -> u64 {
    // Neighbours outside the row or the image count as "no data" (0), which is never near:
    // a missing row above or below reads as `cur` with its neighbours not counted.
    match (above, below) {
        (Some(a), Some(b)) => finish_row_in::<true, true>(a, cur, b, fin, out, rep),
        (Some(a), None) => finish_row_in::<true, false>(a, cur, cur, fin, out, rep),
        (None, Some(b)) => finish_row_in::<false, true>(cur, cur, b, fin, out, rep),
        (None, None) => finish_row_in::<false, false>(cur, cur, cur, fin, out, rep),
    }
}

/// [`finish_row`] with the rows above (`A`) and below (`B`) present or not.
#[inline(always)]
fn finish_row_in<const A: bool, const B: bool>(
    above: &[u16],
    cur: &[u16],
    below: &[u16],
    fin: &Finish,
    out: &mut [u16],
    rep: &mut BandReport,
) -> u64 {
    let w = cur.len();
    let s = 1usize << fin.shift;
    let support = u32::from(fin.support);
    let (mut valid, mut speck) = (0u32, 0u32);
    if above.len() < w || below.len() < w || out.len() < w * s || w == 0 {
        return 0;
    }
    let (pa, pc, pb, po) = (
        above.as_ptr(),
        cur.as_ptr(),
        below.as_ptr(),
        out.as_mut_ptr(),
    );
    for x in 0..w {
        // Safety: `x < w` and every row has at least `w` elements (checked above).
        let d = unsafe { *pc.add(x) };
        if d == 0 {
            continue;
        }
        if support > 0 {
            // Safety: `x - 1` is read only when `x > 0`, `x + 1` only when `x + 1 < w`.
            let ok = unsafe {
                if x > 0 && x + 1 < w {
                    supported::<A, B, true, true>(pa, pc, pb, x, d, support)
                } else if x > 0 {
                    supported::<A, B, true, false>(pa, pc, pb, x, d, support)
                } else if x + 1 < w {
                    supported::<A, B, false, true>(pa, pc, pb, x, d, support)
                } else {
                    supported::<A, B, false, false>(pa, pc, pb, x, d, support)
                }
            };
            if !ok {
                speck += 1;
                continue;
            }
        }
        // Working-size disparity, Q4 (at most 2^18: no overflow).
        let dw = u32::from(d) << fin.shift;
        let v = match fin.mode {
            Output::DisparityQ4 => dw.min(u32::from(u16::MAX)) as u16,
            Output::DepthMm => {
                // depth_k < 4e9 and dw / 2 < 2^17: no overflow.
                let z = (fin.depth_k + dw / 2).checked_div(dw).unwrap_or(0);
                if z == 0 || z > u32::from(u16::MAX) {
                    continue;
                }
                z as u16
            }
        };
        // Safety: `x * s + s <= w * s <= out.len()` (checked above).
        unsafe {
            let o = po.add(x * s);
            match s {
                1 => *o = v,
                2 => {
                    *o = v;
                    *o.add(1) = v;
                }
                _ => {
                    for i in 0..s {
                        *o.add(i) = v;
                    }
                }
            }
        }
        valid += 1;
    }
    rep.rejected_speckle += u64::from(speck);
    u64::from(valid)
}

/// Whether at least `support` (1..=8) of the 8 neighbours of `cur[x]` (disparity `d`, not 0)
/// have a disparity within 1 px of it (Q4: `|v - d| <= 16`, `v` not 0); the row above
/// counts where `A`, the row below where `B`, the left column where `L`, the right where
/// `R`. Counted until `support` is reached (the same verdict as counting all 8).
///
/// # Safety
/// `pa`, `pc` and `pb` point to rows of at least `x + 1` elements (`A` / `B` false: never
/// read), and of `x + 2` when `R`; `x >= 1` when `L`.
#[inline(always)]
unsafe fn supported<const A: bool, const B: bool, const L: bool, const R: bool>(
    pa: *const u16,
    pc: *const u16,
    pb: *const u16,
    x: usize,
    d: u16,
    support: u32,
) -> bool {
    // `v` near `d`: `v` in `[lo, lo + span]` with `lo = max(d - 16, 1)` (so 0 never is),
    // one unsigned compare.
    let d = u32::from(d);
    let lo = d.saturating_sub(u32::from(ONE_Q)).max(1);
    let span = d + u32::from(ONE_Q) - lo;
    let near = |p: *const u16, i: usize| -> u32 {
        // Safety: the caller's bounds (`i` is `x - 1`, `x` or `x + 1` as `L` / `R` allow).
        u32::from(u32::from(unsafe { *p.add(i) }).wrapping_sub(lo) <= span)
    };
    // Safety (every read below): `x - 1` only when `L`, `x + 1` only when `R`, rows above
    // and below only when `A` / `B`.
    let mut n = 0;
    if L {
        n += near(pc, x - 1);
    }
    if R {
        n += near(pc, x + 1);
    }
    if A {
        n += near(pa, x);
    }
    if n >= support {
        return true;
    }
    if B {
        n += near(pb, x);
        if n >= support {
            return true;
        }
    }
    if A && L {
        n += near(pa, x - 1);
    }
    if A && R {
        n += near(pa, x + 1);
    }
    if n >= support {
        return true;
    }
    if B && L {
        n += near(pb, x - 1);
    }
    if B && R {
        n += near(pb, x + 1);
    }
    n >= support
}
