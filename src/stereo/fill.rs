//! The columns a row did not decide (`StereoParams::column_step`, `near_column_step`):
//! each takes the linear blend of the decided columns on either side where they agree.

use super::band::ONE_Q;

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
                let k32 = k as u32;
                // At most 4 * 2^16: no overflow.
                let v = if near {
                    ((a * (n - k32) + b * k32 + n / 2) / n) as u16
                } else {
                    0
                };
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

#[cfg(test)]
mod tests {
    use super::*;

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
