//! The per-pixel placement loop: each pixel of a row to its top-down cell by its depth,
//! integer only (three adds and three multiply-adds per pixel).

use super::accumulator::Cells;
use super::setup::Limits;
use super::{POS_FRAC_BITS, SATURATED};

/// No depth (0) at the pixels of `frow` darker than `below` gray levels
/// ([`RangeOptions::sky_below_gray`]); `drow` the row's depths, as long as `frow` or shorter.
pub(super) fn drop_sky(frow: &[u8], drow: &mut [u16], below: u8) {
    for (d, &g) in drow.iter_mut().zip(frow) {
        if g < below {
            *d = 0;
        }
    }
}

/// Places one row, every `stride`-th pixel from the first: the `k`-th pixel read has the
/// ray `ray + k * step` (`step` is already `stride` columns; Q32 per depth unit: cells
/// east, cells south, metres up). Returns the pixels accumulated. `HEIGHT` / `RANGE` switch the
/// height-band and range tests on.
#[inline(always)]
pub(super) fn place_row<const HEIGHT: bool, const RANGE: bool>(
    frow: &[u8],
    drow: &[u16],
    stride: usize,
    ray: [i32; 3],
    step: [i32; 3],
    lim: &Limits,
    cells: &mut Cells<'_>,
) -> u32 {
    // Every pixel: a plain zip (a runtime `step_by` slows the common loop down).
    if stride <= 1 {
        let it = frow.iter().zip(drow);
        place_pixels::<HEIGHT, RANGE, _>(it, ray, step, lim, cells)
    } else {
        let it = frow.iter().zip(drow).step_by(stride);
        place_pixels::<HEIGHT, RANGE, _>(it, ray, step, lim, cells)
    }
}

/// The per-pixel loop of [`place_row`] over the pixels read.
#[inline(always)]
pub(super) fn place_pixels<'p, const HEIGHT: bool, const RANGE: bool, I>(
    pixels: I,
    ray: [i32; 3],
    step: [i32; 3],
    lim: &Limits,
    cells: &mut Cells<'_>,
) -> u32
where
    I: Iterator<Item = (&'p u8, &'p u16)>,
{
    let [mut dx, mut dy, mut dz] = ray;
    let [bx, by, bz] = step;
    let (max_depth, n, c_q) = (lim.max_depth, lim.n, lim.c_q);
    // Both views cut to one length, so one bound check per pixel covers both.
    let len = cells.counts.len().min(cells.sums.len());
    let (Some(counts), Some(sums)) = (cells.counts.get_mut(..len), cells.sums.get_mut(..len))
    else {
        return 0;
    };
    let mut used = 0u32;
    for (&g, &z) in pixels {
        let (rx, ry, rz) = (dx, dy, dz);
        dx = dx.wrapping_add(bx);
        dy = dy.wrapping_add(by);
        if HEIGHT {
            dz = dz.wrapping_add(bz);
        }
        // One compare for "no depth" (0 wraps to 65535) and "too far".
        if z.wrapping_sub(1) >= max_depth {
            continue;
        }
        let zi = i64::from(z);
        if HEIGHT {
            let hz = zi * i64::from(rz);
            if hz < lim.h_lo || hz > lim.h_hi {
                continue;
            }
        }
        // Positions are below 2^46 (rays < 2^30, depths < 2^16), so the cell index (the
        // high word) fits i32; negative cells wrap to huge u32 and fail the bound.
        let col = ((c_q + zi * i64::from(rx)) >> POS_FRAC_BITS) as i32 as u32;
        let row = ((c_q + zi * i64::from(ry)) >> POS_FRAC_BITS) as i32 as u32;
        if col >= n || row >= n {
            continue;
        }
        if RANGE {
            let ec = 2 * i64::from(col) + 1 - i64::from(n);
            let er = 2 * i64::from(row) + 1 - i64::from(n);
            if ec * ec + er * er > lim.range_lim {
                continue;
            }
        }
        let k = row as usize * n as usize + col as usize;
        if let (Some(c), Some(sum)) = (counts.get_mut(k), sums.get_mut(k)) {
            if *c < SATURATED {
                *c += 1;
                // At most 255 samples of at most 255: the sum stays <= 65,025.
                *sum += u16::from(g);
            }
            used += 1;
        }
    }
    used
}
