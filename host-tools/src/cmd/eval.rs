//! `orbfix eval`: generated queries in the test zone through the whole pipeline (render,
//! reproject, localize), one JSON report per matcher, figures on request.

use anyhow::Context;
use orbfix::localize::LocalizeConfig;
use orbfix_host::eval::pipeline::{
    Condition, DepthSource, PipelineOptions, Reprojection, RoverAttitude,
};
use orbfix_host::eval::run::{run_eval, EvalConfig, EvalOutput};
use orbfix_host::eval::{
    figures, overlay, parse_matchers, save_png_atomic, write_atomic, FIX_OPTIONS, MATCHERS,
};
use orbfix_host::reproject::depth::StereoNoise;
use std::path::{Path, PathBuf};

/// The long help of `--matcher`: the matchers and every option a fix name may carry
/// ([`FIX_OPTIONS`], the list the parser checks).
fn matcher_help() -> String {
    format!(
        "Matcher, or a comma-separated list sharing the renders: fix (the flight core's one \
         fix, `orbfix::fix::run`: CNN over the map product's 4 m window records, the relief \
         stage with depth, masked NCC refinement, sub-pixel peak), fix-ncc (NCC refinement \
         always kept), cnn (the bare CNN: its sub-cell peak only); a fix name may carry \
         options that change one setting of the core's FixConfig, for tuning on a \
         development seed: {FIX_OPTIONS}; e.g. fix-p5 or fix-ra1-u20. The baselines run on \
         the core's top-down image. Available: {}.",
        MATCHERS.join(", ")
    )
}

