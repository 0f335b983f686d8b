//! Localization on the host: the matcher registry, the core's one fix
//! ([`orbfix::fix::run`], matchers `fix`, `fix-ncc`, `cnn`) and the baseline matchers run
//! through the core localizer on owned images, generated evaluation queries in the test
//! zone, metrics, reports, figures and operator pictures.
//!
//! The pipeline of one query (`pipeline`): render the rover's four views (and depth) at the
//! truth, render a 300 x 300 m orbital map region centred on a prior offset from the truth
//! and build its map product, then run the fix (which reprojects, embeds, matches and
//! refines in the core). Baselines get the core's top-down image of the same views and run
//! the study's 441-window search and the coarse-to-fine dense localizer.
//!
//! Files: `matchers` (the registry and the core configuration of each fix matcher),
//! `baseline` (the baselines' preprocessing and search), `map_io` (MAP.png + MAP.json,
//! atomic writes), `pipeline` (one query), `run` (a whole evaluation), `metrics`, `figures`,
//! `fix_figure` and `overlay` (pictures); this file holds the shared types and the adapter
//! from the core's fix report to a [`Localization`].

mod baseline;
pub mod figures;
pub mod fix_figure;
mod map_io;
mod matchers;
pub mod metrics;
pub mod overlay;
pub mod pipeline;
pub mod run;

pub use baseline::{
    cell_scores, localize_top_down, prepare, weights_for, window_cell_scores, Prepared,
};
pub use map_io::{load_map, save_png_atomic, write_atomic, MapMeta};
pub use matchers::{
    best_matcher, fix_config_by_name, fix_config_checked, fix_config_in, matcher_by_name,
    parse_matchers, MatcherSpec, FIX_OPTIONS, MATCHERS,
};

use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::localize::Fix;
use orbfix::matcher::{Grid, OpCounts};

/// A reprojected top-down image centred on the rover, north-up.
#[derive(Clone, Debug)]
pub struct TopDown {
    /// Gray levels, `n * n`, row-major.
    pub image: Vec<u8>,
    /// Validity (0 = no data, else valid), `n * n`.
    pub mask: Vec<u8>,
    /// Side, pixels.
    pub n: usize,
    /// Metres per pixel.
    pub m_per_px: f32,
}

/// A north-up orbital map region with its georeference.
#[derive(Clone, Debug)]
pub struct MapRegion {
    /// Gray levels, row-major.
    pub image: Vec<u8>,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// North-west corner and metres per pixel.
    pub geo: GeoRef,
}

impl MapRegion {
    /// A core view of the map.
    pub fn view(&self) -> anyhow::Result<ImageView<'_>> {
        ImageView::new(&self.image, self.width, self.height)
            .map_err(|e| anyhow::anyhow!("map image does not match its size: {e}"))
    }
}

/// Everything one localization produced.
#[derive(Clone, Debug)]
pub struct Localization {
    /// The coarse-to-fine fix.
    pub fix: Fix,
    /// Coarse response (row-major over `fix.coarse_grid`).
    pub coarse_response: Vec<f32>,
    /// The study's window scores (row-major over `window_grid`).
    pub window_scores: Vec<f32>,
    /// The window grid (21 x 21 for 50 m windows, 12.5 m stride, 300 m map).
    pub window_grid: Grid,
    /// Operations of the window search.
    pub window_ops: OpCounts,
    /// Wall time of the dense coarse-to-fine fix, seconds.
    pub dense_s: f64,
    /// Wall time of the window search, seconds.
    pub windows_s: f64,
    /// The fix's report, for the fix matchers.
    pub fix_report: Option<orbfix::fix::FixReport>,
}

