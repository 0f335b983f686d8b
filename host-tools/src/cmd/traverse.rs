//! `orbfix traverse`: a whole drive through the test zone, fixes fused with drifting
//! odometry in the core's filter (docs/traverse.md).

use anyhow::Context;
use orbfix_host::eval::pipeline::{Condition, Reprojection};
use orbfix_host::eval::{fix_config_by_name, write_atomic};
use orbfix_host::traverse::{figures, markdown_table, summarize, StopRecord, Traverse};
use orbfix_host::traverse::{Summary, TraverseOptions};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Drive the rover along a planned path of the built-in world's test zone: drifting
/// odometry, a heading estimate with a stated error, the core's fix at every stop around the
/// fused prior, and the core's filter (docs/traverse.md).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// World seed (seed 1 is the development seed; report accuracy on others).
    #[arg(long, default_value_t = 2)]
    pub seed: u64,
    /// Stops, the first at the start (legs of 30-50 m: 26 stops drive about 1 km).
    #[arg(long, default_value_t = 26)]
    pub stops: usize,
    /// JSON report (per stop and summary); rewritten after every stop, and a run with the
    /// same settings (or more stops) resumes from it.
    #[arg(long, default_value = "out/traverse/traverse.json")]
    pub json: PathBuf,
    /// Folder for the figures (path.svg, error.svg) and the per-stop table (table.md).
    #[arg(long, default_value = "out/traverse")]
    pub figures: PathBuf,
    /// Lighting of the rover views against the map.
    #[arg(long, value_enum, default_value_t = Condition::SameSun)]
    pub condition: Condition,
    /// Odometry drift, fraction of the distance driven (0.02: about 2 %).
    #[arg(long, default_value_t = 0.02)]
    pub odometry_drift: f64,
    /// Standard deviation of the heading estimate given to the fix, degrees.
    #[arg(long, default_value_t = 0.5)]
    pub heading_sigma_deg: f64,
    /// Heading search step, degrees (the search runs when the heading sigma exceeds
    /// --heading-tolerance-deg and covers +-2 sigma, at most 9 headings; 2 deg chosen by
    /// measurement, docs/traverse.md).
    #[arg(long, default_value_t = 2.0)]
    pub heading_step_deg: f64,
    /// Largest heading sigma for which the fix trusts the estimate (no search), degrees.
    #[arg(long, default_value_t = 1.0)]
    pub heading_tolerance_deg: f64,
    /// At every stop, also run the fix with the known heading, with a heading error of
    /// this sigma (degrees) and with the heading search around it (same views and map).
    #[arg(long)]
    pub compare_heading_sigma_deg: Option<f64>,
    /// Shortest leg, metres.
    #[arg(long, default_value_t = 30.0)]
    pub leg_min_m: f64,
    /// Longest leg, metres.
    #[arg(long, default_value_t = 50.0)]
    pub leg_max_m: f64,
    /// Standard deviation of the start position's error, per axis, metres.
    #[arg(long, default_value_t = 10.0)]
    pub start_sigma_m: f64,
    /// Top-down reprojection (as `orbfix eval`).
    #[arg(long, value_enum, default_value_t = Reprojection::Range)]
    pub reprojection: Reprojection,
    /// CNN weight file (.ofw) [default: the shipped weights].
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Start again even when --json holds a run with the same settings.
    #[arg(long)]
    pub fresh: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Serialize, Deserialize)]
struct Report {
    settings: TraverseOptions,
    fix_config: String,
    reprojection: Reprojection,
    fusion_config: String,
    summary: Summary,
    stops: Vec<StopRecord>,
}