/// Evaluate matchers on generated rover stops of the test zone (no dataset needed).
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example: orbfix eval --seed 1 --queries 30 --matcher ncc,l1,l2 --json out/eval.json --figures out/fig"
)]
pub struct Args {
    /// World seed (also seeds the queries).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of queries (rover stops).
    #[arg(long, default_value_t = 30)]
    pub queries: usize,
    /// Matcher, or a comma-separated list sharing the renders: fix (the flight core's one
    /// fix), fix-ncc, cnn, or a baseline; a fix name may carry options (see --help).
    #[arg(long, default_value = "fix", long_help = matcher_help())]
    pub matcher: String,
    /// CNN weight file (.ofw) for the fix matchers and their map products (default: the
    /// shipped weights/matcher-v2.ofw).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Lighting: same-sun (the study's: 30 deg elevation, azimuth 135 deg) or cross-sun
    /// (map and rover suns drawn independently: elevation 20-60 deg, azimuths 60-180 deg apart).
    #[arg(long, value_enum, default_value_t = Condition::SameSun)]
    pub condition: Condition,
    /// Report file (JSON): one object for one matcher, an array for several.
    #[arg(long)]
    pub json: PathBuf,
    /// Folder for figures (score distributions, ROC, error CDF, example localizations).
    #[arg(long)]
    pub figures: Option<PathBuf>,
    /// Coarse factor of the dense pass (8 at 0.25 m/px = 2 m/px).
    #[arg(long, default_value_t = 8)]
    pub coarse_factor: usize,
    /// Fine factor of the refinement (2 = 0.5 m/px).
    #[arg(long, default_value_t = 2)]
    pub fine_factor: usize,
    /// Example localizations drawn into --figures.
    #[arg(long, default_value_t = 3)]
    pub examples: usize,
    /// Depth of the top-down reprojection: stereo (the rover's own stereo pairs, right
    /// views rendered too, matched by the core inside the fix: its `stereo` stage), truth
    /// (the renderer's exact depth images, as an external stereo engine would give them) or
    /// none (flat ground: the flight core's lookup table).
    #[arg(long, value_enum, default_value_t = DepthSource::Stereo)]
    pub depth: DepthSource,
    /// Older spelling of --depth: range = truth, lut = none, stereo = stereo.
    #[arg(long, value_enum, conflicts_with = "depth")]
    pub reprojection: Option<Reprojection>,
    /// Stereo baseline of the rendered pairs and the matcher, metres (--depth stereo).
    #[arg(long, default_value_t = orbfix_host::render::stereo::DEFAULT_BASELINE_M)]
    pub baseline: f64,
    /// Stereo depth noise of the range path: sigma = K * z^2 metres at depth z metres
    /// (e.g. 0.001: 10 cm at 10 m); 0 = exact depths (millimetre quantized).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::non_negative_f64, default_value_t = 0.0)]
    pub depth_noise_k: f64,
    /// With --depth truth: the exact depth only at pixels whose 15 x 15 window of the frame
    /// has a gray-level standard deviation of at least GRAY (e.g. 1): what an ideal stereo
    /// engine could give at best, nothing in black shadow or on featureless ground. Without
    /// it the exact depth is everywhere, shadows included.
    #[arg(long, value_name = "GRAY", allow_negative_numbers = true, value_parser = crate::cmd::num::non_negative_f64)]
    pub truth_min_texture: Option<f64>,
    /// Range path: largest column stride (1 = every pixel; up to 16: rows near the mast
    /// read every s-th pixel, at most half a cell apart on flat ground; 4 = the fix's default).
    #[arg(long, default_value_t = 4)]
    pub column_stride: u8,
    /// How the rover stands at each stop: level whatever the slope, or pitched and rolled
    /// by the terrain under its wheels (2 m wheelbase and track); the fix is given the
    /// attitude, as the rover's inertial unit would measure it.
    #[arg(long, value_enum, default_value_t = RoverAttitude::Level)]
    pub rover_attitude: RoverAttitude,
    /// With --rover-attitude terrain: only stops where the rover tilts at most this many
    /// degrees from level (terrain it could drive onto; e.g. 20); the query stream's steeper
    /// stops are skipped, the kept ones keep their numbers. Without it every stop counts,
    /// however steep (the world's test zone reaches 40-50 deg at rover scale).
    #[arg(long, value_name = "DEG")]
    pub max_tilt: Option<f64>,
    /// Diagnostic: a world with zero relief and the same albedo.
    #[arg(long)]
    pub flat_world: bool,
    /// A real DEM (single-band GeoTIFF, projected CRS in metres) instead of the built-in
    /// world; rover stops are drawn inside it (docs/interop.md). Needs --ortho.
    #[arg(long, requires = "ortho", conflicts_with = "flat_world")]
    pub dem: Option<PathBuf>,
    /// The orthoimage GeoTIFF drawn as albedo over --dem.
    #[arg(long, requires = "dem")]
    pub ortho: Option<PathBuf>,
    /// With --dem: the orbital map (and the fix's map product) is the orthoimage resampled to
    /// the map grid (ortho, the default: what a mission has; the map sun of --condition then
    /// has no effect) or the DEM rendered with the orthoimage as albedo under the map sun
    /// (render).
    #[arg(long, value_enum, requires = "dem")]
    pub dem_map: Option<orbfix_host::world::dem::MapSource>,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        a.depth_noise_k.is_finite() && (0.0..=1.0).contains(&a.depth_noise_k),
        "--depth-noise-k must be in 0..=1 (1/metres), got {}",
        a.depth_noise_k
    );
    anyhow::ensure!(
        a.baseline.is_finite() && a.baseline > 0.0 && a.baseline <= 10.0,
        "--baseline must be a distance in (0, 10] metres, got {}",
        a.baseline
    );
    anyhow::ensure!(
        (1..=16).contains(&a.column_stride),
        "--column-stride must be in 1..=16, got {}",
        a.column_stride
    );
    if let Some(t) = a.max_tilt {
        anyhow::ensure!(
            t.is_finite() && t > 0.0 && t < 90.0,
            "--max-tilt must be an angle in (0, 90) degrees, got {t}"
        );
        anyhow::ensure!(
            a.rover_attitude == RoverAttitude::Terrain,
            "--max-tilt selects stops by the slope the rover stands on: it needs --rover-attitude terrain"
        );
        anyhow::ensure!(
            a.dem.is_none(),
            "--max-tilt is for the built-in world's stops, not --dem"
        );
    }
    anyhow::ensure!(
        a.truth_min_texture.is_none()
            || a.reprojection.unwrap_or(a.depth.reprojection()) == Reprojection::Range,
        "--truth-min-texture masks the renderer's exact depth: it needs --depth truth"
    );
    let matchers = parse_matchers(&a.matcher)
        .with_context(|| format!("--matcher (available: {})", MATCHERS.join(", ")))?;
    let cfg = EvalConfig {
        seed: a.seed,
        queries: a.queries,
        condition: a.condition,
        matchers,
        localize: LocalizeConfig {
            coarse_factor: a.coarse_factor,
            fine_factor: a.fine_factor,
            ..LocalizeConfig::default()
        },
        stride_px: 50,
        pipeline: PipelineOptions {
            reprojection: a.reprojection.unwrap_or(a.depth.reprojection()),
            stereo_rig: orbfix_host::render::stereo::StereoRender {
                baseline_m: a.baseline,
                ..Default::default()
            },
            depth_noise: (a.depth_noise_k > 0.0).then_some(StereoNoise {
                k_per_m: a.depth_noise_k,
                seed: a.seed,
            }),
            range: orbfix::reproject::RangeOptions {
                max_column_stride: a.column_stride,
                ..Default::default()
            },
            attitude: a.rover_attitude,
            truth_min_texture: a.truth_min_texture,
            ..PipelineOptions::default()
        },
        keep_examples: if a.figures.is_some() { a.examples } else { 0 },
        flat_world: a.flat_world,
        weights: load_weights(a.weights.as_deref())?,
        max_tilt_deg: a.max_tilt,
    };
    let out = match (&a.dem, &a.ortho) {
        (Some(dem), Some(ortho)) => {
            let mut world = orbfix_host::world::World::from_geotiff(dem, ortho)?;
            world.set_dem_map_source(a.dem_map.unwrap_or_default());
            let margin = orbfix_host::eval::pipeline::PRIOR_OFFSET_M
                + 0.5 * cfg.pipeline.map_px as f64 * cfg.pipeline.grid.m_per_px as f64;
            let zone = world.dem().and_then(|d| d.location_zone(margin)).with_context(|| {
                format!("the DEM and orthoimage overlap less than {} m per side (rover stops keep {margin} m from their edges)", 2.0 * margin)
            })?;
            let queries = orbfix_host::eval::pipeline::make_queries_in(
                &zone,
                0.0,
                cfg.seed,
                cfg.queries,
                cfg.condition,
            );
            orbfix_host::eval::run::run_eval_on(&world, &queries, &cfg, !a.quiet)?
        }
        _ => run_eval(&cfg, !a.quiet)?,
    };
    print_table(&out);
    let json = if out.reports.len() == 1 {
        serde_json::to_string_pretty(&out.reports[0])?
    } else {
        serde_json::to_string_pretty(&out.reports)?
    };
    write_atomic(&a.json, json.as_bytes())?;
    println!("report: {}", a.json.display());
    if let Some(dir) = &a.figures {
        write_figures(&out, dir)?;
        println!("figures: {}", dir.display());
    }
    Ok(())
}

