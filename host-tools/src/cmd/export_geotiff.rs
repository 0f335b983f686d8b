//! `orbfix export-geotiff`: a square region of the procedural world as a DEM (f32 heights,
//! metres) and an orthoimage (u8, the renderer's satellite image), both single-band
//! GeoTIFFs in the world CRS IAU_2015:30110 (docs/interop.md), for GDAL and QGIS.

use anyhow::Context;
use orbfix_host::geotiff::{write_dem_f32, write_ortho_u8, Georeference};
use orbfix_host::render::{render_ortho, RenderOptions, Sun};
use orbfix_host::world::World;
use std::path::PathBuf;

/// Write a region of the procedural world as DEM + orthoimage GeoTIFFs.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example: orbfix export-geotiff --seed 1 --x 3000 --y 2000 --size-m 600 \
                  --out-dem out/dem.tif --out-ortho out/ortho.tif\n\
                  Check: gdalinfo out/dem.tif; gdallocationinfo -geoloc out/dem.tif 3000 2000"
)]
pub struct Args {
    /// World seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Centre east, metres (world x = CRS easting).
    #[arg(long, allow_negative_numbers = true)]
    pub x: f64,
    /// Centre north, metres (world y = CRS northing).
    #[arg(long, allow_negative_numbers = true)]
    pub y: f64,
    /// Side of the square region, metres.
    #[arg(long, allow_negative_numbers = true)]
    pub size_m: f64,
    /// Metres per pixel of both rasters (0.25 = the top-down image's resolution).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.25)]
    pub m_per_px: f64,
    /// Sun elevation of the orthoimage, degrees above the horizon.
    #[arg(long, allow_negative_numbers = true, default_value_t = 30.0)]
    pub sun_elevation: f64,
    /// Sun azimuth of the orthoimage, degrees clockwise from north (towards the sun).
    #[arg(long, allow_negative_numbers = true, default_value_t = 135.0)]
    pub sun_azimuth: f64,
    /// Output DEM GeoTIFF (f32 heights, metres, at the pixel centres).
    #[arg(long)]
    pub out_dem: PathBuf,
    /// Output orthoimage GeoTIFF (u8).
    #[arg(long)]
    pub out_ortho: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let n = super::square_raster_px(a.x, a.y, a.size_m, a.m_per_px, "the rasters")?;
    let sun = Sun::new(a.sun_elevation, a.sun_azimuth)
        .map_err(|e| anyhow::anyhow!("{e} (elevation 0-90 deg, azimuth 0-360 deg)"))?;
    let side = n as f64 * a.m_per_px;
    let geo = Georeference::new(a.x - 0.5 * side, a.y + 0.5 * side, a.m_per_px)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let bar = indicatif::ProgressBar::new_spinner();
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar.set_message(format!("sampling the {n} x {n} DEM"));
    let world = World::new(a.seed);
    let grid = world
        .try_sample_grid(geo.origin_x_m(), geo.origin_y_m(), a.m_per_px, n, n)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    write_dem_f32(&a.out_dem, n, n, &grid.height_m, &geo)?;
    bar.set_message(format!("rendering the {n} x {n} orthoimage"));
    let g32 = geo
        .to_georef()
        .map_err(|e| anyhow::anyhow!("georeference for the renderer: {e}"))?;
    let img = render_ortho(
        &world,
        &g32,
        n as u32,
        n as u32,
        sun,
        &RenderOptions::default(),
    )
    .context("rendering the orthoimage")?;
    write_ortho_u8(&a.out_ortho, n, n, img.as_raw(), &geo)?;
    bar.finish_and_clear();
    let [w, s, e, nn] = geo.extent(n, n);
    println!(
        "{} + {}: {n} x {n} px at {} m/px, x {w}..{e} m, y {s}..{nn} m, CRS IAU_2015:30110",
        a.out_dem.display(),
        a.out_ortho.display(),
        a.m_per_px
    );
    Ok(())
}
