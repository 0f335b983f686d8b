//! Heading search around the fix: when the heading estimate is not good enough (a worn IMU
//! gives a few degrees; a 1 deg error turns the far edge of the 50 m top-down image by about
//! 0.4 m), [`run_heading_search`] runs the whole fix ([`super::run`]) at a small set of
//! headings around the estimate and keeps the one whose position scores best. It wraps the
//! fix and changes nothing inside it.
//!
//! Ranking of the tries: a fix refined by the NCC beats one from the CNN's peak; among equal
//! paths the higher score wins (NCC score, or the CNN's cosine), then the higher confidence.
//! Tries without data never win over tries with data. The reported heading is the best
//! try's, moved by a parabola through the scores of its two neighbours (when all three were
//! NCC fixes) within half a step.
//!
//! Cost: [`HeadingSearch::count`] whole fixes (reprojection, embedding, coarse match and
//! refinement each time). The scratch holds the images of the **last** heading tried, not
//! of the best one; the report is the best one's.

use super::{run, FixConfig, FixError, FixInputs, FixPath, FixReport, FixScratch, FixStatus};
use super::{StageClock, StageOps};

/// Most headings one search may try.
pub const MAX_HEADINGS: usize = 9;

/// Which headings are tried: the estimate and `k` steps either side.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingSearch {
    steps_each_side: usize,
    step_deg: f32,
}

impl HeadingSearch {
    /// Headings `estimate + i step_deg` for `i` in `-steps_each_side..=steps_each_side`
    /// (at most [`MAX_HEADINGS`] in all); `step_deg` in `(0, 10]` degrees.
    pub fn new(steps_each_side: usize, step_deg: f32) -> Result<Self, FixError> {
        if steps_each_side
            .checked_mul(2)
            .and_then(|v| v.checked_add(1))
            .is_none_or(|n| n > MAX_HEADINGS)
        {
            return Err(FixError::BadConfig {
                field: "heading.steps_each_side",
            });
        }
        if !(step_deg.is_finite() && step_deg > 0.0 && step_deg <= 10.0) {
            return Err(FixError::BadConfig {
                field: "heading.step_deg",
            });
        }
        Ok(Self {
            steps_each_side,
            step_deg,
        })
    }

    /// The search a heading standard deviation asks for: none (`Ok(None)`) when
    /// `sigma_deg <= tolerance_deg`, else steps of `step_deg` covering `+-2 sigma` (at most
    /// [`MAX_HEADINGS`] headings).
    pub fn for_sigma(
        sigma_deg: f32,
        tolerance_deg: f32,
        step_deg: f32,
    ) -> Result<Option<Self>, FixError> {
        if !(sigma_deg.is_finite() && sigma_deg >= 0.0) {
            return Err(FixError::BadConfig {
                field: "heading.sigma_deg",
            });
        }
        if !(tolerance_deg.is_finite() && tolerance_deg >= 0.0) {
            return Err(FixError::BadConfig {
                field: "heading.tolerance_deg",
            });
        }
        if sigma_deg <= tolerance_deg {
            return Ok(None);
        }
        if !(step_deg.is_finite() && step_deg > 0.0) {
            return Err(FixError::BadConfig {
                field: "heading.step_deg",
            });
        }
        let k = libm::ceilf(2.0 * sigma_deg / step_deg);
        let k = if k.is_finite() && k >= 1.0 {
            (k as usize).min((MAX_HEADINGS - 1) / 2)
        } else {
            1
        };
        Self::new(k, step_deg).map(Some)
    }

    /// Headings tried.
    pub fn count(&self) -> usize {
        2 * self.steps_each_side + 1
    }

    /// Step between headings, degrees.
    pub fn step_deg(&self) -> f32 {
        self.step_deg
    }

    /// Steps either side of the estimate.
    pub fn steps_each_side(&self) -> usize {
        self.steps_each_side
    }

