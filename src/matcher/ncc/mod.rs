//! Masked, weighted normalized cross-correlation (MARSAUTOLOCO's matcher).
//!
//! With weights `w` (0 = hole), template `t` and map window `m`, over the template's pixels:
//! `W = sum w`, `St = sum w t`, `Stt = sum w t^2` (template statistics, computed once per
//! dense call) and `Sm = sum w m`, `Smm = sum w m^2`, `Stm = sum w t m` (three integer
//! correlations per window; the map's statistics are taken under the template's mask, so
//! holes never see the map). Then
//! `ncc = (W Stm - St Sm) / sqrt((W Stt - St^2) (W Smm - Sm^2))`, in `[-1, 1]`.

use super::{check_inputs, Grid, MatchError, Matcher, OpCounts};
use crate::image::ImageView;
#[cfg(not(target_os = "none"))]
use crate::scratch::{claim, Slot, POOL_SLOTS};
use core::num::NonZeroUsize;

/// Masked normalized cross-correlation. Score in `[-1, 1]`; a map window whose weighted
/// standard deviation is below [`Ncc::min_map_std`] (grey levels) scores `0` (nothing to
/// correlate with), so a flat map never yields a confident peak.
#[derive(Clone, Copy, Debug)]
pub struct Ncc {
    /// Minimum weighted standard deviation of a map window, grey levels.
    pub min_map_std: f32,
}

impl Default for Ncc {
    fn default() -> Self {
        Self { min_map_std: 1.0 }
    }
}

/// Weighted statistics of a template: `(W, St, Stt)`.
#[derive(Clone, Copy, Debug)]
struct TemplateStats {
    w: u64,
    st: u64,
    stt: u64,
}

fn template_stats(
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
) -> Result<TemplateStats, MatchError> {
    let mut s = TemplateStats {
        w: 0,
        st: 0,
        stt: 0,
    };
    for y in 0..template.height() {
        let (Some(t), Some(w)) = (template.row(y), weight.row(y)) else {
            return Err(MatchError::MaskSizeMismatch);
        };
        for (&t, &w) in t.iter().zip(w) {
            let wt = w as u64 * t as u64;
            s.w += w as u64;
            s.st += wt;
            s.stt += wt * t as u64;
        }
    }
    if s.w == 0 {
        return Err(MatchError::NoValidPixels);
    }
    // Variance numerator W Stt - St^2 is zero iff all valid pixels are equal.
    if (s.w as u128) * (s.stt as u128) <= (s.st as u128) * (s.st as u128) {
        return Err(MatchError::FeaturelessTemplate);
    }
    Ok(s)
}

impl Ncc {
    fn window(
        &self,
        ts: &TemplateStats,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        let (mut sm, mut smm, mut stm) = (0u64, 0u64, 0u64);
        for y in 0..template.height() {
            let (Some(t), Some(w), Some(m)) = (template.row(y), weight.row(y), window.row(y))
            else {
                return Err(MatchError::WindowTooSmall);
            };
            // Runs of at most ROW_CHUNK pixels keep the partial sums in u32 (at most
            // 256 * 255^3 < 2^32); exact, and much cheaper than u64 per pixel on a 32-bit
            // core.
            for ((t, w), m) in t
                .chunks(ROW_CHUNK)
                .zip(w.chunks(ROW_CHUNK))
                .zip(m.chunks(ROW_CHUNK))
            {
                let (mut a, mut b, mut c) = (0u32, 0u32, 0u32);
                for ((&t, &w), &m) in t.iter().zip(w).zip(m) {
                    let wm = w as u32 * m as u32;
                    a += wm;
                    b += wm * m as u32;
                    c += wm * t as u32;
                }
                sm += a as u64;
                smm += b as u64;
                stm += c as u64;
            }
        }
        ops.macs += 3 * (template.width() * template.height()) as u64;
        ops.windows += 1;
        Ok(self.combine(ts, sm, smm, stm))
    }

