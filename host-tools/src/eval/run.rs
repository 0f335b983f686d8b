//! The evaluation loop: generated queries through the whole pipeline, for several matchers
//! sharing the renders, into one report per matcher.

use super::metrics::{pair_stats, quantile, recall_at, PairStats};
use super::pipeline::{
    drivable_queries, make_queries, render_query_full, Condition, PipelineOptions, Query,
};
use super::{
    fix_config_by_name, fix_config_in, localize_fix, localize_top_down, matcher_by_name,
    Localization, MapRegion, TopDown,
};
use crate::fix::{build_map_product_relief, FixRunner, MapProductOptions};
use crate::world::World;
use anyhow::Context;
use orbfix::image::ImageView;
use orbfix::localize::{nearest_window, rank_of, LocalizeConfig};
use orbfix::matcher::OpCounts;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// What to evaluate.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    /// World seed (also seeds the queries).
    pub seed: u64,
    /// Number of queries.
    pub queries: usize,
    /// Lighting condition.
    pub condition: Condition,
    /// Matcher names (see [`super::MATCHERS`]).
    pub matchers: Vec<String>,
    /// Coarse-to-fine settings.
    pub localize: LocalizeConfig,
    /// Pixels between the study's windows (50 = 12.5 m at 0.25 m/px).
    pub stride_px: usize,
    /// Pipeline (renderer, grid, map size).
    pub pipeline: PipelineOptions,
    /// Queries kept with their images for example figures.
    pub keep_examples: usize,
    /// Diagnostic: a world with zero relief and the same albedo (isolates photometry and
    /// relief from geometry).
    pub flat_world: bool,
    /// The weight file (`.ofw`) of the CNN, for the fix matchers and their map products.
    pub weights: Vec<u8>,
    /// Only stops where the rover, standing on the terrain, tilts at most this many degrees
    /// ([`super::pipeline::drivable_queries`]; with [`super::pipeline::RoverAttitude::Terrain`]).
    pub max_tilt_deg: Option<f64>,
}

/// The result of one query for one matcher.
#[derive(Clone, Debug, Serialize)]
pub struct QueryResult {
    /// Query number.
    pub id: usize,
    /// Truth `(x, y)`, metres.
    pub truth_m: (f64, f64),
    /// Prior `(x, y)`, metres.
    pub prior_m: (f64, f64),
    /// Fix `(x, y)`, metres.
    pub fix_m: (f64, f64),
    /// Distance fix - truth, metres.
    pub error_m: f64,
    /// Rank (0 = best) of the true window among the study's windows.
    pub true_window_rank: usize,
    /// Index of the true window (nearest the truth).
    pub true_window: usize,
    /// Rank (0 = best) of the true window's cell by the dense response
    /// ([`super::window_cell_scores`]).
    pub true_cell_rank: usize,
    /// Confidence of the fix.
    pub confidence: f64,
    /// Peak on the search border (declared a failure).
    pub on_border: bool,
    /// Score of the matching pair (top-down vs the window centred on the truth).
    pub match_score: f64,
    /// Score of the non-matching pair (a window at least 50 m away).
    pub nonmatch_score: f64,
    /// Valid share of the top-down image.
    pub coverage: f64,
    /// The rover's pitch and roll at the stop, degrees (0, 0 when it stands level).
    pub attitude_deg: (f64, f64),
    /// Seconds of the dense fix.
    pub dense_s: f64,
    /// Seconds of the window search.
    pub windows_s: f64,
    /// Per-pixel accumulates (MACs) of the coarse pass, the fine pass and the window search.
    pub macs: [u64; 3],
    /// The fix's status (`ok`, `ambiguous`, `no-data`, `on-border`, `self-check-failed`);
    /// fix matchers only.
    pub status: Option<String>,
    /// Which stage produced the fix (`ncc`, `cnn`, `none`); fix matchers only.
    pub path: Option<String>,
    /// The fix's stated error bound, metres; fix matchers only.
    pub error_bound_m: Option<f64>,
    /// The fix's candidates in the order of the CNN's peaks (the refined ones first), each
    /// with its distance from the truth; fix matchers only (empty otherwise).
    pub candidates: Vec<CandidateResult>,
}

