//! L1 baseline (the study's): minus the weighted mean absolute grey-level difference.

use super::{check_inputs, MatchError, Matcher, OpCounts};
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
        check_inputs(template, weight, window)?;
        let mut total = 0u64;
        let mut acc = 0u64;
        for y in 0..template.height() {
            let (Some(t), Some(w), Some(m)) = (template.row(y), weight.row(y), window.row(y))
            else {
                return Err(MatchError::WindowTooSmall);
            };
            let mut row = 0u32;
            for ((&t, &w), &m) in t.iter().zip(w).zip(m) {
                row += w as u32 * t.abs_diff(m) as u32;
            }
            total += w.iter().map(|&v| v as u64).sum::<u64>();
            acc += row as u64;
        }
        ops.macs += (template.width() * template.height()) as u64;
        ops.windows += 1;
        if total == 0 {
            return Err(MatchError::NoValidPixels);
        }
        Ok(-(acc as f32 / total as f32))
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
