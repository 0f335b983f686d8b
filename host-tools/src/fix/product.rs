//! Map products (`.ofm`, [`orbfix::map_product`]) from a rendered or loaded map region: the
//! ground segment's job, done with the core's own record code, rows in parallel.

use crate::eval::MapRegion;
use anyhow::Context;
use orbfix::fix::FixConfig;
use orbfix::map_product::{self, MapProductLayout, MapProductMeta, RefinePlane};
use orbfix::nn::input::INPUT_LEN;
use orbfix::nn::model::{Arena, SiameseNet};
use orbfix::nn::window_cosine::WINDOW_RECORD_BYTES;
use rayon::prelude::*;

/// How the window records are laid out.
#[derive(Clone, Copy, Debug)]
pub struct MapProductOptions {
    /// Window side, pixels (the top-down grid's `n`: 200).
    pub window_px: usize,
    /// Window grid step, pixels (16 px = 4 m at 0.25 m/px).
    pub step_px: usize,
    /// Sun of the orbital image `(elevation, azimuth)`, degrees, if known.
    pub sun_deg: Option<(f32, f32)>,
    /// The refinement plane's high-pass: the fix's own (`FixConfig::refine_plane`), or the
    /// fix refuses the product.
    pub plane: RefinePlane,
    /// Relief plane block side, pixels: 0 for none, else the window step (the elevation
    /// model the fix's relief stage matches; [`build_map_product_relief`] fills it).
    pub relief_block_px: usize,
}

impl MapProductOptions {
    /// The options a fix with `cfg` needs: its window side and refinement plane, and a
    /// relief plane on the window step when its relief stage is on.
    pub fn for_fix(cfg: &FixConfig, sun_deg: Option<(f32, f32)>) -> anyhow::Result<Self> {
        let d = Self::default();
        Ok(Self {
            window_px: cfg.grid.n,
            sun_deg,
            plane: cfg.refine_plane().map_err(|e| anyhow::anyhow!("{e}"))?,
            relief_block_px: if cfg.relief.weight > 0.0 {
                d.step_px
            } else {
                0
            },
            ..d
        })
    }
}

impl Default for MapProductOptions {
    fn default() -> Self {
        Self {
            window_px: orbfix::reproject::DEFAULT_N,
            step_px: 16,
            sun_deg: None,
            // The default configuration's plane is valid by construction (2 m at 0.25 m/px).
            plane: FixConfig::default()
                .refine_plane()
                .unwrap_or_else(|_| unreachable!("the default FixConfig is valid")),
            relief_block_px: 0,
        }
    }
}

/// Builds the map product of `map` with the network in `weights` (a validated `.ofw`),
/// without a relief plane (whatever `opts.relief_block_px` says).
pub fn build_map_product(
    map: &MapRegion,
    weights: &[u8],
    opts: &MapProductOptions,
) -> anyhow::Result<Vec<u8>> {
    let opts = MapProductOptions {
        relief_block_px: 0,
        ..*opts
    };
    build_map_product_relief(map, weights, &opts, None)
}

/// Heights of the terrain, metres, at world `(east, north)` metres.
pub type Heights<'a> = &'a (dyn Fn(f64, f64) -> f64 + Sync);

/// Sample points per block side of the relief plane (the block mean of `4 x 4` heights).
const RELIEF_SAMPLES: usize = 4;

