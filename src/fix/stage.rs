//! The stages of the fix and the clock the caller times them with.

/// The stages of the fix, in run order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Reprojection lookup table for the pose prior (flat-ground path; set-up floats, in
    /// bands of grid rows).
    LutBuild,
    /// Depth from the rover's own stereo pairs (on-board stereo only: block matching band by
    /// band, [`crate::stereo`]).
    Stereo,
    /// The four frames into the top-down image and mask: integer bilinear sampling through
    /// the table (flat path) or forward projection with depth (range path).
    Reproject,
    /// The CNN's input from the top-down image and its int8 embedding.
    NnEmbed,
    /// Q15 cosines of the embedding against every map-window record: the coarse response.
    NnMatch,
    /// The relief the depth saw against the map's relief plane at every window, added to
    /// the coarse response (with depth and a relief plane only).
    Relief,
    /// Masked, high-passed NCC around the best coarse peaks, sub-pixel peak, confidence.
    Refine,
}

impl Stage {
    /// Every stage, in run order.
    pub const ALL: [Stage; 7] = [
        Stage::LutBuild,
        Stage::Stereo,
        Stage::Reproject,
        Stage::NnEmbed,
        Stage::NnMatch,
        Stage::Relief,
        Stage::Refine,
    ];

    /// Short lower-case name used in reports and the budget table.
    pub fn name(self) -> &'static str {
        match self {
            Stage::LutBuild => "lut_build",
            Stage::Stereo => "stereo",
            Stage::Reproject => "reproject",
            Stage::NnEmbed => "nn_embed",
            Stage::NnMatch => "nn_match",
            Stage::Relief => "relief",
            Stage::Refine => "refine",
        }
    }
}

/// Called around every stage (the firmware reads its instruction counter here; a stage
/// that runs in several spans, like the banded table, calls it once per span).
pub trait StageClock {
    /// `stage` is about to start.
    fn begin(&mut self, stage: Stage);
    /// `stage` has finished.
    fn end(&mut self, stage: Stage);

    /// Fault-injection hook for tests: called once after the reprojection, the embedding
    /// and the coarse match of every run with the scratch as the next stage will read it,
    /// and after the refinement with the whole scratch once the run's report is made (before
    /// [`super::run`]'s redundant-run digest reads it; [`super::SelfCheck::redundant_run`]).
    /// A test flips bits here to show that a damaged scratch bit is detected or harmless.
    /// The default does nothing; it is generic, so with it (every flight and host clock) the
    /// call and its argument compile to nothing.
    #[inline(always)]
    fn after(&mut self, _stage: Stage, _scratch: &mut super::FixScratch<'_>) {}
}

/// A [`StageClock`] that does nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl StageClock for NoClock {
    fn begin(&mut self, _stage: Stage) {}
    fn end(&mut self, _stage: Stage) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_names_are_distinct_and_ordered() {
        for (i, a) in Stage::ALL.iter().enumerate() {
            assert_eq!(*a as usize, i);
            for b in &Stage::ALL[i + 1..] {
                assert_ne!(a.name(), b.name());
            }
        }
    }
}
