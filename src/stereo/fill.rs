//! The columns a row did not decide (`StereoParams::column_step`, `near_column_step`):
//! each takes the linear blend of the decided columns on either side where they agree; and
//! short gaps of a finished working row (`StereoParams::gap_fill_px`): the pixels between
//! two with data that agree within 1 px of disparity take their linear blend.

use super::band::{Output, ONE_Q};

/// Columns `x` of `lo + 1..hi` whose `x - lo` is not a multiple of `step` (not decided)
/// take the linear blend of the decided columns on either side (Q4, rounded half up:
/// `(a (step - k) + b k + step / 2) / step` at `k` columns past `a`; for `step` 2 the mean,
/// rounded up) where both have a disparity and they agree within 1 px, else 0 (no data).
/// The decided columns (and those past the last decided one before `hi`, with no right
/// neighbour: no data) do not change.
pub(crate) fn fill_between(disp: &mut [u16], lo: usize, hi: usize, step: usize) {
    match step {
        2 => fill_by::<2>(disp, lo, hi),
        3 => fill_by::<3>(disp, lo, hi),
        4 => fill_by::<4>(disp, lo, hi),
        _ => {}
    }
}

/// The linear blend of `a` and `b` at `k` of `n` steps past `a`, rounded half up: `(a (n -
/// k) + b k + n / 2) / n` (`k <= n`; no overflow for `n <= 65` and 16-bit `a`, `b`).
#[inline(always)]
fn blend(a: u32, b: u32, k: u32, n: u32) -> u16 {
    ((a * (n - k) + b * k + n / 2) / n) as u16
}

/// [`fill_between`] with the step a constant (the division by 2 and 4 a shift).
#[inline(never)]
fn fill_by<const N: usize>(disp: &mut [u16], lo: usize, hi: usize) {
    let n = N as u32;
    let hi = hi.min(disp.len());
    if lo >= hi {
        return;
    }
    let p = disp.as_mut_ptr();
    // Safety: every index read or written below is below `hi <= disp.len()`.
    unsafe {
        let mut x0 = lo;
        let mut a = u32::from(*p.add(x0));
        // Whole spans: both decided columns inside.
        while x0 + N < hi {
            let x1 = x0 + N;
            let b = u32::from(*p.add(x1));
            let near = a != 0 && b != 0 && a.abs_diff(b) <= u32::from(ONE_Q);
            for k in 1..N {
                let v = if near { blend(a, b, k as u32, n) } else { 0 };
                *p.add(x0 + k) = v;
            }
            x0 = x1;
            a = b;
        }
        // Past the last decided column: no right neighbour.
        for x in x0 + 1..hi {
            *p.add(x) = 0;
        }
    }
}

