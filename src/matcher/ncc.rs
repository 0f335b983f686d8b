//! Masked, weighted normalized cross-correlation (MARSAUTOLOCO's matcher).
//!
//! With weights `w` (0 = hole), template `t` and map window `m`, over the template's pixels:
//! `W = sum w`, `St = sum w t`, `Stt = sum w t^2` (template statistics, computed once per
//! dense call) and `Sm = sum w m`, `Smm = sum w m^2`, `Stm = sum w t m` (three integer
//! correlations per window; the map's statistics are taken under the template's mask, so
//! holes never see the map). Then
//! `ncc = (W Stm - St Sm) / sqrt((W Stt - St^2) (W Smm - Sm^2))`, in `[-1, 1]`.

use super::{check_inputs, Grid, MatchError, Matcher, OpCounts};
use crate::image::ImageView;
use core::num::NonZeroUsize;

/// Masked normalized cross-correlation. Score in `[-1, 1]`; a map window whose weighted
/// standard deviation is below [`Ncc::min_map_std`] (grey levels) scores `0` (nothing to
/// correlate with), so a flat map never yields a confident peak.
#[derive(Clone, Copy, Debug)]
pub struct Ncc {
    /// Minimum weighted standard deviation of a map window, grey levels.
    pub min_map_std: f32,
}

impl Default for Ncc {
    fn default() -> Self {
        Self { min_map_std: 1.0 }
    }
}

/// Weighted statistics of a template: `(W, St, Stt)`.
#[derive(Clone, Copy, Debug)]
struct TemplateStats {
    w: u64,
    st: u64,
    stt: u64,
}

fn template_stats(
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
) -> Result<TemplateStats, MatchError> {
    let mut s = TemplateStats {
        w: 0,
        st: 0,
        stt: 0,
    };
    for y in 0..template.height() {
        let (Some(t), Some(w)) = (template.row(y), weight.row(y)) else {
            return Err(MatchError::MaskSizeMismatch);
        };
        for (&t, &w) in t.iter().zip(w) {
            let wt = w as u64 * t as u64;
            s.w += w as u64;
            s.st += wt;
            s.stt += wt * t as u64;
        }
    }
    if s.w == 0 {
        return Err(MatchError::NoValidPixels);
    }
    // Variance numerator W Stt - St^2 is zero iff all valid pixels are equal.
    if (s.w as u128) * (s.stt as u128) <= (s.st as u128) * (s.st as u128) {
        return Err(MatchError::FeaturelessTemplate);
    }
    Ok(s)
}

impl Ncc {
    fn window(
        &self,
        ts: &TemplateStats,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        let (mut sm, mut smm, mut stm) = (0u64, 0u64, 0u64);
        for y in 0..template.height() {
            let (Some(t), Some(w), Some(m)) = (template.row(y), weight.row(y), window.row(y))
            else {
                return Err(MatchError::WindowTooSmall);
            };
            let (mut a, mut b, mut c) = (0u64, 0u64, 0u64);
            for ((&t, &w), &m) in t.iter().zip(w).zip(m) {
                let wm = w as u32 * m as u32;
                a += wm as u64;
                b += (wm * m as u32) as u64;
                c += (wm * t as u32) as u64;
            }
            sm += a;
            smm += b;
            stm += c;
        }
        ops.macs += 3 * (template.width() * template.height()) as u64;
        ops.windows += 1;
        let w = ts.w as i128;
        let cov = w * stm as i128 - ts.st as i128 * sm as i128;
        let vt = w * ts.stt as i128 - (ts.st as i128) * (ts.st as i128);
        let vm = w * smm as i128 - (sm as i128) * (sm as i128);
        // Weighted map variance (grey levels^2) = vm / W^2.
        let min_var = self.min_map_std * self.min_map_std;
        let wf = ts.w as f32;
        if vm <= 0 || (vm as f32) < min_var * wf * wf || vt <= 0 {
            return Ok(0.0);
        }
        let r = cov as f32 / (libm::sqrtf(vt as f32) * libm::sqrtf(vm as f32));
        Ok(r.clamp(-1.0, 1.0))
    }
}

impl Matcher for Ncc {
    fn name(&self) -> &'static str {
        "ncc"
    }

    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        check_inputs(template, weight, window)?;
        let ts = template_stats(template, weight)?;
        self.window(&ts, template, weight, window, ops)
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
        check_inputs(template, weight, region)?;
        let grid = Grid::new(
            template.width(),
            template.height(),
            region.width(),
            region.height(),
            step,
        )?;
        let out = out
            .get_mut(..grid.len())
            .ok_or(MatchError::OutputTooSmall { needed: grid.len() })?;
        let ts = template_stats(template, weight)?;
        let cols = NonZeroUsize::new(grid.cols).ok_or(MatchError::WindowTooSmall)?;
        for (i, o) in out.iter_mut().enumerate() {
            let (c, r) = (i % cols, i / cols);
            let win = region
                .sub(c * step, r * step, template.width(), template.height())
                .ok_or(MatchError::WindowTooSmall)?;
            *o = self.window(&ts, template, weight, &win, ops)?;
        }
        Ok(grid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ncc_is_gain_and_offset_invariant_and_ignores_holes() {
        let t = [10u8, 50, 30, 90, 70, 20, 0, 0, 0];
        let mut m = [0u8; 9];
        for i in 0..9 {
            m[i] = 40 + t[i] / 2;
        }
        m[6] = 255; // under a hole: must not matter
        let w = [255u8, 255, 255, 255, 255, 255, 0, 0, 0];
        let (tv, mv, wv) = (
            ImageView::new(&t, 3, 3).unwrap(),
            ImageView::new(&m, 3, 3).unwrap(),
            ImageView::new(&w, 3, 3).unwrap(),
        );
        let mut ops = OpCounts::default();
        let s = Ncc::default().score(&tv, &wv, &mv, &mut ops).unwrap();
        assert!(s > 0.999, "{s}");
        // Inverted map: anti-correlated.
        let inv: [u8; 9] = core::array::from_fn(|i| 255 - m[i]);
        let iv = ImageView::new(&inv, 3, 3).unwrap();
        let s = Ncc::default().score(&tv, &wv, &iv, &mut ops).unwrap();
        assert!(s < -0.999, "{s}");
    }

    #[test]
    fn ncc_flat_inputs() {
        let t = [7u8; 4];
        let m = [1u8, 2, 3, 4];
        let w = [1u8; 4];
        let (tv, mv, wv) = (
            ImageView::new(&t, 2, 2).unwrap(),
            ImageView::new(&m, 2, 2).unwrap(),
            ImageView::new(&w, 2, 2).unwrap(),
        );
        let mut ops = OpCounts::default();
        assert_eq!(
            Ncc::default().score(&tv, &wv, &mv, &mut ops),
            Err(MatchError::FeaturelessTemplate)
        );
        // Flat map window scores 0.
        let s = Ncc::default().score(&mv, &wv, &tv, &mut ops).unwrap();
        assert_eq!(s, 0.0);
        let z = [0u8; 4];
        let zv = ImageView::new(&z, 2, 2).unwrap();
        assert_eq!(
            Ncc::default().score(&mv, &zv, &tv, &mut ops),
            Err(MatchError::NoValidPixels)
        );
    }
}
