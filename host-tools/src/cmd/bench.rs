//! `orbfix bench`: speed of the parts, beside the anchors.

use orbfix::geo::GeoRef;
use orbfix_host::render::{self, RenderOptions, Sun};
use orbfix_host::world::World;
use std::time::Instant;

/// Measure speed and print it beside the anchor as a ratio.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to measure. world: locations per second rendered (4 views + satellite crop),
    /// beside the study's Unreal pipeline (60 frames/s = 15 locations/s on a GTX 1080).
    #[arg(value_enum)]
    target: Target,
    /// View size WxH.
    #[arg(long, default_value = "640x360")]
    size: String,
    /// Locations to render.
    #[arg(long, default_value_t = 12)]
    locations: usize,
    /// Also time a 1200 x 1200 map at 0.25 m/px.
    #[arg(long)]
    map: bool,
    /// Sample far terrain afresh for every location (no tile cache shared between them).
    #[arg(long)]
    no_cache: bool,
    /// World seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// reproject: timed repetitions of the table apply and of OpenCV's remap.
    #[arg(long, default_value_t = 2000)]
    reps: usize,
    /// world: also time stereo pairs (4 left + 4 right views + satellite crop), beside mono.
    #[arg(long)]
    stereo: bool,
    /// stereo: baseline, metres (also the world bench's with --stereo).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = orbfix_host::render::stereo::DEFAULT_BASELINE_M)]
    baseline: f64,
    /// stereo: gain of the right camera relative to the left.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 1.02)]
    right_gain: f64,
    /// stereo: Gaussian sensor noise of each camera, gray levels.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::non_negative_f64, default_value_t = 1.0)]
    noise: f64,
    /// stereo: output band of the core, rows.
    #[arg(long, default_value_t = 16)]
    band_rows: usize,
    /// stereo: output folder of the benchmark set (pairs, truth, masks, core disparity,
    /// index.json) that scripts/stereo_bench.py scores.
    #[arg(long, default_value = ".cache/stereo-bench")]
    out: std::path::PathBuf,
    // stereo: the matcher's settings (each defaults to the core's).
    #[command(flatten)]
    matcher: StereoMatcherArgs,
}