    /// The score from the window sums `Sm = sum w m`, `Smm = sum w m^2`, `Stm = sum w t m`
    /// (shared by both dense paths, so they agree to the bit).
    fn combine(&self, ts: &TemplateStats, sm: u64, smm: u64, stm: u64) -> f32 {
        let w = ts.w as i128;
        let cov = w * stm as i128 - ts.st as i128 * sm as i128;
        let vt = w * ts.stt as i128 - (ts.st as i128) * (ts.st as i128);
        let vm = w * smm as i128 - (sm as i128) * (sm as i128);
        // Weighted map variance (grey levels^2) = vm / W^2.
        let min_var = self.min_map_std * self.min_map_std;
        let wf = ts.w as f32;
        if vm <= 0 || (vm as f32) < min_var * wf * wf || vt <= 0 {
            return 0.0;
        }
        let r = cov as f32 / (libm::sqrtf(vt as f32) * libm::sqrtf(vm as f32));
        r.clamp(-1.0, 1.0)
    }

    /// Fast dense path for small templates over narrow regions (the localizer's coarse
    /// pass: 25 x 25 px over 150 px at 2 m/px). Same sums, so the same scores to the bit:
    ///
    /// - `Stm = sum (w t) m`: one u16 x u8 multiply-accumulate per pixel with `w t`
    ///   precomputed;
    /// - `Sm`, `Smm`: with `w_ref` the largest weight (the mask is nearly uniform: only a
    ///   blind disc, thin wedges and edge blocks differ), `sum w m = w_ref * box(m) + sum_K (w - w_ref) m`
    ///   over the few pixels `K` whose weight differs. `box(m)` and `box(m^2)` are
    ///   rectangle sums from column sums kept up to date row by row.
    ///
    /// MACs counted: `N + 2 |K|` per window (`N` template pixels). Returns `Ok(false)`
    /// (nothing written) when the template, region or differing set exceeds the static
    /// tables ([`FAST_MAX_PX`], [`FAST_MAX_COLS`], [`FAST_MAX_K`]).
    #[allow(clippy::too_many_arguments)]
    fn dense_fast(
        &self,
        ts: &TemplateStats,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        region: &ImageView<'_>,
        step: usize,
        grid: &Grid,
        out: &mut [f32],
        ops: &mut OpCounts,
    ) -> Result<bool, MatchError> {
        let (tw, th) = (template.width(), template.height());
        let n = tw * th;
        let (rw, stride) = (region.width(), region.stride());
        if n > FAST_MAX_PX || rw > FAST_MAX_COLS || tw == 0 || th == 0 {
            return Ok(false);
        }
        let span = (th - 1) * stride + tw;
        if span > u16::MAX as usize + 1 {
            return Ok(false);
        }
        // Reference weight: the largest (full blocks of the mask; the rest are few).
        let mut wref = 0u32;
        for y in 0..th {
            let w = weight.row(y).ok_or(MatchError::MaskSizeMismatch)?;
            wref = wref.max(w.iter().copied().max().unwrap_or(0) as u32);
        }
        // w t per pixel (row-major, tw per row) and the pixels whose weight differs
        // (window offsets, u16 as span <= 65536).
        // 6.6 KB of tables: from the static pool on a host, on the stack on bare metal
        // (see `fast_tables`).
        #[cfg(not(target_os = "none"))]
        let mut claimed = claim(&FAST_TABLES).ok_or(MatchError::WindowTooSmall)?;
        #[cfg(not(target_os = "none"))]
        let tables: &mut FastTables = &mut claimed;
        #[cfg(target_os = "none")]
        let mut local = FastTables::new();
        #[cfg(target_os = "none")]
        let tables: &mut FastTables = &mut local;
        let FastTables {
            wt,
            koff,
            kdelta,
            colm,
            colmm,
        } = tables;
        let mut k = 0usize;
        let mut wt_rows = wt.iter_mut();
        for y in 0..th {
            let (Some(t), Some(w)) = (template.row(y), weight.row(y)) else {
                return Err(MatchError::MaskSizeMismatch);
            };
            for (x, (&t, &w)) in t.iter().zip(w).enumerate() {
                if let Some(d) = wt_rows.next() {
                    *d = (w as u32 * t as u32) as u16;
                }
                if w as u32 != wref {
                    let (Some(o), Some(d)) = (koff.get_mut(k), kdelta.get_mut(k)) else {
                        // More differing weights than the table holds: general path.
                        return Ok(false);
                    };
                    *o = (y * stride + x) as u16;
                    *d = w as i16 - wref as i16;
                    k += 1;
                }
            }
        }
        let wt = &wt[..];
        let wt = wt.get(..n).ok_or(MatchError::WindowTooSmall)?;
        let (koff, kdelta) = match (koff.get(..k), kdelta.get(..k)) {
            (Some(o), Some(d)) => (o, d),
            _ => return Err(MatchError::WindowTooSmall),
        };
        let data = region.data();
        // Column sums of m and m^2 over the template's rows at the current grid row
        // (th <= FAST_MAX_PX rows: at most 1024 * 255^2 < 2^32).
        let colm = colm.get_mut(..rw).ok_or(MatchError::WindowTooSmall)?;
        let colmm = colmm.get_mut(..rw).ok_or(MatchError::WindowTooSmall)?;
        let mut outs = out.iter_mut();
        for r in 0..grid.rows {
            let y0 = r * step;
            if r == 0 || step >= th {
                colm.fill(0);
                colmm.fill(0);
                for y in y0..y0 + th {
                    add_row(colm, colmm, region.row(y), true)?;
                }
            } else {
                for y in y0 - step..y0 {
                    add_row(colm, colmm, region.row(y), false)?;
                }
                for y in y0 - step + th..y0 + th {
                    add_row(colm, colmm, region.row(y), true)?;
                }
            }
            let mut c = 0usize;
            while c < grid.cols {
                // Stm of up to BLOCK horizontally adjacent windows at once (step 1: they
                // share the map bytes, kept in registers), else of one window.
                let nb = if step == 1 && c + BLOCK <= grid.cols {
                    BLOCK
                } else {
                    1
                };
                let base = y0 * stride + c * step;
                let mut stm = [0u64; BLOCK];
                for (y, wrow) in (0..th).zip(wt.chunks(tw)) {
                    let from = base + y * stride;
                    let mrow = data
                        .get(from..from + tw + nb - 1)
                        .ok_or(MatchError::WindowTooSmall)?;
                    if nb == BLOCK {
                        for (s, a) in stm.iter_mut().zip(dot4(wrow, mrow)) {
                            *s += a as u64;
                        }
                    } else {
                        // tw <= FAST_MAX_COLS = 256 pixels: 256 * 255^3 < 2^32.
                        let mut acc = 0u32;
                        for (&a, &m) in wrow.iter().zip(mrow) {
                            acc += a as u32 * m as u32;
                        }
                        stm[0] += acc as u64;
                    }
                }
                for (i, &stm) in stm.iter().enumerate().take(nb) {
                    let x0 = (c + i) * step;
                    let (Some(cm), Some(cmm)) = (colm.get(x0..x0 + tw), colmm.get(x0..x0 + tw))
                    else {
                        return Err(MatchError::WindowTooSmall);
                    };
                    let bm: u64 = cm.iter().map(|&v| v as u64).sum();
                    let bmm: u64 = cmm.iter().map(|&v| v as u64).sum();
                    let wbase = y0 * stride + x0;
                    let win = data
                        .get(wbase..wbase + span)
                        .ok_or(MatchError::WindowTooSmall)?;
                    let (cs, css) = corrections(win, koff, kdelta);
                    let sm = (wref as i64 * bm as i64 + cs) as u64;
                    let smm = (wref as i64 * bmm as i64 + css) as u64;
                    if let Some(o) = outs.next() {
                        *o = self.combine(ts, sm, smm, stm);
                    }
                }
                c += nb;
            }
        }
        ops.macs += (n as u64 + 2 * k as u64) * grid.len() as u64;
        ops.windows += grid.len() as u64;
        Ok(true)
    }
}

