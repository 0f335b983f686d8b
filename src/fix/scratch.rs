//! Caller-provided working memory of one fix and its sizes ([`fix_buffer_sizes`]).

use super::{FixConfig, FixError};
use crate::map_product::MapProductMeta;
use crate::matcher::prep::highpass_buffer_len;
use crate::nn::input::INPUT_LEN;
use crate::nn::model::{Arena, EMBED_LEN};
use crate::reproject::{relief_words, ReliefGrid};

/// `u32` words of the work area the CNN stage uses: its [`Arena`], then its int8 input
/// (the work area is free between the reprojection and the refinement).
pub const NN_WORK_WORDS: usize = core::mem::size_of::<Arena>().div_ceil(4) + INPUT_LEN.div_ceil(4);

// The arena is viewed inside `u32` words: its alignment must not exceed theirs, and it
// must have no padding (see [`nn_views`]).
const _: () = assert!(core::mem::align_of::<Arena>() <= core::mem::align_of::<u32>());
const _: () = assert!(
    core::mem::size_of::<Arena>()
        == 2 * crate::nn::model::ACTIVATION_BYTES + 2 * crate::nn::model::SCRATCH_LEN
);

/// The CNN's arena and int8 input, viewed in the first [`NN_WORK_WORDS`] of `work`.
pub(crate) fn nn_views(work: &mut [u32]) -> Result<(&mut Arena, &mut [i8; INPUT_LEN]), FixError> {
    let too_small = FixError::ScratchTooSmall { buffer: "work" };
    let arena_words = core::mem::size_of::<Arena>().div_ceil(4);
    let (aw, rest) = work.split_at_mut_checked(arena_words).ok_or(too_small)?;
    let iw = rest.get_mut(..INPUT_LEN.div_ceil(4)).ok_or(too_small)?;
    // Safety: `Arena` is `repr(C)` over `i8` and `i16` arrays without padding (asserted
    // above), so every bit pattern of its bytes is a valid value; its alignment (2) divides
    // that of `u32`, and `aw` holds at least `size_of::<Arena>()` bytes, exclusively
    // borrowed for the returned lifetime.
    let arena = unsafe { &mut *aw.as_mut_ptr().cast::<Arena>() };
    // Safety: `i8` is valid for every bit pattern and has alignment 1; `iw` holds at least
    // `INPUT_LEN` bytes, exclusively borrowed for the returned lifetime.
    let input = unsafe { &mut *iw.as_mut_ptr().cast::<[i8; INPUT_LEN]>() };
    Ok((arena, input))
}

/// Grid rows per band of the flat-ground reprojection table: one band's cells (8 bytes
/// each) and overlap taps (at most one per cell) live in [`FixScratch::work`] at a time.
pub const LUT_BAND_ROWS: usize = 25;

/// Element counts of every buffer of one fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixBufferSizes {
    /// Top-down image, bytes (`n * n`).
    pub top: usize,
    /// Its validity mask, bytes (`n * n`).
    pub mask: usize,
    /// Shared work area, `u32` words: the range accumulator or one band of the table during
    /// reprojection, then the CNN's arena and input ([`NN_WORK_WORDS`]), then the
    /// refinement's images ([`RefineLayout`]).
    pub work_words: usize,
    /// Coarse response, one Q15 cosine per map window.
    pub response: usize,
    /// NCC responses of the refinement levels, `f32`.
    pub refine_floats: usize,
    /// The relief stage's blocks, `i32` words ([`crate::reproject::relief_words`]; 0 when
    /// the configuration or the map product has no relief).
    pub relief_words: usize,
}

impl FixBufferSizes {
    /// Bytes of all of them together (the CNN's embedding, [`EMBED_LEN`] bytes, not
    /// included: see [`FixScratch`]).
    pub fn bytes(&self) -> usize {
        self.top
            + self.mask
            + 4 * self.work_words
            + 4 * self.response
            + 4 * self.refine_floats
            + 4 * self.relief_words
    }
}

/// Where the refinement keeps its images inside the work area (bytes after
/// `hp_words` words of high-pass scratch).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RefineLayout {
    /// `u32` words of high-pass scratch at the start of the work area.
    pub hp_words: usize,
    /// Side of the coarse-level template (`n / factor0`), pixels.
    pub a: usize,
    /// Side of the fine-level template (`n / factor1`), pixels.
    pub b: usize,
    /// Side of the map region a peak's search stays in, pixels (clipped to the map).
    pub region_w: usize,
    /// Height of the region, pixels.
    pub region_h: usize,
    /// Side of the coarse-level map patch, pixels.
    pub patch0: usize,
    /// Side of the fine-level map patch, pixels.
    pub patch1: usize,
}

