//! `orbfix map`: an orbital map region of the built-in world, or of a DEM + orthoimage site
//! (GeoTIFFs), as MAP.png + MAP.json (the georeference `orbfix localize` needs) and, with
//! `--product`, as the map product the rover carries (`.ofm`, docs/map-format.md).

use anyhow::Context;
use orbfix_host::eval::pipeline::map_region;
use orbfix_host::eval::{save_png_atomic, write_atomic, MapMeta};
use orbfix_host::fix::{build_map_product_relief, MapProductOptions};
use orbfix_host::fsutil::check_output;
use orbfix_host::nn::weights_file::WeightsArg;
use orbfix_host::render::{RenderOptions, Sun};
use orbfix_host::world::dem::MapSource;
use orbfix_host::world::World;
use std::path::PathBuf;

/// Write a north-up map region centred on (x, y) with its georeference sidecar.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  orbfix map --x 3000 --y 2000 --out out/map.png  (writes out/map.png and out/map.json)\n  \
                  orbfix map --x 3000 --y 2000 --out out/map.png --product out/map.ofm\n  \
                  (also the map product the rover carries: pixels, georeference, refinement plane,\n  \
                  CNN window records of the weights, CRC-32; docs/map-format.md)\n  \
                  orbfix map --dem dem.tif --ortho ortho.tif --x 500 --y 500 --out out/site-map.png\n  \
                  (a DEM site: x, y in world metres = CRS metres minus the offset the command prints)"
)]
pub struct Args {
    /// World seed (the built-in world; unused with --dem).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Centre east, metres (world frame; for --dem the CRS easting minus the site's offset).
    #[arg(long, allow_negative_numbers = true)]
    pub x: f64,
    /// Centre north, metres (world frame; for --dem the CRS northing minus the offset).
    #[arg(long, allow_negative_numbers = true)]
    pub y: f64,
    /// A real DEM (single-band GeoTIFF, projected CRS in metres; docs/interop.md) instead of
    /// the built-in world. Needs --ortho.
    #[arg(long, requires = "ortho")]
    pub dem: Option<PathBuf>,
    /// The orthoimage GeoTIFF of --dem (same CRS).
    #[arg(long, requires = "dem")]
    pub ortho: Option<PathBuf>,
    /// With --dem: the map is the orthoimage resampled to the grid (ortho, the default: what
    /// a mission has) or the DEM rendered with the orthoimage as albedo under --sun-* (render).
    #[arg(long, value_enum, requires = "dem")]
    pub dem_map: Option<MapSource>,
    /// Side of the region, metres (300 = the study's search region).
    #[arg(long, allow_negative_numbers = true, default_value_t = 300.0)]
    pub size_m: f64,
    /// Metres per pixel (0.25 = the top-down image's resolution).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.25)]
    pub m_per_px: f64,
    /// Sun elevation, degrees above the horizon.
    #[arg(long, allow_negative_numbers = true, default_value_t = 30.0)]
    pub sun_elevation: f64,
    /// Sun azimuth, degrees clockwise from north (towards the sun).
    #[arg(long, allow_negative_numbers = true, default_value_t = 135.0)]
    pub sun_azimuth: f64,
    /// Output PNG; the georeference goes next to it with the extension .json.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the map product (`.ofm`) of this region: what the rover carries and the
    /// fix reads, made with the default fix configuration's window grid (50 m windows every
    /// 4 m) and refinement plane, and the CNN records of --weights.
    #[arg(long, value_name = "FILE.ofm")]
    pub product: Option<PathBuf>,
    #[command(flatten)]
    pub weights: WeightsArg,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let px = super::square_raster_px(a.x, a.y, a.size_m, a.m_per_px, "the map")?;
    // The product's checks first: a bad weight file or output is refused before the rendering.
    let weights = match &a.product {
        Some(path) => {
            let grid = orbfix::fix::FixConfig::default().grid;
            let (n, res) = (grid.n, f64::from(grid.m_per_px));
            anyhow::ensure!(
                (a.m_per_px - res).abs() < 1e-6,
                "--product needs --m-per-px {res}, the fix's top-down resolution (got {})",
                a.m_per_px
            );
            anyhow::ensure!(
                px >= n,
                "--product needs a map at least as wide as the fix's top-down window ({n} px, \
                 {:.0} m); this one is {px} px: raise --size-m",
                n as f64 * res
            );
            check_output(path)?;
            Some(a.weights.bytes()?)
        }
        None => None,
    };
    let sun = Sun::new(a.sun_elevation, a.sun_azimuth)
        .map_err(|e| anyhow::anyhow!("{e} (elevation 0-90 deg, azimuth 0-360 deg)"))?;
    let world = match (&a.dem, &a.ortho) {
        (Some(dem), Some(ortho)) => {
            let mut w = World::from_geotiff(dem, ortho)?;
            w.set_dem_map_source(a.dem_map.unwrap_or_default());
            let [west, south, east, north] = w.dem().map(|d| d.extent_m()).unwrap_or_default();
            let half = 0.5 * px as f64 * a.m_per_px;
            anyhow::ensure!(
                a.x - half >= west
                    && a.x + half <= east
                    && a.y - half >= south
                    && a.y + half <= north,
                "the {:.0} m map around ({}, {}) leaves the rasters' common region \
                 x {west:.1}..{east:.1}, y {south:.1}..{north:.1} (world metres): move --x/--y or \
                 shrink --size-m",
                a.size_m,
                a.x,
                a.y
            );
            w
        }
        _ => World::new(a.seed),
    };
    let dem = world.dem();
    let rendered = dem.is_none_or(|d| d.map_source() == MapSource::Render);
    let map = map_region(
        &world,
        a.x,
        a.y,
        px,
        a.m_per_px,
        sun,
        &RenderOptions::default(),
    )?;
    let img = image::GrayImage::from_raw(map.width as u32, map.height as u32, map.image.clone())
        .context("map buffer has the wrong size")?;
    save_png_atomic(&img, &a.out)?;
    let meta = MapMeta {
        origin_x_m: map.geo.origin_x_m() as f64,
        origin_y_m: map.geo.origin_y_m() as f64,
        m_per_px: map.geo.m_per_px() as f64,
        width_px: map.width,
        height_px: map.height,
        world_seed: dem.is_none().then_some(a.seed),
        sun_deg: rendered.then_some((a.sun_elevation, a.sun_azimuth)),
        crs_offset_m: dem.map(|d| d.crs_offset_m()),
    };
    let meta_path = a.out.with_extension("json");
    write_atomic(&meta_path, serde_json::to_string_pretty(&meta)?.as_bytes())?;
    println!("{} + {}", a.out.display(), meta_path.display());
    if let (Some(path), Some(weights)) = (&a.product, &weights) {
        let sun_deg = rendered.then_some((a.sun_elevation as f32, a.sun_azimuth as f32));
        let opts = MapProductOptions::for_fix(&orbfix::fix::FixConfig::default(), sun_deg)?;
        let heights = |x: f64, y: f64| world.height_m(x, y);
        let bytes = build_map_product_relief(&map, weights, &opts, Some(&heights))?;
        // What the rover will do first: the core's own validation, CRC included.
        let product =
            orbfix::map_product::MapProduct::parse(&bytes, orbfix::map_product::CrcCheck::Verify)
                .map_err(|e| anyhow::anyhow!("the map product just built does not validate: {e}"))?;
        let meta = *product.meta();
        write_atomic(path, &bytes)?;
        println!(
            "{}: map product, {} x {} px, {} x {} CNN windows of {} px every {} px, weights {} \
             ({:.1} MB)",
            path.display(),
            meta.width,
            meta.height,
            (meta.width - meta.window_px) / meta.step_px + 1,
            (meta.height - meta.window_px) / meta.step_px + 1,
            meta.window_px,
            meta.step_px,
            a.weights.describe(),
            bytes.len() as f64 / 1e6
        );
        if let Some(r) = product.relief() {
            println!(
                "  relief plane: {} x {} elevation blocks of {} px ({} per window side), Q4 m",
                r.cols(),
                r.rows(),
                meta.relief_block_px,
                r.blocks()
            );
        }
    }
    if let Some(d) = dem {
        let (ox, oy) = d.crs_offset_m();
        println!(
            "site in {}: world (x, y) = CRS (easting - {ox}, northing - {oy}) m; map from the {}",
            d.crs().describe(),
            if rendered {
                "rendered DEM"
            } else {
                "orthoimage"
            }
        );
    }
    Ok(())
}
