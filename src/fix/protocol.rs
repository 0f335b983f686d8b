//! The flight firmware's result protocol, defined once for the firmware that writes it and
//! the host that reads and checks it (`orbfix budget`).
//!
//! The firmware prints one record per line over semihosting:
//!
//! ```text
//! ORBFIX-FW <VERSION>
//! STAGE <stage name> <SysTick ticks>     one per Stage::ALL, in order
//! TOTAL <SysTick ticks>                  the whole fix
//! RESULT <key> 0x<8 hex digits>          one per RESULT_KEYS, in order (f32 as bit patterns)
//! FUSION <SysTick ticks>                the filter's per-stop work (optional)
//! FUSION-RESULT <key> 0x<8 hex digits>   one per FUSION_KEYS, in order (with FUSION)
//! HEADING <headings> <SysTick ticks>     the heading search (optional)
//! HEADING-RESULT <key> 0x<8 hex digits>  one per HEADING_KEYS, in order (with HEADING)
//! STACK <peak bytes> <stack region bytes>
//! END OK | END ERR <what>
//! ```
//!
//! [`result_values`] gives the values of the `RESULT` lines for a report and its output
//! digest; the host computes them from its own run of the same code on the same inputs and
//! requires every line to be equal (bit-exactness). [`fusion_stop`] is the filter's work at
//! one stop of a drive as `orbfix traverse` does it, and [`fusion_values`] /
//! [`heading_values`] give the `FUSION-RESULT` and `HEADING-RESULT` values the same way.

use super::{FixReport, HeadingFix, MAX_HEADINGS};
use crate::fusion::{Fusion, FusionConfig, FusionError, OdometryLeg, UpdateOutcome};

/// Protocol version (the number after [`HEADER`]).
pub const VERSION: u32 = 3;
/// First line's tag.
pub const HEADER: &str = "ORBFIX-FW";
/// Tag of a stage's ticks.
pub const STAGE: &str = "STAGE";
/// Tag of the whole fix's ticks.
pub const TOTAL: &str = "TOTAL";
/// Tag of a result.
pub const RESULT: &str = "RESULT";
/// Tag of the stack high-water mark.
pub const STACK: &str = "STACK";
/// Tag of the last line.
pub const END: &str = "END";
/// Tag of the filter's per-stop ticks ([`fusion_stop`]).
pub const FUSION: &str = "FUSION";
/// Tag of a filter result.
pub const FUSION_RESULT: &str = "FUSION-RESULT";
/// Tag of the heading search's headings and ticks.
pub const HEADING: &str = "HEADING";
/// Tag of a heading-search result.
pub const HEADING_RESULT: &str = "HEADING-RESULT";

/// Number of `RESULT` lines.
pub const RESULTS: usize = 16;

/// Keys of the `RESULT` lines, in order.
pub const RESULT_KEYS: [&str; RESULTS] = [
    "x_m",
    "y_m",
    "error_bound_m",
    "confidence",
    "status",
    "path",
    "score",
    "best_window",
    "cnn_best_window",
    "cnn_best_q15",
    "windows",
    "valid_cells",
    "coverage_permille",
    "candidates",
    "refine_macs",
    "digest",
];

/// Values of the `RESULT` lines for `r` and its [`super::output_digest`], in key order.
pub fn result_values(r: &FixReport, digest: u32) -> [u32; RESULTS] {
    [
        r.x_m.to_bits(),
        r.y_m.to_bits(),
        r.error_bound_m.to_bits(),
        r.confidence.to_bits(),
        r.status.code(),
        r.path as u32,
        r.score.to_bits(),
        r.best_window,
        r.cnn_best_window,
        r.cnn_best_q15 as u32,
        r.windows,
        r.reprojection.valid_cells as u32,
        r.coverage_permille,
        r.candidates.len() as u32,
        r.ops.refine_macs as u32,
        digest,
    ]
}

/// What the filter did at one stop ([`fusion_stop`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FusionStop {
    /// Search radius of this stop's fix, computed after the prediction, metres.
    pub search_radius_m: f32,
    /// What the update did with the fix.
    pub outcome: UpdateOutcome,
}

/// The filter's work at one stop of a drive, in the order `orbfix traverse` does it: the
/// prediction over the odometry leg driven to the stop, the search radius of the stop's
/// fix around the predicted position, then the fix's update (status check, innovation
/// gate, gain and Joseph update, or the covariance inflation of a refused fix).
pub fn fusion_stop(
    fusion: &mut Fusion,
    leg: &OdometryLeg,
    fix: &FixReport,
) -> Result<FusionStop, FusionError> {
    fusion.predict(leg)?;
    let search_radius_m = fusion.search_radius_m();
    let outcome = fusion.update(fix)?;
    Ok(FusionStop {
        search_radius_m,
        outcome,
    })
}

