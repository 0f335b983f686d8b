//! The drive's summary ([`summarize`]) and its per-stop table.

use super::{HeadingCompare, StopRecord};
use serde::{Deserialize, Serialize};

/// Share of `v` at most `t` (NaN when empty).
pub(super) fn share(v: &[f64], t: f64) -> f64 {
    v.iter().filter(|&&e| e <= t).count() as f64 / v.len() as f64
}

/// The drive's summary.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    /// Stops.
    pub stops: usize,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Odometry alone: error at the last stop, metres.
    pub odometry_final_error_m: f64,
    /// Odometry alone: largest error, metres.
    pub odometry_max_error_m: f64,
    /// Odometry alone: drift since the start at the last stop, share of the distance.
    pub odometry_drift_share: f64,
    /// Fused: largest error after the first five stops, metres.
    pub fused_max_error_after_5_m: f64,
    /// Fused: share of stops after the first five within 1 m.
    pub fused_within_1m_after_5: f64,
    /// Fused: share of stops after the first five within 2 m.
    pub fused_within_2m_after_5: f64,
    /// Fused: mean error after the first five stops, metres.
    pub fused_mean_error_after_5_m: f64,
    /// Fixes with a position (status other than no-data).
    pub fixes: usize,
    /// Fixes within 1 m of the truth, share of all stops (no data counts as a miss).
    pub fix_within_1m: f64,
    /// Fixes the filter accepted.
    pub accepted: usize,
    /// Largest error of an accepted fix, metres.
    pub accepted_max_error_m: f64,
    /// Accepted fixes more than 5 m off.
    pub accepted_over_5m: usize,
    /// Every refused fix: stop, fix error (m) and why.
    pub rejected: Vec<(usize, Option<f64>, String)>,
    /// Heading comparison: share of stops with a fix within 1 m with the known heading,
    /// the noisy one without search, and with the search (if compared).
    pub compare_within_1m: Option<(f64, f64, f64)>,
    /// Mean wall time of the fix, milliseconds (host).
    pub fix_ms_mean: f64,
    /// Mean wall time of the comparison's known-heading fix and of its heading search,
    /// milliseconds (host).
    pub compare_ms_mean: Option<(f64, f64)>,
}

/// Summarizes `records`.
pub fn summarize(records: &[StopRecord]) -> Summary {
    let after: Vec<&StopRecord> = records.iter().filter(|r| r.stop >= 5).collect();
    let fe: Vec<f64> = after.iter().map(|r| r.fused_error_m).collect();
    let last = records.last();
    let acc: Vec<f64> = records
        .iter()
        .filter(|r| r.accepted)
        .filter_map(|r| r.fix_error_m)
        .collect();
    let err_or_inf = |e: Option<f64>| e.unwrap_or(f64::INFINITY);
    let fix_all: Vec<f64> = records.iter().map(|r| err_or_inf(r.fix_error_m)).collect();
    let cmp: Vec<&HeadingCompare> = records.iter().filter_map(|r| r.compare.as_ref()).collect();
    let compare_within_1m = (!cmp.is_empty()).then(|| {
        let k: Vec<f64> = cmp.iter().map(|c| err_or_inf(c.known_error_m)).collect();
        let n: Vec<f64> = cmp.iter().map(|c| err_or_inf(c.noisy_error_m)).collect();
        let s: Vec<f64> = cmp.iter().map(|c| err_or_inf(c.search_error_m)).collect();
        (share(&k, 1.0), share(&n, 1.0), share(&s, 1.0))
    });
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Summary {
        stops: records.len(),
        distance_m: last.map_or(0.0, |r| r.distance_m),
        odometry_final_error_m: last.map_or(0.0, |r| r.odometry_error_m),
        odometry_max_error_m: records
            .iter()
            .map(|r| r.odometry_error_m)
            .fold(0.0, f64::max),
        odometry_drift_share: last.map_or(0.0, |r| r.odometry_drift_m / r.distance_m.max(1.0)),
        fused_max_error_after_5_m: fe.iter().copied().fold(0.0, f64::max),
        fused_within_1m_after_5: share(&fe, 1.0),
        fused_within_2m_after_5: share(&fe, 2.0),
        fused_mean_error_after_5_m: mean(&fe),
        fixes: records.iter().filter(|r| r.fix_m.is_some()).count(),
        fix_within_1m: share(&fix_all, 1.0),
        accepted: records.iter().filter(|r| r.accepted).count(),
        accepted_max_error_m: acc.iter().copied().fold(0.0, f64::max),
        accepted_over_5m: acc.iter().filter(|&&e| e > 5.0).count(),
        rejected: records
            .iter()
            .filter(|r| !r.accepted)
            .map(|r| {
                (
                    r.stop,
                    r.fix_error_m,
                    r.reject_reason.clone().unwrap_or_default(),
                )
            })
            .collect(),
        compare_within_1m,
        fix_ms_mean: mean(&records.iter().map(|r| r.fix_ms).collect::<Vec<_>>()),
        compare_ms_mean: (!cmp.is_empty()).then(|| {
            (
                mean(&cmp.iter().map(|c| c.known_ms).collect::<Vec<_>>()),
                mean(&cmp.iter().map(|c| c.search_ms).collect::<Vec<_>>()),
            )
        }),
    }
}

/// The per-stop table in Markdown.
pub fn markdown_table(records: &[StopRecord]) -> String {
    let mut s = String::from(
        "| stop | driven m | odometry err m | prior err m | radius m | fix err m | bound m | status | accepted | fused err m | fused sigma m |\n|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---:|\n",
    );
    let f = |v: Option<f64>| v.map_or("-".to_string(), |e| format!("{e:.2}"));
    for r in records {
        s.push_str(&format!(
            "| {} | {:.0} | {:.2} | {:.2} | {:.0} | {} | {} | {} | {} | {:.2} | {:.2} |\n",
            r.stop,
            r.distance_m,
            r.odometry_error_m,
            r.prior_error_m,
            r.search_radius_m,
            f(r.fix_error_m),
            f(r.fix_bound_m),
            r.fix_status,
            if r.accepted {
                "yes".to_string()
            } else {
                format!(
                    "no ({})",
                    r.reject_reason
                        .as_deref()
                        .and_then(|x| x.split(':').next())
                        .unwrap_or("?")
                )
            },
            r.fused_error_m,
            r.fused_sigma_m
        ));
    }
    s
}
