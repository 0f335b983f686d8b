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
    // The weights of the row's own disparity and its neighbour's, times `2^L`.
    let (wd, wn) = (
        ((two_m - t2m).max(0) as u32) << level,
        (t2m as u32) << level,
    );
    let flat = u64::from(place.flat_q15);
    let has_nb = !nb.is_empty();
    let mut written = 0u32;
    // Pointers moved on with the column (no multiply per pixel): the pass mask (`out` in
    // place or every `stride`-th value of `mask`), the level row, its neighbour, `out`.
    let step_pass = if IN_PLACE { s } else { stride };
    let mut po = out.as_mut_ptr();
    // The pass mask in place is read through `out`'s one pointer.
    let mut pp = if IN_PLACE {
        po.cast_const()
    } else {
        mask.as_ptr()
    };
    let (mut pc, mut pn) = (cur.as_ptr(), nb.as_ptr());
    for _ in 0..cur.len() {
        // Safety: at the `x`-th step (`x < cur.len()`) `pc` is `cur`'s element `x`, `po`
        // `out`'s element `x s` (`out` holds `cur.len() s` values), `pp` `out`'s element `x
        // s` or `mask`'s `x stride` (at least `(cur.len() - 1) stride + 1` values; all
        // checked by `expand_row`); `pn` is read only when `nb` holds `cur.len()` values.
        // The pointers move on with `wrapping_add`, so the last step's (one past the
        // rows) are never read.
        let (pass, d) = unsafe { (*pp, *pc) };
        if pass != 0 && d != 0 {
            let d = i32::from(d);
            // Safety: as above.
            let n = if has_nb { i32::from(unsafe { *pn }) } else { 0 };
            // Working-size Q4 disparity of this row.
            let dw = if n != 0 && (n - d).unsigned_abs() <= ONE_Q {
                // (d 2m + (n - d) 2m|t|) 2^L / 2m = (d wd + n wn) / 2m, rounded (`d`, `n`
                // and both weights >= 0; below 2^16 2^5 2^2: no overflow).
                ((d as u32) * wd + (n as u32) * wn + m) >> den_bits
            } else {
                let v = u64::from((d as u32) << level) * flat;
                ((v + (1 << (ROW_SCALE_BITS - 1))) >> ROW_SCALE_BITS) as u32
            };
            let v = output_value(dw, mode, depth_k).unwrap_or(0);
            // Safety: `po` is `out`'s element `x s` and `x s + s <= out.len()`.
            unsafe {
                for c in 0..s {
                    *po.add(c) = v;
                }
            }
            written += u32::from(v != 0);
        }
        pp = pp.wrapping_add(step_pass);
        pc = pc.wrapping_add(1);
        pn = pn.wrapping_add(usize::from(has_nb));
        po = po.wrapping_add(s);
    }
    written * S as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-pixel form `expand_in` replaced (index arithmetic, the interpolation as `d
    /// 2m + (n - d) 2m|t|`), kept as the reference.
    #[allow(clippy::too_many_arguments)]
    fn expand_ref(
        cur: &[u16],
        nb: Option<&[u16]>,
        mask: Option<(&[u16], usize)>,
        out: &mut [u16],
        place: &RowPlace,
        mode: Output,
        depth_k: u32,
    ) -> u64 {
        let s = 1usize << place.level;
        let m = place.rows.max(1) as i32;
        let t2m = (2 * place.offset as i32 + 1 - m).abs();
        let mut written = 0;
        for x in 0..cur.len() {
            let pass = match mask {
                Some((r, stride)) => r[x * stride],
                None => out[x * s],
            };
            let d = i32::from(cur[x]);
            if pass == 0 || d == 0 {
                continue;
            }
            let n = nb.map_or(0, |r| i32::from(r[x]));
            let dw = if n != 0 && (n - d).abs() <= 16 {
                let num = (d * 2 * m + (n - d) * t2m).max(0) as u32;
                ((num << place.level) + m as u32) / (2 * m as u32)
            } else {
                let v = u64::from((d as u32) << place.level) * u64::from(place.flat_q15);
                ((v + (1 << 14)) >> 15) as u32
            };
            let v = output_value(dw, mode, depth_k).unwrap_or(0);
            out[x * s..x * s + s].fill(v);
            written += u64::from(v != 0) * s as u64;
        }
        written
    }

    #[test]
    fn expansion_matches_the_per_pixel_form() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = |n: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 32) as u32 % n
        };
        for case in 0..600 {
            let level = case % 3;
            let s = 1usize << level;
            let rows = s * [1, 2][case % 2];
            let w = 1 + next(40) as usize;
            // Disparities with holes, neighbours near them (within 1 px or across an edge).
            let (mut cur, mut nb) = ([0u16; 40], [0u16; 40]);
            let (cur, nb) = (&mut cur[..w], &mut nb[..w]);
            for (c, n) in cur.iter_mut().zip(nb.iter_mut()) {
                // Disparities with holes, neighbours near them (within 1 px or across an
                // edge).
                *c = if next(5) == 0 {
                    0
                } else {
                    1 + next(2000) as u16
                };
                *n = match next(4) {
                    0 => 0,
                    1 => c.saturating_add(next(200) as u16),
                    _ => (i32::from(*c) + next(33) as i32 - 16).clamp(0, 65535) as u16,
                };
            }
            let place = RowPlace {
                level,
                rows,
                offset: next(rows as u32) as usize,
                flat_q15: 20_000 + next(30_000),
            };
            let mode = if case % 4 == 3 {
                Output::DisparityQ4
            } else {
                Output::DepthMm
            };
            let depth_k = [96_000u32, 1_536_000, 4_000_000_000][case % 3];
            let with_nb = case % 5 != 0;
            let in_place = case % 2 == 1;
            let stride = 1 + next(3) as usize;
            let mut mask = [0u16; 120];
            let mask = &mut mask[..w * stride];
            mask.iter_mut().for_each(|v| *v = next(3) as u16);
            let mut init = [7u16; 160];
            let init = &mut init[..w * s];
            init.iter_mut().step_by(s).for_each(|v| *v = next(3) as u16);
            let (mut a, mut b) = ([0u16; 160], [0u16; 160]);
            let (a, b) = (&mut a[..w * s], &mut b[..w * s]);
            a.copy_from_slice(init);
            b.copy_from_slice(init);
            let nbo = with_nb.then_some(&nb[..]);
            let (got, want) = if in_place {
                (
                    expand_row(cur, nbo, Passed::InPlace, a, &place, mode, depth_k),
                    expand_ref(cur, nbo, None, b, &place, mode, depth_k),
                )
            } else {
                (
                    expand_row(
                        cur,
                        nbo,
                        Passed::Row(mask, stride),
                        a,
                        &place,
                        mode,
                        depth_k,
                    ),
                    expand_ref(cur, nbo, Some((mask, stride)), b, &place, mode, depth_k),
                )
            };
            assert_eq!(a, b, "case {case}");
            assert_eq!(got, want, "case {case}");
        }
    }
}