/// The stereo matcher's options of `bench stereo`, a group of their own (clap builds each
/// group's argument table in its own function, which keeps every frame small).
#[derive(clap::Args, Debug)]
#[command(next_help_heading = "Stereo matcher (bench stereo; defaults: the core's)")]
struct StereoMatcherArgs {
    /// stereo: reduction of the frames before matching (1..=4).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().downsample)]
    downsample: u8,
    /// stereo: aggregation radius, pixels at the working size (window 2r + 1).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().radius_px)]
    radius: u8,
    /// stereo: the runner-up must be this many percent worse than the winner (0..=50).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().uniqueness_pct)]
    uniqueness: u8,
    /// stereo: the runner-up must be this many cost units per window pixel worse (0..=16).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().min_gap_per_px)]
    min_gap: u8,
    /// stereo: neighbours (of 8) within 1 px a disparity needs (0..=8).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().min_support)]
    min_support: u8,
    /// stereo: gaps of at most N working pixels in a row, between two disparities that
    /// agree within 1 px, take their blend (0: off).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().gap_fill_px)]
    gap_fill: u8,
    /// stereo: relief searched above the ground under the rover, metres (the disparity
    /// range of each row follows from it; docs/stereo.md).
    #[arg(long, allow_negative_numbers = true, default_value_t = orbfix::stereo::StereoParams::default().relief_above_m)]
    relief_above: f32,
    /// stereo: relief searched above the ground near the rover, metres, growing by
    /// --relief-above-grade metres per metre of depth up to --relief-above (default: off).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().relief_above_near_m)]
    relief_above_near: f32,
    /// stereo: grade of the relief above with depth, metres per metre.
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().relief_above_grade)]
    relief_above_grade: f32,
    /// stereo: the horizon rows (flat ground beyond the range) search terrain rising this
    /// many metres per metre of depth (0: off; docs/stereo.md).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().horizon_grade)]
    horizon_grade: f32,
    /// stereo: the horizon rows matched at level 1, half the working size (with
    /// --horizon-grade above 0; true/false; docs/stereo.md).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().horizon_coarse, action = clap::ArgAction::Set)]
    horizon_coarse: bool,
    /// stereo: relief searched below the ground under the rover, metres.
    #[arg(long, allow_negative_numbers = true, default_value_t = orbfix::stereo::StereoParams::default().relief_below_m)]
    relief_below: f32,
    /// stereo: pitch and roll margin around the rover's attitude, degrees.
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().attitude_margin_deg)]
    attitude_margin: f32,
    /// stereo: coarser scales near rows may be matched at (0..=2; 0: every row at the
    /// working size).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().scale_levels)]
    scale_levels: u8,
    /// stereo: a row goes to a coarser scale only where a quarter-pixel disparity error
    /// there moves its flat ground by at most this, metres.
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().scale_error_m)]
    scale_error: f32,
    /// stereo: rows reduced this many times more than columns (1 or 2; docs/stereo.md,
    /// "Rows reduced twice").
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().row_factor)]
    row_factor: u8,
    /// stereo: every N-th column of a row decided (1 or 2; 2: the window slides over every
    /// column, the columns between take their neighbours' mean where they agree).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().column_step)]
    column_step: u8,
    /// stereo: every N-th column decided in the near rows (1..=4, at least --column-step;
    /// the rows where N columns span at most --near-column-span metres of flat ground).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().near_column_step)]
    near_column_step: u8,
    /// stereo: ground span, metres, of --near-column-step columns up to which a row is
    /// near (0: none).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().near_column_span_m)]
    near_column_span: f32,
    /// stereo: working rows matched in pairs where a pair spans at most this many metres of
    /// flat ground down the image (0: none).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().pair_rows_m)]
    pair_rows: f32,
    /// stereo: aggregation radius down in the paired rows, pairs (1..=--radius-rows).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().pair_radius_rows_px)]
    pair_radius_rows: u8,
    /// stereo: aggregation radius down, rows of the level image (1..=7).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().radius_rows_px)]
    radius_rows: u8,
    /// stereo: sub-pixel fit of the winner's disparity.
    #[arg(long, value_enum, default_value_t = SubPixelArg::from(orbfix::stereo::StereoParams::default().subpixel))]
    subpixel: SubPixelArg,
    /// stereo: windows that follow the flat ground down the image (true/false).
    #[arg(long, default_value_t = orbfix::stereo::StereoParams::default().ground_shear, action = clap::ArgAction::Set)]
    ground_shear: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum Target {
    /// The world renderer.
    World,
    /// The core's LUT reprojection (apply vs f64 reference vs OpenCV remap; table bytes and
    /// build time).
    Reproject,
    /// The core's stereo matcher on world-rendered pairs: writes the benchmark set that
    /// scripts/stereo-bench.sh scores against OpenCV (docs/stereo.md).
    Stereo,
}

/// CPU time (user + system) of this process so far, seconds.
pub fn cpu_seconds() -> f64 {
    // Safety: getrusage only writes the struct we pass; zeroed is a valid rusage.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    // Safety: RUSAGE_SELF with a valid pointer to a rusage.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return f64::NAN;
    }
    let t = |v: libc::timeval| v.tv_sec as f64 + 1e-6 * v.tv_usec as f64;
    t(u.ru_utime) + t(u.ru_stime)
}

/// The study's rendering rate: 60 frames/s, 4 frames per location.
pub const ANCHOR_LOCATIONS_PER_S: f64 = 15.0;

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.target {
        Target::World => bench_world(&args),
        Target::Reproject => bench_reproject(&args),
        Target::Stereo => bench_stereo(&args),
    }
}

