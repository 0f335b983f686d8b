//! The sparse relief pass: which rows and columns of a frame give the heights of the
//! relief blocks (about eight points per block side at every distance).

use super::setup::Limits;
use super::POS_FRAC_BITS;
use crate::reproject::relief::{ReliefCells, RELIEF_FRAC_BITS};

/// Points per block side the relief pass aims for, along and across the frame's rows.
pub(super) const RELIEF_SAMPLES: f32 = 8.0;
/// Most frame rows between two rows of the relief pass (a power of two).
pub(super) const RELIEF_MAX_ROW_STEP: usize = 16;
/// Most columns between two points of the relief pass.
pub(super) const RELIEF_MAX_COL_STEP: usize = 64;

/// Frame rows between two rows of the relief pass where the flat ground lies beyond the
/// grid, or above the horizon (a power of two).
pub(super) const RELIEF_FAR_ROW_STEP: usize = 4;

/// Row and column steps of the relief pass ([`relief_row`]) for a frame row whose
/// flat-ground depth at the centre column is `flat_m` metres (`None`: at or above the
/// horizon), for blocks `block_m` metres wide, focal length `f` pixels, camera `h` metres
/// up: about [`RELIEF_SAMPLES`] points per block side. On flat ground a row covers `t / f`
/// metres per column and `(h^2 + t^2) / (f h)` metres per row at depth `t`. Rows whose
/// flat ground lies beyond `reach_m` (the grid's half diagonal) see the grid only where the
/// terrain rises: every [`RELIEF_FAR_ROW_STEP`]-th row, columns as at `reach_m`. The row
/// step is a power of two, so the rows a step picks are also picked by every smaller step.
pub(super) fn relief_steps(
    flat_m: Option<f32>,
    reach_m: f32,
    block_m: f32,
    f: f32,
    h: f32,
) -> (usize, usize) {
    let along = block_m / RELIEF_SAMPLES;
    let col_step = |t: f32| {
        let c = libm::floorf(along * f / t);
        if c >= 1.0 {
            (c as usize).min(RELIEF_MAX_COL_STEP)
        } else {
            1
        }
    };
    let t = match flat_m {
        Some(t) if t.is_finite() && t > 0.0 && t <= reach_m => t,
        _ => return (RELIEF_FAR_ROW_STEP, col_step(reach_m)),
    };
    let rows = libm::floorf(along * f * h / (h * h + t * t));
    let rows = if rows >= 1.0 {
        (rows as usize).min(RELIEF_MAX_ROW_STEP)
    } else {
        1
    };
    // The largest power of two not above `rows`.
    (
        1usize << (usize::BITS - 1 - rows.leading_zeros()),
        col_step(t),
    )
}

/// The relief pass over one frame row: every `stride`-th depth of `drow` from the first,
/// with rays as [`place_row`]'s (`step` already `stride` columns), adds the point's height
/// (Q7 metres) to its block. Points without depth, beyond the depth limit or outside the
/// height band add nothing.
pub(super) fn relief_row(
    drow: &[u16],
    stride: usize,
    ray: [i32; 3],
    step: [i32; 3],
    lim: &Limits,
    rc: &mut ReliefCells<'_>,
) {
    let [mut dx, mut dy, mut dz] = ray;
    let [bx, by, bz] = step;
    for &z in drow.iter().step_by(stride.max(1)) {
        let (rx, ry, rz) = (dx, dy, dz);
        dx = dx.wrapping_add(bx);
        dy = dy.wrapping_add(by);
        dz = dz.wrapping_add(bz);
        if z.wrapping_sub(1) >= lim.max_depth {
            continue;
        }
        let zi = i64::from(z);
        let hz = zi * i64::from(rz);
        if hz < lim.h_lo || hz > lim.h_hi {
            continue;
        }
        // As in `place_pixels`: the cell index fits i32; negative cells fail the bound.
        let col = ((lim.c_q + zi * i64::from(rx)) >> POS_FRAC_BITS) as i32 as u32;
        let row = ((lim.c_q + zi * i64::from(ry)) >> POS_FRAC_BITS) as i32 as u32;
        if let Some(b) = rc.grid.block_of(col, row) {
            // Q32 metres to Q7: heights within +-2^24 m fit i32.
            rc.add(b, (hz >> (POS_FRAC_BITS - RELIEF_FRAC_BITS)) as i32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relief_pass_samples_evenly_on_the_ground() {
        // 4 m blocks, f = 320 px, camera 2 m up, grid reach 35.4 m.
        let at = |t: Option<f32>| relief_steps(t, 35.4, 4.0, 320.0, 2.0);
        // Near: 0.5 m is 32 columns at 5 m; rows cover ~4.5 cm each, so the step is capped
        // to a power of two (11 -> 8).
        assert_eq!(at(Some(5.0)), (8, 32));
        // Far: every row, a few columns apart.
        assert_eq!(at(Some(30.0)), (1, 5));
        // Beyond the grid's reach, above the horizon or not finite: sparse rows, columns as
        // at the reach.
        for t in [
            Some(80.0),
            None,
            Some(f32::INFINITY),
            Some(f32::NAN),
            Some(-1.0),
        ] {
            assert_eq!(at(t), (RELIEF_FAR_ROW_STEP, 4), "{t:?}");
        }
        // Every row step is a power of two within its cap, every column step at least 1.
        for t in (1..400).map(|k| k as f32 * 0.1) {
            let (r, c) = at(Some(t));
            assert!(r.is_power_of_two() && r <= RELIEF_MAX_ROW_STEP, "{t}: {r}");
            assert!((1..=RELIEF_MAX_COL_STEP).contains(&c), "{t}: {c}");
        }
    }
}
