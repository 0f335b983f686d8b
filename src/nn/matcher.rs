//! The int8 CNN behind the localization engine's [`Matcher`] interface (`--matcher cnn`).
//!
//! Template (the rover's top-down image with its weight mask) and window must be square and
//! cover 50 m (at least 64 px a side, e.g. 200 px at 0.25 m/px). Each is prepared
//! ([`super::input::prepare_input_view`]) and embedded; the score is the cosine similarity
//! of the embeddings in `[-1, 1]`. A flat or fully masked **window** scores -1 (it cannot be
//! the match); a flat or fully masked **template** is an error.
//!
//! Memory: each call claims one [`CnnScratch`] (the network's [`Arena`], the prepared input
//! and two embeddings: [`CNN_SCRATCH_BYTES`]) from a static pool
//! ([`crate::scratch`], [`crate::scratch::POOL_SLOTS`] slots), so nothing large is on the
//! stack and the matcher is `Send + Sync`. [`Matcher::dense`] embeds the template once
//! and every window once. In flight, window embeddings depend only on the map and should be
//! precomputed once per map (see `docs/matcher.md`).

use super::input::{prepare_input_view, INPUT_LEN};
use super::model::{cosine_q15, embedding_macs, shipped, Arena, SiameseNet, EMBED_LEN};
use super::weights::WeightsError;
use super::NnError;
use crate::image::ImageView;
use crate::matcher::{Grid, MatchError, Matcher, OpCounts};
use crate::scratch::{claim, Slot, POOL_SLOTS};

/// Working memory of one [`CnnMatcher`] call: the network's arena, the prepared input and
/// the template's and a window's embeddings.
pub struct CnnScratch {
    arena: Arena,
    input: [i8; INPUT_LEN],
    template: [i8; EMBED_LEN],
    window: [i8; EMBED_LEN],
}

impl CnnScratch {
    /// Zeroed scratch (usable in a `static` initializer).
    pub const fn new() -> Self {
        Self {
            arena: Arena::new(),
            input: [0; INPUT_LEN],
            template: [0; EMBED_LEN],
            window: [0; EMBED_LEN],
        }
    }
}

impl Default for CnnScratch {
    fn default() -> Self {
        Self::new()
    }
}

/// Bytes of one [`CnnScratch`] (the static pool holds [`POOL_SLOTS`] of them).
pub const CNN_SCRATCH_BYTES: usize = core::mem::size_of::<CnnScratch>();

static SCRATCH: [Slot<CnnScratch>; POOL_SLOTS] =
    [const { Slot::new(CnnScratch::new()) }; POOL_SLOTS];

/// The int8 siamese CNN matcher.
#[derive(Clone, Copy, Debug)]
pub struct CnnMatcher<'a> {
    net: SiameseNet<'a>,
}

fn to_match_error(e: NnError) -> MatchError {
    match e {
        NnError::TooFewValid => MatchError::NoValidPixels,
        NnError::FlatInput => MatchError::FeaturelessTemplate,
        NnError::BadGeometry | NnError::BufferSize | NnError::ScratchTooSmall => {
            MatchError::WindowTooSmall
        }
        NnError::TooLarge => MatchError::TooLarge,
    }
}

impl<'a> CnnMatcher<'a> {
    /// A matcher running `net`.
    pub fn new(net: SiameseNet<'a>) -> Self {
        Self { net }
    }

    #[allow(clippy::too_many_arguments)]
    fn embed(
        &self,
        img: &ImageView<'_>,
        mask: Option<&ImageView<'_>>,
        input: &mut [i8; INPUT_LEN],
        arena: &mut Arena,
        out: &mut [i8; EMBED_LEN],
        ops: &mut OpCounts,
    ) -> Result<(), NnError> {
        prepare_input_view(img, mask, input)?;
        self.net.embed(input, arena, out)?;
        ops.macs += embedding_macs();
        Ok(())
    }

    fn window_score(
        &self,
        window: &ImageView<'_>,
        s: &mut CnnScratch,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        ops.windows += 1;
        let CnnScratch {
            arena,
            input,
            template,
            window: e,
        } = s;
        match self.embed(window, None, input, arena, e, ops) {
            Ok(()) => {
                ops.macs += EMBED_LEN as u64;
                Ok(cosine_q15(template, e, self.net.embedding_zero_point()) as f32 / 32768.0)
            }
            Err(NnError::FlatInput | NnError::TooFewValid) => Ok(-1.0),
            Err(e) => Err(to_match_error(e)),
        }
    }
}

impl CnnMatcher<'static> {
    /// The matcher with the shipped weights.
    pub fn shipped() -> Result<Self, WeightsError> {
        Ok(Self::new(shipped()?))
    }
}

impl Matcher for CnnMatcher<'_> {
    fn name(&self) -> &'static str {
        "cnn"
    }

    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        // One window: the dense response over a region the template's size.
        let window = window
            .sub(0, 0, template.width(), template.height())
            .ok_or(MatchError::WindowTooSmall)?;
        let mut out = [0f32; 1];
        self.dense(template, weight, &window, 1, &mut out, ops)?;
        Ok(out[0])
    }

    fn dense(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        region: &ImageView<'_>,
        step: usize,
        out: &mut [f32],
        ops: &mut OpCounts,
    ) -> Result<Grid, MatchError> {
        let (w, h) = (template.width(), template.height());
        if weight.width() != w || weight.height() != h {
            return Err(MatchError::MaskSizeMismatch);
        }
        let (grid, out) = Grid::dense(template, region, step, out)?;
        let mut s = claim(&SCRATCH).ok_or(MatchError::WindowTooSmall)?;
        let CnnScratch {
            arena,
            input,
            template: t,
            ..
        } = &mut *s;
        self.embed(template, Some(weight), input, arena, t, ops)
            .map_err(to_match_error)?;
        for (i, o) in out.iter_mut().enumerate() {
            let (c, r) = (i % grid.cols(), i / grid.cols());
            let win = region
                .sub(c * step, r * step, w, h)
                .ok_or(MatchError::WindowTooSmall)?;
            *o = self.window_score(&win, &mut s, ops)?;
        }
        Ok(grid)
    }
}
