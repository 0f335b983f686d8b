//! The int8 CNN behind the localization engine's [`Matcher`] interface (`--matcher cnn`).
//!
//! Template (the rover's top-down image with its weight mask) and window must be square and
//! cover 50 m (at least 64 px a side, e.g. 200 px at 0.25 m/px). Each is prepared
//! ([`super::input::prepare_input_view`]) and embedded; the score is the cosine similarity
//! of the embeddings in `[-1, 1]`. A flat or fully masked **window** scores -1 (it cannot be
//! the match); a flat or fully masked **template** is an error.
//!
//! Memory: the network's [`Arena`] (33,920 bytes) lives on the stack of each call; nothing
//! is shared, so the matcher is `Send + Sync`. [`Matcher::dense`] embeds the template once
//! and every window once. In flight, window embeddings depend only on the map and should be
//! precomputed once per map (see `docs/matcher.md`).

use super::input::{prepare_input_view, INPUT_LEN};
use super::model::{cosine_q15, embedding_macs, shipped, Arena, SiameseNet, EMBED_LEN};
use super::weights::WeightsError;
use super::NnError;
use crate::image::ImageView;
use crate::matcher::{Grid, MatchError, Matcher, OpCounts};

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
    }
}

impl<'a> CnnMatcher<'a> {
    /// A matcher running `net`.
    pub fn new(net: SiameseNet<'a>) -> Self {
        Self { net }
    }

    fn embed(
        &self,
        img: &ImageView<'_>,
        mask: Option<&ImageView<'_>>,
        arena: &mut Arena,
        out: &mut [i8; EMBED_LEN],
        ops: &mut OpCounts,
    ) -> Result<(), NnError> {
        let mut input = [0i8; INPUT_LEN];
        prepare_input_view(img, mask, &mut input)?;
        self.net.embed(&input, arena, out)?;
        ops.macs += embedding_macs();
        Ok(())
    }

    fn window_score(
        &self,
        t: &[i8; EMBED_LEN],
        window: &ImageView<'_>,
        arena: &mut Arena,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        let mut e = [0i8; EMBED_LEN];
        ops.windows += 1;
        match self.embed(window, None, arena, &mut e, ops) {
            Ok(()) => {
                ops.macs += EMBED_LEN as u64;
                Ok(cosine_q15(t, &e, self.net.embedding_zero_point()) as f32 / 32768.0)
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
        let grid = Grid::new(w, h, region.width(), region.height(), step)?;
        let out = out
            .get_mut(..grid.len())
            .ok_or(MatchError::OutputTooSmall { needed: grid.len() })?;
        let mut arena = Arena::new();
        let mut t = [0i8; EMBED_LEN];
        self.embed(template, Some(weight), &mut arena, &mut t, ops)
            .map_err(to_match_error)?;
        for (i, o) in out.iter_mut().enumerate() {
            let (c, r) = (i % grid.cols, i / grid.cols);
            let win = region
                .sub(c * step, r * step, w, h)
                .ok_or(MatchError::WindowTooSmall)?;
            *o = self.window_score(&t, &win, &mut arena, ops)?;
        }
        Ok(grid)
    }
}
