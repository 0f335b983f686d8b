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
    // Columns taken by the loop below: all, or only the first and the last when the
    // interior went through the assembly loop (Armv7E-M: depths at the working size, both
    // rows beside, support 3).
    #[allow(unused_mut)]
    let mut step = 1;
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    if A && B && w >= 3 && fin.shift == 0 && support == 3 && matches!(fin.mode, Output::DepthMm) {
        // Safety: every row has at least `w` elements and `out` at least `w` (checked
        // above); the interior is `1 .. w - 1`.
        let (v, sp) = unsafe { interior_depth_asm(pa, pc, pb, po, w - 2, fin.depth_k) };
        valid += v;
        speck += sp;
        step = w - 1;
    }
    for x in (0..w).step_by(step) {
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

/// The interior pixels `1 ..= n` of [`finish_row_in`] with both rows beside, support 3 and
/// depths at the working size (shift 0), as one Armv7E-M loop: per pixel with a disparity
/// `d`, the neighbours within 1 px (`v - lo <= span`, `lo = max(d - 16, 1)`) counted in the
/// order left, right, above, below, the diagonals, until 3; then the depth `(k + d / 2) /
/// d`, written where it is 1..=65,535. Returns the pixels written and those the speckle
/// test rejected (the same as [`supported`] and the loop of [`finish_row_in`]).
///
/// # Safety
/// `n >= 1`; `pa`, `pc`, `pb` point to rows of at least `n + 2` elements, `po` to `n + 1`
/// writable ones.
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
unsafe fn interior_depth_asm(
    pa: *const u16,
    pc: *const u16,
    pb: *const u16,
    po: *mut u16,
    n: usize,
    k: u32,
) -> (u32, u32) {
    // Byte offsets from a pixel of the row to the same column above, below and out.
    let oa = (pa as usize).wrapping_sub(pc as usize);
    let ob = (pb as usize).wrapping_sub(pc as usize);
    let oo = (po as usize).wrapping_sub(pc as usize);
    let counts: u32;
    // Safety: reads `pc[0 ..= n + 1]` and, for pixel `x` in `1 ..= n`, the rows above and
    // below at `x - 1 ..= x + 1` (through the offsets: plain address arithmetic), writes
    // `po[x]` (the caller's contract); no stack. The flags are not declared preserved.
    // `counts`: pixels written in the low half, rejected in the high half (`n < 2^16`:
    // the working width).
    unsafe {
        core::arch::asm!(
            "movs {cnt}, #0",
            "2:",
            "ldrh {d}, [{pc}, #2]!",
            "cmp {d}, #0",
            "beq 9f",
            "subs {lo}, {d}, #16",
            "it le",
            "movle {lo}, #1",
            "add {span}, {d}, #16",
            "sub {span}, {span}, {lo}",
            "movs {c}, #0",
            "ldrh {v}, [{pc}, #-2]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "ldrh {v}, [{pc}, #2]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "ldrh {v}, [{pc}, {oa}]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "cmp {c}, #3",
            "beq 5f",
            "ldrh {v}, [{pc}, {ob}]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "cmp {c}, #3",
            "beq 5f",
            "add {d}, {pc}, {oa}",
            "ldrh {v}, [{d}, #-2]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "ldrh {v}, [{d}, #2]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "cmp {c}, #3",
            "bhs 5f",
            "add {d}, {pc}, {ob}",
            "ldrh {v}, [{d}, #-2]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "ldrh {v}, [{d}, #2]",
            "sub {v}, {v}, {lo}",
            "cmp {v}, {span}",
            "it ls",
            "addls {c}, {c}, #1",
            "cmp {c}, #3",
            "bhs 5f",
            "add {cnt}, {cnt}, #0x10000",
            "b 9f",
            "5:",
            "ldrh {d}, [{pc}]",
            "add {v}, {k}, {d}, lsr #1",
            "udiv {v}, {v}, {d}",
            "cmp {v}, #0",
            "beq 9f",
            "cmp {v}, #0x10000",
            "bhs 9f",
            "strh {v}, [{pc}, {oo}]",
            "add {cnt}, {cnt}, #1",
            "9:",
            "subs {n}, {n}, #1",
            "bne 2b",
            pc = inout(reg) pc => _,
            oa = in(reg) oa,
            ob = in(reg) ob,
            oo = in(reg) oo,
            n = inout(reg) n => _,
            k = in(reg) k,
            cnt = out(reg) counts,
            d = out(reg) _,
            lo = out(reg) _,
            span = out(reg) _,
            c = out(reg) _,
            v = out(reg) _,
            options(nostack),
        );
    }
    (counts & 0xffff, counts >> 16)
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
