//! The float CNN (candle) behind the core's [`Matcher`] interface (`--matcher cnn-f32`): the
//! same input preparation as the int8 core matcher ([`prepare_input_view`]), float
//! embeddings, cosine similarity in `[-1, 1]`. A flat or fully masked window scores -1; a
//! flat or fully masked template is an error. [`Matcher::dense`] embeds the template once
//! and the windows in batches.

use super::float_model::{batch_tensor, FloatNet};
use orbfix::image::ImageView;
use orbfix::matcher::{Grid, MatchError, Matcher, OpCounts};
use orbfix::nn::input::{prepare_input_view, INPUT_LEN};
use orbfix::nn::model::embedding_macs;
use orbfix::nn::NnError;
use std::path::Path;

/// Windows embedded per candle batch.
const BATCH: usize = 64;

/// The float siamese CNN matcher.
pub struct FloatCnnMatcher {
    net: FloatNet,
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

impl FloatCnnMatcher {
    /// Loads a float checkpoint (`orbfix train`'s `checkpoint.safetensors`).
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        Ok(Self {
            net: FloatNet::load(path)?,
        })
    }

    /// Embeddings (L2-normalized, 2048 floats each) of prepared inputs.
    fn embed(&self, inputs: &[&[i8; INPUT_LEN]]) -> Result<Vec<Vec<f32>>, MatchError> {
        let t = batch_tensor(inputs).map_err(|_| MatchError::WindowTooSmall)?;
        self.net
            .embed(&t)
            .and_then(|e| Ok(e.to_vec2::<f32>()?))
            .map_err(|_| MatchError::WindowTooSmall)
    }

    fn template(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
    ) -> Result<Vec<f32>, MatchError> {
        if weight.width() != template.width() || weight.height() != template.height() {
            return Err(MatchError::MaskSizeMismatch);
        }
        let mut x = [0i8; INPUT_LEN];
        prepare_input_view(template, Some(weight), &mut x).map_err(to_match_error)?;
        self.embed(&[&x])?.pop().ok_or(MatchError::WindowTooSmall)
    }

    /// Scores of `t` against windows (`None` = flat window, scores -1).
    fn scores(
        &self,
        t: &[f32],
        windows: &[Option<[i8; INPUT_LEN]>],
        ops: &mut OpCounts,
    ) -> Result<Vec<f32>, MatchError> {
        let mut out = vec![-1f32; windows.len()];
        let idx: Vec<usize> = (0..windows.len())
            .filter(|&i| windows[i].is_some())
            .collect();
        for chunk in idx.chunks(BATCH) {
            let refs: Vec<&[i8; INPUT_LEN]> =
                chunk.iter().filter_map(|&i| windows[i].as_ref()).collect();
            let e = self.embed(&refs)?;
            for (&i, ei) in chunk.iter().zip(&e) {
                out[i] = t.iter().zip(ei).map(|(a, b)| a * b).sum();
            }
        }
        ops.windows += windows.len() as u64;
        ops.macs += (idx.len() as u64 + 1) * embedding_macs() + (idx.len() * t.len()) as u64;
        Ok(out)
    }
}

fn window_input(win: &ImageView<'_>) -> Result<Option<[i8; INPUT_LEN]>, MatchError> {
    let mut x = [0i8; INPUT_LEN];
    match prepare_input_view(win, None, &mut x) {
        Ok(()) => Ok(Some(x)),
        Err(NnError::FlatInput | NnError::TooFewValid) => Ok(None),
        Err(e) => Err(to_match_error(e)),
    }
}

impl Matcher for FloatCnnMatcher {
    fn name(&self) -> &'static str {
        "cnn-f32"
    }

    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        let t = self.template(template, weight)?;
        let win = window
            .sub(0, 0, template.width(), template.height())
            .ok_or(MatchError::WindowTooSmall)?;
        let w = window_input(&win)?;
        Ok(self.scores(&t, &[w], ops)?[0])
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
        let (grid, out) = Grid::dense(template, region, step, out)?;
        let t = self.template(template, weight)?;
        let mut wins = Vec::with_capacity(grid.len());
        for i in 0..grid.len() {
            let (c, r) = (i % grid.cols(), i / grid.cols());
            let win = region
                .sub(c * step, r * step, w, h)
                .ok_or(MatchError::WindowTooSmall)?;
            wins.push(window_input(&win)?);
        }
        out.copy_from_slice(&self.scores(&t, &wins, ops)?);
        Ok(grid)
    }
}
