//! The ground shear of the right image (`StereoParams::ground_shear`): each filtered right
//! row moved right by its row's shift `g(v) = a + s v` (Q8 pixels, the flat ground's
//! disparity less a constant, [`super::geometry::RowRanges::shear_q8`]) before matching, and
//! the residual disparities found turned back into disparities.

/// The shear `a + s v`, Q8 pixels, of row `v` ([`super::geometry::RowRanges::shear_q8`]).
#[inline]
pub(crate) fn shear_at((a, s): (i32, i32), v: usize) -> i32 {
    a.saturating_add(s.saturating_mul(v.min(1 << 15) as i32))
}

/// Turns a matched row's residual disparities (Q4, 0 = none) into disparities: adds the
/// row's shear `g_q8` (Q8 pixels, rounded half up to Q4), at least 1 where there was data.
#[cfg(test)]
pub(crate) fn add_shear(disp: &mut [u16], g_q8: i32) {
    let g4 = shear_q4(g_q8);
    if g4 == 0 {
        return;
    }
    for v in disp.iter_mut().filter(|v| **v != 0) {
        *v = sheared(*v, g4);
    }
}

/// A row's shear `g_q8` (Q8 pixels) rounded half up to Q4.
#[inline(always)]
pub(crate) fn shear_q4(g_q8: i32) -> i32 {
    g_q8.saturating_add(8) >> 4
}

/// Residual disparity `v` (Q4, not 0) plus shear `g4` (Q4), at least 1.
#[inline(always)]
pub(crate) fn sheared(v: u16, g4: i32) -> u16 {
    (i32::from(v) + g4).max(1).min(i32::from(u16::MAX)) as u16
}

/// Moves a filtered row `g` pixels right in place (`g` Q8 pixels, either sign): `row[x]`
/// becomes the row at `x - g`, linearly interpolated (rounded half up) between its two
/// nearest pixels, pixels past either end taking the end's value. The ground shear of the
/// right image ([`super::geometry::RowRanges::shear_q8`]).
pub fn shear_row(row: &mut [u8], g_q8: i32) {
    let w = row.len();
    if w == 0 || g_q8 == 0 {
        return;
    }
    let n = g_q8 >> 8;
    // Weights of pixels `x - n` and `x - n - 1`, 1/256.
    let f = (g_q8 & 0xff) as u32;
    let a = 256 - f;
    let p = row.as_mut_ptr();
    if n >= 0 {
        // Right: the pixels read (`x - n - 1 ..= x - n`, four columns `x - n - 1 ..= x - n +
        // 3` at a time) lie left of the next ones written, so from the right end on every
        // read is of the row as it was; `x <= n` reads only pixel 0 (held).
        let n = (n as usize).min(w);
        let rem = w.saturating_sub(n + 1) % 4;
        // Safety: for `x` in `n + 1 .. w`, `x - n - 1 >= 0` and `x < w`: all pixels read and
        // written lie inside `row` (a block at `x` reads `x - n - 1 ..= x - n + 3 <= x + 3 <
        // w` and writes `x ..= x + 3 < w`), and `p` is its only access here.
        unsafe {
            for x in (w - rem..w).rev() {
                *p.add(x) = lerp(a, f, *p.add(x - n), *p.add(x - n - 1));
            }
            let mut x = w - rem;
            while x >= n + 5 {
                x -= 4;
                lerp4(a, f, p.add(x - n), p.add(x - n - 1), p.add(x));
            }
        }
        let first = row.first().copied().unwrap_or(0);
        row.iter_mut().take(n + 1).for_each(|v| *v = first);
    } else {
        // Left by `m = -n` (and right by `f / 256`): pixels `x + m - 1 ..= x + m` lie at or
        // right of `x`, so from the left end on every read is of the row as it was; `x >= w -
        // m` reads only pixel `w - 1` (held).
        let m = (n.unsigned_abs() as usize).min(w);
        let end = w - m;
        let blocks = end - end % 4;
        // Safety: for `x` in `0 .. w - m`, `x + m - 1 >= x >= 0` and `x + m < w`: all pixels
        // read and written lie inside `row` (a block at `x`, `x + 3 < w - m`, reads `x + m -
        // 1 ..= x + m + 3 < w`), and `p` is its only access here.
        unsafe {
            let mut x = 0;
            while x < blocks {
                lerp4(a, f, p.add(x + m), p.add(x + m - 1), p.add(x));
                x += 4;
            }
            for x in blocks..end {
                *p.add(x) = lerp(a, f, *p.add(x + m), *p.add(x + m - 1));
            }
        }
        let last = row.last().copied().unwrap_or(0);
        row.iter_mut().skip(end).for_each(|v| *v = last);
    }
}

