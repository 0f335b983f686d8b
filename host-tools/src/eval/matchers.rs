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

/// The options a fix matcher name may carry after its base, each `-<key><value>`, e.g.
/// `fix-p5-ra1`: the same fix with one setting of [`FixConfig`] changed, for tuning on the
/// development seed; the report prints the whole configuration.
pub const FIX_OPTIONS: &str = "-pN (coarse peaks refined), -mnN (smallest NCC kept, 0..1), \
-mnsN (smallest NCC kept with the fix's own stereo depth), -nmN (NCC margin another refined \
peak needs over the CNN's best with the fix's own stereo depth), \
-raN / -rbN (stereo: relief searched above / below the ground, metres), -anN / -agN \
(stereo: relief above near the rover, metres, growing by N metres per metre of depth up to -ra), \
-hgN (stereo: the horizon rows search terrain rising N metres per metre of depth; 0: off), \
-hlN (stereo: the horizon rows matched at level 1, half the working size, 1 on, 0 off), \
-skN (frame pixels darker than N gray levels get no stereo depth: the black sky; 0: off), \
-amN (stereo: pitch and roll margin around the rover's attitude, degrees), -srN (stereo: \
ground range matched, metres), -rfN (stereo: rows reduced N times more, 1..2), -rrN (stereo: \
window radius down, rows), -rcN (stereo: window radius across, pixels), -seN (stereo: coarser scale where a quarter pixel moves the ground \
at most N metres), -spN (stereo sub-pixel fit: 0 parabola, 1 equiangular), -gsN (stereo: windows follow the flat ground down the image, 1 on, 0 off), -uN (stereo: uniqueness, percent), -mgN (stereo: smallest \
cost gap per window pixel), -msN (stereo: support, neighbours of 8), -gfN (stereo: gaps of at most N working pixels between agreeing disparities filled; 0: none), -fnN (top-down holes with at least N of 8 neighbours filled; 0: none), -mdN (largest depth \
reprojected, metres), -rwN (relief stage weight, 0..4; 0: off), -rmN (relief: fewest blocks), -csN (stereo: \
every N-th column decided, 1..2), -ncN (stereo: every N-th column decided in the near rows, \
1..4; -cs1-nc1 decides every column everywhere), -nsN (stereo: ground span of those N columns up to which a row is near, metres; 0: none), -pmN (stereo: working rows \
matched in pairs where a pair spans at most N metres of ground; 0: none), -prN (stereo: window radius \
down in the paired rows, pairs), -mxN (stereo: most disparities \
of a row the fix's scratch holds; wider reliefs need more), -dsN (stereo: frames reduced N times before matching, 1..4; the fix's width and disparity limits follow)";

/// The fix configuration behind a fix matcher name (`fix`, `fix-ncc`, `fix-signed`, `cnn`,
/// each optionally followed by [`FIX_OPTIONS`]), `None` for a baseline (or a fix name with
/// bad options: [`fix_config_checked`] says what is wrong).
pub fn fix_config_by_name(name: &str) -> Option<FixConfig> {
    fix_config_checked(name).ok().flatten()
}

/// As [`fix_config_by_name`], with the run's pipeline settings (grid, range options, stereo
/// matcher) in place of the defaults, the name's options applied over them.
pub fn fix_config_in(name: &str, pipeline: &super::pipeline::PipelineOptions) -> Option<FixConfig> {
    let (mut cfg, tail) = fix_base(name)?;
    cfg.grid = pipeline.grid;
    cfg.range = pipeline.range;
    cfg.stereo.matcher = pipeline.stereo_params();
    apply_fix_options(name, tail, &mut cfg).ok()?;
    Some(cfg)
}

/// As [`fix_config_by_name`], an error when the name is a fix matcher's with bad options.
pub fn fix_config_checked(name: &str) -> anyhow::Result<Option<FixConfig>> {
    let Some((mut cfg, tail)) = fix_base(name) else {
        return Ok(None);
    };
    apply_fix_options(name, tail, &mut cfg)?;
    Ok(Some(cfg))
}

/// The base configuration of a fix matcher name and the option tail after the base.
fn fix_base(name: &str) -> Option<(FixConfig, &str)> {
    let mut cfg = FixConfig::default();
    // Longer bases first: `fix-ncc` is a base, not `fix` with an option `ncc`.
    for (base, mode, rectify) in [
        ("fix-ncc", RefineMode::Ncc, true),
        ("fix-signed", RefineMode::Auto, false),
        ("cnn", RefineMode::Cnn, true),
        ("fix", RefineMode::Auto, true),
    ] {
        let Some(tail) = name.strip_prefix(base) else {
            continue;
        };
        if !(tail.is_empty() || tail.starts_with('-')) {
            continue;
        }
        cfg.refine.mode = mode;
        cfg.refine.rectify = rectify;
        return Some((cfg, tail));
    }
    None
}

