//! A whole drive on the built-in world (`orbfix traverse`): a planned path of straight legs
//! and turns through the test zone, drifting odometry, a heading estimate with a stated
//! error, and at every stop the eval's rendering (the four views and their depth at the
//! truth, the orbital map region around the prior, its map product) and the core's one fix
//! ([`orbfix::fix::run`], or its heading search [`orbfix::fix::run_heading_search`]) around
//! the fused prior, folded into the core's filter ([`orbfix::fusion::Fusion`]). Nothing here
//! localizes: the host simulates the drive, renders and reports.
//!
//! Files: `plan` (the path and the sensors' readings), `summary` (the summary and table),
//! `figures`; this file holds the options, the per-stop record and the run loop.

pub mod figures;
mod plan;
mod summary;

pub use plan::{plan, Plan, PlannedStop};
use plan::{BIAS0_PER_DRIFT, BIAS_WALK_PER_DRIFT, SCALE_PER_DRIFT, WALK_PER_DRIFT};
pub use summary::{markdown_table, summarize, Summary};

use crate::eval::pipeline::{map_region, observe_raw, Condition, PipelineOptions, Reprojection};
use crate::fix::{build_map_product_relief, FixRunner, MapProductOptions};
use crate::world::World;
use orbfix::fix::{FixConfig, FixReport, FixStatus, HeadingSearch};
use orbfix::fusion::{Fusion, FusionConfig, OdometryLeg};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Settings of a simulated drive.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TraverseOptions {
    /// World seed (also seeds the path, the odometry and the headings).
    pub seed: u64,
    /// Stops, the first at the start.
    pub stops: usize,
    /// Lighting of the rover views against the map.
    pub condition: Condition,
    /// Odometry drift, fraction of the distance driven (module docs: the model).
    pub odometry_drift: f64,
    /// Standard deviation of the heading estimate given to the fix, degrees.
    pub heading_sigma_deg: f64,
    /// Heading search step, degrees (used when the heading sigma exceeds the tolerance).
    pub heading_step_deg: f64,
    /// Largest heading sigma without a search, degrees.
    pub heading_tolerance_deg: f64,
    /// Shortest leg between stops, metres.
    pub leg_min_m: f64,
    /// Longest leg between stops, metres.
    pub leg_max_m: f64,
    /// Standard deviation of the start position's error, per axis, metres.
    pub start_sigma_m: f64,
    /// Heading sigma of the per-stop comparison (known heading, this sigma without search,
    /// with search), degrees; `None`: no comparison.
    pub compare_heading_sigma_deg: Option<f64>,
}

impl Default for TraverseOptions {
    fn default() -> Self {
        Self {
            seed: 2,
            stops: 26,
            condition: Condition::SameSun,
            odometry_drift: 0.02,
            heading_sigma_deg: 0.5,
            heading_step_deg: 2.0,
            heading_tolerance_deg: 1.0,
            leg_min_m: 30.0,
            leg_max_m: 50.0,
            start_sigma_m: 10.0,
            compare_heading_sigma_deg: None,
        }
    }
}