/// One of a fix's candidate positions ([`orbfix::localize::Candidate`]) against the truth.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateResult {
    /// Position `(x, y)`, metres.
    pub at_m: (f64, f64),
    /// Distance from the truth, metres.
    pub error_m: f64,
    /// NCC score when `refined`, else the CNN's coarse score.
    pub score: f64,
    /// Whether the refinement scored it.
    pub refined: bool,
    /// The coarse score of its window (CNN cosine plus the relief stage's correlation).
    pub coarse: f64,
}

/// What a fix matcher's users read besides the errors.
#[derive(Clone, Debug, Serialize)]
pub struct FixStats {
    /// Share of stops whose fix has status ok.
    pub accepted_share: f64,
    /// Stops whose fix is ok but more than 5 m off (wrong but confident).
    pub wrong_confident: usize,
    /// The same as a share of all stops.
    pub wrong_confident_share: f64,
    /// Share of ok fixes whose error is within their stated bound.
    pub bound_coverage: f64,
    /// Share of fixes within 1 m among the ok ones.
    pub accepted_within_1m: f64,
    /// Share of fixes produced by each path.
    pub path_share: BTreeMap<String, f64>,
    /// Count of each status.
    pub status_count: BTreeMap<String, usize>,
    /// The exact configuration of the core's fix.
    pub config: String,
}

/// The report of one matcher under one condition.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    /// Matcher name.
    pub matcher: String,
    /// World and query seed.
    pub seed: u64,
    /// `same-sun` or `cross-sun`.
    pub condition: String,
    /// Number of queries.
    pub queries: usize,
    /// Windows per query (441 for the study's setting).
    pub windows_per_query: usize,
    /// Share of queries whose true window is among the `k` best windows (the study's
    /// protocol: each window scored once at its own position).
    pub recall_at: BTreeMap<String, f64>,
    /// The same with windows ranked by their cell's best dense-response score
    /// ([`super::window_cell_scores`]).
    pub recall_at_dense: BTreeMap<String, f64>,
    /// Median distance fix - truth, metres.
    pub median_error_m: f64,
    /// 95th percentile distance fix - truth, metres.
    pub p95_error_m: f64,
    /// Share of fixes within 1 m / 5 m of the truth.
    pub within_m: BTreeMap<String, f64>,
    /// Match / non-match pair classification (one pair of each per query).
    pub pairs: PairStats,
    /// Fixes whose peak lay on the search border.
    pub border_rejections: usize,
    /// Mean confidence of fixes within 5 m and of the others.
    pub mean_confidence_correct: f64,
    /// Mean confidence of fixes more than 5 m off.
    pub mean_confidence_wrong: f64,
    /// Mean seconds of one dense fix and of one window search.
    pub mean_dense_s: f64,
    /// Mean seconds of one window search.
    pub mean_windows_s: f64,
    /// Mean per-pixel accumulates per query: coarse, fine, windows.
    pub ops: BTreeMap<String, f64>,
    /// Settings.
    pub settings: serde_json::Value,
    /// Fix matchers: acceptance, wrong-but-confident fixes, bound coverage, paths.
    pub fix: Option<FixStats>,
    /// Every query.
    pub per_query: Vec<QueryResult>,
}

/// A query kept with its images, for figures.
pub struct Example {
    /// The query.
    pub query: Query,
    /// Its top-down image.
    pub top: TopDown,
    /// Its map region.
    pub map: MapRegion,
    /// Its localization per matcher (in config order).
    pub locs: Vec<Localization>,
}

/// Everything one evaluation produced.
pub struct EvalOutput {
    /// One report per matcher, in config order.
    pub reports: Vec<EvalReport>,
    /// The first queries with their images.
    pub examples: Vec<Example>,
}

