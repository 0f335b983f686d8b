//! `orbfix demo`: the README's main command. On the built-in world, with no files needed:
//! a handful of rover stops in the test zone, each rendered and localized by the flight
//! core's one fix (`orbfix::fix::run`, matcher `fix`; a baseline matcher on request); prints
//! a table and writes the pictures.

use anyhow::Context;
use orbfix::localize::{nearest_window, rank_of, LocalizeConfig};
use orbfix_host::eval::fix_figure::{fix_svg, FixMarks};
use orbfix_host::eval::pipeline::{
    make_queries, render_query_full, Condition, DepthSource, PipelineOptions, Reprojection,
};
use orbfix_host::eval::{
    best_matcher, fix_config_checked, fix_config_in, localize_fix, localize_top_down,
    matcher_by_name, overlay, save_png_atomic, window_cell_scores, write_atomic, MATCHERS,
};
use orbfix_host::fix::{build_map_product_relief, FixRunner, MapProductOptions};
use orbfix_host::world::World;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Localize a few rover stops of the built-in world and draw the results (no files needed).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder for the pictures and demo.json.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Number of rover stops.
    #[arg(long, default_value_t = 5)]
    pub stops: usize,
    /// World seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Matcher: fix (default: the flight core's one fix), fix-ncc, fix-signed, cnn, or a
    /// baseline (ncc-hp2, ncc, l1, l2, ...).
    #[arg(long)]
    pub matcher: Option<String>,
    /// CNN weight file (.ofw) [default: the shipped weights/matcher-v2.ofw].
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Depth of the top-down reprojection: stereo (the rover's own stereo pairs, matched by
    /// the core inside the fix; the truth-depth fix is shown beside it), truth (the
    /// renderer's exact depth images) or none (the flight core's flat-ground table, which
    /// relief distorts beyond ~10 m; see docs/results.md).
    #[arg(long, value_enum, default_value_t = DepthSource::Stereo)]
    pub depth: DepthSource,
    /// Lighting (same-sun is the study's setting).
    #[arg(long, value_enum, default_value_t = Condition::SameSun)]
    pub condition: Condition,
    /// Instead of separate stops, drive a short traverse of this many stops (the fixes
    /// fused with drifting odometry, `orbfix traverse`): pictures in OUT/traverse.
    #[arg(long)]
    pub traverse: Option<usize>,
}

#[derive(Serialize)]
struct Row {
    stop: usize,
    truth_m: (f64, f64),
    prior_m: (f64, f64),
    fix_m: (f64, f64),
    error_m: f64,
    confidence: f64,
    on_border: bool,
    status: String,
    path: String,
    error_bound_m: Option<f64>,
    true_window_rank: usize,
    true_cell_rank: usize,
    render_s: f64,
    localize_s: f64,
    /// Depth source of the fix (stereo, truth, none).
    depth: String,
    /// With stereo depth: the same fix on the renderer's exact depth.
    truth_depth: Option<TruthRow>,
}

