//! `orbfix generate`: render a dataset of locations (views, satellite crops, manifest).

use anyhow::{ensure, Context};
use orbfix_host::dataset::{self, DegRange, DemSite, GenerateConfig, Preset, Shard};
use orbfix_host::world::dem::MapSource;
use std::path::PathBuf;

/// Render a dataset: per location the four ground views, the satellite crop (and optionally
/// range images and a point cloud), plus `manifest.jsonl` and `dataset.json` (docs/dataset.md).
/// Deterministic and resumable: run it again to continue an interrupted run.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  orbfix generate --preset smoke --seed 2 --out out/ds\n  \
                  orbfix generate --preset small --dem dem.tif --ortho ortho.tif --out out/site-ds\n  \
                  (a real site: views rendered over the DEM with the orthoimage as albedo, \
                  satellite crops from the orthoimage; docs/dataset.md)"
)]
pub struct Args {
    /// Size preset: smoke (seconds, CI), small (1,000 at 640x360), paper (606,000 at 1920x1080).
    #[arg(long, value_enum, default_value = "smoke")]
    preset: Preset,
    /// World and sampling seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output folder (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// View size WxH in pixels (overrides the preset), e.g. 640x360; up to 1920x1080 and beyond.
    #[arg(long, allow_hyphen_values = true)]
    size: Option<String>,
    /// Sun elevation of the ground views, degrees: A or a range A..B drawn per location.
    #[arg(long, default_value = "30", allow_hyphen_values = true)]
    sun_elevation: String,
    /// Sun azimuth of the ground views, degrees clockwise from north: A or A..B.
    #[arg(long, default_value = "135", allow_hyphen_values = true)]
    sun_azimuth: String,
    /// Sun elevation of the satellite crops (default: as --sun-elevation, drawn separately).
    #[arg(long, allow_hyphen_values = true)]
    map_sun_elevation: Option<String>,
    /// Sun azimuth of the satellite crops (default: as --sun-azimuth, drawn separately).
    #[arg(long, allow_hyphen_values = true)]
    map_sun_azimuth: Option<String>,
    /// Zero relief with the same albedo texture.
    #[arg(long)]
    flat: bool,
    /// A real DEM (single-band GeoTIFF, projected CRS in metres; docs/interop.md) instead of
    /// the procedural world, the same terrain `orbfix map --dem` and `orbfix eval --dem`
    /// use: locations are drawn inside it (--seed then only draws them). Needs --ortho.
    #[arg(long, requires = "ortho", conflicts_with_all = ["flat", "combine"])]
    dem: Option<PathBuf>,
    /// The orthoimage GeoTIFF of --dem (same CRS): the albedo of the views and, by default,
    /// the satellite crops.
    #[arg(long, requires = "dem")]
    ortho: Option<PathBuf>,
    /// With --dem: satellite crops are the orthoimage resampled to their grid (ortho, the
    /// default: what a mission has; --map-sun-* then has no effect and is refused) or the
    /// DEM rendered with the orthoimage as albedo under --map-sun-* (render).
    #[arg(long, value_enum, requires = "dem")]
    dem_map: Option<MapSource>,
    /// With --dem: metres every location keeps from the edges of the rasters' common region
    /// (default 150: a 300 m map around any location stays on them; at least half the
    /// satellite crop's side).
    #[arg(long, requires = "dem", allow_negative_numbers = true)]
    dem_margin: Option<f64>,
    /// Render only shard I of N (0-based, I < N), e.g. $SLURM_ARRAY_TASK_ID/$N; writes
    /// manifest-I-of-N.jsonl. Combine the shards with --combine afterwards.
    #[arg(long)]
    shard: Option<String>,
    /// Merge finished shard manifests of --out into manifest.jsonl and exit.
    #[arg(long)]
    combine: bool,
    /// Also write a 16-bit range image per view.
    #[arg(long)]
    range: bool,
    /// Also write a PLY point cloud per location (implies --range's rendering).
    #[arg(long)]
    point_cloud: bool,
    /// Also render each view's stereo partner (right camera, `--baseline` along the view
    /// camera's x axis) and write it beside the view as ID_VIEW_right.png.
    #[arg(long)]
    stereo: bool,
    /// Stereo baseline, metres (with --stereo).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = orbfix_host::render::stereo::DEFAULT_BASELINE_M)]
    baseline: f64,
    /// Gain of the right camera relative to the left, e.g. 1.02 (with --stereo).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 1.0)]
    right_gain: f64,
    /// Gaussian sensor noise, gray levels (standard deviation; 0 = none; each camera draws
    /// its own).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    noise: f64,
    /// Largest rover pitch and roll, degrees (each drawn in [-A, A] per location; 0 = level).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    max_attitude: f64,
    /// Number of locations (overrides the preset; split 93/5/2 %, at least one each).
    #[arg(long)]
    count: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Parses `WxH`.
pub fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("size '{s}' must be WxH, e.g. 640x360"))?;
    let w: u32 = w
        .trim()
        .parse()
        .with_context(|| format!("width '{w}' in --size {s} is not a positive whole number"))?;
    let h: u32 = h
        .trim()
        .parse()
        .with_context(|| format!("height '{h}' in --size {s} is not a positive whole number"))?;
    let min = orbfix::reproject::MIN_FRAME_PX;
    ensure!(
        w >= min && h >= min,
        "size {s}: the views must be at least {min}x{min} pixels (the smallest the reprojection can use)"
    );
    ensure!(w <= 8192 && h <= 8192, "size {s}: at most 8192 px per side");
    Ok((w, h))
}

