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
}

impl MapProductOptions {
    /// The options a fix with `cfg` needs: its window side and refinement plane.
    pub fn for_fix(cfg: &FixConfig, sun_deg: Option<(f32, f32)>) -> anyhow::Result<Self> {
        Ok(Self {
            window_px: cfg.grid.n,
            sun_deg,
            plane: cfg.refine_plane().map_err(|e| anyhow::anyhow!("{e}"))?,
            ..Self::default()
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
        }
    }
}

/// Builds the map product of `map` with the network in `weights` (a validated `.ofw`).
pub fn build_map_product(
    map: &MapRegion,
    weights: &[u8],
    opts: &MapProductOptions,
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
    };
    let layout = MapProductLayout::new(map.width, map.height, opts.window_px, opts.step_px)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
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
    let records = &mut out[layout.records_at..layout.total - 4];
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
    map_product::seal(&mut out).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out)
}