/// The bytes of a weight file, validated (`None`: the shipped weights).
pub fn load_weights(path: Option<&Path>) -> anyhow::Result<Vec<u8>> {
    orbfix_host::nn::weights_file::load_bytes(path)
}

/// One line per matcher.
pub fn print_table(out: &EvalOutput) {
    println!(
        "{:<12} {:<9} {:>4} {:>6} {:>6} {:>6} {:>7} {:>7} {:>7} {:>9} {:>8} {:>6} {:>6} {:>7}",
        "matcher",
        "condition",
        "n",
        "R@1",
        "R@5",
        "R@10",
        "dR@1",
        "dR@5",
        "dR@10",
        "median m",
        "p95 m",
        "AUC",
        "err",
        "border"
    );
    println!("R@k: true window among the k best of the study's windows (each scored at its position); dR@k: windows ranked by their cell's best dense score");
    for r in &out.reports {
        println!(
            "{:<12} {:<9} {:>4} {:>6.3} {:>6.3} {:>6.3} {:>7.3} {:>7.3} {:>7.3} {:>9.2} {:>8.2} {:>6.3} {:>6.3} {:>7}",
            r.matcher,
            r.condition,
            r.queries,
            r.recall_at["1"],
            r.recall_at["5"],
            r.recall_at["10"],
            r.recall_at_dense["1"],
            r.recall_at_dense["5"],
            r.recall_at_dense["10"],
            r.median_error_m,
            r.p95_error_m,
            r.pairs.auc,
            r.pairs.error_rate,
            r.border_rejections
        );
    }
    println!(
        "{:<12} {:>7} {:>7} {:>9} {:>8} {:>9} {:>11} {:>9} {:>9}",
        "matcher",
        "<=1 m",
        "<=5 m",
        "median m",
        "p95 m",
        "accepted",
        "wrong-conf",
        "bound ok",
        "ms/fix"
    );
    for r in &out.reports {
        let (acc, wrong, cover) = match &r.fix {
            Some(f) => (
                format!("{:.3}", f.accepted_share),
                format!("{}", f.wrong_confident),
                format!("{:.3}", f.bound_coverage),
            ),
            None => ("-".into(), "-".into(), "-".into()),
        };
        println!(
            "{:<12} {:>7.3} {:>7.3} {:>9.3} {:>8.2} {:>9} {:>11} {:>9} {:>9.1}",
            r.matcher,
            r.within_m["1"],
            r.within_m["5"],
            r.median_error_m,
            r.p95_error_m,
            acc,
            wrong,
            cover,
            1000.0 * r.mean_dense_s
        );
    }
}

