//! Network input: a 50 m x 50 m north-up grayscale raster and its validity mask, area-
//! downsampled to `INPUT_SIDE x INPUT_SIDE` and normalized to zero mean, unit standard
//! deviation over the valid pixels, quantized with scale `1 / INPUT_UNITS_PER_SIGMA`, zero
//! point 0. Invalid pixels become 0 (the mean), so the mask multiplies the input.
//!
//! Integer only: box sums (the source walked once, one output row of cells at a time), a Q4
//! mean per cell, an integer square root and one integer division per pixel (32-bit where
//! the operands fit, which they do for every valid input). Stack: 2.5 KB (one row of cell
//! sums, and the cells' high bits between the two passes).

use super::NnError;
use crate::image::ImageView;

/// Input side, pixels (50 m / 64 = 0.78125 m per pixel).
pub const INPUT_SIDE: usize = 64;
/// Input elements.
pub const INPUT_LEN: usize = INPUT_SIDE * INPUT_SIDE;
/// Quantized units per standard deviation: the input scale is `1 / 32`, so int8 covers
/// about +-4 sigma.
pub const INPUT_UNITS_PER_SIGMA: i64 = 32;
/// Largest source side, pixels: a cell then has at most 1024 x 1024 pixels, so its `u32`
/// sum (`<= 1024^2 * 255`, times 16 for the Q4 mean) cannot overflow. Larger sources are
/// [`NnError::TooLarge`].
pub const MAX_SOURCE_SIDE: usize = 64 * 1024;
/// Fewest valid cells (of [`INPUT_LEN`]) accepted: one eighth of the window.
pub const MIN_VALID_CELLS: usize = INPUT_LEN / 8;

/// Integer square root (floor).
pub const fn isqrt_u64(n: u64) -> u64 {
    if n < 2 {
        return n;
    }
    let mut x = n;
    let mut y = x.div_ceil(2);
    // Newton from above converges monotonically to floor(sqrt(n)).
    while y < x {
        x = y;
        // x >= floor(sqrt(n)) >= 1 throughout; the match keeps the division panic free.
        y = match n.checked_div(x) {
            Some(q) => (x + q) / 2,
            None => return 0,
        };
    }
    x
}

/// [`row_cells`]'s value of a cell without valid pixels.
const NO_CELL: u32 = u32::MAX;

/// Q4 means of the valid source pixels of the [`INPUT_SIDE`] cells of output row `oy`, into
/// `cells` ([`NO_CELL`] where none is valid): `round(16 sum / n)` over the cell's source
/// rows `oy side / 64 .. (oy + 1) side / 64` and columns likewise. The source rows are walked
/// once for the whole output row (per-cell sums in `count`), so the per-row overhead is paid
/// once per row rather than once per cell. No overflow: a cell has at most `1024^2` pixels
/// ([`MAX_SOURCE_SIDE`]), so `16 sum + n / 2 < 2^32` and a valid value is at most 4080.
fn row_cells(
    src: &ImageView<'_>,
    mask: Option<&ImageView<'_>>,
    oy: usize,
    cells: &mut [u32; INPUT_SIDE],
    count: &mut [u32; INPUT_SIDE],
) {
    let side = src.width();
    let (r0, r1) = (oy * side / INPUT_SIDE, (oy + 1) * side / INPUT_SIDE);
    cells.fill(0);
    count.fill(0);
    for r in r0..r1 {
        let Some(row) = src.row(r) else {
            continue;
        };
        let mrow = match mask {
            Some(m) => match m.row(r) {
                Some(mr) => Some(mr),
                None => continue,
            },
            None => None,
        };
        let mut c0 = 0usize;
        for (ox, (sum, n)) in cells.iter_mut().zip(count.iter_mut()).enumerate() {
            let c1 = (ox + 1) * side / INPUT_SIDE;
            let px = row.get(c0..c1);
            match (px, mrow) {
                (Some(px), Some(mrow)) => {
                    if let Some(ok) = mrow.get(c0..c1) {
                        for (&v, &ok) in px.iter().zip(ok) {
                            if ok != 0 {
                                *sum += v as u32;
                                *n += 1;
                            }
                        }
                    }
                }
                (Some(px), None) => {
                    for &v in px {
                        *sum += v as u32;
                    }
                    *n += px.len() as u32;
                }
                (None, _) => {}
            }
            c0 = c1;
        }
    }
    for (sum, &n) in cells.iter_mut().zip(count.iter()) {
        *sum = (*sum * 16 + n / 2).checked_div(n).unwrap_or(NO_CELL);
    }
}

