//! Stage 1 of the fix on its own: the top-down image and mask that the fix embeds, from
//! the frames and the depth source ([`Depth`]: flat ground, depth images, or the stereo
//! pairs through the fix's own stereo stage). [`super::run`] calls it as its first stage;
//! the host calls it where it needs exactly the fix's top-down image without the rest of
//! the fix (e.g. training the network on the images the rover will embed), so there is one
//! implementation of the stage.

use super::{
    reproject_depth, reproject_flat, stereo_depth, Depth, FixConfig, FixError, FixInputs,
    ReprojectionSummary, Stage, StageClock, StageOps, LUT_BAND_ROWS,
};
use crate::reproject::{range_scratch_len, Cell, ReliefGrid, Tap};

/// Buffer sizes of [`top_down`] for a configuration: the top-down image and mask (bytes)
/// and the work area (`u32` words) for each depth source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TopDownBufferSizes {
    /// Top-down image, bytes (`n * n`).
    pub top: usize,
    /// Validity mask, bytes (`n * n`).
    pub mask: usize,
    /// Work area for flat ground (the lookup table's band), words.
    pub work_words_flat: usize,
    /// Work area with depth images (the range accumulator), words.
    pub work_words_images: usize,
    /// Work area with the stereo pairs (accumulator and stereo scratch), words.
    pub work_words_stereo: usize,
}

impl TopDownBufferSizes {
    /// The work area (words) for `depth`.
    pub fn work_words(&self, depth: &Depth<'_>) -> usize {
        match depth {
            Depth::Flat => self.work_words_flat,
            Depth::Images(_) => self.work_words_images,
            Depth::Stereo(_) => self.work_words_stereo,
        }
    }
}

/// The sizes [`top_down`] needs under `cfg` (checked first).
pub fn top_down_buffer_sizes(cfg: &FixConfig) -> Result<TopDownBufferSizes, FixError> {
    cfg.validate()?;
    let n = cfg.grid.n;
    let band_cells = LUT_BAND_ROWS.min(n) * n;
    let word = core::mem::size_of::<u32>();
    let lut_words = (band_cells * (core::mem::size_of::<Cell>() + core::mem::size_of::<Tap>()))
        .div_ceil(word)
        + 4;
    Ok(TopDownBufferSizes {
        top: n * n,
        mask: n * n,
        work_words_flat: lut_words,
        work_words_images: range_scratch_len(n),
        work_words_stereo: range_scratch_len(n) + stereo_depth::stereo_work_words(&cfg.stereo),
    })
}

/// Stage 1 of the fix: writes the north-up top-down image (`n x n`, row 0 north) and its
/// mask (255 valid, 0 no data) into `top` and `mask`, using `work` as scratch, and returns
/// what the reprojection saw and its operation counts. Only the frames, depth, camera rig
/// and pose of `inputs` are read (not the map product or the weights). Buffers at least as
/// long as [`top_down_buffer_sizes`] says, else [`FixError::ScratchTooSmall`].
pub fn top_down<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    work: &mut [u32],
    top: &mut [u8],
    mask: &mut [u8],
    clock: &mut C,
) -> Result<(ReprojectionSummary, StageOps), FixError> {
    top_down_relief(inputs, cfg, work, top, mask, None, clock)
}

/// [`top_down`] that also accumulates the relief the depth gives on `relief`'s grid into
/// its words ([`crate::reproject::RangeAccumulator::with_relief`]; flat ground adds none).
pub fn top_down_relief<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    work: &mut [u32],
    top: &mut [u8],
    mask: &mut [u8],
    relief: Option<(ReliefGrid, &mut [i32])>,
    clock: &mut C,
) -> Result<(ReprojectionSummary, StageOps), FixError> {
    let sizes = top_down_buffer_sizes(cfg)?;
    let too_small = |buffer| FixError::ScratchTooSmall { buffer };
    let top = top.get_mut(..sizes.top).ok_or(too_small("top"))?;
    let mask = mask.get_mut(..sizes.mask).ok_or(too_small("mask"))?;
    let work = work
        .get_mut(..sizes.work_words(&inputs.depth))
        .ok_or(too_small("work"))?;
    let mut ops = StageOps::default();
    let summary = match inputs.depth {
        Depth::Flat => reproject_flat(inputs, cfg, work, top, mask, clock, &mut ops)?,
        Depth::Images(depths) => {
            clock.begin(Stage::Reproject);
            let r = reproject_depth(inputs, &depths, cfg, work, top, mask, relief)?;
            clock.end(Stage::Reproject);
            ops.reproject_px = r.pixels_read;
            ReprojectionSummary {
                range: true,
                status: r.status,
                valid_cells: r.valid_cells,
                stereo: None,
            }
        }
        Depth::Stereo(rights) => stereo_depth::reproject_stereo(
            inputs, &rights, cfg, work, top, mask, relief, clock, &mut ops,
        )?,
    };
    Ok((summary, ops))
}
