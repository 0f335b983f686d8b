//! Holes of the stereo top-down image filled from flat ground: after the fix's own stereo
//! stage has placed what it measured ([`super::stereo_depth`]), the top-down cells it left
//! empty within [`super::StereoConfig::flat_fill_m`] of the rover take the flat-ground
//! reprojection of the same frames ([`crate::reproject::Lut`], band by band as in the
//! flat-ground path). Near the rover the ground a cell shows is close to the flat plane
//! under the wheels, so a flat cell there is nearly where stereo would have put it; the
//! cells stereo leaves empty (dark shadow, texture too weak to match, a view without a
//! right image) would otherwise give the network and the NCC nothing to match.
//!
//! Memory: in the fix's work area, after the stereo stage is done with it: one band of the
//! table ([`super::LUT_BAND_ROWS`] rows) and one band of image and mask bytes.

use super::{
    lut_scratch, FixConfig, FixError, FixInputs, LutScratch, Stage, StageClock, StageOps,
    LUT_BAND_ROWS,
};
use crate::reproject::{classify_frame, FrameStatus, Lut};

/// Words of the work area [`fill_holes`] needs for an `n x n` grid: the table's band (cells
/// and taps, 8 bytes each) and a band of image and mask bytes.
pub(super) fn flat_fill_words(n: usize) -> usize {
    let band_cells = LUT_BAND_ROWS.min(n) * n;
    4 * band_cells + 2 + (2 * band_cells).div_ceil(4)
}

/// Fills the cells of `top` whose `mask` is 0 and that lie within
/// [`super::StereoConfig::flat_fill_m`] metres of the rover with the flat-ground
/// reprojection (mask 255); returns how many it filled (0 when the setting is 0). `work`:
/// at least [`flat_fill_words`] words, free for this stage.
pub(super) fn fill_holes<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    work: &mut [u32],
    top: &mut [u8],
    mask: &mut [u8],
    clock: &mut C,
    ops: &mut StageOps,
) -> Result<usize, FixError> {
    let reach_m = cfg.stereo.flat_fill_m;
    if reach_m <= 0.0 {
        return Ok(0);
    }
    let n = cfg.grid.n;
    let too_small = FixError::ScratchTooSmall { buffer: "work" };
    let mut grid = cfg.grid;
    grid.max_range_m = grid.max_range_m.min(reach_m);
    let band_rows = LUT_BAND_ROWS.min(n);
    let band_cells = band_rows * n;
    let LutScratch { cells, taps, rest } = lut_scratch(work, band_cells)?;
    // Safety: `u8` is valid for every bit pattern and its alignment divides `u32`'s, so
    // `align_to_mut` views the word buffer as bytes (empty prefix and suffix).
    let (_, bytes, _) = unsafe { rest.align_to_mut::<u8>() };
    let (band_top, rest) = bytes.split_at_mut(band_cells.min(bytes.len()));
    let band_mask = rest.get_mut(..band_cells).ok_or(too_small)?;
    if band_top.len() < band_cells {
        return Err(too_small);
    }
    // Rows whose centre lies within the reach of the rover (the grid's centre): cell row
    // `r` is `(n / 2 - r - 0.5) * m_per_px` north of it.
    let reach_rows = (reach_m / grid.m_per_px) as usize + 1;
    let first = (n / 2).saturating_sub(reach_rows);
    let last = (n / 2 + reach_rows).min(n);
    let stride = inputs.params.width_px as usize;
    clock.begin(Stage::Reproject);
    let status = inputs
        .frames
        .map(|f| f.as_ref().map_or(FrameStatus::Missing, classify_frame));
    clock.end(Stage::Reproject);
    let mut filled = 0usize;
    let mut row = first;
    while row < last {
        let end = (row + band_rows).min(last);
        let band = (end - row) * n;
        let (Some(bc), Some(bt), Some(bm), Some(mask_band)) = (
            cells.get_mut(..band),
            band_top.get_mut(..band),
            band_mask.get_mut(..band),
            mask.get(row * n..end * n),
        ) else {
            return Err(too_small);
        };
        if mask_band.iter().all(|&m| m != 0) {
            row = end;
            continue;
        }
        clock.begin(Stage::LutBuild);
        let lut = Lut::build_rows(
            bc,
            taps,
            &inputs.params,
            &inputs.pose,
            &grid,
            stride,
            row..end,
        )?;
        clock.end(Stage::LutBuild);
        clock.begin(Stage::Reproject);
        lut.apply_with_status(&inputs.frames, &status, bt, bm)?;
        let (Some(top_band), Some(mask_band)) = (
            top.get_mut(row * n..end * n),
            mask.get_mut(row * n..end * n),
        ) else {
            return Err(too_small);
        };
        for (((t, m), &ft), &fm) in top_band
            .iter_mut()
            .zip(mask_band.iter_mut())
            .zip(bt.iter())
            .zip(bm.iter())
        {
            if *m == 0 && fm != 0 {
                *t = ft;
                *m = fm;
                filled += 1;
            }
        }
        clock.end(Stage::Reproject);
        ops.lut_cells += band as u64;
        row = end;
    }
    Ok(filled)
}