impl TraverseOptions {
    /// Checks the settings; the message names the flag.
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            (1..=500).contains(&self.stops),
            "--stops must be 1..=500 (got {})",
            self.stops
        );
        anyhow::ensure!(
            self.odometry_drift.is_finite() && (0.0..=0.5).contains(&self.odometry_drift),
            "--odometry-drift must be a fraction in 0..=0.5 (e.g. 0.02 for 2 % of distance)"
        );
        for (v, flag) in [
            (self.heading_sigma_deg, "--heading-sigma-deg"),
            (self.heading_tolerance_deg, "--heading-tolerance-deg"),
            (self.start_sigma_m, "--start-sigma-m"),
        ] {
            anyhow::ensure!(
                v.is_finite() && (0.0..=100.0).contains(&v),
                "{flag} must be a number in 0..=100"
            );
        }
        anyhow::ensure!(
            self.heading_step_deg.is_finite()
                && self.heading_step_deg > 0.0
                && self.heading_step_deg <= 10.0,
            "--heading-step-deg must be in (0, 10] degrees"
        );
        anyhow::ensure!(
            self.leg_min_m.is_finite()
                && self.leg_min_m >= 1.0
                && self.leg_max_m.is_finite()
                && self.leg_max_m >= self.leg_min_m
                && self.leg_max_m <= 200.0,
            "legs must satisfy 1 <= --leg-min-m <= --leg-max-m <= 200"
        );
        if let Some(s) = self.compare_heading_sigma_deg {
            anyhow::ensure!(
                s.is_finite() && (0.0..=20.0).contains(&s),
                "--compare-heading-sigma-deg must be in 0..=20"
            );
        }
        Ok(())
    }

    /// The core filter's settings for this odometry model (the rover knows its odometry's
    /// specification; the filter's noise is set a little above the simulated one).
    pub fn fusion_config(&self) -> FusionConfig {
        let f = self.odometry_drift as f32;
        FusionConfig {
            initial_sigma_m: (2.0 * self.start_sigma_m as f32).max(1.0),
            initial_bias_sigma_rad: (1.5 * BIAS0_PER_DRIFT * f).max(1e-4),
            scale_sigma: (SCALE_PER_DRIFT * 2.0 * f).max(1e-4),
            walk_m2_per_m: (2.0 * WALK_PER_DRIFT * f).powi(2).max(1e-6),
            bias_walk_rad2_per_m: (2.0 * BIAS_WALK_PER_DRIFT * f).powi(2).max(1e-9),
            ..FusionConfig::default()
        }
    }

    /// The heading search the fused fix runs (`None`: the heading is good enough).
    pub fn heading_search(&self, sigma_deg: f64) -> anyhow::Result<Option<HeadingSearch>> {
        HeadingSearch::for_sigma(
            sigma_deg as f32,
            self.heading_tolerance_deg as f32,
            self.heading_step_deg as f32,
        )
        .map_err(|e| anyhow::anyhow!("heading search: {e}"))
    }
}

/// The comparison of one stop: the fix's error with the known heading, with the heading
/// estimate of the comparison's sigma, and with the heading search around that estimate.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct HeadingCompare {
    /// Error of the fix with the true heading, metres (null: no data).
    pub known_error_m: Option<f64>,
    /// Status of that fix.
    pub known_status: String,
    /// Error with the noisy heading, no search, metres.
    pub noisy_error_m: Option<f64>,
    /// Status of that fix.
    pub noisy_status: String,
    /// Heading error given, degrees.
    pub noisy_heading_error_deg: f64,
    /// Error with the heading search, metres.
    pub search_error_m: Option<f64>,
    /// Status of that fix.
    pub search_status: String,
    /// Heading error after the search, degrees.
    pub search_heading_error_deg: f64,
    /// Headings tried.
    pub search_tried: usize,
    /// Wall time of the search, milliseconds.
    pub search_ms: f64,
    /// Wall time of the known-heading fix, milliseconds.
    pub known_ms: f64,
}

