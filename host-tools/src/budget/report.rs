//! Reading the firmware's semihosting report (the core's result protocol,
//! [`orbfix::fix::protocol`]) and the host's expected `RESULT` values.

use anyhow::{bail, Context, Result};
use orbfix::fix::protocol;

/// What the firmware reported.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FirmwareReport {
    /// SysTick ticks per stage, in report order.
    pub stages: Vec<(String, u64)>,
    /// SysTick ticks of the whole fix (all stages and the glue between them).
    pub total_ticks: u64,
    /// `RESULT` lines, in order: key and value.
    pub results: Vec<(String, String)>,
    /// Deepest stack use, bytes.
    pub stack_peak_bytes: u64,
    /// Size of the stack region, bytes.
    pub stack_region_bytes: u64,
    /// `END OK` seen.
    pub ok: bool,
    /// `END ERR ...` texts.
    pub errors: Vec<String>,
    /// The filter's per-stop work (`FUSION` and its `FUSION-RESULT` lines), if reported.
    pub fusion: Option<ExtraReport>,
    /// The heading search (`HEADING` and its `HEADING-RESULT` lines), if reported.
    pub heading: Option<ExtraReport>,
}

/// A measurement the firmware reports after the fix: the filter or the heading search.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExtraReport {
    /// SysTick ticks.
    pub ticks: u64,
    /// Headings tried (heading search; 0 for the filter).
    pub headings: u64,
    /// Result lines, in order: key and value.
    pub results: Vec<(String, String)>,
}

fn hex_lines<const N: usize>(keys: &[&str; N], values: [u32; N]) -> Vec<(String, String)> {
    keys.iter()
        .zip(values)
        .map(|(k, v)| (k.to_string(), format!("0x{v:08x}")))
        .collect()
}

/// The `FUSION-RESULT` lines the firmware must print for the host's run of the same filter
/// work ([`orbfix::fix::protocol::fusion_stop`]).
pub fn expected_fusion(
    fusion: &orbfix::fusion::Fusion,
    stop: &protocol::FusionStop,
) -> Vec<(String, String)> {
    hex_lines(
        &protocol::FUSION_KEYS,
        protocol::fusion_values(fusion, stop),
    )
}

/// The `HEADING-RESULT` lines the firmware must print for the host's heading search and its
/// digest.
pub fn expected_heading(h: &orbfix::fix::HeadingFix, digest: u32) -> Vec<(String, String)> {
    hex_lines(&protocol::HEADING_KEYS, protocol::heading_values(h, digest))
}

/// The `RESULT` lines the firmware must print for a report and its digest (same format).
pub fn expected_results(r: &orbfix::fix::FixReport, digest: u32) -> Vec<(String, String)> {
    protocol::RESULT_KEYS
        .iter()
        .zip(protocol::result_values(r, digest))
        .map(|(k, v)| (k.to_string(), format!("0x{v:08x}")))
        .collect()
}

/// Parses the firmware's semihosting output. Lines that are not part of the report (QEMU
/// messages) are ignored; a report without its header or its `END` line is an error.
pub fn parse_report(text: &str) -> Result<FirmwareReport> {
    let mut r = FirmwareReport::default();
    let mut header = false;
    let mut end = false;
    let num = |s: Option<&str>, line: &str| -> Result<u64> {
        s.context("missing number")
            .and_then(|v| v.parse::<u64>().context("not a number"))
            .with_context(|| format!("bad firmware report line {line:?}"))
    };
    for line in text.lines().map(str::trim) {
        let mut it = line.split_whitespace();
        match it.next() {
            Some(t) if t == protocol::HEADER => {
                let v = it.next().unwrap_or("");
                if v != protocol::VERSION.to_string() {
                    bail!(
                        "firmware report version {v:?} is not {} ({line:?}); rebuild the firmware and host tools from the same tree",
                        protocol::VERSION
                    );
                }
                header = true;
            }
            Some(t) if t == protocol::STAGE => {
                let name = it.next().context("STAGE line without a name")?.to_string();
                r.stages.push((name, num(it.next(), line)?));
            }
            Some(t) if t == protocol::TOTAL => r.total_ticks = num(it.next(), line)?,
            Some(t) if t == protocol::RESULT => {
                let key = it.next().context("RESULT line without a key")?.to_string();
                let value = it.collect::<Vec<_>>().join(" ");
                r.results.push((key, value));
            }
            Some(t) if t == protocol::FUSION => {
                r.fusion = Some(ExtraReport {
                    ticks: num(it.next(), line)?,
                    ..ExtraReport::default()
                });
            }
            Some(t) if t == protocol::HEADING => {
                let headings = num(it.next(), line)?;
                r.heading = Some(ExtraReport {
                    headings,
                    ticks: num(it.next(), line)?,
                    ..ExtraReport::default()
                });
            }
            Some(t) if t == protocol::FUSION_RESULT || t == protocol::HEADING_RESULT => {
                let entry = if t == protocol::FUSION_RESULT {
                    r.fusion.as_mut()
                } else {
                    r.heading.as_mut()
                }
                .with_context(|| {
                    format!(
                        "firmware report line {line:?} comes before its {} line",
                        t.trim_end_matches("-RESULT")
                    )
                })?;
                let key = it.next().context("result line without a key")?.to_string();
                entry.results.push((key, it.collect::<Vec<_>>().join(" ")));
            }
            Some(t) if t == protocol::STACK => {
                r.stack_peak_bytes = num(it.next(), line)?;
                r.stack_region_bytes = num(it.next(), line)?;
            }
            Some(t) if t == protocol::END => {
                end = true;
                match it.next() {
                    Some("OK") => r.ok = true,
                    _ => r.errors.push(it.collect::<Vec<_>>().join(" ")),
                }
            }
            _ => {}
        }
    }
    if !header {
        bail!(
            "no firmware report in QEMU's output (no '{}' line); output was:\n{text}",
            protocol::HEADER
        );
    }
    if !end {
        bail!("the firmware report has no END line (did QEMU time out or the firmware fault?); output was:\n{text}");
    }
    Ok(r)
}

/// Keys whose values differ between the firmware's report and the host's expectation
/// (missing and unexpected keys included).
pub fn mismatches(report: &FirmwareReport, expected: &[(String, String)]) -> Vec<String> {
    keyed_mismatches(&report.results, expected)
}

/// Keys whose values differ between reported `results` and `expected` (missing and
/// unexpected keys included).
pub fn keyed_mismatches(
    results: &[(String, String)],
    expected: &[(String, String)],
) -> Vec<String> {
    let mut out = Vec::new();
    for (k, want) in expected {
        let got = results.iter().find(|(rk, _)| rk == k).map(|(_, v)| v);
        if got != Some(want) {
            out.push(k.clone());
        }
    }
    for (k, _) in results {
        if !expected.iter().any(|(ek, _)| ek == k) {
            out.push(k.clone());
        }
    }
    out
}