/// Windows whose `Stm` the fast path computes together (step 1).
const BLOCK: usize = 4;

/// Dot products of `w` with `m` at offsets 0..4 (`m` holds `w.len() + 3` bytes; fewer
/// and the missing products are 0). `w.len() <= 256` keeps each sum in u32
/// (`256 * 65025 * 255 < 2^32`). Each map byte is loaded once for the four windows: about
/// 1.5 instructions per MAC on a Cortex-M7 instead of about 5.
#[inline(always)]
fn dot4(w: &[u16], m: &[u8]) -> [u32; 4] {
    let (Some(&m0), Some(&m1), Some(&m2), Some(rest)) = (m.first(), m.get(1), m.get(2), m.get(3..))
    else {
        return [0; 4];
    };
    let (mut p0, mut p1, mut p2) = (m0 as u32, m1 as u32, m2 as u32);
    let (mut a0, mut a1, mut a2, mut a3) = (0u32, 0u32, 0u32, 0u32);
    for (&a, &n) in w.iter().zip(rest) {
        let (a, n) = (a as u32, n as u32);
        a0 += a * p0;
        a1 += a * p1;
        a2 += a * p2;
        a3 += a * n;
        p0 = p1;
        p1 = p2;
        p2 = n;
    }
    [a0, a1, a2, a3]
}