/// What happened at one stop.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StopRecord {
    /// Stop number.
    pub stop: usize,
    /// Distance driven from the start, metres.
    pub distance_m: f64,
    /// True position, metres.
    pub truth_m: (f64, f64),
    /// Odometry alone (dead reckoning from the start prior), metres.
    pub odometry_m: (f64, f64),
    /// Its error, metres.
    pub odometry_error_m: f64,
    /// Its drift since the start (error less the start prior's error, as vectors), metres.
    pub odometry_drift_m: f64,
    /// The fused prediction the fix searched around, metres.
    pub prior_m: (f64, f64),
    /// Its error, metres.
    pub prior_error_m: f64,
    /// Search radius the filter asked for, metres.
    pub search_radius_m: f64,
    /// Side of the map region searched, metres.
    pub map_side_m: f64,
    /// The fix's position (null when no data).
    pub fix_m: Option<(f64, f64)>,
    /// Its error, metres (null when no fix).
    pub fix_error_m: Option<f64>,
    /// Its stated error bound, metres (null when no fix).
    pub fix_bound_m: Option<f64>,
    /// Its status.
    pub fix_status: String,
    /// Its path (ncc, cnn, none).
    pub fix_path: String,
    /// Its confidence.
    pub fix_confidence: f64,
    /// Heading given to the fix, degrees; its error.
    pub heading_error_deg: f64,
    /// Heading the fix reported (heading search), and its error, degrees.
    pub fix_heading_error_deg: Option<f64>,
    /// Headings the fix tried.
    pub headings_tried: usize,
    /// Whether the filter folded the fix in.
    pub accepted: bool,
    /// Why not (status name or `innovation-gate`), with the detail.
    pub reject_reason: Option<String>,
    /// Squared Mahalanobis distance of the innovation.
    pub mahalanobis2: f64,
    /// The fused position after the stop, metres.
    pub fused_m: (f64, f64),
    /// Its error, metres.
    pub fused_error_m: f64,
    /// The filter's standard deviation along the major axis, metres.
    pub fused_sigma_m: f64,
    /// The filter's heading bias estimate, degrees.
    pub heading_bias_deg: f64,
    /// Per-stop heading comparison (with `--compare-heading-sigma-deg`).
    pub compare: Option<HeadingCompare>,
    /// Wall time: rendering views and map, building the map product, seconds.
    pub render_s: f64,
    /// Wall time of the fix (all headings), milliseconds.
    pub fix_ms: f64,
}

fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt()
}

/// A fix report rebuilt from a stop record (to replay the filter when resuming).
fn report_of(r: &StopRecord) -> FixReport {
    let (x, y) = r.fix_m.unwrap_or(r.prior_m);
    let mut rep = FixReport::no_data(
        x as f32,
        y as f32,
        orbfix::fix::ReprojectionSummary {
            range: true,
            status: [orbfix::reproject::FrameStatus::Ok; 4],
            valid_cells: 0,
            stereo: None,
        },
    );
    rep.status = match r.fix_status.as_str() {
        "ok" => FixStatus::Ok,
        "ambiguous" => FixStatus::Ambiguous,
        "on-border" => FixStatus::OnBorder,
        "self-check-failed" => FixStatus::SelfCheckFailed,
        _ => FixStatus::NoData,
    };
    rep.error_bound_m = r.fix_bound_m.map_or(f32::INFINITY, |b| b as f32);
    rep.confidence = r.fix_confidence as f32;
    rep
}

/// The drive in progress: the plan, the filter, dead reckoning and the records so far.
pub struct Traverse {
    /// Settings.
    pub opts: TraverseOptions,
    /// The plan.
    pub plan: Plan,
    /// The rendering pipeline (the eval's).
    pub pipeline: PipelineOptions,
    /// The fix.
    pub runner: FixRunner,
    world: World,
    fusion: Fusion,
    odo: (f64, f64),
    /// Stops done.
    pub records: Vec<StopRecord>,
}

