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
    /// World seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum Target {
    /// The world renderer.
    World,
}

/// The study's rendering rate: 60 frames/s, 4 frames per location.
pub const ANCHOR_LOCATIONS_PER_S: f64 = 15.0;

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.target {
        Target::World => bench_world(&args),
    }
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
    let mut t_views = 0.0;
    let mut t_sat = 0.0;
    let t0 = Instant::now();
    for i in 0..args.locations {
        let x = 300.0 + 97.0 * i as f64;
        let y = 400.0 + 61.0 * i as f64;
        let pose = render::ground_pose(&world, x, y, 37.0 * i as f64);
        let t = Instant::now();
        let v = render::render_views(&world, &pose, sun, &opts)?;
        t_views += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let s = render::render_satellite_crop(&world, x, y, 200, 0.25, sun, &opts)?;
        t_sat += t.elapsed().as_secs_f64();
        std::hint::black_box((v, s));
    }
    let total = t0.elapsed().as_secs_f64();
    let rate = args.locations as f64 / total;
    println!("bench world: {} locations at {w}x{h} (4 views + 200x200 satellite crop), {threads} threads", args.locations);
    println!(
        "  views {:.1} ms/location, satellite {:.1} ms/location",
        1e3 * t_views / args.locations as f64,
        1e3 * t_sat / args.locations as f64
    );
    println!(
        "  orbfix {rate:.2} locations/s | anchor (Unreal, GTX 1080) {ANCHOR_LOCATIONS_PER_S:.0} locations/s | ratio {:.3}x",
        rate / ANCHOR_LOCATIONS_PER_S
    );
    if args.map {
        let geo = GeoRef::centred(1000.0, 1000.0, 1200, 1200, 0.25)
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
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