/// Number of `FUSION-RESULT` lines.
pub const FUSION_RESULTS: usize = 10;

/// Keys of the `FUSION-RESULT` lines, in order.
pub const FUSION_KEYS: [&str; FUSION_RESULTS] = [
    "x_m",
    "y_m",
    "heading_bias_deg",
    "p_xx",
    "p_xy",
    "p_yy",
    "search_radius_m",
    "accepted",
    "mahalanobis2",
    "next_search_radius_m",
];

/// Values of the `FUSION-RESULT` lines: the filter after [`fusion_stop`] and what it
/// returned, in key order (`f32` as bit patterns).
pub fn fusion_values(fusion: &Fusion, stop: &FusionStop) -> [u32; FUSION_RESULTS] {
    let (x, y) = fusion.position();
    let p = fusion.position_covariance();
    [
        x.to_bits(),
        y.to_bits(),
        fusion.heading_bias_deg().to_bits(),
        p[0][0].to_bits(),
        p[0][1].to_bits(),
        p[1][1].to_bits(),
        stop.search_radius_m.to_bits(),
        stop.outcome.accepted() as u32,
        stop.outcome.mahalanobis2.to_bits(),
        fusion.search_radius_m().to_bits(),
    ]
}

/// Number of `HEADING-RESULT` lines.
pub const HEADING_RESULTS: usize = 12 + MAX_HEADINGS;

/// Keys of the `HEADING-RESULT` lines, in order (`try<i>_score`: the score of try `i` in
/// offset order, 0 for headings not tried).
pub const HEADING_KEYS: [&str; HEADING_RESULTS] = [
    "x_m",
    "y_m",
    "heading_deg",
    "best_offset_deg",
    "tried",
    "status",
    "path",
    "score",
    "confidence",
    "error_bound_m",
    "refine_macs",
    "digest",
    "try0_score",
    "try1_score",
    "try2_score",
    "try3_score",
    "try4_score",
    "try5_score",
    "try6_score",
    "try7_score",
    "try8_score",
];

/// Values of the `HEADING-RESULT` lines for a heading search and the
/// [`super::output_digest`] of its report over the scratch it left (the last heading's
/// images), in key order.
pub fn heading_values(h: &HeadingFix, digest: u32) -> [u32; HEADING_RESULTS] {
    let r = &h.report;
    let mut v = [0u32; HEADING_RESULTS];
    let head = [
        r.x_m.to_bits(),
        r.y_m.to_bits(),
        h.heading_deg.to_bits(),
        h.best_offset_deg.to_bits(),
        h.tried as u32,
        r.status.code(),
        r.path as u32,
        r.score.to_bits(),
        r.confidence.to_bits(),
        r.error_bound_m.to_bits(),
        r.ops.refine_macs as u32,
        digest,
    ];
    for (d, s) in v.iter_mut().zip(head) {
        *d = s;
    }
    for (d, s) in v.iter_mut().skip(head.len()).zip(&h.scores) {
        *d = s.to_bits();
    }
    v
}

/// Number of words of [`fusion_config_words`].
pub const FUSION_CONFIG_WORDS: usize = 12;

/// The filter's settings as `f32` bit patterns in field order, as the host writes them into
/// the firmware's test vectors ([`fusion_config_from_words`] reads them back).
pub fn fusion_config_words(c: &FusionConfig) -> [u32; FUSION_CONFIG_WORDS] {
    [
        c.initial_sigma_m,
        c.initial_bias_sigma_rad,
        c.scale_sigma,
        c.walk_m2_per_m,
        c.bias_walk_rad2_per_m,
        c.bound_to_sigma,
        c.gate_chi2,
        c.reject_inflation,
        c.radius_sigmas,
        c.radius_margin_m,
        c.radius_min_m,
        c.radius_max_m,
    ]
    .map(f32::to_bits)
}

/// The filter's settings from [`fusion_config_words`] (not validated here:
/// [`Fusion::new`] does).
pub fn fusion_config_from_words(w: &[u32; FUSION_CONFIG_WORDS]) -> FusionConfig {
    let f = w.map(f32::from_bits);
    FusionConfig {
        initial_sigma_m: f[0],
        initial_bias_sigma_rad: f[1],
        scale_sigma: f[2],
        walk_m2_per_m: f[3],
        bias_walk_rad2_per_m: f[4],
        bound_to_sigma: f[5],
        gate_chi2: f[6],
        reject_inflation: f[7],
        radius_sigmas: f[8],
        radius_margin_m: f[9],
        radius_min_m: f[10],
        radius_max_m: f[11],
    }
}
