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

pub mod figures;
pub mod fix_figure;
pub mod metrics;
pub mod overlay;
pub mod pipeline;
pub mod run;

use anyhow::{bail, Context};
use orbfix::fix::{FixConfig, RefineMode};
use orbfix::geo::GeoRef;
use orbfix::image::{ImageView, ImageViewMut};
use orbfix::localize::{self, Fix, LocalizeConfig};
use orbfix::matcher::{distance_weights, l1::L1, l2::L2, ncc::Ncc, Grid, Matcher, OpCounts};
use serde::{Deserialize, Serialize};
use std::time::Instant;

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

/// The weights a matcher sees for a top-down mask.
pub fn weights_for(spec: &MatcherSpec, top: &TopDown) -> anyhow::Result<Vec<u8>> {
    let mut mask = top.mask.clone();
    if let Some(r) = spec.max_range_m {
        let r_px = (r / top.m_per_px) as f64;
        let c = top.n as f64 / 2.0;
        for (i, m) in mask.iter_mut().enumerate() {
            let (x, y) = ((i % top.n) as f64 + 0.5 - c, (i / top.n) as f64 + 0.5 - c);
            if x * x + y * y > r_px * r_px {
                *m = 0;
            }
        }
    }
    let top = &TopDown {
        mask,
        image: Vec::new(),
        ..*top
    };
    match spec.distance_weighting_px {
        None => Ok(top.mask.clone()),
        Some(r0) => {
            let mut out = vec![0u8; top.n * top.n];
            let m = ImageView::new(&top.mask, top.n, top.n)
                .map_err(|e| anyhow::anyhow!("bad top-down mask: {e}"))?;
            let mut o = ImageViewMut::new(&mut out, top.n, top.n)
                .map_err(|e| anyhow::anyhow!("bad weight buffer: {e}"))?;
            distance_weights(&m, &mut o, r0)
                .map_err(|e| anyhow::anyhow!("distance weighting failed: {e}"))?;
            Ok(out)
        }
    }
}

/// The images a matcher sees: top-down image, its weights and the map, pre-processed.
pub struct Prepared {
    /// Top-down image (high-passed if the matcher asks).
    pub top: Vec<u8>,
    /// Weights (mask, range cut, distance weighting).
    pub weights: Vec<u8>,
    /// Map (high-passed if the matcher asks).
    pub map: Vec<u8>,
}

fn baseline_highpass_image(
    img: &[u8],
    mask: Option<&[u8]>,
    w: usize,
    h: usize,
    radius: usize,
) -> anyhow::Result<Vec<u8>> {
    let src = ImageView::new(img, w, h).map_err(|e| anyhow::anyhow!("bad image: {e}"))?;
    let m = match mask {
        Some(m) => Some(ImageView::new(m, w, h).map_err(|e| anyhow::anyhow!("bad mask: {e}"))?),
        None => None,
    };
    let mut out = vec![0u8; w * h];
    let mut o = ImageViewMut::new(&mut out, w, h).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut scratch = vec![0u32; orbfix::matcher::prep::highpass_buffer_len(w)];
    orbfix::matcher::prep::highpass(&src, m.as_ref(), radius, &mut o, &mut scratch)
        .map_err(|e| anyhow::anyhow!("high-pass failed: {e}"))?;
    Ok(out)
}

/// Pre-processes a query's images for a matcher.
pub fn prepare(spec: &MatcherSpec, top: &TopDown, map: &MapRegion) -> anyhow::Result<Prepared> {
    let weights = weights_for(spec, top)?;
    let equalized;
    let top = if spec.equalize_rings {
        let mut img = top.image.clone();
        let mask: Vec<u8> = top
            .mask
            .iter()
            .map(|&m| if m != 0 { 255 } else { 0 })
            .collect();
        let ring = ((1.0 / top.m_per_px).round() as u32).max(1);
        orbfix::reproject::equalize_rings(&mut img, &mask, top.n, ring);
        equalized = TopDown {
            image: img,
            ..top.clone()
        };
        &equalized
    } else {
        top
    };
    match spec.highpass_m {
        None => Ok(Prepared {
            top: top.image.clone(),
            weights,
            map: map.image.clone(),
        }),
        Some(r_m) => {
            let r = ((r_m / top.m_per_px).round() as usize).max(1);
            Ok(Prepared {
                top: baseline_highpass_image(&top.image, Some(&weights), top.n, top.n, r)?,
                map: baseline_highpass_image(&map.image, None, map.width, map.height, r)?,
                weights,
            })
        }
    }
}

