//! `orbfix bench-localize`: time one full localization per matcher (the study's 441-window
//! search and the coarse-to-fine dense fix) on a rendered rover stop, with operation counts
//! per stage beside the flight budget.

use orbfix::localize::LocalizeConfig;
use orbfix_host::eval::pipeline::{
    make_queries, render_query, reproject_depths, Condition, PipelineOptions,
};
use orbfix_host::eval::{localize_top_down, matcher_by_name, parse_matchers};
use orbfix_host::render;
use orbfix_host::reproject::depth::depth_images;
use orbfix_host::world::World;

/// Flight budget of one whole fix, instructions (Cortex-M7 class, ~100 MHz).
pub const FLIGHT_BUDGET_INSTR: f64 = 100e6;

/// Benchmark localization per matcher (build with --release).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Matchers, comma-separated.
    #[arg(long, default_value = "ncc,ncc-dist,l1,l2")]
    pub matcher: String,
    /// Repetitions (the best time is reported).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// World seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Coarse factor of the dense pass.
    #[arg(long, default_value_t = 8)]
    pub coarse_factor: usize,
    /// Fine factor of the refinement.
    #[arg(long, default_value_t = 2)]
    pub fine_factor: usize,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let names = parse_matchers(&a.matcher)?;
    // Every matcher is set up before anything is printed: a bad name or option is an error
    // on its own, not after half a table.
    let specs = names
        .iter()
        .map(|n| matcher_by_name(n))
        .collect::<anyhow::Result<Vec<_>>>()?;
    anyhow::ensure!(a.reps >= 1, "--reps must be at least 1");
    if cfg!(debug_assertions) {
        eprintln!("warning: debug build; run with --release for meaningful times");
    }
    let world = World::new(a.seed);
    let q = make_queries(a.seed, 1, Condition::SameSun)[0];
    let (top, map) = render_query(&world, &q, &PipelineOptions::default())?;
    let cfg = LocalizeConfig {
        coarse_factor: a.coarse_factor,
        fine_factor: a.fine_factor,
        ..LocalizeConfig::default()
    };
    println!(
        "one localization: top-down {n} x {n} px, map {w} x {h} px (0.25 m/px), coarse 1/{cf}, fine 1/{ff}; best of {r}",
        n = top.n, w = map.width, h = map.height, cf = cfg.coarse_factor, ff = cfg.fine_factor, r = a.reps
    );
    // The reprojection stage of the same stop: the core's range path on millimetre depths.
    let opts = PipelineOptions::default();
    let pose = render::ground_pose(&world, q.x_m, q.y_m, q.heading_deg);
    let set = render::render_views_with_range(&world, &pose, q.sun_rover, &opts.render)?;
    let depths = depth_images(&set, None)?;
    let mut best_s = f64::INFINITY;
    let mut rep = None;
    for _ in 0..a.reps {
        let t0 = std::time::Instant::now();
        let (_, r) = reproject_depths(&set.views, &depths, &opts.render, &pose, &opts.grid)?;
        best_s = best_s.min(t0.elapsed().as_secs_f64());
        rep = Some(r);
    }
    if let Some(r) = rep {
        // Per pixel with a depth: 3 multiply-accumulates (east, south, up); counted as an
        // upper bound over every pixel read.
        let macs = 3 * r.pixels_read;
        println!(
            "reprojection (range path): {} pixels read, {} placed, {} cell visits, <= {} MACs ({:.3} of budget), {:.2} ms (includes allocating the buffers)",
            r.pixels_read,
            r.points_used,
            r.cells_visited,
            macs,
            macs as f64 / FLIGHT_BUDGET_INSTR,
            best_s * 1e3
        );
    }
    println!(
        "{:<9} {:<16} {:>9} {:>12} {:>14} {:>10} {:>11} {:>12}",
        "matcher", "stage", "windows", "MACs", "downsample px", "time ms", "GMAC/s", "MACs/budget"
    );
    for (name, spec) in names.iter().zip(&specs) {
        let mut best: Option<orbfix_host::eval::Localization> = None;
        for _ in 0..a.reps {
            let loc = localize_top_down(spec, &top, &map, (q.prior_x_m, q.prior_y_m), &cfg, 50)?;
            if best
                .as_ref()
                .is_none_or(|b| loc.dense_s + loc.windows_s < b.dense_s + b.windows_s)
            {
                best = Some(loc);
            }
        }
        let Some(l) = best else { continue };
        let dense_macs = l.fix.ops_coarse.macs + l.fix.ops_fine.macs;
        let rows = [
            ("windows (441)", l.window_ops, l.windows_s),
            ("dense: coarse", l.fix.ops_coarse, f64::NAN),
            ("dense: fine", l.fix.ops_fine, f64::NAN),
        ];
        for (stage, ops, t) in rows {
            println!(
                "{:<9} {:<16} {:>9} {:>12} {:>14} {:>10} {:>11} {:>12.3}",
                name,
                stage,
                ops.windows,
                ops.macs,
                ops.downsample_px,
                if t.is_nan() {
                    "-".into()
                } else {
                    format!("{:.2}", t * 1e3)
                },
                if t.is_nan() {
                    "-".into()
                } else {
                    format!("{:.2}", ops.macs as f64 / t / 1e9)
                },
                ops.macs as f64 / FLIGHT_BUDGET_INSTR
            );
        }
        println!(
            "{:<9} {:<16} {:>9} {:>12} {:>14} {:>10.2} {:>11.2} {:>12.3}   dense/windows: time x{:.2}, MACs x{:.2}",
            name,
            "dense: total",
            l.fix.ops_coarse.windows + l.fix.ops_fine.windows,
            dense_macs,
            l.fix.ops_coarse.downsample_px + l.fix.ops_fine.downsample_px,
            l.dense_s * 1e3,
            dense_macs as f64 / l.dense_s / 1e9,
            dense_macs as f64 / FLIGHT_BUDGET_INSTR,
            l.dense_s / l.windows_s,
            dense_macs as f64 / l.window_ops.macs.max(1) as f64
        );
    }
    println!("MACs/budget: per-pixel accumulates / {FLIGHT_BUDGET_INSTR:.0e} instructions (a MAC costs >= 1 instruction on a Cortex-M7).");
    Ok(())
}