/// Runs the core's fix on an observation against a map product and describes it as a
/// [`Localization`] (the study's windows ranked by their cells' best coarse scores).
pub fn localize_fix(
    runner: &crate::fix::FixRunner,
    obs: &pipeline::Observation,
    map: &MapRegion,
    product: &[u8],
    prior: (f64, f64),
    stride_px: usize,
) -> anyhow::Result<(Localization, crate::fix::FixOutcome)> {
    let mut pose = obs.pose;
    pose.x_m = prior.0 as f32;
    pose.y_m = prior.1 as f32;
    // The stereo path: the fix matches the pairs itself (its `stereo` stage).
    let depth = match (obs.right_frames()?, obs.depths.as_ref()) {
        (Some(rights), _) => crate::fix::FixDepth::Stereo(rights),
        (None, Some(d)) => crate::fix::FixDepth::Images(d),
        (None, None) => crate::fix::FixDepth::Flat,
    };
    let out = runner.run_with(&obs.params, &pose, obs.frames()?, depth, product)?;
    let n = runner.cfg.grid.n;
    let (cols, rows, step) = out.grid;
    let cg = Grid::new(n, n, map.width, map.height, step)
        .map_err(|e| anyhow::anyhow!("window grid: {e}"))?;
    anyhow::ensure!(
        cg.len() == cols * rows,
        "map product grid differs from the map"
    );
    let wg = Grid::new(n, n, map.width, map.height, stride_px)
        .map_err(|e| anyhow::anyhow!("window grid: {e}"))?;
    let r = &out.report;
    let windows = r.windows as usize;
    let coarse_response: Vec<f32> = if windows > 0 {
        out.response[..windows]
            .iter()
            .map(|&v| v as f32 / 32768.0)
            .collect()
    } else {
        vec![-1.0; cg.len()]
    };
    let window_scores = cell_scores(&coarse_response, &cg, &wg);
    let ops = OpCounts {
        macs: r.ops.embed_macs + r.ops.match_elements,
        windows: r.windows as u64,
        downsample_px: 0,
    };
    let fix = Fix {
        x_m: r.x_m,
        y_m: r.y_m,
        score: r.score,
        confidence: r.confidence,
        peak_score: r.cnn_best_q15 as f32 / 32768.0,
        second_score: r.candidates.get(1).map_or(r.score, |c| c.score),
        on_border: r.status == orbfix::fix::FixStatus::OnBorder,
        candidates: r.candidates.clone(),
        coarse_grid: cg,
        ops_coarse: ops,
        ops_fine: OpCounts {
            macs: r.ops.refine_macs,
            ..OpCounts::default()
        },
    };
    Ok((
        Localization {
            fix,
            coarse_response,
            window_scores,
            window_grid: wg,
            window_ops: OpCounts::default(),
            dense_s: out.seconds,
            windows_s: 0.0,
            fix_report: Some(out.report.clone()),
        },
        out,
    ))
}

/// A sentence for a core localization error.
pub fn describe(e: &orbfix::localize::LocalizeError) -> String {
    use orbfix::localize::LocalizeError as E;
    use orbfix::matcher::MatchError as M;
    match e {
        E::Match(M::NoValidPixels) => {
            "the top-down image is all \"no data\" (no camera saw the ground): check the frames".into()
        }
        E::Match(M::FeaturelessTemplate) => {
            "the top-down image has no contrast (all valid pixels equal): check the frames".into()
        }
        E::Match(m) => m.to_string(),
        E::ResolutionMismatch {
            map_m_per_px,
            top_m_per_px,
        } => format!(
            "map is {map_m_per_px} m/px but the top-down image is {top_m_per_px} m/px: resample the map"
        ),
        E::PriorOutsideMap => "the prior position lies outside the map: pass a map region around the prior".into(),
        E::TooLittleCoverage { permille } => format!(
            "only {:.1} % of the top-down image has data (too little to match)",
            *permille as f64 / 10.0
        ),
        E::BadConfig => "bad localization configuration (template size must be a multiple of the coarse factor, coarse a multiple of fine)".into(),
        E::ScratchTooSmall => "scratch buffers too small".into(),
    }
}

/// The JSON description of a localization (fix, confidence, candidates, operation counts).
pub fn describe_fix(loc: &Localization) -> serde_json::Value {
    let f = &loc.fix;
    let mut order: Vec<usize> = (0..loc.window_scores.len()).collect();
    order.sort_by(|&a, &b| loc.window_scores[b].total_cmp(&loc.window_scores[a]));
    serde_json::json!({
        "fix_m": [f.x_m, f.y_m],
        "score": f.score,
        "confidence": f.confidence,
        "peak_score": f.peak_score,
        "second_score": f.second_score,
        "on_border": f.on_border,
        "candidates": f.candidates.iter().map(|c| serde_json::json!({
            "x_m": c.x_m, "y_m": c.y_m, "score": c.score, "refined": c.refined, "coarse": c.coarse
        })).collect::<Vec<_>>(),
        "best_windows": order.iter().take(10).map(|&i| serde_json::json!({
            "index": i, "col": i % loc.window_grid.cols(), "row": i / loc.window_grid.cols(),
            "score": loc.window_scores[i]
        })).collect::<Vec<_>>(),
        "ops": {"coarse": ops_json(&f.ops_coarse), "fine": ops_json(&f.ops_fine), "windows": ops_json(&loc.window_ops)},
        "time_s": {"dense": loc.dense_s, "windows": loc.windows_s},
    })
}

fn ops_json(o: &OpCounts) -> serde_json::Value {
    serde_json::json!({"macs": o.macs, "windows": o.windows, "downsample_px": o.downsample_px})
}
