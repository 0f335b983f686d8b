//! L2 baseline (the study's): minus the weighted mean squared grey-level difference.

use super::{weighted_distance, MatchError, Matcher, OpCounts};
use crate::image::ImageView;

/// L2 distance matcher. Score = `-sum(w (t - m)^2) / sum(w)`, grey levels squared (0 =
/// identical, -65025 = opposite); holes (`w = 0`) are ignored.
#[derive(Clone, Copy, Debug, Default)]
pub struct L2;

impl Matcher for L2 {
    fn name(&self) -> &'static str {
        "l2"
    }

    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        weighted_distance(template, weight, window, ops, |d| d * d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn l2_counts_only_valid_pixels() {
        let t = [10u8, 20, 30, 40];
        let m = [12u8, 20, 200, 40];
        let w = [1u8, 1, 0, 1];
        let (t, m, w) = (
            ImageView::new(&t, 2, 2).unwrap(),
            ImageView::new(&m, 2, 2).unwrap(),
            ImageView::new(&w, 2, 2).unwrap(),
        );
        let mut ops = OpCounts::default();
        let s = L2.score(&t, &w, &m, &mut ops).unwrap();
        assert!((s + 4.0 / 3.0).abs() < 1e-6, "{s}");
        assert_eq!(ops.macs, 4);
    }
}