/// Splits `n` locations 93 / 5 / 2 % with at least one per split.
pub fn split_counts(n: usize) -> anyhow::Result<[usize; 3]> {
    ensure!(
        n >= 3,
        "--count {n}: need at least 3 locations (one per split)"
    );
    let val = ((n as f64 * 0.05).round() as usize).max(1);
    let test = ((n as f64 * 0.02).round() as usize).max(1);
    Ok([n - val - test, val, test])
}

/// The config the arguments describe.
pub fn config(args: &Args) -> anyhow::Result<GenerateConfig> {
    let mut cfg = GenerateConfig::preset(args.preset, args.seed);
    if let Some(s) = &args.size {
        let (w, h) = parse_size(s)?;
        cfg.render.camera.width_px = w;
        cfg.render.camera.height_px = h;
    }
    if let Some(n) = args.count {
        cfg.counts = split_counts(n)?;
    }
    cfg.flat = args.flat;
    if let (Some(dem), Some(ortho)) = (&args.dem, &args.ortho) {
        let map = args.dem_map.unwrap_or_default();
        if map == MapSource::Ortho {
            anyhow::ensure!(
                args.map_sun_elevation.is_none() && args.map_sun_azimuth.is_none(),
                "--map-sun-elevation/--map-sun-azimuth have no effect with --dem: the satellite \
                 crops are the orthoimage, lit by its own sun; drop them, or add --dem-map render \
                 to render the DEM under that sun"
            );
        }
        let margin = args.dem_margin.unwrap_or(dataset::DEFAULT_DEM_MARGIN_M);
        cfg.dem = Some(DemSite::new(dem, ortho, map, margin)?);
    }
    cfg.sun_view_elevation = DegRange::parse(&args.sun_elevation).context("--sun-elevation")?;
    cfg.sun_view_azimuth = DegRange::parse(&args.sun_azimuth).context("--sun-azimuth")?;
    cfg.sun_map_elevation = match &args.map_sun_elevation {
        Some(s) => DegRange::parse(s).context("--map-sun-elevation")?,
        None => cfg.sun_view_elevation,
    };
    cfg.sun_map_azimuth = match &args.map_sun_azimuth {
        Some(s) => DegRange::parse(s).context("--map-sun-azimuth")?,
        None => cfg.sun_view_azimuth,
    };
    cfg.range = args.range || args.point_cloud;
    cfg.point_cloud = args.point_cloud;
    cfg.render.noise_sigma = args.noise;
    cfg.max_attitude_deg = args.max_attitude;
    if args.stereo {
        let rig = orbfix_host::render::stereo::StereoRender {
            baseline_m: args.baseline,
            right_gain: args.right_gain,
        };
        rig.validate().context("--baseline / --right-gain")?;
        cfg.stereo = Some(rig);
    }
    cfg.validate()?;
    Ok(cfg)
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.combine {
        let n = dataset::combine_shards(&args.out)?;
        println!(
            "combined {n} locations into {}",
            args.out.join("manifest.jsonl").display()
        );
        return Ok(());
    }
    let cfg = config(&args)?;
    let shard = args.shard.as_deref().map(Shard::parse).transpose()?;
    let t = std::time::Instant::now();
    let rep = dataset::generate(&cfg, &args.out, shard, !args.quiet)?;
    println!(
        "{} locations rendered, {} already complete, in {:.1} s; manifest {}",
        rep.rendered,
        rep.skipped,
        t.elapsed().as_secs_f64(),
        rep.manifest.display()
    );
    Ok(())
}
