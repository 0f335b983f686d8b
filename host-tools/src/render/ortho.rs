//! Orthographic north-up renders: satellite crops and map regions.

use super::shadow::ShadowField;
use super::terrain::Terrain;
use super::Surface;
use super::{RenderError, RenderOptions, Sun};
use image::GrayImage;
use orbfix::geo::GeoRef;
use rayon::prelude::*;

/// Largest orthographic raster side, pixels.
pub const MAX_ORTHO_PX: u32 = 16384;

/// Renders the `w x h` north-up raster with georeference `geo` (NW corner, m/px), seen from
/// straight above, under `sun`, with the lighting of the ground views. Each pixel shows the
/// terrain below its centre: with `ortho_supersample = s`, the mean radiance of `s x s`
/// samples spread evenly over the pixel (s = 1: the pixel centre only).
pub fn render_ortho(
    world: &dyn Surface,
    geo: &GeoRef,
    w: u32,
    h: u32,
    sun: Sun,
    opts: &RenderOptions,
) -> Result<GrayImage, RenderError> {
    render_ortho_cached(world, geo, w, h, sun, opts, None)
}

/// As [`render_ortho`], sharing the coarse surround (traced for shadows) between calls
/// through `cache` (one per world; identical results).
pub fn render_ortho_cached(
    world: &dyn Surface,
    geo: &GeoRef,
    w: u32,
    h: u32,
    sun: Sun,
    opts: &RenderOptions,
    cache: Option<&super::terrain::TileCache>,
) -> Result<GrayImage, RenderError> {
    sun.validate()?;
    opts.validate()?;
    if w == 0 || h == 0 || w > MAX_ORTHO_PX || h > MAX_ORTHO_PX {
        return Err(RenderError::Option(format!(
            "orthographic size {w}x{h} must be 1..={MAX_ORTHO_PX} px per side"
        )));
    }
    // `geo` was checked by `GeoRef::new` (finite origin, positive resolution).
    // Supersampling: each pixel averages the radiance of s x s samples spread evenly over
    // its footprint (a box filter, as a real sensor integrates), centred on the pixel centre.
    let ss = opts.ortho_supersample.max(1) as usize;
    let fine = GeoRef::new(
        geo.origin_x_m(),
        geo.origin_y_m(),
        geo.m_per_px() / ss as f32,
    )
    .map_err(|e| RenderError::Option(format!("supersampled georeference: {e}")))?;
    let (fw, fh) = (w * ss as u32, h * ss as u32);
    let terrain = Terrain::region(world, &fine, fw, fh, opts.shadow_reach_m, cache);
    let shadow = ShadowField::build_levels(&terrain, &sun, opts.shadow_reach_m, 1);
    let sdir = sun.direction();
    let gmap = super::GrayMap::new(opts.gamma);
    let l0 = &terrain.levels[0];
    let (w_us, nx) = (w as usize, l0.grid.nx);
    let norm = 1.0 / (ss * ss) as f64;
    let mut gray = vec![0f32; w_us * h as usize];
    gray.par_chunks_mut(w_us).enumerate().for_each(|(r, row)| {
        for (c, out) in row.iter_mut().enumerate() {
            let mut rad = 0.0;
            for j in 0..ss {
                for i in 0..ss {
                    // Level-0 node (fc + 1, fr + 1) is fine pixel (fc, fr)'s centre.
                    let (gc, gr) = (c * ss + i + 1, r * ss + j + 1);
                    let n = l0.normal(gc, gr);
                    let (x, y) = l0.node_xy(gc, gr);
                    let albedo = l0.grid.albedo[gr * nx + gc] as f64;
                    let lit = shadow.lit(x, y) as f64;
                    rad += opts.radiance(albedo, n, sdir, [0.0, 0.0, 1.0], lit);
                }
            }
            *out = gmap.gray(rad * norm);
        }
    });
    // Noise stream 0 is the orthographic one (views use 1..=4).
    Ok(opts.finish(w, h, &gray, 0))
}