#[derive(Serialize)]
struct TruthRow {
    fix_m: (f64, f64),
    error_m: f64,
    status: String,
    path: String,
    confidence: f64,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(stops) = a.traverse {
        anyhow::ensure!(
            (2..=100).contains(&stops),
            "--traverse must be 2..=100 stops"
        );
        let dir = a.out.join("traverse");
        let d = orbfix_host::traverse::TraverseOptions::default();
        return super::traverse::run(super::traverse::Args {
            seed: a.seed,
            stops,
            json: dir.join("traverse.json"),
            figures: dir,
            condition: a.condition,
            odometry_drift: d.odometry_drift,
            heading_sigma_deg: d.heading_sigma_deg,
            heading_step_deg: d.heading_step_deg,
            heading_tolerance_deg: d.heading_tolerance_deg,
            compare_heading_sigma_deg: None,
            leg_min_m: d.leg_min_m,
            leg_max_m: d.leg_max_m,
            start_sigma_m: d.start_sigma_m,
            // The traverse renders depth images (truth depth, an external stereo engine's);
            // on-board stereo inside the traverse is not wired yet.
            reprojection: match a.depth {
                orbfix_host::eval::pipeline::DepthSource::None => a.depth.reprojection(),
                _ => orbfix_host::eval::pipeline::Reprojection::Range,
            },
            weights: a.weights,
            fresh: true,
            quiet: false,
        });
    }
    anyhow::ensure!((1..=100).contains(&a.stops), "--stops must be 1..=100");
    let name = a
        .matcher
        .clone()
        .unwrap_or_else(|| best_matcher().to_string());
    let fix_cfg = fix_config_checked(&name).context("--matcher")?;
    let spec = match fix_cfg {
        Some(_) => None,
        None => Some(
            matcher_by_name(&name)
                .with_context(|| format!("--matcher (available: {})", MATCHERS.join(", ")))?,
        ),
    };
    let weights = super::eval::load_weights(a.weights.as_deref())?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create the output folder {}", a.out.display()))?;
    let world = World::new(a.seed);
    let reprojection = a.depth.reprojection();
    let opts = PipelineOptions {
        reprojection,
        ..PipelineOptions::default()
    };
    let fix_cfg = fix_cfg.and_then(|_| fix_config_in(&name, &opts));
    let cfg = LocalizeConfig::default();
    let queries = make_queries(a.seed, a.stops, a.condition);
    println!(
        "orbfix demo: {} stops in the test zone, world seed {}, matcher {}, {}, top-down by {}; map 300 x 300 m at 0.25 m/px, prior within +-100 m",
        a.stops,
        a.seed,
        name,
        a.condition.name(),
        match reprojection {
            Reprojection::Range => "the flight core's range path with the renderer's exact depth images (true 3D points)",
            Reprojection::Stereo => "the flight core's range path with depth from the rover's own stereo pairs (the fix's stereo stage); the truth-depth fix beside it",
            Reprojection::Lut => "the flight LUT (flat ground)",
        }
    );
    let stereo_side = reprojection == Reprojection::Stereo && fix_cfg.is_some();
    println!(
        "{:>4}  {:>19}  {:>19}  {:>8}  {:>7}  {:>5}  {:<9}  {:>4}  {:>4}  {:>8}  {:>8}",
        "stop",
        "truth x, y (m)",
        "fix x, y (m)",
        "error m",
        "bound m",
        "conf",
        "status",
        "win",
        "cell",
        "render s",
        "fix ms"
    );
    if stereo_side {
        println!("      (with stereo depth; the last columns: the same fix on the renderer's exact depth)");
    }
    let mut rows = Vec::new();
    for q in &queries {
        let t0 = Instant::now();
        let (obs, top, map) = render_query_full(&world, q, &opts)?;
        let render_s = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let mut truth_loc = None;
        // The top-down image the fix itself made (stereo: from its own stereo stage), and the
        // truth-depth fix's beside it.
        let mut fix_top: Option<orbfix_host::eval::TopDown> = None;
        let mut truth_top: Option<orbfix_host::eval::TopDown> = None;
        let loc = match (&spec, fix_cfg) {
            (None, Some(cfg)) => {
                let heights = |x: f64, y: f64| world.height_m(x, y);
                let product = build_map_product_relief(
                    &map,
                    &weights,
                    &MapProductOptions::for_fix(
                        &cfg,
                        Some((q.sun_map.elevation_deg as f32, q.sun_map.azimuth_deg as f32)),
                    )?,
                    Some(&heights),
                )?;
                let runner = FixRunner {
                    weights: weights.clone(),
                    cfg,
                };
                // One fix on `o`: its localization and the top-down image it made.
                let fix_on = |o: &_, what: &str| {
                    let (l, out) =
                        localize_fix(&runner, o, &map, &product, (q.prior_x_m, q.prior_y_m), 50)
                            .with_context(|| format!("stop {}{what}", q.id))?;
                    let t = orbfix_host::eval::TopDown {
                        image: out.top,
                        mask: out.mask,
                        n: top.n,
                        m_per_px: top.m_per_px,
                    };
                    anyhow::Ok((l, t))
                };
                if stereo_side {
                    if let Some(tobs) = obs.with_truth_depth() {
                        let (l, t) = fix_on(&tobs, " (truth depth)")?;
                        truth_loc = Some(l);
                        truth_top = Some(t);
                    }
                }
                let (l, t) = fix_on(&obs, "")?;
                fix_top = Some(t);
                l
            }
            (Some(spec), _) => {
                localize_top_down(spec, &top, &map, (q.prior_x_m, q.prior_y_m), &cfg, 50)
                    .with_context(|| format!("stop {}", q.id))?
            }
            (None, None) => anyhow::bail!("no matcher"),
        };
        // The fix alone (the map product is the ground segment's work, made here per stop).
        let localize_s = match loc.fix_report {
            Some(_) => loc.dense_s,
            None => t1.elapsed().as_secs_f64(),
        };
        let tw = nearest_window(
            &loc.window_grid,
            &map.geo,
            top.n,
            top.n,
            q.x_m as f32,
            q.y_m as f32,
        );
        let rank = rank_of(&loc.window_scores, tw).unwrap_or(usize::MAX);
        let cell_rank = rank_of(&window_cell_scores(&loc), tw).unwrap_or(usize::MAX);
        let fix = (loc.fix.x_m as f64, loc.fix.y_m as f64);
        let err = ((fix.0 - q.x_m).powi(2) + (fix.1 - q.y_m).powi(2)).sqrt();
        let (status, path, bound) = match &loc.fix_report {
            Some(r) => (
                r.status.name().to_string(),
                r.path.name().to_string(),
                Some(r.error_bound_m as f64),
            ),
            None => ("-".to_string(), "-".to_string(), None),
        };
        let truth_row = truth_loc.as_ref().and_then(|l| {
            let r = l.fix_report.as_ref()?;
            let f = (l.fix.x_m as f64, l.fix.y_m as f64);
            Some(TruthRow {
                fix_m: f,
                error_m: ((f.0 - q.x_m).powi(2) + (f.1 - q.y_m).powi(2)).sqrt(),
                status: r.status.name().to_string(),
                path: r.path.name().to_string(),
                confidence: l.fix.confidence as f64,
            })
        });
        println!(
            "{:>4}  {:>9.2},{:>9.2}  {:>9.2},{:>9.2}  {:>8.2}  {:>7}  {:>5.2}  {:<9}  {:>4}  {:>4}  {:>8.2}  {:>8.1}{}{}",
            q.id,
            q.x_m,
            q.y_m,
            fix.0,
            fix.1,
            err,
            bound.map_or("-".to_string(), |b| format!("{b:.2}")),
            loc.fix.confidence,
            status,
            rank + 1,
            cell_rank + 1,
            render_s,
            1000.0 * localize_s,
            if loc.fix.on_border && loc.fix_report.is_none() {
                "  (border: rejected)"
            } else {
                ""
            },
            truth_row.as_ref().map_or(String::new(), |t| format!(
                "  | truth depth: error {:.2} m, {}",
                t.error_m, t.status
            ))
        );
        if let (Some(tl), Some(t)) = (&truth_loc, &truth_row) {
            let svg = fix_svg(
                &map,
                tl,
                top.n,
                &FixMarks {
                    truth: Some((q.x_m, q.y_m)),
                    prior: (q.prior_x_m, q.prior_y_m),
                    bound_m: tl.fix_report.as_ref().map_or(f64::NAN, |r| r.error_bound_m as f64),
                    title: format!(
                        "stop {}: {name} with truth depth, error {:.2} m ({}, {} path, confidence {:.2})",
                        q.id, t.error_m, t.status, t.path, t.confidence
                    ),
                },
            )?;
            write_atomic(
                &a.out.join(format!("stop_{:02}_map_truth_depth.svg", q.id)),
                svg.as_bytes(),
            )?;
        }
        save_png_atomic(
            &overlay::top_down_picture(fix_top.as_ref().unwrap_or(&top)),
            &a.out.join(format!("stop_{:02}_topdown.png", q.id)),
        )?;
        if let Some(t) = &truth_top {
            save_png_atomic(
                &overlay::top_down_picture(t),
                &a.out
                    .join(format!("stop_{:02}_topdown_truth_depth.png", q.id)),
            )?;
        }
        let svg = fix_svg(
            &map,
            &loc,
            top.n,
            &FixMarks {
                truth: Some((q.x_m, q.y_m)),
                prior: (q.prior_x_m, q.prior_y_m),
                bound_m: bound.unwrap_or(f64::NAN),
                title: format!(
                    "stop {}: {name} ({} depth), error {:.2} m{}",
                    q.id,
                    a.depth.name(),
                    err,
                    if status == "-" {
                        String::new()
                    } else {
                        format!(
                            " ({status}, {path} path, confidence {:.2})",
                            loc.fix.confidence
                        )
                    }
                ),
            },
        )?;
        write_atomic(
            &a.out.join(format!("stop_{:02}_map.svg", q.id)),
            svg.as_bytes(),
        )?;
        rows.push(Row {
            stop: q.id,
            truth_m: (q.x_m, q.y_m),
            prior_m: (q.prior_x_m, q.prior_y_m),
            fix_m: fix,
            error_m: err,
            confidence: loc.fix.confidence as f64,
            on_border: loc.fix.on_border,
            status,
            path,
            error_bound_m: bound,
            true_window_rank: rank + 1,
            true_cell_rank: cell_rank + 1,
            render_s,
            localize_s,
            depth: a.depth.name().to_string(),
            truth_depth: truth_row,
        });
    }
    let json = serde_json::json!({
        "seed": a.seed, "matcher": name, "condition": a.condition.name(),
        "reprojection": reprojection, "depth": a.depth.name(), "stops": rows,
    });
    write_atomic(
        &a.out.join("demo.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    println!(
        "bound = the fix's stated error bound; status: ok / ambiguous / no-data / on-border; win = rank of the true 50 m window among the study's 441 (fix: ranked by the best coarse score in its 12.5 m cell), cell = its rank by the best dense score in its cell; pictures in {}: stop_NN_topdown.png (the top-down image the fix made; with stereo depth also stop_NN_topdown_truth_depth.png), stop_NN_map.svg (map with the CNN response, truth, fix, error bound, candidates, legend)",
        a.out.display()
    );
    Ok(())
}