    /// Offset of try `i` (`0..count()`) from the estimate, degrees.
    pub fn offset_deg(&self, i: usize) -> f32 {
        (i as f32 - self.steps_each_side as f32) * self.step_deg
    }
}

/// The best fix of a heading search.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadingFix {
    /// The best heading's report (its `ops` are the sum over all tries).
    pub report: FixReport,
    /// The best heading, degrees clockwise from north (sub-step by a parabola).
    pub heading_deg: f32,
    /// The best try's offset from the estimate, degrees (a multiple of the step).
    pub best_offset_deg: f32,
    /// Headings tried.
    pub tried: usize,
    /// Score of each try (offset order; `-2` for a try without data).
    pub scores: heapless::Vec<f32, MAX_HEADINGS>,
}

/// Ranking key of a report (higher is better).
fn rank(r: &FixReport) -> (u8, f32, f32) {
    let tier = match (r.status, r.path) {
        (FixStatus::NoData, _) | (_, FixPath::None) => 0,
        (_, FixPath::Cnn) => 1,
        (_, FixPath::Ncc) => 2,
    };
    (tier, r.score, r.confidence)
}

fn better(a: (u8, f32, f32), b: (u8, f32, f32)) -> bool {
    a.0 > b.0 || (a.0 == b.0 && (a.1 > b.1 || (a.1 == b.1 && a.2 > b.2)))
}

/// Runs the fix at every heading of `search` around `inputs.pose.heading_deg` and returns
/// the best one (module docs). Errors are the fix's own (the first try's).
pub fn run_heading_search<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    search: &HeadingSearch,
    scratch: &mut FixScratch<'_>,
    clock: &mut C,
) -> Result<HeadingFix, FixError> {
    let h0 = inputs.pose.heading_deg;
    if !h0.is_finite() {
        return Err(FixError::BadConfig {
            field: "pose.heading_deg",
        });
    }
    let mut best: Option<(usize, FixReport)> = None;
    let mut scores: heapless::Vec<f32, MAX_HEADINGS> = heapless::Vec::new();
    let mut tiers: heapless::Vec<u8, MAX_HEADINGS> = heapless::Vec::new();
    let mut ops = StageOps::default();
    for i in 0..search.count() {
        let mut inp = *inputs;
        inp.pose.heading_deg = h0 + search.offset_deg(i);
        let r = run(&inp, cfg, scratch, clock)?;
        ops.lut_cells = ops.lut_cells.saturating_add(r.ops.lut_cells);
        ops.reproject_px = ops.reproject_px.saturating_add(r.ops.reproject_px);
        ops.embed_macs = ops.embed_macs.saturating_add(r.ops.embed_macs);
        ops.match_elements = ops.match_elements.saturating_add(r.ops.match_elements);
        ops.refine_macs = ops.refine_macs.saturating_add(r.ops.refine_macs);
        let key = rank(&r);
        let _ = scores.push(if key.0 == 0 { -2.0 } else { r.score });
        let _ = tiers.push(key.0);
        if best.as_ref().is_none_or(|(_, b)| better(key, rank(b))) {
            best = Some((i, r));
        }
    }
    let Some((bi, mut report)) = best else {
        return Err(FixError::BadConfig {
            field: "heading.steps_each_side",
        });
    };
    report.ops = ops;
    let best_offset_deg = search.offset_deg(bi);
    let ncc = |i: usize| tiers.get(i).copied() == Some(2);
    let sub = match (bi.checked_sub(1), bi + 1 < search.count()) {
        (Some(l), true) if ncc(l) && ncc(bi) && ncc(bi + 1) => {
            match (scores.get(l), scores.get(bi), scores.get(bi + 1)) {
                (Some(&a), Some(&b), Some(&c)) => crate::peak::parabola_offset(a, b, c),
                _ => 0.0,
            }
        }
        _ => 0.0,
    };
    Ok(HeadingFix {
        report,
        heading_deg: h0 + best_offset_deg + sub * search.step_deg(),
        best_offset_deg,
        tried: search.count(),
        scores,
    })
}