impl Traverse {
    /// A drive with the weights `weights` and the fix configuration `cfg` (the eval's
    /// `fix` matcher by default); rendering with `reprojection` as the eval does.
    pub fn new(
        opts: TraverseOptions,
        weights: Vec<u8>,
        cfg: FixConfig,
        reprojection: Reprojection,
    ) -> anyhow::Result<Self> {
        let plan = plan(&opts)?;
        let pipeline = PipelineOptions {
            reprojection,
            ..PipelineOptions::default()
        };
        let mut cfg = cfg;
        cfg.grid = pipeline.grid;
        cfg.range = pipeline.range;
        let fusion = Fusion::new(
            opts.fusion_config(),
            plan.start_prior_m.0 as f32,
            plan.start_prior_m.1 as f32,
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok(Self {
            world: World::new(opts.seed),
            odo: plan.start_prior_m,
            plan,
            pipeline,
            runner: FixRunner { weights, cfg },
            fusion,
            opts,
            records: Vec::new(),
        })
    }

    /// The core filter.
    pub fn fusion(&self) -> &Fusion {
        &self.fusion
    }

    /// Replays `done` (records of an earlier run of the same settings) through the
    /// filter and dead reckoning without rendering; returns how many were taken.
    pub fn resume(&mut self, done: Vec<StopRecord>) -> anyhow::Result<usize> {
        let mut taken = 0;
        for r in done {
            let planned = self.plan.stops.get(r.stop).map(|s| s.truth_m);
            if r.stop != self.records.len() || planned.is_none() {
                break;
            }
            anyhow::ensure!(
                planned.is_some_and(|t| dist(t, r.truth_m) < 1e-6),
                "stop {}: the saved run was planned differently (delete the JSON or pass --fresh)",
                r.stop
            );
            self.advance()?;
            let u = self
                .fusion
                .update(&report_of(&r))
                .map_err(|e| anyhow::anyhow!("stop {}: {e}", r.stop))?;
            anyhow::ensure!(
                u.accepted() == r.accepted,
                "stop {}: the saved run does not replay (delete the JSON or pass --fresh)",
                r.stop
            );
            self.records.push(r);
            taken += 1;
        }
        Ok(taken)
    }

    /// Dead reckoning and the filter's prediction over the leg to the next stop.
    fn advance(&mut self) -> anyhow::Result<&PlannedStop> {
        let i = self.records.len();
        let s = self
            .plan
            .stops
            .get(i)
            .ok_or_else(|| anyhow::anyhow!("the drive has only {i} stops"))?;
        if let Some((d, h)) = s.odometry_leg {
            let r = h.to_radians();
            self.odo = (self.odo.0 + d * r.sin(), self.odo.1 + d * r.cos());
            self.fusion
                .predict(&OdometryLeg {
                    distance_m: d as f32,
                    heading_deg: h as f32,
                })
                .map_err(|e| anyhow::anyhow!("stop {i}: {e}"))?;
        }
        Ok(s)
    }

    /// Drives to the next stop, renders it, runs the fix around the fused prior and folds
    /// the report into the filter.
    pub fn step(&mut self) -> anyhow::Result<&StopRecord> {
        let s = *self.advance()?;
        let prior = self.fusion.position();
        let prior = (prior.0 as f64, prior.1 as f64);
        let radius = self.fusion.search_radius_m() as f64;
        let t0 = Instant::now();
        let opts = &self.pipeline;
        let obs = observe_raw(
            &self.world,
            s.truth_m.0,
            s.truth_m.1,
            s.heading_deg,
            s.sun_rover,
            opts,
        )?;
        // Window centres within `radius` of the prior: a map of the window side plus twice
        // the radius, in whole window steps.
        let mo = MapProductOptions::for_fix(
            &self.runner.cfg,
            Some((s.sun_map.elevation_deg as f32, s.sun_map.azimuth_deg as f32)),
        )?;
        let m = opts.grid.m_per_px as f64;
        let steps = (radius / m / mo.step_px as f64).ceil().max(1.0) as usize;
        let map_px = opts.grid.n + 2 * steps * mo.step_px;
        let map = map_region(
            &self.world,
            prior.0,
            prior.1,
            map_px,
            m,
            s.sun_map,
            &opts.render,
        )?;
        let world = &self.world;
        let heights = |x: f64, y: f64| world.height_m(x, y);
        let product = build_map_product_relief(&map, &self.runner.weights, &mo, Some(&heights))?;
        let render_s = t0.elapsed().as_secs_f64();
        let frames = obs.frames()?;
        let pose_at = |h: f64| {
            let mut p = obs.pose;
            p.x_m = prior.0 as f32;
            p.y_m = prior.1 as f32;
            p.heading_deg = h as f32;
            p
        };
        let depths = obs.depths.as_ref();
        let run_fix = |h: f64,
                       search: Option<HeadingSearch>|
         -> anyhow::Result<(FixReport, Option<f64>, usize, f64)> {
            let t = Instant::now();
            let pose = pose_at(h);
            Ok(match search {
                None => {
                    let out = self
                        .runner
                        .run(&obs.params, &pose, frames, depths, &product)?;
                    (out.report, None, 1, t.elapsed().as_secs_f64() * 1e3)
                }
                Some(hs) => {
                    let (hf, _) = self.runner.run_heading_search(
                        &obs.params,
                        &pose,
                        frames,
                        depths,
                        &product,
                        &hs,
                    )?;
                    (
                        hf.report,
                        Some(hf.heading_deg as f64),
                        hf.tried,
                        t.elapsed().as_secs_f64() * 1e3,
                    )
                }
            })
        };
        let search = self.opts.heading_search(self.opts.heading_sigma_deg)?;
        let (report, fix_heading, tried, fix_ms) = run_fix(s.heading_estimate_deg, search)?;
        let herr = |h: f64| (h - s.heading_deg + 540.0).rem_euclid(360.0) - 180.0;
        let err_of = |r: &FixReport| {
            (r.status != FixStatus::NoData).then(|| dist((r.x_m as f64, r.y_m as f64), s.truth_m))
        };
        let compare = match (self.opts.compare_heading_sigma_deg, s.compare_heading_deg) {
            (Some(sigma), Some(h)) => {
                let (known, _, _, known_ms) = run_fix(s.heading_deg, None)?;
                let (noisy, _, _, _) = run_fix(h, None)?;
                let hs = self
                    .opts
                    .heading_search(sigma)?
                    .map_or_else(|| HeadingSearch::new(0, 1.0), Ok)
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                let (found, fh, n, ms) = run_fix(h, Some(hs))?;
                Some(HeadingCompare {
                    known_error_m: err_of(&known),
                    known_status: known.status.name().into(),
                    noisy_error_m: err_of(&noisy),
                    noisy_status: noisy.status.name().into(),
                    noisy_heading_error_deg: herr(h),
                    search_error_m: err_of(&found),
                    search_status: found.status.name().into(),
                    search_heading_error_deg: herr(fh.unwrap_or(h)),
                    search_tried: n,
                    search_ms: ms,
                    known_ms,
                })
            }
            _ => None,
        };
        let u = self
            .fusion
            .update(&report)
            .map_err(|e| anyhow::anyhow!("stop {}: {e}", s.stop))?;
        let fused = self.fusion.position();
        let fused = (fused.0 as f64, fused.1 as f64);
        let has_fix = report.status != FixStatus::NoData;
        self.records.push(StopRecord {
            stop: s.stop,
            distance_m: s.distance_m,
            truth_m: s.truth_m,
            odometry_m: self.odo,
            odometry_error_m: dist(self.odo, s.truth_m),
            odometry_drift_m: {
                let (p0, t0) = (self.plan.start_prior_m, self.plan.stops[0].truth_m);
                dist(
                    (self.odo.0 - s.truth_m.0, self.odo.1 - s.truth_m.1),
                    (p0.0 - t0.0, p0.1 - t0.1),
                )
            },
            prior_m: prior,
            prior_error_m: dist(prior, s.truth_m),
            search_radius_m: radius,
            map_side_m: map_px as f64 * m,
            fix_m: has_fix.then_some((report.x_m as f64, report.y_m as f64)),
            fix_error_m: err_of(&report),
            fix_bound_m: has_fix.then_some(report.error_bound_m as f64),
            fix_status: report.status.name().into(),
            fix_path: report.path.name().into(),
            fix_confidence: report.confidence as f64,
            heading_error_deg: herr(s.heading_estimate_deg),
            fix_heading_error_deg: fix_heading.map(herr),
            headings_tried: tried,
            accepted: u.accepted(),
            reject_reason: u.rejected.map(|r| format!("{}: {r}", r.name())),
            mahalanobis2: u.mahalanobis2 as f64,
            fused_m: fused,
            fused_error_m: dist(fused, s.truth_m),
            fused_sigma_m: self.fusion.sigma_major_m() as f64,
            heading_bias_deg: self.fusion.heading_bias_deg() as f64,
            compare,
            render_s,
            fix_ms,
        });
        self.records
            .last()
            .ok_or_else(|| anyhow::anyhow!("no record"))
    }
}