/// Builds the network input from a `side x side` raster (`side >= INPUT_SIDE`) covering
/// 50 m x 50 m and an optional mask of the same size (non-zero = valid pixel), both packed
/// row-major. See [`prepare_input_view`].
pub fn prepare_input(
    src: &[u8],
    mask: Option<&[u8]>,
    side: usize,
    out: &mut [i8; INPUT_LEN],
) -> Result<(), NnError> {
    if side > MAX_SOURCE_SIDE {
        return Err(NnError::TooLarge);
    }
    // No buffer has usize::MAX bytes, so an area that does not fit never matches one.
    let area = side.saturating_mul(side);
    if side < INPUT_SIDE || src.len() != area || mask.is_some_and(|m| m.len() != area) {
        return Err(NnError::BufferSize);
    }
    let src = ImageView::new(src, side, side).map_err(|_| NnError::BufferSize)?;
    let mask = match mask {
        Some(m) => Some(ImageView::new(m, side, side).map_err(|_| NnError::BufferSize)?),
        None => None,
    };
    prepare_input_view(&src, mask.as_ref(), out)
}

/// Builds the network input from a square image view (side >= [`INPUT_SIDE`] pixels,
/// covering 50 m x 50 m) and an optional mask view of the same size (non-zero = valid).
///
/// Errors: non-square, too small or mismatched views ([`NnError::BufferSize`]), a side above
/// [`MAX_SOURCE_SIDE`] ([`NnError::TooLarge`]), fewer than
/// [`MIN_VALID_CELLS`] valid cells ([`NnError::TooFewValid`]), or no contrast among them
/// ([`NnError::FlatInput`], e.g. a black or saturated frame).
pub fn prepare_input_view(
    src: &ImageView<'_>,
    mask: Option<&ImageView<'_>>,
    out: &mut [i8; INPUT_LEN],
) -> Result<(), NnError> {
    let side = src.width();
    if side > MAX_SOURCE_SIDE {
        return Err(NnError::TooLarge);
    }
    if side < INPUT_SIDE
        || src.height() != side
        || mask.is_some_and(|m| m.width() != side || m.height() != side)
    {
        return Err(NnError::BufferSize);
    }
    let (mut n, mut s, mut q) = (0u64, 0u64, 0u64);
    // One output row of cell values and its pixel counts (512 bytes).
    let (mut cells, mut count) = ([0u32; INPUT_SIDE], [0u32; INPUT_SIDE]);
    // Every cell's 12-bit code (its Q4 mean, at most 4080 = 0xFF0, or `EMPTY` for no valid
    // pixel) is kept between the two passes: the low 8 bits in `out`, the high 4 bits in
    // `high` (two per byte, 2,048 bytes), so the source is walked once.
    const EMPTY: u32 = 0xFFF;
    let mut high = [0u8; INPUT_LEN / 2];
    for ((orow, hrow), oy) in out
        .chunks_exact_mut(INPUT_SIDE)
        .zip(high.chunks_exact_mut(INPUT_SIDE / 2))
        .zip(0..)
    {
        row_cells(src, mask, oy, &mut cells, &mut count);
        for ((o, h), v) in orow
            .chunks_exact_mut(2)
            .zip(hrow.iter_mut())
            .zip(cells.chunks_exact(2))
        {
            let (([o0, o1], [v0, v1]), h) = ((o, v), h) else {
                return Err(NnError::BufferSize);
            };
            let code = |v: u32| if v == NO_CELL { EMPTY } else { v.min(0xFF0) };
            let (c0, c1) = (code(*v0), code(*v1));
            *o0 = c0 as u8 as i8;
            *o1 = c1 as u8 as i8;
            *h = (c0 >> 8) as u8 | ((c1 >> 8) as u8) << 4;
            for &v in [*v0, *v1].iter().filter(|&&v| v != NO_CELL) {
                n += 1;
                s += v as u64;
                q += (v as u64) * (v as u64);
            }
        }
    }
    if (n as usize) < MIN_VALID_CELLS {
        return Err(NnError::TooFewValid);
    }
    // n * std (Q4 units) = sqrt(n Q - S^2).
    let std_n = isqrt_u64(n * q - s * s) as i64;
    // Below 1/4 grey level of standard deviation there is nothing to match.
    if std_n * 4 < n as i64 * 16 {
        return Err(NnError::FlatInput);
    }
    let (n, s) = (n as i64, s as i64);
    // std_n >= 4 n > 0 here (the flat-input check), so the divisor is never zero.
    let den = 2 * std_n;
    for (i, o) in out.iter_mut().enumerate() {
        let h = high.get(i / 2).map_or(0, |&h| (h >> (4 * (i % 2))) & 0xF);
        let code = (*o as u8 as u32) | (h as u32) << 8;
        *o = match code {
            EMPTY => 0,
            v => {
                let num = INPUT_UNITS_PER_SIGMA * (n * v as i64 - s);
                // Round half away from zero: `(2 |num| + std_n) / den` with the sign of
                // `num` (truncating division is symmetric). With `v <= 4080` (Q4 of 255)
                // and `n <= 4096` cells, `|num| <= 32 * 4096 * 4080 < 2^29` and
                // `std_n < 2^25`, so both operands fit a `u32` and one hardware `UDIV`
                // gives the same quotient as the 64-bit division (kept for any other
                // input).
                let mag = 2 * num.unsigned_abs() + std_n as u64;
                let q = match (u32::try_from(mag), u32::try_from(den)) {
                    (Ok(m), Ok(d)) => m.checked_div(d).map(u64::from),
                    _ => mag.checked_div(den as u64),
                };
                let q = q.ok_or(NnError::FlatInput)?.min(127) as i8;
                if num >= 0 {
                    q
                } else {
                    -q
                }
            }
        };
    }
    Ok(())
}