fn score_at(
    spec: &super::MatcherSpec,
    top: &TopDown,
    p: &super::Prepared,
    map: &MapRegion,
    col: usize,
    row: usize,
) -> anyhow::Result<f64> {
    let t = ImageView::new(&p.top, top.n, top.n).map_err(|e| anyhow::anyhow!("{e}"))?;
    let w = ImageView::new(&p.weights, top.n, top.n).map_err(|e| anyhow::anyhow!("{e}"))?;
    let m = ImageView::new(&p.map, map.width, map.height).map_err(|e| anyhow::anyhow!("{e}"))?;
    let win = m
        .sub(col, row, top.n, top.n)
        .ok_or_else(|| anyhow::anyhow!("pair window ({col}, {row}) outside the map"))?;
    let mut ops = OpCounts::default();
    match spec.matcher.score(&t, &w, &win, &mut ops) {
        Ok(s) => Ok(s as f64),
        // A top-down image the matcher cannot use (e.g. too few valid cells for the CNN's
        // input) scores both pairs at the floor: a tie.
        Err(orbfix::matcher::MatchError::NoValidPixels)
        | Err(orbfix::matcher::MatchError::FeaturelessTemplate) => Ok(-1.0),
        Err(e) => Err(anyhow::anyhow!("pair score: {e}")),
    }
}