/// Applies a fix matcher name's options ([`FIX_OPTIONS`]) and validates the result.
fn apply_fix_options(name: &str, tail: &str, cfg: &mut FixConfig) -> anyhow::Result<()> {
    for part in tail.split('-').filter(|p| !p.is_empty()) {
        let at = part
            .find(|c: char| !c.is_ascii_alphabetic())
            .unwrap_or(part.len());
        let (key, value) = part.split_at(at);
        if ![
            "p", "mn", "mns", "ra", "rb", "sr", "rf", "rr", "se", "sp", "u", "mg", "ms", "md",
            "rw", "rm", "ds", "cs", "nm", "nc", "ns", "pm", "pr", "mx", "gf", "an", "ag", "am",
            "gs", "rc", "fn", "hg", "hl", "sk",
        ]
        .contains(&key)
        {
            bail!("unknown option '{part}' of matcher '{name}' (fix options: {FIX_OPTIONS})");
        }
        let v: f32 = value.parse().ok().filter(|v: &f32| v.is_finite() && *v >= 0.0).with_context(|| {
            format!("option '{part}' of matcher '{name}': expected {key}<number >= 0> (fix options: {FIX_OPTIONS})")
        })?;
        let m = &mut cfg.stereo.matcher;
        let whole = |v: f32| -> anyhow::Result<u32> {
            anyhow::ensure!(
                v.fract() == 0.0 && v <= 1000.0,
                "option '{part}' of matcher '{name}' takes a whole number"
            );
            Ok(v as u32)
        };
        match key {
            "p" => cfg.refine.peaks = whole(v)? as usize,
            "mn" => cfg.refine.min_ncc = v,
            "mns" => cfg.refine.min_ncc_stereo = v,
            "nm" => cfg.refine.ncc_margin_stereo = v,
            "ra" => m.relief_above_m = v,
            "an" => m.relief_above_near_m = v,
            "ag" => m.relief_above_grade = v,
            "hg" => m.horizon_grade = v,
            "sk" => {
                cfg.range.sky_below_gray = u8::try_from(whole(v)?).map_err(|_| {
                    anyhow::anyhow!(
                        "option '{part}' of matcher '{name}': sk is 0..=255 gray levels"
                    )
                })?
            }
            "am" => m.attitude_margin_deg = v,
            "rb" => m.relief_below_m = v,
            "sr" => m.max_ground_range_m = v,
            "se" => m.scale_error_m = v,
            "sp" => {
                m.subpixel = match whole(v)? {
                    0 => orbfix::stereo::SubPixel::Parabola,
                    1 => orbfix::stereo::SubPixel::Equiangular,
                    _ => bail!(
                    "option '{part}' of matcher '{name}': sp is 0 (parabola) or 1 (equiangular)"
                ),
                }
            }
            "hl" => {
                m.horizon_coarse = match whole(v)? {
                    0 => false,
                    1 => true,
                    _ => bail!("option '{part}' of matcher '{name}': hl is 0 (off) or 1 (on)"),
                }
            }
            "gs" => {
                m.ground_shear = match whole(v)? {
                    0 => false,
                    1 => true,
                    _ => bail!("option '{part}' of matcher '{name}': gs is 0 (off) or 1 (on)"),
                }
            }
            "ds" => {
                let ds = whole(v)?;
                anyhow::ensure!(
                    (1..=4).contains(&ds),
                    "option '{part}' of matcher '{name}': ds is 1..=4"
                );
                // The fix's width and disparity limits scale with the working size.
                let (old, new) = (usize::from(m.downsample.max(1)), ds as usize);
                m.downsample = ds as u8;
                let s = &mut cfg.stereo;
                s.max_width_px = (s.max_width_px * old).div_ceil(new);
                s.max_disparities = (s.max_disparities * old).div_ceil(new);
            }
            "cs" => m.column_step = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "nc" => m.near_column_step = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "ns" => m.near_column_span_m = v,
            "pm" => m.pair_rows_m = v,
            "mx" => cfg.stereo.max_disparities = whole(v)? as usize,
            "pr" => m.pair_radius_rows_px = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "rf" => m.row_factor = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "rc" => m.radius_px = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "rr" => m.radius_rows_px = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            // Out of u8 range: u8::MAX, refused below by the rig's check.
            "u" => m.uniqueness_pct = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "mg" => m.min_gap_per_px = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "ms" => m.min_support = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "gf" => m.gap_fill_px = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "md" => cfg.range.max_depth_m = v,
            "fn" => cfg.range.fill_min_neighbours = u8::try_from(whole(v)?).unwrap_or(u8::MAX),
            "rw" => cfg.relief.weight = v,
            "rm" => cfg.relief.min_blocks = u16::try_from(whole(v)?).unwrap_or(u16::MAX),
            _ => bail!("unknown option '{part}' of matcher '{name}' (fix options: {FIX_OPTIONS})"),
        }
    }
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("matcher '{name}': {e}"))?;
    // The stereo settings are checked against a camera by the core's rig (at the rovers'
    // camera; the fix checks them again against its own).
    orbfix::stereo::StereoRig::new(
        &orbfix::camera::CameraParams::default(),
        &cfg.stereo.matcher,
    )
    .map_err(|e| anyhow::anyhow!("matcher '{name}': {e}"))?;
    Ok(())
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
        if fix_config_checked(n)?.is_none() {
            matcher_by_name(n)?;
        }
    }
    Ok(names)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fix_names_and_their_options() {
        let d = FixConfig::default();
        assert_eq!(fix_config_by_name("fix"), Some(d));
        assert_eq!(
            fix_config_by_name("fix-ncc").map(|c| c.refine.mode),
            Some(RefineMode::Ncc)
        );
        assert_eq!(
            fix_config_by_name("fix-signed").map(|c| c.refine.rectify),
            Some(false)
        );
        assert_eq!(fix_config_by_name("ncc-hp2"), None);
        let c = fix_config_by_name("fix-p5-ra1.5-u20-ms4-mn0.4-rb1-sr30-md25-mg2").unwrap();
        assert_eq!(c.refine.mode, RefineMode::Auto);
        assert_eq!(c.refine.peaks, 5);
        assert_eq!(c.refine.min_ncc, 0.4);
        assert_eq!(c.stereo.matcher.relief_above_m, 1.5);
        assert_eq!(c.stereo.matcher.relief_below_m, 1.0);
        assert_eq!(c.stereo.matcher.max_ground_range_m, 30.0);
        assert_eq!(c.stereo.matcher.uniqueness_pct, 20);
        assert_eq!(c.stereo.matcher.min_support, 4);
        assert_eq!(c.stereo.matcher.min_gap_per_px, 2);
        assert_eq!(c.range.max_depth_m, 25.0);
        let c = fix_config_by_name("fix-rc6-fn3").unwrap();
        assert_eq!(c.stereo.matcher.radius_px, 6);
        assert_eq!(c.range.fill_min_neighbours, 3);
        // The horizon rows at level 1 and the sky rule: on by default, off by name.
        assert_eq!(d.stereo.matcher.horizon_grade, 0.3);
        assert!(d.stereo.matcher.horizon_coarse);
        assert_eq!(d.range.sky_below_gray, 8);
        let c = fix_config_by_name("fix-hg0-hl0-sk0").unwrap();
        assert_eq!(c.stereo.matcher.horizon_grade, 0.0);
        assert!(!c.stereo.matcher.horizon_coarse);
        assert_eq!(c.range.sky_below_gray, 0);
        let c = fix_config_by_name("fix-hg0.2-hl1-sk12").unwrap();
        assert_eq!(c.stereo.matcher.horizon_grade, 0.2);
        assert!(c.stereo.matcher.horizon_coarse);
        assert_eq!(c.range.sky_below_gray, 12);
        // Options on the other bases too.
        let c = fix_config_by_name("fix-ncc-p4").unwrap();
        assert_eq!((c.refine.mode, c.refine.peaks), (RefineMode::Ncc, 4));
        assert_eq!(
            fix_config_by_name("cnn-p2").map(|c| c.refine.peaks),
            Some(2)
        );
    }

    #[test]
    fn bad_fix_options_are_errors_that_say_why() {
        for (name, says) in [
            ("fix-q3", "unknown option 'q3'"),
            ("fix-p", "expected p<number"),
            ("fix-p2.5", "whole number"),
            ("fix-pnan", "unknown option 'pnan'"),
            ("fix-p-1", "expected p<number"),
            ("fix-p0", "peaks"),
            ("fix-p99", "peaks"),
            ("fix-u300", "uniqueness"),
            ("fix-u60", "uniqueness"),
            ("fix-ms9", "min_support"),
            ("fix-mg17", "min_gap"),
            ("fix-ra5", "relief_above"),
            ("fix-rc8", "radius_px"),
            ("fix-fn9", "fill"),
            ("fix-hg11", "horizon_grade"),
            ("fix-sk256", "sk is 0..=255"),
            ("fix-hl2", "hl is 0 (off) or 1 (on)"),
            ("fix-sk2.5", "whole number"),
        ] {
            let e = fix_config_checked(name).expect_err(name);
            let msg = format!("{e:#}");
            assert!(msg.contains(says), "{name}: {msg}");
            assert_eq!(fix_config_by_name(name), None, "{name}");
            assert!(parse_matchers(&format!("fix,{name}")).is_err(), "{name}");
        }
        // `fixed` is not `fix` with an option.
        assert_eq!(fix_config_checked("fixed").unwrap(), None);
    }

    #[test]
    fn the_run_settings_come_first_then_the_options() {
        let mut p = super::super::pipeline::PipelineOptions::default();
        p.range.max_depth_m = 40.0;
        p.stereo.relief_above_m = 0.7;
        let c = fix_config_in("fix-ra1", &p).unwrap();
        assert_eq!(c.range.max_depth_m, 40.0);
        assert_eq!(c.stereo.matcher.relief_above_m, 1.0);
        let c = fix_config_in("fix", &p).unwrap();
        assert_eq!(c.stereo.matcher.relief_above_m, 0.7);
        assert!(fix_config_in("l1", &p).is_none());
    }
}
