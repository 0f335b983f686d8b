//! The matcher registry: the names `orbfix eval` and `orbfix demo` accept, the core
//! configuration each fix matcher runs, and the option grammar of the baselines.

use anyhow::{bail, Context};
use orbfix::fix::{FixConfig, RefineMode};
use orbfix::matcher::{l1::L1, l2::L2, ncc::Ncc, Matcher};

/// Names of the matchers reported, best first for `demo`. `fix` is the flight core's one
/// fix ([`orbfix::fix::run`], default [`FixConfig`]); `fix-ncc` the same with the NCC
/// refinement always kept; `fix-signed` with the signed (not rectified) high-pass in the
/// refinement; `cnn` the same with only the CNN's sub-cell peak (the bare CNN). The others are baselines on the core's top-down image: masked NCC (`ncc-hp2`:
/// after a 2 m masked high-pass; see [`matcher_by_name`] for the option grammar), L1, L2.
pub const MATCHERS: &[&str] = &[
    "fix",
    "fix-ncc",
    "fix-signed",
    "cnn",
    "ncc-hp2",
    "ncc",
    "ncc-dist",
    "l1",
    "l2",
];

/// The matcher `demo` uses: the best one available.
pub fn best_matcher() -> &'static str {
    MATCHERS[0]
}

/// The fix configuration behind a fix matcher name (`fix`, `fix-ncc`, `cnn`), `None` for a
/// baseline.
pub fn fix_config_by_name(name: &str) -> Option<FixConfig> {
    let mut cfg = FixConfig::default();
    cfg.refine.mode = match name {
        "fix" => RefineMode::Auto,
        "fix-ncc" => RefineMode::Ncc,
        "fix-signed" => {
            cfg.refine.rectify = false;
            RefineMode::Auto
        }
        "cnn" => RefineMode::Cnn,
        _ => return None,
    };
    Some(cfg)
}

/// A baseline matcher with its host-side options.
pub struct MatcherSpec {
    /// Name as given on the command line.
    pub name: String,
    /// The core matcher.
    pub matcher: Box<dyn Matcher + Send + Sync>,
    /// Weight the mask by 1 / distance from the rover (MARSAUTOLOCO's option), radius of
    /// full weight in pixels; `None` = uniform weights.
    pub distance_weighting_px: Option<u32>,
    /// Masked high-pass of top-down image and map before matching: box radius, metres.
    pub highpass_m: Option<f32>,
    /// Ignore top-down pixels farther than this from the rover, metres.
    pub max_range_m: Option<f32>,
    /// Equalize the top-down image's brightness per 1 m range ring first (the reprojection's
    /// `equalize_rings`).
    pub equalize_rings: bool,
}

/// Looks a baseline matcher up by name: a base (`l1`, `l2`, `ncc`) followed by options,
/// each `-dist` (1 / distance weights, full weight within 5 m), `-eq` (top-down brightness
/// equalized per 1 m range ring, `orbfix::reproject::equalize_rings`), `-hpN` (high-pass, box radius N
/// metres), `-rN` (use the top-down image within N metres of the rover only); e.g.
/// `ncc-hp4-r20`. The fix matchers are looked up with [`fix_config_by_name`].
pub fn matcher_by_name(name: &str) -> anyhow::Result<MatcherSpec> {
    let base = name.split('-').next().unwrap_or("");
    let rest = &name[base.len()..];
    let parts = rest.split('-').filter(|p| !p.is_empty());
    let matcher: Box<dyn Matcher + Send + Sync> = match base {
        "l1" => Box::new(L1),
        "l2" => Box::new(L2),
        "ncc" => Box::new(Ncc::default()),
        _ if fix_config_by_name(name).is_some() => bail!(
            "'{name}' is the whole fix, which runs from the rover's frames (`orbfix eval --matcher {name}`, `orbfix demo`); this command matches a top-down image with a baseline: ncc, ncc-dist, l1, l2 (options -dist, -eq, -hpN, -rN)"
        ),
        _ => bail!(
            "unknown matcher '{name}': choose one of {} (baseline options: -dist, -eq, -hpN, -rN)",
            MATCHERS.join(", ")
        ),
    };
    let mut spec = MatcherSpec {
        name: name.to_string(),
        matcher,
        distance_weighting_px: None,
        highpass_m: None,
        max_range_m: None,
        equalize_rings: false,
    };
    for p in parts {
        let num = |pre: &str| -> anyhow::Result<f32> {
            let v: f32 = p[pre.len()..].parse().with_context(|| {
                format!("matcher option '{p}' of '{name}': expected {pre}<metres>")
            })?;
            anyhow::ensure!(
                v.is_finite() && v > 0.0,
                "matcher option '{p}' must be positive"
            );
            Ok(v)
        };
        if p == "dist" {
            spec.distance_weighting_px = Some(20);
        } else if p == "eq" {
            spec.equalize_rings = true;
        } else if p.starts_with("hp") {
            spec.highpass_m = Some(num("hp")?);
        } else if p.starts_with('r') {
            spec.max_range_m = Some(num("r")?);
        } else {
            bail!("unknown option '{p}' in matcher '{name}' (options: -dist, -eq, -hpN, -rN)");
        }
    }
    Ok(spec)
}

/// Parses a comma-separated matcher list (`l1,l2,ncc`), checking every name.
pub fn parse_matchers(list: &str) -> anyhow::Result<Vec<String>> {
    let names: Vec<String> = list
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() {
        bail!("no matcher given: choose from {}", MATCHERS.join(", "));
    }
    for n in &names {
        if fix_config_by_name(n).is_none() {
            matcher_by_name(n)?;
        }
    }
    Ok(names)
}