/// [`build_map_product`] with the relief plane `opts.relief_block_px` asks for, from
/// `heights` (required then): each block the mean of `4 x 4` heights at its sub-block
/// centres, minus the plane's mean, Q4 metres.
pub fn build_map_product_relief(
    map: &MapRegion,
    weights: &[u8],
    opts: &MapProductOptions,
    heights: Option<Heights<'_>>,
) -> anyhow::Result<Vec<u8>> {
    let net = SiameseNet::from_bytes(weights)
        .map_err(|e| anyhow::anyhow!("the weight file was refused: {e}"))?;
    let meta = MapProductMeta {
        geo: map.geo,
        width: map.width,
        height: map.height,
        window_px: opts.window_px,
        step_px: opts.step_px,
        weights_crc: orbfix::fix::weights_crc(weights),
        sun_deg: opts.sun_deg,
        plane: opts.plane,
        relief_block_px: opts.relief_block_px,
    };
    let layout = MapProductLayout::of(&meta).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut out = vec![0u8; layout.total];
    map_product::write_header(&meta, &mut out).map_err(|e| anyhow::anyhow!("{e}"))?;
    out[layout.pixels_at..layout.pixels_at + map.width * map.height].copy_from_slice(&map.image);
    let view = map.view()?;
    let mut hp = vec![0u32; map_product::refine_plane_buffer_len(map.width)];
    map_product::write_refine_plane(
        &view,
        opts.plane,
        &mut out[layout.plane_at..layout.plane_at + map.width * map.height],
        &mut hp,
    )
    .map_err(|e| anyhow::anyhow!("the map product's refinement plane: {e}"))?;
    let row_bytes = layout.cols * WINDOW_RECORD_BYTES;
    let records = &mut out[layout.records_at..layout.relief_at];
    records
        .par_chunks_mut(row_bytes)
        .enumerate()
        .try_for_each_init(
            || {
                (
                    Box::new(Arena::new()),
                    Box::new([0i8; INPUT_LEN]),
                    vec![0u8; opts.window_px * opts.window_px],
                )
            },
            |(arena, input, window), (r, chunk)| {
                map_product::write_window_records(
                    &view,
                    opts.window_px,
                    opts.step_px,
                    &layout,
                    r..r + 1,
                    &net,
                    window,
                    arena,
                    input,
                    chunk,
                )
                .map(|_| ())
                .map_err(|e| anyhow::anyhow!("window records of row {r}: {e}"))
            },
        )
        .context("computing the map product's window records")?;
    if layout.relief_blocks > 0 {
        let heights = heights.context(
            "a relief plane was asked for but no heights were given (a map image alone has no elevation)",
        )?;
        let plane = relief_plane(map, &layout, opts, heights);
        for (k, v) in plane.iter().enumerate() {
            let at = layout.relief_at + 2 * k;
            out[at..at + 2].copy_from_slice(&v.to_le_bytes());
        }
    }
    map_product::seal(&mut out).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out)
}

/// The relief plane's heights (Q4 metres about their mean), row-major.
fn relief_plane(
    map: &MapRegion,
    layout: &MapProductLayout,
    opts: &MapProductOptions,
    heights: Heights<'_>,
) -> Vec<i16> {
    let b = opts.relief_block_px as f64;
    let o = ((opts.window_px - layout.relief_blocks * opts.relief_block_px) / 2) as f64;
    let res = map.geo.m_per_px() as f64;
    let (x0, y0) = (map.geo.origin_x_m() as f64, map.geo.origin_y_m() as f64);
    let (rc, rr) = (layout.relief_cols, layout.relief_rows);
    let means: Vec<f64> = (0..rc * rr)
        .into_par_iter()
        .map(|k| {
            let (i, j) = ((k % rc) as f64, (k / rc) as f64);
            let mut s = 0.0;
            for sy in 0..RELIEF_SAMPLES {
                for sx in 0..RELIEF_SAMPLES {
                    let f = |t: usize| (t as f64 + 0.5) / RELIEF_SAMPLES as f64;
                    let px = o + (i + f(sx)) * b;
                    let py = o + (j + f(sy)) * b;
                    s += heights(x0 + px * res, y0 - py * res);
                }
            }
            s / (RELIEF_SAMPLES * RELIEF_SAMPLES) as f64
        })
        .collect();
    let mean = means.iter().sum::<f64>() / means.len().max(1) as f64;
    let one = (1u32 << map_product::RELIEF_PLANE_FRAC_BITS) as f64;
    means
        .iter()
        .map(|h| {
            ((h - mean) * one)
                .round()
                .clamp(i16::MIN as f64, i16::MAX as f64) as i16
        })
        .collect()
}
