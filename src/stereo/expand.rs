//! Expansion of a matched level row onto the working rows it covers.
//!
//! A row of level `L` (frames reduced by `downsample * 2^L` across and `row_factor` times
//! that down, [`super::scale`]) covers `m = row_factor * 2^L` working rows and `2^L` working
//! columns per pixel. Its disparity belongs to the centre of its rows; working row `y` lies
//! `t = (y - q m + 0.5) / m - 0.5` level rows from that centre (`|t| < 1/2`). For any plane
//! (ground, a rock face) the disparity is affine in the image coordinates, so a working row
//! takes the disparity interpolated linearly towards the level row next to it on its side
//! (`d + |t| (n - d)`), where that neighbour has a disparity within 1 pixel of `d`; where it
//! has none (or lies across a depth edge), the disparity is scaled by the ratio of the two
//! rows' flat-ground disparities ([`super::scale::Scales::row_scale_q15`]). Integer only.

use super::band::Output;
use super::scale::ROW_SCALE_BITS;
use super::DISPARITY_FRAC_BITS;

/// One pixel (1.0) of a Q4 disparity.
const ONE_Q: u32 = 1 << DISPARITY_FRAC_BITS;

/// The value written for a working-size disparity `dw` (Q4): the disparity itself (at most
/// `u16::MAX`), or the depth in millimetres `depth_k / dw` (rounded; `None` when it is 0
/// or does not fit `u16`: no data).
#[inline(always)]
pub(crate) fn output_value(dw: u32, mode: Output, depth_k: u32) -> Option<u16> {
    match mode {
        Output::DisparityQ4 => Some(dw.min(u32::from(u16::MAX)) as u16),
        Output::DepthMm => {
            // depth_k < 4e9 and dw / 2 < 2^31: no overflow beyond what `checked_add` catches.
            let z = depth_k.checked_add(dw / 2)?.checked_div(dw)?;
            if z == 0 || z > u32::from(u16::MAX) {
                None
            } else {
                Some(z as u16)
            }
        }
    }
}

/// Which pixels of the level row passed the matcher's last test (speckle): those whose
/// value is not 0 in a finished row with `stride` values per level pixel.
#[derive(Clone, Copy)]
pub(crate) enum Passed<'a> {
    /// Another row (e.g. the level row finished at the level's width, stride 1, or the
    /// first working row, stride `2^L`).
    Row(&'a [u16], usize),
    /// The output row itself, finished in place (stride `2^L`).
    InPlace,
}

/// Where a working row lies in its level row.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RowPlace {
    /// Level `L`: each level pixel covers `2^L` working columns.
    pub level: usize,
    /// Working rows per level row (`row_factor * 2^L`, a power of two).
    pub rows: usize,
    /// This row's offset in its level row, `0..rows`.
    pub offset: usize,
    /// The flat-ground disparity scale of this row, Q15 (the fallback).
    pub flat_q15: u32,
}

/// Working row `place` of the level row `cur` (Q4 disparities at the level's scale, 0 = no
/// data) into `out` (`2^L` values per level pixel), its neighbour level row on the row's
/// side being `nb` (`None` at the image's edge). Pixels that did not pass (`passed`) are
/// left as they are (the caller cleared them). Returns the working pixels written.
pub(crate) fn expand_row(
    cur: &[u16],
    nb: Option<&[u16]>,
    passed: Passed<'_>,
    out: &mut [u16],
    place: &RowPlace,
    mode: Output,
    depth_k: u32,
) -> u64 {
    let s = 1usize << place.level.min(8);
    let w = cur.len();
    // Without a neighbour row every pixel takes the fallback (`cur` as its own neighbour
    // would be "consistent": the loop reads `0`s from `zero` instead).
    let nb = match nb {
        Some(r) if r.len() >= w => r,
        _ => &[],
    };
    if out.len() < w * s {
        return 0;
    }
    let (mask, stride) = match passed {
        Passed::Row(r, stride) if stride > 0 && r.len() > (w.max(1) - 1) * stride => (r, stride),
        Passed::Row(..) => return 0,
        Passed::InPlace => (&[][..], s),
    };
    let in_place = matches!(passed, Passed::InPlace);
    // The levels a rig has, each with its columns per pixel a constant.
    let n = match (in_place, s) {
        (false, 1) => expand_in::<false, 1>(cur, nb, mask, stride, out, place, mode, depth_k),
        (false, 2) => expand_in::<false, 2>(cur, nb, mask, stride, out, place, mode, depth_k),
        (false, 4) => expand_in::<false, 4>(cur, nb, mask, stride, out, place, mode, depth_k),
        (true, 1) => expand_in::<true, 1>(cur, nb, mask, stride, out, place, mode, depth_k),
        (true, 2) => expand_in::<true, 2>(cur, nb, mask, stride, out, place, mode, depth_k),
        (true, 4) => expand_in::<true, 4>(cur, nb, mask, stride, out, place, mode, depth_k),
        _ => 0,
    };
    u64::from(n)
}

/// [`expand_row`] with the pass mask in `out` itself (`IN_PLACE`) or in `mask` (every
/// `stride`-th value); lengths checked by the caller (`nb` empty: no neighbour row).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn expand_in<const IN_PLACE: bool, const S: usize>(
    cur: &[u16],
    nb: &[u16],
    mask: &[u16],
    stride: usize,
    out: &mut [u16],
    place: &RowPlace,
    mode: Output,
    depth_k: u32,
) -> u32 {
    let s = S;
    let level = S.trailing_zeros();
    let m = place.rows.max(1) as u32;
    // 2 m |t| in 0..m: the weight of the neighbour in units of 1 / (2 m).
    let t2m = (2 * place.offset as i32 + 1 - m as i32).unsigned_abs() as i32;
    let den_bits = (2 * m).trailing_zeros();
    let two_m = (2 * m) as i32;
    let flat = u64::from(place.flat_q15);
    let has_nb = !nb.is_empty();
    let mut written = 0u32;
    let (pc, pn, pm, po) = (cur.as_ptr(), nb.as_ptr(), mask.as_ptr(), out.as_mut_ptr());
    for x in 0..cur.len() {
        // Safety: `x < cur.len()`; `out` holds `cur.len() * s` values and `mask` at least
        // `(cur.len() - 1) * stride + 1` (checked by `expand_row`); `nb` is read only when
        // it holds `cur.len()` values.
        let pass = unsafe {
            if IN_PLACE {
                *po.add(x * s)
            } else {
                *pm.add(x * stride)
            }
        };
        // Safety: as above.
        let d = unsafe { *pc.add(x) };
        if pass == 0 || d == 0 {
            continue;
        }
        let d = i32::from(d);
        // Safety: as above.
        let n = if has_nb {
            i32::from(unsafe { *pn.add(x) })
        } else {
            0
        };
        // Working-size Q4 disparity of this row.
        let dw = if n != 0 && (n - d).unsigned_abs() <= ONE_Q {
            // (d 2m + (n - d) 2m|t|) 2^L / 2m, rounded; never negative (|n - d| <= 16).
            let num = (d * two_m + (n - d) * t2m).max(0) as u32;
            ((num << level) + m) >> den_bits
        } else {
            let v = u64::from((d as u32) << level) * flat;
            ((v + (1 << (ROW_SCALE_BITS - 1))) >> ROW_SCALE_BITS) as u32
        };
        let v = output_value(dw, mode, depth_k).unwrap_or(0);
        // Safety: `x * s + s <= out.len()`.
        unsafe {
            for c in 0..s {
                *po.add(x * s + c) = v;
            }
        }
        written += u32::from(v != 0);
    }
    written * S as u32
}