/// `(sum_K d m, sum_K d m^2)` over the differing pixels (window offsets `koff`, weight
/// differences `kdelta`). Partial sums in i32 over 128 entries (`128 * 255^3 < 2^31`).
fn corrections(win: &[u8], koff: &[u16], kdelta: &[i16]) -> (i64, i64) {
    let (mut cs, mut css) = (0i64, 0i64);
    for (o, d) in koff.chunks(128).zip(kdelta.chunks(128)) {
        let (mut a, mut b) = (0i32, 0i32);
        for (&o, &d) in o.iter().zip(d) {
            let m = win.get(o as usize).copied().unwrap_or(0) as i32;
            let dm = d as i32 * m;
            a += dm;
            b += dm * m;
        }
        cs += a as i64;
        css += b as i64;
    }
    (cs, css)
}

/// `[sum w m, sum w m^2, sum w t m]` of one row (at most [`ROW_CHUNK`] pixels, so the
/// sums fit u32).
#[inline(always)]
fn sums1(t: &[u8], w: &[u8], m: &[u8]) -> [u32; 3] {
    let (mut a, mut b, mut c) = (0u32, 0u32, 0u32);
    for ((&t, &w), &m) in t.iter().zip(w).zip(m) {
        let wm = w as u32 * m as u32;
        a += wm;
        b += wm * m as u32;
        c += wm * t as u32;
    }
    [a, b, c]
}

/// [`sums1`] of one row for two adjacent windows (`m` holds `t.len() + 1` bytes; fewer
/// and the sums are 0): each template pixel is loaded once for both.
#[inline(always)]
fn sums2(t: &[u8], w: &[u8], m: &[u8]) -> [[u32; 3]; 2] {
    let (Some(&m0), Some(rest)) = (m.first(), m.get(1..)) else {
        return [[0; 3]; 2];
    };
    let mut p = m0 as u32;
    let (mut a0, mut b0, mut c0, mut a1, mut b1, mut c1) = (0u32, 0u32, 0u32, 0u32, 0u32, 0u32);
    for ((&t, &w), &n) in t.iter().zip(w).zip(rest) {
        let (t, w, n) = (t as u32, w as u32, n as u32);
        let wm0 = w * p;
        a0 += wm0;
        b0 += wm0 * p;
        c0 += wm0 * t;
        let wm1 = w * n;
        a1 += wm1;
        b1 += wm1 * n;
        c1 += wm1 * t;
        p = n;
    }
    [[a0, b0, c0], [a1, b1, c1]]
}

/// Pixels per u32 partial sum in the general path (256 * 255^3 < 2^32).
const ROW_CHUNK: usize = 256;

/// Largest template (pixels) of the fast dense path; its `w t` table lives in the static pool
/// (`FAST_MAX_PX` x 2 bytes).
pub const FAST_MAX_PX: usize = 1024;

/// Most pixels whose weight differs from the largest, in the fast dense path (static table
/// of `FAST_MAX_K` x 4 bytes); more and the general path runs.
pub const FAST_MAX_K: usize = 640;

/// Widest region (pixels) of the fast dense path (column sums in the static pool,
/// `FAST_MAX_COLS` x 8 bytes); also bounds the template width to 256 pixels.
pub const FAST_MAX_COLS: usize = 256;

/// Tables of the fast dense path: `w t` per template pixel, the differing-weight pixels,
/// and the region's column sums.
struct FastTables {
    wt: [u16; FAST_MAX_PX],
    koff: [u16; FAST_MAX_K],
    kdelta: [i16; FAST_MAX_K],
    colm: [u32; FAST_MAX_COLS],
    colmm: [u32; FAST_MAX_COLS],
}

impl FastTables {
    const fn new() -> Self {
        Self {
            wt: [0; FAST_MAX_PX],
            koff: [0; FAST_MAX_K],
            kdelta: [0; FAST_MAX_K],
            colm: [0; FAST_MAX_COLS],
            colmm: [0; FAST_MAX_COLS],
        }
    }
}

