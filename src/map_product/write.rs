//! Writing a map product (on the ground, by `orbfix map`): the header, the refinement
//! plane, the window records, and the CRC-32 trailer that [`seal`] adds last. The reader
//! in [`super`] validates every file before any use.

use super::{
    MapProductError, MapProductLayout, MapProductMeta, RefinePlane, HEADER_BYTES, MAGIC,
    MAX_ORIGIN_M, VERSION,
};
use crate::image::{ImageView, ImageViewMut};
use crate::matcher::prep::{highpass, highpass_buffer_len, rectify};
use crate::nn::input::{prepare_input, INPUT_LEN};
use crate::nn::model::{Arena, SiameseNet, EMBED_LEN};
use crate::nn::weights::crc32;
use crate::nn::window_cosine::{write_window_record, WINDOW_RECORD_BYTES};
use crate::nn::NnError;

/// Writes the header of a map product with `meta` into `out[..HEADER_BYTES]` and returns
/// the layout; the caller then fills the pixels at `layout.pixels_at`, the records at
/// `layout.records_at`, and calls [`seal`].
pub fn write_header(
    meta: &MapProductMeta,
    out: &mut [u8],
) -> Result<MapProductLayout, MapProductError> {
    let layout = MapProductLayout::of(meta)?;
    let g = meta.geo;
    if !(g.origin_x_m().abs() <= MAX_ORIGIN_M && g.origin_y_m().abs() <= MAX_ORIGIN_M) {
        return Err(MapProductError::BadField { field: "origin" });
    }
    let head = out
        .get_mut(..HEADER_BYTES)
        .ok_or(MapProductError::BufferTooSmall {
            needed: layout.total,
        })?;
    head.fill(0);
    let (el, az) = meta.sun_deg.unwrap_or((f32::NAN, f32::NAN));
    let plane = u32::from(meta.plane.radius_px) | (u32::from(meta.plane.rectify) << 16);
    let words: [(usize, u32); 14] = [
        (8, HEADER_BYTES as u32),
        (12, meta.width as u32),
        (16, meta.height as u32),
        (20, g.origin_x_m().to_bits()),
        (24, g.origin_y_m().to_bits()),
        (28, g.m_per_px().to_bits()),
        (32, meta.window_px as u32),
        (36, meta.step_px as u32),
        (40, layout.cols as u32),
        (44, layout.rows as u32),
        (48, meta.weights_crc),
        (52, el.to_bits()),
        (56, az.to_bits()),
        (60, plane),
    ];
    if let Some(m) = head.get_mut(..4) {
        m.copy_from_slice(&MAGIC);
    }
    if let Some(v) = head.get_mut(4..6) {
        v.copy_from_slice(&VERSION.to_le_bytes());
    }
    if let Some(v) = head.get_mut(6..8) {
        v.copy_from_slice(&(meta.relief_block_px as u16).to_le_bytes());
    }
    for (at, w) in words {
        if let Some(d) = head.get_mut(at..at + 4) {
            d.copy_from_slice(&w.to_le_bytes());
        }
    }
    Ok(layout)
}

/// Writes the CRC-32 trailer of a complete map product (`out.len() == layout.total`).
pub fn seal(out: &mut [u8]) -> Result<(), MapProductError> {
    let n = out.len();
    if n < HEADER_BYTES + 4 {
        return Err(MapProductError::Truncated { got: n });
    }
    let c = crc32(out.get(..n - 4).unwrap_or_default());
    if let Some(t) = out.get_mut(n - 4..) {
        t.copy_from_slice(&c.to_le_bytes());
    }
    Ok(())
}

/// Scratch `u32` elements [`write_refine_plane`] needs for a map `width` pixels wide.
pub const fn refine_plane_buffer_len(width: usize) -> usize {
    highpass_buffer_len(width)
}

/// Writes the refinement plane of `map` into `out` (`width * height` bytes, the product's
/// bytes at `layout.plane_at`): the high-pass of [`crate::matcher::prep::highpass`] with
/// `plane`'s radius, rectified if it says so. Done on the ground; inside the region the fix
/// refines on, every box is whole, so the plane equals the high-pass of that region alone.
/// `scratch`: at least [`refine_plane_buffer_len`] elements.
pub fn write_refine_plane(
    map: &ImageView<'_>,
    plane: RefinePlane,
    out: &mut [u8],
    scratch: &mut [u32],
) -> Result<(), MapProductError> {
    let (w, h) = (map.width(), map.height());
    let needed = w * h;
    let dst = out
        .get_mut(..needed)
        .ok_or(MapProductError::BufferTooSmall { needed })?;
    let mut view =
        ImageViewMut::new(dst, w, h).map_err(|_| MapProductError::BufferTooSmall { needed })?;
    highpass(map, None, plane.radius_px(), &mut view, scratch).map_err(|_| {
        MapProductError::BufferTooSmall {
            needed: refine_plane_buffer_len(w),
        }
    })?;
    if plane.rectify() {
        rectify(&mut view);
    }
    Ok(())
}

/// Computes the records of the window-grid rows `rows` of a `layout` over `map` with
/// `net` into `out` (`rows.len() * layout.cols` records, row-major), using `window`
/// (`n * n` bytes) as the copy buffer. Done on the ground, with the same network code as
/// the flight stage; rows are independent, so a host can compute them in parallel. A window
/// the network cannot embed (no contrast) gets the all-zero-point record (cosine 0).
#[allow(clippy::too_many_arguments)]
pub fn write_window_records(
    map: &ImageView<'_>,
    n: usize,
    step: usize,
    layout: &MapProductLayout,
    rows: core::ops::Range<usize>,
    net: &SiameseNet<'_>,
    window: &mut [u8],
    arena: &mut Arena,
    input: &mut [i8; INPUT_LEN],
    out: &mut [u8],
) -> Result<usize, NnError> {
    let window = window.get_mut(..n * n).ok_or(NnError::BufferSize)?;
    let zp = i8::try_from(net.embedding_zero_point()).map_err(|_| NnError::BadGeometry)?;
    let mut emb = [0i8; EMBED_LEN];
    let mut chunks = out.chunks_exact_mut(WINDOW_RECORD_BYTES);
    let mut count = 0;
    for r in rows {
        if r >= layout.rows {
            return Err(NnError::BufferSize);
        }
        for c in 0..layout.cols {
            let sub = map
                .sub(c * step, r * step, n, n)
                .ok_or(NnError::BufferSize)?;
            for (y, dst) in window.chunks_exact_mut(n).enumerate() {
                dst.copy_from_slice(sub.row(y).ok_or(NnError::BufferSize)?);
            }
            match prepare_input(window, None, n, input) {
                Ok(()) => net.embed(input, arena, &mut emb)?,
                Err(NnError::FlatInput | NnError::TooFewValid) => emb = [zp; EMBED_LEN],
                Err(e) => return Err(e),
            }
            write_window_record(&emb, chunks.next().ok_or(NnError::BufferSize)?)?;
            count += 1;
        }
    }
    Ok(count)
}