/// Runs the core on owned images: the study's window search (`stride_px` between windows)
/// and the coarse-to-fine fix.
pub fn localize_top_down(
    spec: &MatcherSpec,
    top: &TopDown,
    map: &MapRegion,
    prior: (f64, f64),
    cfg: &LocalizeConfig,
    stride_px: usize,
) -> anyhow::Result<Localization> {
    if top.image.len() != top.n * top.n || top.mask.len() != top.n * top.n {
        bail!(
            "top-down image is {} bytes and mask {} bytes, expected {} x {}",
            top.image.len(),
            top.mask.len(),
            top.n,
            top.n
        );
    }
    let p = prepare(spec, top, map)?;
    let t = ImageView::new(&p.top, top.n, top.n)
        .map_err(|e| anyhow::anyhow!("bad top-down image: {e}"))?;
    let w = ImageView::new(&p.weights, top.n, top.n)
        .map_err(|e| anyhow::anyhow!("bad top-down mask: {e}"))?;
    let m = ImageView::new(&p.map, map.width, map.height)
        .map_err(|e| anyhow::anyhow!("map image does not match its size: {e}"))?;
    let (nb, nf) = localize::buffer_sizes(top.n, top.n, map.width, map.height, cfg)
        .map_err(|e| anyhow::anyhow!("localization set-up rejected: {e}"))?;
    let mut bytes = vec![0u8; nb];
    let mut floats = vec![0f32; nf];
    let t0 = Instant::now();
    let fix = localize::localize(
        spec.matcher.as_ref(),
        &t,
        &w,
        top.m_per_px,
        &m,
        &map.geo,
        prior.0 as f32,
        prior.1 as f32,
        cfg,
        &mut bytes,
        &mut floats,
    )
    .map_err(|e| anyhow::anyhow!("localization failed: {}", describe(&e)))?;
    let dense_s = t0.elapsed().as_secs_f64();
    let coarse_response = floats[..fix.coarse_grid.len()].to_vec();
    let grid = Grid::new(top.n, top.n, map.width, map.height, stride_px)
        .map_err(|e| anyhow::anyhow!("window grid: {e}"))?;
    let mut window_scores = vec![0f32; grid.len()];
    let mut window_ops = OpCounts::default();
    let t1 = Instant::now();
    let window_grid = localize::window_search(
        spec.matcher.as_ref(),
        &t,
        &w,
        &m,
        stride_px,
        &mut window_scores,
        &mut window_ops,
    )
    .map_err(|e| anyhow::anyhow!("window search failed: {}", describe(&e)))?;
    let windows_s = t1.elapsed().as_secs_f64();
    Ok(Localization {
        fix,
        coarse_response,
        window_scores,
        window_grid,
        window_ops,
        dense_s,
        windows_s,
        fix_report: None,
    })
}

/// Window scores from the dense coarse response: each of the study's windows gets the best
/// coarse score of the rover positions in its cell (within half a stride of the window's
/// centre), so a window 6 m off a sharp texture is not penalised for its offset. Row-major
/// over `loc.window_grid`.
pub fn window_cell_scores(loc: &Localization) -> Vec<f32> {
    cell_scores(&loc.coarse_response, &loc.fix.coarse_grid, &loc.window_grid)
}

