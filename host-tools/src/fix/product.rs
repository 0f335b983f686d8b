//! Map products (`.ofm`, [`orbfix::map_product`]) from a rendered or loaded map region: the
//! ground segment's job, done with the core's own record code, rows in parallel.

use crate::eval::MapRegion;
use anyhow::Context;
use orbfix::map_product::{self, MapProductLayout, MapProductMeta};
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
}

impl Default for MapProductOptions {
    fn default() -> Self {
        Self {
            window_px: orbfix::reproject::DEFAULT_N,
            step_px: 16,
            sun_deg: None,
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
    };
    let layout = MapProductLayout::new(map.width, map.height, opts.window_px, opts.step_px)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut out = vec![0u8; layout.total];
    map_product::write_header(&meta, &mut out).map_err(|e| anyhow::anyhow!("{e}"))?;
    out[layout.pixels_at..layout.pixels_at + map.width * map.height].copy_from_slice(&map.image);
    let view = map.view()?;
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
