//! `orbfix geotiff-info`: what orbfix reads from a GeoTIFF (size, sample type, georeference,
//! CRS, no-data, chosen pixel values), as JSON, or why it refuses the file.

use orbfix_host::geotiff::read_geotiff;
use std::path::PathBuf;

/// Print what orbfix reads from a single-band GeoTIFF, as JSON.
#[derive(clap::Args, Debug)]
#[command(after_help = "Example: orbfix geotiff-info dem.tif --pixel 0,0 --pixel 10,20")]
pub struct Args {
    /// The GeoTIFF.
    pub file: PathBuf,
    /// Pixel `COL,ROW` whose value to print (repeatable); null where no-data.
    #[arg(long, value_parser = parse_pixel)]
    pub pixel: Vec<(usize, usize)>,
}

fn parse_pixel(s: &str) -> Result<(usize, usize), String> {
    let (c, r) = s
        .split_once(',')
        .ok_or_else(|| format!("'{s}': expected COL,ROW (e.g. 10,20)"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<usize>()
            .map_err(|_| format!("'{v}' is not a pixel index (0, 1, 2, ...)"))
    };
    Ok((p(c)?, p(r)?))
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let r = read_geotiff(&a.file)?;
    for &(c, row) in &a.pixel {
        anyhow::ensure!(
            c < r.width && row < r.height,
            "pixel {c},{row} is outside the {} x {} raster",
            r.width,
            r.height
        );
    }
    let values: Vec<_> = a
        .pixel
        .iter()
        .map(|&(c, row)| serde_json::json!({"col": c, "row": row, "value": r.get(c, row)}))
        .collect();
    let out = serde_json::json!({
        "width": r.width,
        "height": r.height,
        "sample": format!("{:?}", r.kind).to_lowercase(),
        "origin_x_m": r.georef.origin_x_m(),
        "origin_y_m": r.georef.origin_y_m(),
        "m_per_px": r.georef.m_per_px(),
        "crs": r.crs.describe(),
        "epsg": r.crs.epsg,
        "raster_type": format!("{:?}", r.crs.raster_type),
        "nodata": r.nodata,
        "values": values,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