impl StereoMatcherArgs {
    /// The matcher settings of these options (each defaults to the core's default).
    fn params(&self) -> orbfix::stereo::StereoParams {
        orbfix::stereo::StereoParams {
            downsample: self.downsample,
            radius_px: self.radius,
            uniqueness_pct: self.uniqueness,
            min_gap_per_px: self.min_gap,
            min_support: self.min_support,
            gap_fill_px: self.gap_fill,
            relief_above_m: self.relief_above,
            relief_above_near_m: self.relief_above_near,
            relief_above_grade: self.relief_above_grade,
            horizon_grade: self.horizon_grade,
            horizon_coarse: self.horizon_coarse,
            relief_below_m: self.relief_below,
            attitude_margin_deg: self.attitude_margin,
            scale_levels: self.scale_levels,
            scale_error_m: self.scale_error,
            row_factor: self.row_factor,
            column_step: self.column_step,
            near_column_step: self.near_column_step,
            near_column_span_m: self.near_column_span,
            pair_rows_m: self.pair_rows,
            pair_radius_rows_px: self.pair_radius_rows,
            radius_rows_px: self.radius_rows,
            subpixel: self.subpixel.into(),
            ground_shear: self.ground_shear,
            ..Default::default()
        }
    }
}

fn bench_stereo(args: &Args) -> anyhow::Result<()> {
    let (w, h) = super::generate::parse_size(&args.size)?;
    let mut render = RenderOptions::default();
    render.camera.width_px = w;
    render.camera.height_px = h;
    render.noise_sigma = args.noise;
    let rig = orbfix_host::render::stereo::StereoRender {
        baseline_m: args.baseline,
        right_gain: args.right_gain,
    };
    rig.validate()?;
    let params = args.matcher.params();
    let opts = orbfix_host::stereo_bench::StereoBenchOptions {
        seed: args.seed,
        locations: args.locations,
        render,
        rig,
        params,
        half_square_m: 25.0,
        band_rows: args.band_rows,
        out: args.out.clone(),
    };
    let ix = orbfix_host::stereo_bench::run(&opts)?;
    println!(
        "bench stereo: {} pairs at {}x{} -> {}x{} (downsample {}), baseline {} m, noise {} gray, right gain {}",
        ix.entries.len(),
        w,
        h,
        ix.size[0],
        ix.size[1],
        ix.downsample,
        ix.baseline_m,
        ix.noise_sigma,
        ix.right_gain
    );
    println!(
        "  core: {:.2} ms per view (1 thread), {:.0} pixel-disparities and {:.0} column-cost updates per view ({:.2} M pixel-disparities for 4 views), working memory {} bytes + output band {} bytes ({} rows)",
        ix.core_ms_per_view,
        ix.core_pixel_disparities_per_view,
        ix.core_cost_updates_per_view,
        4.0 * ix.core_pixel_disparities_per_view / 1e6,
        ix.core_working_bytes,
        ix.core_band_bytes,
        ix.band_rows
    );
    println!(
        "  set written to {}",
        orbfix_host::stereo_bench::index_path(&args.out).display()
    );
    Ok(())
}