/// Runs one query for every matcher.
fn run_query(
    world: &World,
    cfg: &EvalConfig,
    q: &Query,
) -> anyhow::Result<(Vec<QueryResult>, Option<Example>)> {
    let (obs, top, map) = render_query_full(world, q, &cfg.pipeline)?;
    let coverage = top.mask.iter().filter(|&&m| m != 0).count() as f64 / top.mask.len() as f64;
    let attitude_deg = (obs.pose.pitch_deg as f64, obs.pose.roll_deg as f64);
    let mut results = Vec::new();
    let mut locs = Vec::new();
    let n = top.n;
    // Pair windows: the truth's window and a random one at least 50 m away.
    let (tc, tr) = map.geo.to_pixel(q.x_m as f32, q.y_m as f32);
    let half = n as f64 / 2.0;
    let tcol = (tc as f64 - half)
        .round()
        .clamp(0.0, (map.width - n) as f64) as usize;
    let trow = (tr as f64 - half)
        .round()
        .clamp(0.0, (map.height - n) as f64) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed.wrapping_mul(1000).wrapping_add(q.id as u64));
    let away = 50.0 / map.geo.m_per_px() as f64;
    let (ncol, nrow) = loop {
        let c = rng.random_range(0..=map.width - n);
        let r = rng.random_range(0..=map.height - n);
        let d = ((c as f64 - tcol as f64).powi(2) + (r as f64 - trow as f64).powi(2)).sqrt();
        if d >= away {
            break (c, r);
        }
    };
    // One map product per refinement plane the fix matchers need (`fix-signed` has its own).
    let sun_deg = Some((q.sun_map.elevation_deg as f32, q.sun_map.azimuth_deg as f32));
    let mut products: Vec<((orbfix::map_product::RefinePlane, usize), Vec<u8>)> = Vec::new();
    let heights = |x: f64, y: f64| world.height_m(x, y);
    for name in &cfg.matchers {
        if let Some(fcfg) = fix_config_in(name, &cfg.pipeline) {
            let opts = MapProductOptions::for_fix(&fcfg, sun_deg)?;
            let key = (opts.plane, opts.relief_block_px);
            let at = match products.iter().position(|(p, _)| *p == key) {
                Some(i) => i,
                None => {
                    let bytes =
                        build_map_product_relief(&map, &cfg.weights, &opts, Some(&heights))?;
                    products.push((key, bytes));
                    products.len() - 1
                }
            };
            let product = products[at].1.as_slice();
            let runner = FixRunner {
                weights: cfg.weights.clone(),
                cfg: fcfg,
            };
            let (loc, out) = localize_fix(
                &runner,
                &obs,
                &map,
                product,
                (q.prior_x_m, q.prior_y_m),
                cfg.stride_px,
            )
            .with_context(|| format!("query {} with {name}", q.id))?;
            let tw = nearest_window(&loc.window_grid, &map.geo, n, n, q.x_m as f32, q.y_m as f32);
            let rank = rank_of(&loc.window_scores, tw).unwrap_or(usize::MAX);
            let r = &out.report;
            let fx = (r.x_m as f64, r.y_m as f64);
            let (cols, rows, step) = out.grid;
            let at = |col: usize, row: usize| -> f64 {
                let c = ((col as f64 / step as f64).round() as usize).min(cols - 1);
                let rr = ((row as f64 / step as f64).round() as usize).min(rows - 1);
                loc.coarse_response[rr * cols + c] as f64
            };
            results.push(QueryResult {
                id: q.id,
                truth_m: (q.x_m, q.y_m),
                prior_m: (q.prior_x_m, q.prior_y_m),
                fix_m: fx,
                error_m: ((fx.0 - q.x_m).powi(2) + (fx.1 - q.y_m).powi(2)).sqrt(),
                true_window_rank: rank,
                true_window: tw,
                true_cell_rank: rank,
                confidence: r.confidence as f64,
                on_border: r.status == orbfix::fix::FixStatus::OnBorder,
                match_score: at(tcol, trow),
                nonmatch_score: at(ncol, nrow),
                coverage,
                attitude_deg,
                dense_s: out.seconds,
                windows_s: 0.0,
                macs: [loc.fix.ops_coarse.macs, r.ops.refine_macs, 0],
                status: Some(r.status.name().to_string()),
                path: Some(r.path.name().to_string()),
                error_bound_m: Some(r.error_bound_m as f64),
                candidates: r
                    .candidates
                    .iter()
                    .map(|c| {
                        let at = (c.x_m as f64, c.y_m as f64);
                        CandidateResult {
                            at_m: at,
                            error_m: ((at.0 - q.x_m).powi(2) + (at.1 - q.y_m).powi(2)).sqrt(),
                            score: c.score as f64,
                            refined: c.refined,
                            coarse: c.coarse as f64,
                        }
                    })
                    .collect(),
            });
            locs.push(loc);
            continue;
        }
        let spec = matcher_by_name(name)?;
        let loc = localize_top_down(
            &spec,
            &top,
            &map,
            (q.prior_x_m, q.prior_y_m),
            &cfg.localize,
            cfg.stride_px,
        )
        .with_context(|| format!("query {} with {name}", q.id))?;
        let tw = nearest_window(&loc.window_grid, &map.geo, n, n, q.x_m as f32, q.y_m as f32);
        let rank = rank_of(&loc.window_scores, tw).unwrap_or(usize::MAX);
        let cell_rank = rank_of(&super::window_cell_scores(&loc), tw).unwrap_or(usize::MAX);
        let fx = (loc.fix.x_m as f64, loc.fix.y_m as f64);
        let prepared = super::prepare(&spec, &top, &map)?;
        results.push(QueryResult {
            id: q.id,
            truth_m: (q.x_m, q.y_m),
            prior_m: (q.prior_x_m, q.prior_y_m),
            fix_m: fx,
            error_m: ((fx.0 - q.x_m).powi(2) + (fx.1 - q.y_m).powi(2)).sqrt(),
            true_window_rank: rank,
            true_window: tw,
            true_cell_rank: cell_rank,
            confidence: loc.fix.confidence as f64,
            on_border: loc.fix.on_border,
            match_score: score_at(&spec, &top, &prepared, &map, tcol, trow)?,
            nonmatch_score: score_at(&spec, &top, &prepared, &map, ncol, nrow)?,
            coverage,
            attitude_deg,
            dense_s: loc.dense_s,
            windows_s: loc.windows_s,
            macs: [
                loc.fix.ops_coarse.macs,
                loc.fix.ops_fine.macs,
                loc.window_ops.macs,
            ],
            status: None,
            path: None,
            error_bound_m: None,
            candidates: Vec::new(),
        });
        locs.push(loc);
    }
    let example = (q.id < cfg.keep_examples).then(|| Example {
        query: *q,
        top,
        map,
        locs,
    });
    Ok((results, example))
}