/// Q4 mean of the valid source pixels of output cell `(oy, ox)`, or `None` if none is valid:
/// the cell by cell definition [`row_cells`] must equal (unit tests compare them).
#[cfg(test)]
fn cell(src: &ImageView<'_>, mask: Option<&ImageView<'_>>, oy: usize, ox: usize) -> Option<u32> {
    let side = src.width();
    let (r0, r1) = (oy * side / INPUT_SIDE, (oy + 1) * side / INPUT_SIDE);
    let (c0, c1) = (ox * side / INPUT_SIDE, (ox + 1) * side / INPUT_SIDE);
    let (mut sum, mut n) = (0u32, 0u32);
    for r in r0..r1 {
        let Some(row) = src.row(r).and_then(|x| x.get(c0..c1)) else {
            continue;
        };
        match mask {
            Some(m) => {
                let Some(mrow) = m.row(r).and_then(|x| x.get(c0..c1)) else {
                    continue;
                };
                for (&v, &ok) in row.iter().zip(mrow) {
                    if ok != 0 {
                        sum += v as u32;
                        n += 1;
                    }
                }
            }
            None => {
                for &v in row {
                    sum += v as u32;
                }
                n += row.len() as u32;
            }
        }
    }
    (sum * 16 + n / 2).checked_div(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isqrt_is_floor_sqrt() {
        for n in [0u64, 1, 2, 3, 4, 15, 16, 17, 99, 100, 1 << 40, u64::MAX] {
            let r = isqrt_u64(n);
            assert!(r.checked_mul(r).is_some_and(|rr| rr <= n));
            assert!((r + 1).checked_mul(r + 1).is_none_or(|rr| rr > n));
        }
    }

    #[test]
    fn row_cells_equal_the_cell_definition() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut src = [0u8; 203 * 203];
        let mut mask = [0u8; 203 * 203];
        let (mut cells, mut count) = ([0u32; INPUT_SIDE], [0u32; INPUT_SIDE]);
        let mut seen_none = false;
        for side in [64usize, 65, 127, 200, 203] {
            for v in src.iter_mut() {
                *v = next() as u8;
            }
            for (i, m) in mask.iter_mut().enumerate() {
                // Blocks of invalid pixels (whole cells empty) and scattered ones.
                *m = u8::from((i / 7) % 5 != 0 && next() % 4 != 0);
            }
            let s = ImageView::new(&src[..side * side], side, side).unwrap();
            let m = ImageView::new(&mask[..side * side], side, side).unwrap();
            for mk in [None, Some(&m)] {
                for oy in 0..INPUT_SIDE {
                    row_cells(&s, mk, oy, &mut cells, &mut count);
                    for (ox, &v) in cells.iter().enumerate() {
                        let want = cell(&s, mk, oy, ox);
                        seen_none |= want.is_none();
                        assert_eq!(v, want.unwrap_or(NO_CELL), "side {side} cell {oy},{ox}");
                    }
                }
            }
        }
        assert!(seen_none, "no empty cell was tried");
    }

    #[test]
    fn normalizes_and_masks() {
        // Left half 50, right half 150, 128 x 128: every valid cell is +-1 sigma -> +-32.
        let side = 128;
        let mut src = [0u8; 128 * 128];
        for r in 0..side {
            for c in 0..side {
                src[r * side + c] = if c < side / 2 { 50 } else { 150 };
            }
        }
        let mut mask = [1u8; 128 * 128];
        mask[..side * 2].fill(0); // first output row invalid
        let mut out = [0i8; INPUT_LEN];
        prepare_input(&src, Some(&mask), side, &mut out).unwrap();
        assert!(out[..INPUT_SIDE].iter().all(|&v| v == 0));
        assert_eq!(out[INPUT_SIDE], -32);
        assert_eq!(out[2 * INPUT_SIDE - 1], 32);
        let flat = [77u8; 128 * 128];
        assert_eq!(
            prepare_input(&flat, None, side, &mut out),
            Err(NnError::FlatInput)
        );
        assert_eq!(
            prepare_input(&src, Some(&[0u8; 128 * 128]), side, &mut out),
            Err(NnError::TooFewValid)
        );
        assert_eq!(
            prepare_input(&src[..100], None, side, &mut out),
            Err(NnError::BufferSize)
        );
    }
}