fn bench_world(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.locations > 0, "--locations must be at least 1");
    let (w, h) = super::generate::parse_size(&args.size)?;
    let world = World::new(args.seed);
    let mut opts = RenderOptions::default();
    opts.camera.width_px = w;
    opts.camera.height_px = h;
    opts.validate()?;
    let sun = Sun::default();
    let threads = rayon::current_num_threads();
    // Warm-up (page faults, thread pool).
    let p = render::ground_pose(&world, 1000.0, 1000.0, 0.0);
    render::render_views(&world, &p, sun, &opts)?;
    if args.stereo {
        let rig = orbfix_host::render::stereo::StereoRender {
            baseline_m: args.baseline,
            right_gain: args.right_gain,
        };
        rig.validate()?;
        let mono = world_rate(&world, &opts, sun, args, None)?;
        let st = world_rate(&world, &opts, sun, args, Some(rig))?;
        println!(
            "bench world: {} locations at {w}x{h}, {threads} threads, mono then stereo in one run",
            args.locations
        );
        for (name, (rate, tv, ts, cpu)) in [("mono (4 views)", mono), ("stereo (4 pairs)", st)] {
            println!(
                "  {name}: {rate:.2} locations/s wall, {:.2} locations/s on {threads} unshared cores (threads / CPU time); views {:.1} ms + satellite {:.1} ms per location, CPU {:.0} ms per location",
                threads as f64 / cpu,
                1e3 * tv,
                1e3 * ts,
                1e3 * cpu
            );
        }
        println!("  stereo / mono time per location: {:.2}x", mono.0 / st.0);
        let parts = stereo_parts(&world, &opts, sun, args, &rig)?;
        println!(
            "  stereo CPU per location by part (a third pass, same locations, own cache): terrain levels {:.0} ms, shadows {:.0} ms, node attributes {:.0} ms, near-field texture {:.0} ms, raster 8 views {:.0} ms, satellite crop {:.0} ms; total {:.0} ms",
            1e3 * parts[0],
            1e3 * parts[1],
            1e3 * parts[2],
            1e3 * parts[3],
            1e3 * parts[4],
            1e3 * parts[5],
            1e3 * parts.iter().sum::<f64>()
        );
        return Ok(());
    }
    let cache = render::terrain::TileCache::new(1 << 26);
    let mut t_views = 0.0;
    let mut t_sat = 0.0;
    let t0 = Instant::now();
    let c0 = cpu_seconds();
    for i in 0..args.locations {
        let x = 300.0 + 97.0 * i as f64;
        let y = 400.0 + 61.0 * i as f64;
        let pose = render::ground_pose(&world, x, y, 37.0 * i as f64);
        let t = Instant::now();
        let v = if args.no_cache {
            render::render_views(&world, &pose, sun, &opts)?
        } else {
            render::render_views_cached(&world, &pose, sun, &opts, Some(&cache))?.views
        };
        t_views += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let c = (!args.no_cache).then_some(&cache);
        let s = render::render_satellite_crop_cached(&world, x, y, 200, 0.25, sun, &opts, c)?;
        t_sat += t.elapsed().as_secs_f64();
        std::hint::black_box((v, s));
    }
    let total = t0.elapsed().as_secs_f64();
    let cpu = (cpu_seconds() - c0) / args.locations as f64;
    let rate = args.locations as f64 / total;
    // What the cores would give if nobody else used them: threads / CPU-seconds per location.
    let rate_cpu = threads as f64 / cpu;
    println!("bench world: {} locations at {w}x{h} (4 views + 200x200 satellite crop), {threads} threads", args.locations);
    println!(
        "  views {:.1} ms/location, satellite {:.1} ms/location",
        1e3 * t_views / args.locations as f64,
        1e3 * t_sat / args.locations as f64
    );
    println!(
        "  CPU {:.0} ms per location; load average {}",
        1e3 * cpu,
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .split_whitespace()
            .next()
            .unwrap_or("?")
    );
    println!(
        "  orbfix {rate:.2} locations/s wall | anchor (Unreal, GTX 1080) {ANCHOR_LOCATIONS_PER_S:.0} locations/s | ratio {:.3}x",
        rate / ANCHOR_LOCATIONS_PER_S
    );
    println!(
        "  orbfix {rate_cpu:.2} locations/s on {threads} unshared cores (threads / CPU time) | ratio {:.3}x",
        rate_cpu / ANCHOR_LOCATIONS_PER_S
    );
    // Where the time goes, one location, phase by phase.
    let pose = render::ground_pose(&world, 1234.0, 876.0, 10.0);
    let params = opts.camera_params();
    let t = Instant::now();
    let terrain = render::terrain::Terrain::around(
        &world,
        pose.x_m as f64,
        pose.y_m as f64,
        &opts,
        params.focal_px() as f64,
    );
    let t_terrain = t.elapsed().as_secs_f64();
    let nodes: usize = terrain.levels.iter().map(|l| l.grid.nx * l.grid.ny).sum();
    let t = Instant::now();
    let shadow = render::shadow::ShadowField::build(&terrain, &sun, opts.shadow_reach_m);
    let t_shadow = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let attrs = render::raster::NodeAttrs::compute(&terrain, &shadow);
    let t_attrs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let detail = render::near_field_detail(&world, &pose, &terrain, &sun, &opts);
    let t_detail = t.elapsed().as_secs_f64();
    let cam = orbfix::camera::Camera::new(&params, &pose, orbfix::camera::View::Front)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let t = Instant::now();
    std::hint::black_box(render::raster::render_view(
        &terrain,
        &attrs,
        detail.as_ref(),
        &cam,
        &sun,
        &opts,
    ));
    let t_view = t.elapsed().as_secs_f64();
    println!(
        "  breakdown (one location): terrain sampling {:.0} ms ({} levels, {} nodes), shadows {:.0} ms, normals {:.0} ms, near-field texture {:.0} ms, raster {:.0} ms per view (x4)",
        1e3 * t_terrain,
        terrain.levels.len(),
        nodes,
        1e3 * t_shadow,
        1e3 * t_attrs,
        1e3 * t_detail,
        1e3 * t_view
    );
    if args.map {
        let geo = GeoRef::centred(1000.0, 1000.0, 1200, 1200, 0.25)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let t = Instant::now();
        let m = render::render_ortho(&world, &geo, 1200, 1200, sun, &opts)?;
        std::hint::black_box(m);
        println!(
            "  map 1200x1200 at 0.25 m/px: {:.0} ms",
            1e3 * t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Locations per second (wall), views and satellite seconds per location, CPU seconds per
/// location, of mono views or stereo pairs (`rig`), each pass with its own cache.
fn world_rate(
    world: &World,
    opts: &RenderOptions,
    sun: Sun,
    args: &Args,
    rig: Option<orbfix_host::render::stereo::StereoRender>,
) -> anyhow::Result<(f64, f64, f64, f64)> {
    let cache = render::terrain::TileCache::new(1 << 26);
    let (mut t_views, mut t_sat) = (0.0, 0.0);
    let t0 = Instant::now();
    let c0 = cpu_seconds();
    for i in 0..args.locations {
        let x = 300.0 + 97.0 * i as f64;
        let y = 400.0 + 61.0 * i as f64;
        let pose = render::ground_pose(world, x, y, 37.0 * i as f64);
        let c = (!args.no_cache).then_some(&cache);
        let t = Instant::now();
        match &rig {
            Some(r) => {
                let s = render::stereo::render_stereo_views(world, &pose, sun, opts, r, c)?;
                std::hint::black_box(s);
            }
            None => {
                std::hint::black_box(render::render_views_cached(world, &pose, sun, opts, c)?);
            }
        }
        t_views += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let s = render::render_satellite_crop_cached(world, x, y, 200, 0.25, sun, opts, c)?;
        t_sat += t.elapsed().as_secs_f64();
        std::hint::black_box(s);
    }
    let n = args.locations as f64;
    Ok((
        n / t0.elapsed().as_secs_f64(),
        t_views / n,
        t_sat / n,
        (cpu_seconds() - c0) / n,
    ))
}

/// CPU seconds per location of each part of a stereo location, run part by part as
/// `render_stereo_views` runs them (terrain levels with the shared cache, shadow sweep, node
/// attributes, the near-field texture, the 8 views with their quantization, the satellite
/// crop).
fn stereo_parts(
    world: &World,
    opts: &RenderOptions,
    sun: Sun,
    args: &Args,
    rig: &orbfix_host::render::stereo::StereoRender,
) -> anyhow::Result<[f64; 6]> {
    use rayon::prelude::*;
    let cache = render::terrain::TileCache::new(1 << 26);
    let params = opts.camera_params();
    let mut cpu = [0.0f64; 6];
    for i in 0..args.locations {
        let x = 300.0 + 97.0 * i as f64;
        let y = 400.0 + 61.0 * i as f64;
        let pose = render::ground_pose(world, x, y, 37.0 * i as f64);
        let c = (!args.no_cache).then_some(&cache);
        let mut c0 = cpu_seconds();
        let mut lap = |k: usize| {
            let c1 = cpu_seconds();
            cpu[k] += c1 - c0;
            c0 = c1;
        };
        let terrain =
            render::terrain::Terrain::around_cached(world, x, y, opts, params.focal_px() as f64, c);
        lap(0);
        let shadow = render::shadow::ShadowField::build(&terrain, &sun, opts.shadow_reach_m);
        lap(1);
        let attrs = render::raster::NodeAttrs::compute(&terrain, &shadow);
        lap(2);
        let detail = render::near_field_detail(world, &pose, &terrain, &sun, opts);
        lap(3);
        let lefts = render::view_cameras(&pose, opts)?;
        let cams: Vec<_> = lefts
            .iter()
            .copied()
            .chain(
                lefts
                    .iter()
                    .map(|l| render::stereo::right_camera(l, rig.baseline_m)),
            )
            .collect();
        let out: Vec<_> = cams
            .par_iter()
            .enumerate()
            .map(|(k, cam)| {
                let (gray, range) =
                    render::raster::render_view(&terrain, &attrs, detail.as_ref(), cam, &sun, opts);
                (
                    opts.finish(cam.width_px, cam.height_px, &gray, k as u64),
                    range,
                )
            })
            .collect();
        std::hint::black_box(out);
        lap(4);
        let s = render::render_satellite_crop_cached(world, x, y, 200, 0.25, sun, opts, c)?;
        std::hint::black_box(s);
        lap(5);
    }
    Ok(cpu.map(|v| v / args.locations as f64))
}

fn bench_reproject(args: &Args) -> anyhow::Result<()> {
    let (w, h) = super::generate::parse_size(&args.size)?;
    orbfix_host::reproject::bench::run(&orbfix_host::reproject::bench::BenchOptions {
        width_px: w,
        height_px: h,
        reps: args.reps,
        ..Default::default()
    })
}

/// `--subpixel`: the core's sub-pixel fit ([`orbfix::stereo::SubPixel`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SubPixelArg {
    /// The parabola through the winner's cost and its neighbours'.
    Parabola,
    /// Equiangular (V) line fitting.
    Equiangular,
}

impl From<orbfix::stereo::SubPixel> for SubPixelArg {
    fn from(s: orbfix::stereo::SubPixel) -> Self {
        match s {
            orbfix::stereo::SubPixel::Parabola => Self::Parabola,
            orbfix::stereo::SubPixel::Equiangular => Self::Equiangular,
        }
    }
}

impl From<SubPixelArg> for orbfix::stereo::SubPixel {
    fn from(s: SubPixelArg) -> Self {
        match s {
            SubPixelArg::Parabola => Self::Parabola,
            SubPixelArg::Equiangular => Self::Equiangular,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    #[test]
    fn bench_stereo_defaults_are_the_cores() {
        let cli = Cli::try_parse_from(["bench", "stereo"]).unwrap();
        assert_eq!(
            cli.args.matcher.params(),
            orbfix::stereo::StereoParams::default()
        );
        let cli = Cli::try_parse_from(["bench", "stereo", "--horizon-coarse", "false"]).unwrap();
        assert!(!cli.args.matcher.params().horizon_coarse);
    }
}