/// Runs an evaluation; `progress` shows a progress bar on stderr.
pub fn run_eval(cfg: &EvalConfig, progress: bool) -> anyhow::Result<EvalOutput> {
    let world = if cfg.flat_world {
        World::flat(cfg.seed)
    } else {
        World::new(cfg.seed)
    };
    let queries = match cfg.max_tilt_deg {
        Some(t) => drivable_queries(&world, cfg.seed, cfg.queries, cfg.condition, t)?,
        None => make_queries(cfg.seed, cfg.queries, cfg.condition),
    };
    run_eval_on(&world, &queries, cfg, progress)
}

/// As [`run_eval`] on a given world and queries (e.g. a DEM world from
/// [`World::from_geotiff`] with queries from [`super::pipeline::make_queries_in`]).
pub fn run_eval_on(
    world: &World,
    queries: &[Query],
    cfg: &EvalConfig,
    progress: bool,
) -> anyhow::Result<EvalOutput> {
    anyhow::ensure!(!queries.is_empty(), "--queries must be at least 1");
    for m in &cfg.matchers {
        if fix_config_by_name(m).is_none() {
            matcher_by_name(m)?;
        }
    }
    let bar = if progress {
        indicatif::ProgressBar::new(queries.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:30}] {pos}/{len} queries, {elapsed} (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(format!("eval {}", cfg.condition.name()));
    let outs: Vec<anyhow::Result<(Vec<QueryResult>, Option<Example>)>> = queries
        .par_iter()
        .map(|q| {
            let r = run_query(world, cfg, q);
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    let mut per_matcher: Vec<Vec<QueryResult>> = vec![Vec::new(); cfg.matchers.len()];
    let mut examples = Vec::new();
    for o in outs {
        let (rs, ex) = o?;
        for (k, r) in rs.into_iter().enumerate() {
            per_matcher[k].push(r);
        }
        examples.extend(ex);
    }
    let windows = {
        let g = orbfix::matcher::Grid::new(
            cfg.pipeline.grid.n,
            cfg.pipeline.grid.n,
            cfg.pipeline.map_px,
            cfg.pipeline.map_px,
            cfg.stride_px,
        )
        .map_err(|e| anyhow::anyhow!("window grid: {e}"))?;
        g.len()
    };
    let settings = serde_json::json!({
        "map_px": cfg.pipeline.map_px,
        "map_m_per_px": cfg.pipeline.grid.m_per_px,
        "top_down_px": cfg.pipeline.grid.n,
        "window_stride_px": cfg.stride_px,
        "prior_offset_max_m": super::pipeline::PRIOR_OFFSET_M,
        "coarse_factor": cfg.localize.coarse_factor,
        "fine_factor": cfg.localize.fine_factor,
        "refine_peaks": cfg.localize.refine_peaks,
        "nms_radius_m": cfg.localize.nms_radius_m,
        "camera": cfg.pipeline.render.camera,
        "depth": cfg.pipeline.reprojection.depth_name(),
        "rover_attitude": cfg.pipeline.attitude,
        "max_tilt_deg": cfg.max_tilt_deg,
        "truth_min_texture": cfg.pipeline.truth_min_texture,
        "stereo_baseline_m": cfg.pipeline.stereo_rig.baseline_m,
        "stereo": format!("{:?}", cfg.pipeline.stereo_params()),
    });
    let mut reports = Vec::new();
    for (k, name) in cfg.matchers.iter().enumerate() {
        let rs = &per_matcher[k];
        let ranks: Vec<usize> = rs.iter().map(|r| r.true_window_rank).collect();
        let cell_ranks: Vec<usize> = rs.iter().map(|r| r.true_cell_rank).collect();
        let errs: Vec<f64> = rs.iter().map(|r| r.error_m).collect();
        let pos: Vec<f64> = rs.iter().map(|r| r.match_score).collect();
        let neg: Vec<f64> = rs.iter().map(|r| r.nonmatch_score).collect();
        let mean = |v: Vec<f64>| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let share = |d: f64| errs.iter().filter(|&&e| e <= d).count() as f64 / errs.len() as f64;
        let mut ops = BTreeMap::new();
        for (i, stage) in ["coarse", "fine", "windows"].iter().enumerate() {
            let m: Vec<f64> = rs.iter().map(|r| r.macs[i] as f64).collect();
            ops.insert(format!("{stage}_macs_mean"), mean(m));
        }
        reports.push(EvalReport {
            matcher: name.clone(),
            seed: cfg.seed,
            condition: cfg.condition.name().to_string(),
            queries: rs.len(),
            windows_per_query: windows,
            recall_at: [1usize, 5, 10]
                .iter()
                .map(|&k| (k.to_string(), recall_at(&ranks, k)))
                .collect(),
            recall_at_dense: [1usize, 5, 10]
                .iter()
                .map(|&k| (k.to_string(), recall_at(&cell_ranks, k)))
                .collect(),
            median_error_m: quantile(&errs, 0.5),
            p95_error_m: quantile(&errs, 0.95),
            within_m: [("1", 1.0), ("5", 5.0)]
                .iter()
                .map(|&(k, d)| (k.to_string(), share(d)))
                .collect(),
            pairs: pair_stats(&pos, &neg),
            border_rejections: rs.iter().filter(|r| r.on_border).count(),
            mean_confidence_correct: mean(
                rs.iter()
                    .filter(|r| r.error_m <= 5.0)
                    .map(|r| r.confidence)
                    .collect(),
            ),
            mean_confidence_wrong: mean(
                rs.iter()
                    .filter(|r| r.error_m > 5.0)
                    .map(|r| r.confidence)
                    .collect(),
            ),
            mean_dense_s: mean(rs.iter().map(|r| r.dense_s).collect()),
            mean_windows_s: mean(rs.iter().map(|r| r.windows_s).collect()),
            ops,
            settings: settings.clone(),
            fix: fix_config_in(name, &cfg.pipeline).map(|c| fix_stats(rs, &c)),
            per_query: rs.clone(),
        });
    }
    Ok(EvalOutput { reports, examples })
}

/// Acceptance, wrong-but-confident fixes, bound coverage and paths of a fix matcher.
fn fix_stats(rs: &[QueryResult], cfg: &orbfix::fix::FixConfig) -> FixStats {
    let n = rs.len().max(1) as f64;
    let ok: Vec<&QueryResult> = rs
        .iter()
        .filter(|r| r.status.as_deref() == Some("ok"))
        .collect();
    let share_ok = |f: &dyn Fn(&QueryResult) -> bool| {
        if ok.is_empty() {
            f64::NAN
        } else {
            ok.iter().filter(|r| f(r)).count() as f64 / ok.len() as f64
        }
    };
    let wrong = ok.iter().filter(|r| r.error_m > 5.0).count();
    let mut path_share = BTreeMap::new();
    let mut status_count = BTreeMap::new();
    for r in rs {
        *path_share
            .entry(r.path.clone().unwrap_or_default())
            .or_insert(0.0) += 1.0 / n;
        *status_count
            .entry(r.status.clone().unwrap_or_default())
            .or_insert(0) += 1;
    }
    FixStats {
        accepted_share: ok.len() as f64 / n,
        wrong_confident: wrong,
        wrong_confident_share: wrong as f64 / n,
        bound_coverage: share_ok(&|r| r.error_m <= r.error_bound_m.unwrap_or(f64::INFINITY)),
        accepted_within_1m: share_ok(&|r| r.error_m <= 1.0),
        path_share,
        status_count,
        config: format!("{cfg:?}"),
    }
}