// Where the tables live. On a host (x86_64 and the like: threads, and stack probes for
// frames of 4 KiB and more, see docs/toolchain.md) in a static pool. On bare metal (the
// flight firmware: one thread, no probes) on the stack of `dense_fast`, where they share the
// 20 KiB stack region with the other stages (the measured peak is the CNN stage's, not this
// one), instead of adding 6.6 KB of statics to a RAM region that has 1.7 KB left
// (docs/flight-target.md). A caller-provided table for the flight path is the lead's
// follow-up in the `orbfix::fix` pipeline.
#[cfg(not(target_os = "none"))]
static FAST_TABLES: [Slot<FastTables>; POOL_SLOTS] =
    [const { Slot::new(FastTables::new()) }; POOL_SLOTS];

/// Adds (`add`) or subtracts one region row's `m` and `m^2` into the column sums.
fn add_row(
    colm: &mut [u32],
    colmm: &mut [u32],
    row: Option<&[u8]>,
    add: bool,
) -> Result<(), MatchError> {
    let row = row.ok_or(MatchError::WindowTooSmall)?;
    for ((s, ss), &m) in colm.iter_mut().zip(colmm.iter_mut()).zip(row) {
        let (m, mm) = (m as u32, m as u32 * m as u32);
        if add {
            *s += m;
            *ss += mm;
        } else {
            *s -= m;
            *ss -= mm;
        }
    }
    Ok(())
}

impl Matcher for Ncc {
    fn name(&self) -> &'static str {
        "ncc"
    }

    fn score(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        window: &ImageView<'_>,
        ops: &mut OpCounts,
    ) -> Result<f32, MatchError> {
        check_inputs(template, weight, window)?;
        let ts = template_stats(template, weight)?;
        self.window(&ts, template, weight, window, ops)
    }

    fn dense(
        &self,
        template: &ImageView<'_>,
        weight: &ImageView<'_>,
        region: &ImageView<'_>,
        step: usize,
        out: &mut [f32],
        ops: &mut OpCounts,
    ) -> Result<Grid, MatchError> {
        check_inputs(template, weight, region)?;
        let (grid, out) = Grid::dense(template, region, step, out)?;
        let ts = template_stats(template, weight)?;
        if self.dense_fast(&ts, template, weight, region, step, &grid, out, ops)? {
            return Ok(grid);
        }
        let (tw, th) = (template.width(), template.height());
        if step == 1 && tw <= ROW_CHUNK {
            // Pairs of adjacent windows share each template pixel's loads.
            let mut outs = out.iter_mut();
            for r in 0..grid.rows {
                let mut c = 0usize;
                while c < grid.cols {
                    let nb = if c + 2 <= grid.cols { 2 } else { 1 };
                    let mut acc = [[0u64; 3]; 2];
                    for y in 0..th {
                        let m = region
                            .row(r + y)
                            .and_then(|row| row.get(c..c + tw + nb - 1));
                        let (Some(t), Some(w), Some(m)) = (template.row(y), weight.row(y), m)
                        else {
                            return Err(MatchError::WindowTooSmall);
                        };
                        let p = if nb == 2 {
                            sums2(t, w, m)
                        } else {
                            [sums1(t, w, m), [0; 3]]
                        };
                        for (a, p) in acc.iter_mut().zip(p) {
                            for (a, p) in a.iter_mut().zip(p) {
                                *a += p as u64;
                            }
                        }
                    }
                    for a in acc.iter().take(nb) {
                        if let Some(o) = outs.next() {
                            *o = self.combine(&ts, a[0], a[1], a[2]);
                        }
                    }
                    ops.macs += (3 * tw * th * nb) as u64;
                    ops.windows += nb as u64;
                    c += nb;
                }
            }
            return Ok(grid);
        }
        let cols = NonZeroUsize::new(grid.cols).ok_or(MatchError::WindowTooSmall)?;
        for (i, o) in out.iter_mut().enumerate() {
            let (c, r) = (i % cols, i / cols);
            let win = region
                .sub(c * step, r * step, tw, th)
                .ok_or(MatchError::WindowTooSmall)?;
            *o = self.window(&ts, template, weight, &win, ops)?;
        }
        Ok(grid)
    }
}

#[cfg(test)]
mod tests;