/// `(a s0 + f s1 + 128) / 256` (`a + f = 256`): the linear interpolation of [`shear_row`].
#[inline(always)]
fn lerp(a: u32, f: u32, s0: u8, s1: u8) -> u8 {
    ((a * u32::from(s0) + f * u32::from(s1) + 128) >> 8) as u8
}

/// [`lerp`] of four pixels at once: `s0`, `s1` the first pixels of the two sources, `out`
/// the first written (two bytes in each 16-bit lane: `255 * 256 + 128` stays below 2^16).
///
/// # Safety
/// `s0`, `s1` must be readable and `out` writable for four bytes (any alignment); all four
/// source bytes are read before any is written.
#[inline(always)]
unsafe fn lerp4(a: u32, f: u32, s0: *const u8, s1: *const u8, out: *mut u8) {
    const LO: u32 = 0x00ff_00ff;
    const HALF: u32 = 0x0080_0080;
    // Safety: the caller's contract (unaligned reads and write of four bytes). Each byte
    // position is its own lane, so the byte order does not matter.
    let (u, v) = unsafe {
        (
            core::ptr::read_unaligned(s0.cast::<u32>()),
            core::ptr::read_unaligned(s1.cast::<u32>()),
        )
    };
    let even = (((u & LO) * a + (v & LO) * f + HALF) >> 8) & LO;
    let odd = (((u >> 8) & LO) * a + ((v >> 8) & LO) * f + HALF) & !LO;
    // Safety: as above.
    unsafe { core::ptr::write_unaligned(out.cast::<u32>(), even | odd) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shear_moves_a_row_right_by_a_fraction() {
        let base: [u8; 8] = [10, 20, 40, 80, 160, 200, 220, 250];
        // Whole pixels right and left, edges held.
        let mut r = base;
        shear_row(&mut r, 2 * 256);
        assert_eq!(r, [10, 10, 10, 20, 40, 80, 160, 200]);
        let mut r = base;
        shear_row(&mut r, -256);
        assert_eq!(r, [20, 40, 80, 160, 200, 220, 250, 250]);
        // A quarter pixel right: 3/4 of x and 1/4 of x - 1, rounded half up.
        let mut r = base;
        shear_row(&mut r, 64);
        assert_eq!(r, [10, 18, 35, 70, 140, 190, 215, 243]);
        // 1.5 pixels left: the mean of x + 1 and x + 2.
        let mut r = base;
        shear_row(&mut r, -384);
        assert_eq!(r, [30, 60, 120, 180, 210, 235, 250, 250]);
        // Any shift, any length: the clamped interpolation written out.
        let mut seed = 12345u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed >> 8
        };
        for _ in 0..2000 {
            let w = 1 + (next() % 24) as usize;
            let g = (next() % 12_000) as i32 - 6000;
            let row: [u8; 24] = core::array::from_fn(|_| next() as u8);
            let at = |i: i64| i64::from(row[i.clamp(0, w as i64 - 1) as usize]);
            let (n, f) = (i64::from(g >> 8), i64::from(g & 0xff));
            let mut got = row;
            shear_row(&mut got[..w], g);
            for x in 0..w as i64 {
                let want = ((256 - f) * at(x - n) + f * at(x - n - 1) + 128) >> 8;
                assert_eq!(i64::from(got[x as usize]), want, "w {w} g {g} x {x}");
            }
        }
        // Nothing for 0 or an empty row.
        let mut r = base;
        shear_row(&mut r, 0);
        assert_eq!(r, base);
        shear_row(&mut [], 300);
        // And residuals back to disparities: data only, at least 1.
        let mut d = [0u16, 40, 3, 100];
        add_shear(&mut d, -64);
        assert_eq!(d, [0, 36, 1, 96]);
        add_shear(&mut d, 8 * 16);
        assert_eq!(d, [0, 44, 9, 104]);
    }
}