/// Runs of at most `max_gap` pixels without data (0) in a finished working row, between
/// two pixels with data whose disparities agree within 1 px, take the linear blend of the
/// two values (rounded half up: `(a (n - k) + b k + n / 2) / n` at `k` pixels past `a`,
/// `n` pixels apart): disparities (Q4) in [`Output::DisparityQ4`]; depths (millimetres) in
/// [`Output::DepthMm`], where two depths `a`, `b` agree when their disparities
/// `depth_k / a` and `depth_k / b` (working-size Q4) do, `depth_k |a - b| <= 16 a b`.
/// Gaps at the row's ends, and across a depth edge (an occlusion), stay without data.
/// Returns the pixels filled.
#[inline(never)]
pub(crate) fn fill_gaps(row: &mut [u16], max_gap: usize, mode: Output, depth_k: u32) -> u64 {
    if max_gap == 0 {
        return 0;
    }
    let agree = |a: u32, b: u32| match mode {
        Output::DisparityQ4 => a.abs_diff(b) <= u32::from(ONE_Q),
        Output::DepthMm => {
            u64::from(depth_k) * u64::from(a.abs_diff(b))
                <= u64::from(ONE_Q) * u64::from(a) * u64::from(b)
        }
    };
    let mut filled = 0u64;
    // The last pixel with data: its index and value.
    let mut last: Option<(usize, u32)> = None;
    for x in 0..row.len() {
        let b = u32::from(row.get(x).copied().unwrap_or(0));
        if b == 0 {
            continue;
        }
        if let Some((p, a)) = last {
            let n = x - p;
            if n > 1 && n - 1 <= max_gap && agree(a, b) {
                for k in 1..n {
                    // `n <= 65` (`max_gap <= 64`); never 0 (both ends are not).
                    if let Some(o) = row.get_mut(p + k) {
                        *o = blend(a, b, k as u32, n as u32);
                    }
                }
                filled += (n - 1) as u64;
            }
        }
        last = Some((x, b));
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_gaps_between_agreeing_pixels_take_the_blend() {
        let q = |px: u16| px * ONE_Q;
        // A gap of 2 between 5 and 5.75 px; a gap of 3 (too long for 2); a gap of 1 across
        // a 2 px edge; the ends stay without data.
        let mut d = [0, q(5), 0, 0, q(5) + 12, 0, 0, 0, q(6), 0, q(8), 0];
        assert_eq!(fill_gaps(&mut d, 2, Output::DisparityQ4, 0), 2);
        assert_eq!(
            d,
            [
                0,
                q(5),
                q(5) + 4,
                q(5) + 8,
                q(5) + 12,
                0,
                0,
                0,
                q(6),
                0,
                q(8),
                0
            ]
        );
        let mut e = d;
        assert_eq!(fill_gaps(&mut e, 3, Output::DisparityQ4, 0), 3);
        assert_eq!(
            &e[4..9],
            &[q(5) + 12, q(5) + 13, q(5) + 14, q(5) + 15, q(6)]
        );
        assert_eq!(fill_gaps(&mut d, 0, Output::DisparityQ4, 0), 0);
    }

    #[test]
    fn depths_agree_when_their_disparities_do() {
        // depth_k = 16 * 48,000: 4,000 mm is 12 px, 4,300 mm 11.16 px (agree), 6,000 mm 8 px.
        let k = 16 * 48_000;
        let mut d = [4000, 0, 0, 4300, 0, 6000];
        assert_eq!(fill_gaps(&mut d, 4, Output::DepthMm, k), 2);
        assert_eq!(d, [4000, 4100, 4200, 4300, 0, 6000]);
    }

    #[test]
    fn columns_between_decided_ones_take_the_mean_of_agreeing_neighbours() {
        // Decided columns 2, 4, ...; the row's matched columns are 2..10.
        let q = |px: u16| px * ONE_Q;
        let mut d = [0, 0, q(5), 7, q(5) + 8, 7, q(7), 7, 0, 7, q(9), 0];
        fill_between(&mut d, 2, 10, 2);
        // 3: 5 and 5.5 agree (the mean); 5: 5.5 and 7 are 1.5 px apart; 7: one side has
        // no data; 9: its right neighbour lies outside 2..10. Outside 2..10: untouched.
        assert_eq!(
            d,
            [0, 0, q(5), q(5) + 4, q(5) + 8, 0, q(7), 0, 0, 0, q(9), 0]
        );
    }

    #[test]
    fn columns_between_decided_ones_four_apart_take_the_linear_blend() {
        // Decided columns 1, 5, 9, 13; the row's matched columns are 1..12.
        let q = |px: u16| px * ONE_Q;
        let mut d = [0, q(4), 9, 9, 9, q(5), 9, 9, 9, q(7), 9, 9, 0, q(8)];
        fill_between(&mut d, 1, 12, 4);
        // 2-4: 4 -> 5 px in quarters (rounded half up: 4.25, 4.5, 4.75 px); 6-8: 5 and 7
        // are 2 px apart; 10-11: column 13 lies outside 1..12 (no right neighbour).
        assert_eq!(
            d,
            [
                0,
                q(4),
                q(4) + 4,
                q(4) + 8,
                q(4) + 12,
                q(5),
                0,
                0,
                0,
                q(7),
                0,
                0,
                0,
                q(8)
            ]
        );
        // Step 3: thirds of the 1 px (16 Q4 units) between them, rounded half up.
        let mut e = [q(2), 0, 0, q(3)];
        fill_between(&mut e, 0, 4, 3);
        assert_eq!(e, [q(2), q(2) + 5, q(2) + 11, q(3)]);
    }
}
