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
//! STACK <peak bytes> <stack region bytes>
//! END OK | END ERR <what>
//! ```
//!
//! [`result_values`] gives the values of the `RESULT` lines for a report and its output
//! digest; the host computes them from its own run of the same code on the same inputs and
//! requires every line to be equal (bit-exactness).

use super::FixReport;

/// Protocol version (the number after [`HEADER`]).
pub const VERSION: u32 = 2;
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