impl RefineLayout {
    /// The layout for `cfg` over a `map_w x map_h` map.
    pub fn new(cfg: &FixConfig, map_w: usize, map_h: usize) -> Self {
        let n = cfg.grid.n;
        let [l0, l1] = cfg.refine.levels;
        let margin = cfg.refine_margin_px();
        let region_w = (n + 2 * margin).min(map_w);
        let region_h = (n + 2 * margin).min(map_h);
        let a = n / l0.factor.max(1);
        let b = n / l1.factor.max(1);
        Self {
            hp_words: highpass_buffer_len(n),
            a,
            b,
            region_w,
            region_h,
            patch0: a + 2 * l0.reach_px,
            patch1: b + 2 * l1.reach_px,
        }
    }

    /// Bytes kept for the whole stage: the two levels' templates and weights.
    pub fn persistent_bytes(&self) -> usize {
        2 * self.a * self.a + 2 * self.b * self.b
    }

    /// Bytes of the template phase (high-passed full template) after the persistent ones.
    pub fn template_phase_bytes(&self, n: usize) -> usize {
        n * n
    }

    /// Bytes of the per-peak phase (the larger of the two levels' map patches; the
    /// high-passed map comes from the map product's refinement plane).
    pub fn peak_phase_bytes(&self) -> usize {
        (self.patch0 * self.patch0).max(self.patch1 * self.patch1)
    }

    /// Work words the refinement needs.
    pub fn words(&self, n: usize) -> usize {
        let bytes =
            self.persistent_bytes() + self.template_phase_bytes(n).max(self.peak_phase_bytes());
        self.hp_words + bytes.div_ceil(4)
    }
}

/// Sizes of every buffer of a fix with `cfg` over the map product described by `meta`.
pub fn fix_buffer_sizes(
    cfg: &FixConfig,
    meta: &MapProductMeta,
) -> Result<FixBufferSizes, FixError> {
    cfg.validate()?;
    let n = cfg.grid.n;
    if meta.window_px != n {
        return Err(FixError::MapMismatch {
            what: "window side differs from the top-down grid",
        });
    }
    if meta.plane != cfg.refine_plane()? {
        return Err(FixError::MapMismatch {
            what: "its refinement plane was made with another high-pass radius or rectification",
        });
    }
    let cols = (meta.width - n) / meta.step_px.max(1) + 1;
    let rows = (meta.height - n) / meta.step_px.max(1) + 1;
    let stage1 = super::top_down_buffer_sizes(cfg)?;
    let refine = RefineLayout::new(cfg, meta.width, meta.height);
    let [l0, l1] = cfg.refine.levels;
    let floats = (2 * l0.reach_px + 1).pow(2) + (2 * l1.reach_px + 1).pow(2);
    Ok(FixBufferSizes {
        top: n * n,
        mask: n * n,
        work_words: stage1
            .work_words_stereo
            .max(stage1.work_words_images)
            .max(stage1.work_words_flat)
            .max(refine.words(n))
            .max(NN_WORK_WORDS),
        response: cols * rows,
        refine_floats: floats,
        relief_words: relief_grid(cfg, meta)?.map_or(0, |g| relief_words(&g)),
    })
}

/// The relief blocks of the fix under `cfg` with the product `meta`: `None` when the
/// relief stage is off or the product has no relief plane.
pub fn relief_grid(cfg: &FixConfig, meta: &MapProductMeta) -> Result<Option<ReliefGrid>, FixError> {
    if cfg.relief.weight <= 0.0 || meta.relief_block_px == 0 {
        return Ok(None);
    }
    ReliefGrid::new(cfg.grid.n, meta.relief_block_px)
        .map(Some)
        .map_err(|_| FixError::MapMismatch {
            what: "its relief blocks do not fit the top-down grid",
        })
}

/// Caller-provided working memory of one fix (static buffers on the target, `Vec`s on
/// the host), each at least as long as [`fix_buffer_sizes`] says.
pub struct FixScratch<'a> {
    /// Top-down image, bytes.
    pub top: &'a mut [u8],
    /// Validity mask, bytes (255 valid, 0 no data).
    pub mask: &'a mut [u8],
    /// Shared work area, `u32` words.
    pub work: &'a mut [u32],
    /// Coarse response (Q15 cosines, row-major over the map product's window grid).
    pub response: &'a mut [i32],
    /// Refinement responses.
    pub refine_floats: &'a mut [f32],
    /// The top-down image's embedding.
    pub nn_embedding: &'a mut [i8; EMBED_LEN],
    /// The relief stage's blocks ([`FixBufferSizes::relief_words`]; may be empty when that
    /// is 0).
    pub relief: &'a mut [i32],
}