/// [`window_cell_scores`] of a response over grid `cg` for the windows of `wg`.
pub fn cell_scores(response: &[f32], cg: &Grid, wg: &Grid) -> Vec<f32> {
    let half = wg.step() as i64 / 2;
    let cell_of = |x: i64, y: i64| -> Option<usize> {
        // Cell (c, r) holds positions in [c step - half, c step + half).
        let c = (x + half).div_euclid(wg.step() as i64);
        let r = (y + half).div_euclid(wg.step() as i64);
        (c >= 0 && r >= 0 && (c as usize) < wg.cols() && (r as usize) < wg.rows())
            .then(|| r as usize * wg.cols() + c as usize)
    };
    let mut best = vec![f32::NEG_INFINITY; wg.len()];
    for (i, &s) in response.iter().enumerate().take(cg.len()) {
        let (x, y) = (
            (i % cg.cols() * cg.step()) as i64,
            (i / cg.cols() * cg.step()) as i64,
        );
        if let Some(k) = cell_of(x, y) {
            best[k] = best[k].max(s);
        }
    }
    best
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

/// Map georeference sidecar (`MAP.json` next to `MAP.png`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MapMeta {
    /// World east of the map's west edge, metres.
    pub origin_x_m: f64,
    /// World north of the map's north edge, metres.
    pub origin_y_m: f64,
    /// Metres per pixel.
    pub m_per_px: f64,
    /// Width, pixels (checked against the PNG).
    pub width_px: usize,
    /// Height, pixels (checked against the PNG).
    pub height_px: usize,
    /// World seed the map was rendered from, if any.
    #[serde(default)]
    pub world_seed: Option<u64>,
    /// Sun elevation and azimuth of the render, degrees, if any.
    #[serde(default)]
    pub sun_deg: Option<(f64, f64)>,
    /// For a map of a DEM world (`orbfix map --dem`): what to add to world `(x, y)` to get
    /// the GeoTIFFs' CRS `(easting, northing)`, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs_offset_m: Option<(f64, f64)>,
}

/// Loads `MAP.png` + `MAP.json`, checking the georeference and sizes.
pub fn load_map(png: &std::path::Path, meta: &std::path::Path) -> anyhow::Result<MapRegion> {
    let text = std::fs::read_to_string(meta).with_context(|| {
        format!(
            "cannot read the map georeference {} (write one with `orbfix map`)",
            meta.display()
        )
    })?;
    let m: MapMeta = serde_json::from_str(&text).with_context(|| {
        format!(
            "{} is not a map georeference (needs origin_x_m, origin_y_m, m_per_px, width_px, height_px)",
            meta.display()
        )
    })?;
    let geo = GeoRef::new(m.origin_x_m as f32, m.origin_y_m as f32, m.m_per_px as f32)
        .map_err(|e| anyhow::anyhow!("{}: bad georeference: {e}", meta.display()))?;
    let img = image::open(png)
        .with_context(|| format!("cannot read the map image {}", png.display()))?
        .to_luma8();
    if img.width() as usize != m.width_px || img.height() as usize != m.height_px {
        bail!(
            "{} is {} x {} px but {} says {} x {}",
            png.display(),
            img.width(),
            img.height(),
            meta.display(),
            m.width_px,
            m.height_px
        );
    }
    Ok(MapRegion {
        width: img.width() as usize,
        height: img.height() as usize,
        image: img.into_raw(),
        geo,
    })
}

/// Writes `bytes` to `path` atomically, only to a regular file or `-` (the one
/// implementation: [`crate::fsutil::write_atomic`]); creates the parent folder first.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    crate::fsutil::write_atomic(path, bytes)
}

/// Saves a gray or RGB image as PNG atomically.
pub fn save_png_atomic<P, C>(
    img: &image::ImageBuffer<P, C>,
    path: &std::path::Path,
) -> anyhow::Result<()>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png)
        .with_context(|| format!("cannot encode {}", path.display()))?;
    write_atomic(path, buf.get_ref())
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
            "x_m": c.x_m, "y_m": c.y_m, "score": c.score, "refined": c.refined
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