/// The settings of `a`.
pub fn options(a: &Args) -> TraverseOptions {
    TraverseOptions {
        seed: a.seed,
        stops: a.stops,
        condition: a.condition,
        odometry_drift: a.odometry_drift,
        heading_sigma_deg: a.heading_sigma_deg,
        heading_step_deg: a.heading_step_deg,
        heading_tolerance_deg: a.heading_tolerance_deg,
        leg_min_m: a.leg_min_m,
        leg_max_m: a.leg_max_m,
        start_sigma_m: a.start_sigma_m,
        compare_heading_sigma_deg: a.compare_heading_sigma_deg,
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        a.reprojection != Reprojection::Stereo,
        "--reprojection stereo is not available in traverses yet (the drive renders depth images); use range (truth depth, the default) or lut"
    );
    let opts = options(&a);
    opts.validate()?;
    let weights = super::eval::load_weights(a.weights.as_deref())?;
    let cfg = fix_config_by_name("fix").context("the fix configuration")?;
    let mut t = Traverse::new(opts.clone(), weights, cfg, a.reprojection)?;
    std::fs::create_dir_all(&a.figures)
        .with_context(|| format!("cannot create the figures folder {}", a.figures.display()))?;
    if let Some(dir) = a.json.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the folder {}", dir.display()))?;
    }
    if !a.fresh {
        if let Ok(bytes) = std::fs::read(&a.json) {
            match serde_json::from_slice::<Report>(&bytes) {
                // Same settings (a longer drive extends a shorter one: the plan draws stop
                // by stop).
                Ok(old)
                    if TraverseOptions {
                        stops: opts.stops,
                        ..old.settings.clone()
                    } == opts
                        && old.settings.stops <= opts.stops
                        && old.reprojection == a.reprojection =>
                {
                    let n = t.resume(old.stops)?;
                    if n > 0 {
                        eprintln!("resuming from {} after {n} stops", a.json.display());
                    }
                }
                _ => {}
            }
        }
    }
    let fix_config = format!("{:?}", t.runner.cfg);
    let fusion_config = format!("{:?}", t.fusion().config());
    let total = t.plan.stops.len();
    println!(
        "orbfix traverse: world seed {}, {} stops over {:.0} m, {}, odometry drift {:.1} %, heading sigma {} deg{}; fix: matcher fix (default FixConfig), top-down by {:?}",
        opts.seed,
        total,
        t.plan.stops.last().map_or(0.0, |s| s.distance_m),
        opts.condition.name(),
        100.0 * opts.odometry_drift,
        opts.heading_sigma_deg,
        match opts.heading_search(opts.heading_sigma_deg)? {
            Some(h) => format!(
                " (heading search: {} headings every {} deg)",
                h.count(),
                h.step_deg()
            ),
            None => " (no heading search)".into(),
        },
        a.reprojection,
    );
    let bar = if a.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(total as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} stops (eta {eta}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_position(t.records.len() as u64);
    let write = |t: &Traverse| -> anyhow::Result<()> {
        let report = Report {
            settings: opts.clone(),
            fix_config: fix_config.clone(),
            reprojection: a.reprojection,
            fusion_config: fusion_config.clone(),
            summary: summarize(&t.records),
            stops: t.records.clone(),
        };
        write_atomic(&a.json, serde_json::to_string_pretty(&report)?.as_bytes())
    };
    while t.records.len() < total {
        let r = t.step()?;
        bar.set_message(format!(
            "odometry {:.1} m, fix {}, fused {:.2} m",
            r.odometry_error_m,
            r.fix_error_m
                .map_or("none".to_string(), |e| format!("{e:.2} m {}", r.fix_status)),
            r.fused_error_m
        ));
        bar.inc(1);
        write(&t)?;
    }
    bar.finish_and_clear();
    write(&t)?;
    let title = format!(
        "seed {}, {}, {} stops, {:.0} m, drift {:.0} %, heading sigma {} deg",
        opts.seed,
        opts.condition.name(),
        total,
        t.records.last().map_or(0.0, |r| r.distance_m),
        100.0 * opts.odometry_drift,
        opts.heading_sigma_deg
    );
    figures::path_svg(&a.figures.join("path.svg"), &t.records, &title)?;
    figures::error_svg(&a.figures.join("error.svg"), &t.records, &title)?;
    write_atomic(
        &a.figures.join("table.md"),
        markdown_table(&t.records).as_bytes(),
    )?;
    print!("{}", markdown_table(&t.records));
    let s = summarize(&t.records);
    let fused = if s.stops > 5 {
        format!(
            "fused after stop 5: max {:.2} m, mean {:.2} m, within 1 m {:.0} %, within 2 m {:.0} %",
            s.fused_max_error_after_5_m,
            s.fused_mean_error_after_5_m,
            100.0 * s.fused_within_1m_after_5,
            100.0 * s.fused_within_2m_after_5
        )
    } else {
        format!(
            "fused at the last stop {:.2} m (the targets count stops after the fifth)",
            t.records.last().map_or(0.0, |r| r.fused_error_m)
        )
    };
    println!(
        "summary: {:.0} m driven; odometry alone {:.1} m off at the end (drift since the start {:.1} % of distance; max error {:.1} m); {fused}; fixes within 1 m {:.0} % of stops; accepted {} (max error {:.2} m, {} over 5 m), refused {}",
        s.distance_m,
        s.odometry_final_error_m,
        100.0 * s.odometry_drift_share,
        s.odometry_max_error_m,
        100.0 * s.fix_within_1m,
        s.accepted,
        s.accepted_max_error_m,
        s.accepted_over_5m,
        s.rejected.len()
    );
    for (stop, e, why) in &s.rejected {
        println!(
            "  refused at stop {stop}: fix error {}, {why}",
            e.map_or("none".to_string(), |e| format!("{e:.2} m"))
        );
    }
    if let (Some((k, n, h)), Some((km, hm))) = (s.compare_within_1m, s.compare_ms_mean) {
        println!(
            "heading comparison: fixes within 1 m: known heading {:.3}, noisy heading without search {:.3}, with the heading search {:.3}; host ms per fix: known {:.1}, search {:.1}",
            k, n, h, km, hm
        );
    }
    println!(
        "written: {}, {}/path.svg, {}/error.svg, {}/table.md",
        a.json.display(),
        a.figures.display(),
        a.figures.display(),
        a.figures.display()
    );
    Ok(())
}
