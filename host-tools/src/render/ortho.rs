//! Orthographic north-up renders: satellite crops and map regions.

use super::shadow::ShadowField;
use super::terrain::Terrain;
use super::{RenderError, RenderOptions, Sun};
use crate::world::World;
use image::GrayImage;
use orbfix::geo::GeoRef;
use rayon::prelude::*;

/// Largest orthographic raster side, pixels.
pub const MAX_ORTHO_PX: u32 = 16384;

/// Renders the `w x h` north-up raster with georeference `geo` (NW corner, m/px), seen from
/// straight above, under `sun`, with the lighting of the ground views. Each pixel shows the
/// terrain below its centre (heights, normals and albedo sampled at pixel centres).
pub fn render_ortho(
    world: &World,
    geo: &GeoRef,
    w: u32,
    h: u32,
    sun: Sun,
    opts: &RenderOptions,
) -> Result<GrayImage, RenderError> {
    sun.validate()?;
    opts.validate()?;
    if w == 0 || h == 0 || w > MAX_ORTHO_PX || h > MAX_ORTHO_PX {
        return Err(RenderError::Option(format!(
            "orthographic size {w}x{h} must be 1..={MAX_ORTHO_PX} px per side"
        )));
    }
    if !(geo.m_per_px.is_finite()
        && geo.m_per_px > 0.0
        && geo.origin_x_m.is_finite()
        && geo.origin_y_m.is_finite())
    {
        return Err(RenderError::Option(format!(
            "bad georeference {geo:?}: resolution must be > 0 and the origin finite"
        )));
    }
    let terrain = Terrain::region(world, geo, w, h, opts.shadow_reach_m);
    let shadow = ShadowField::build_levels(&terrain, &sun, opts.shadow_reach_m, 1);
    let sdir = sun.direction();
    let l0 = &terrain.levels[0];
    let (w_us, nx) = (w as usize, l0.grid.nx);
    let mut gray = vec![0f32; w_us * h as usize];
    gray.par_chunks_mut(w_us).enumerate().for_each(|(r, row)| {
        for (c, out) in row.iter_mut().enumerate() {
            // Level-0 node (c + 1, r + 1) is pixel (c, r)'s centre.
            let (gc, gr) = (c + 1, r + 1);
            let n = l0.normal(gc, gr);
            let (x, y) = l0.node_xy(gc, gr);
            let albedo = l0.grid.albedo[gr * nx + gc] as f64;
            let lit = shadow.lit(x, y) as f64;
            *out = opts.gray(opts.radiance(albedo, n, sdir, [0.0, 0.0, 1.0], lit)) as f32;
        }
    });
    // Noise stream 0 is the orthographic one (views use 1..=4).
    Ok(opts.finish(w, h, &gray, 0))
}
