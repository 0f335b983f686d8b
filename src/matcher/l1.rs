//! L1 baseline (the study's): minus the weighted mean absolute grey-level difference.

use super::{weighted_distance, MatchError, Matcher, OpCounts};
use crate::image::ImageView;

/// L1 distance matcher. Score = `-sum(w |t - m|) / sum(w)`, grey levels (0 = identical,
/// -255 = opposite); holes (`w = 0`) are ignored.
#[derive(Clone, Copy, Debug, Default)]
pub struct L1;

impl Matcher for L1 {
    fn name(&self) -> &'static str {
        "l1"
    }

    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        weighted_distance(template, weight, window, ops, |d| d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn l1_counts_only_valid_pixels() {
        let t = [10u8, 20, 30, 40];
        let m = [12u8, 20, 200, 40];
        let w = [1u8, 1, 0, 1];
        let (t, m, w) = (
            ImageView::new(&t, 2, 2).unwrap(),
            ImageView::new(&m, 2, 2).unwrap(),
            ImageView::new(&w, 2, 2).unwrap(),
        );
        let mut ops = OpCounts::default();
        let s = L1.score(&t, &w, &m, &mut ops).unwrap();
        assert!((s + 2.0 / 3.0).abs() < 1e-6, "{s}");
        assert_eq!(ops.macs, 4);
    }
}