/// Score histograms, ROC, error CDF and example localizations.
pub fn write_figures(out: &EvalOutput, dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut rocs = Vec::new();
    let mut cdfs = Vec::new();
    for r in &out.reports {
        let pos: Vec<f64> = r.per_query.iter().map(|q| q.match_score).collect();
        let neg: Vec<f64> = r.per_query.iter().map(|q| q.nonmatch_score).collect();
        figures::score_histograms(
            &dir.join(format!("scores_{}_{}.svg", r.matcher, r.condition)),
            &r.matcher,
            &pos,
            &neg,
        )?;
        rocs.push((r.matcher.clone(), pos, neg));
        cdfs.push((
            r.matcher.clone(),
            r.per_query.iter().map(|q| q.error_m).collect(),
        ));
    }
    let cond = out
        .reports
        .first()
        .map(|r| r.condition.as_str())
        .unwrap_or("eval");
    figures::roc_curves(&dir.join(format!("roc_{cond}.svg")), &rocs)?;
    figures::error_cdfs(&dir.join(format!("error_cdf_{cond}.svg")), &cdfs)?;
    for ex in &out.examples {
        let id = ex.query.id;
        save_png_atomic(
            &overlay::top_down_picture(&ex.top),
            &dir.join(format!("example_{cond}_{id:03}_topdown.png")),
        )?;
        // The map under the truth, the same size as the top-down image, for comparison.
        let (c, r) = ex
            .map
            .geo
            .to_pixel(ex.query.x_m as f32, ex.query.y_m as f32);
        let n = ex.top.n;
        let c0 = (c.round() as i64 - n as i64 / 2).clamp(0, (ex.map.width - n) as i64) as u32;
        let r0 = (r.round() as i64 - n as i64 / 2).clamp(0, (ex.map.height - n) as i64) as u32;
        if let Some(full) = image::GrayImage::from_raw(
            ex.map.width as u32,
            ex.map.height as u32,
            ex.map.image.clone(),
        ) {
            let crop = image::imageops::crop_imm(&full, c0, r0, n as u32, n as u32).to_image();
            save_png_atomic(
                &crop,
                &dir.join(format!("example_{cond}_{id:03}_map_at_truth.png")),
            )?;
        }
        for (r, loc) in out.reports.iter().zip(&ex.locs) {
            let pic = overlay::map_picture(
                &ex.map,
                loc,
                ex.top.n,
                Some((ex.query.x_m, ex.query.y_m)),
                (ex.query.prior_x_m, ex.query.prior_y_m),
                2,
            );
            save_png_atomic(
                &pic,
                &dir.join(format!("example_{cond}_{id:03}_{}.png", r.matcher)),
            )?;
        }
    }
    Ok(())
}
