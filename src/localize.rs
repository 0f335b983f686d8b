//! Localization: find where a north-up top-down image (centred on the rover) lies in an
//! orbital map region, in bounded caller-provided memory.
//!
//! Two searches, both over any [`Matcher`]:
//! - [`window_search`]: the 2018 study's sliding window (template-sized windows every
//!   `stride` pixels: 50 m windows at a 12.5 m stride over 300 x 300 m = 21 x 21 = 441);
//! - [`localize`]: coarse-to-fine dense search. The template, its weight mask and the map are
//!   block-averaged by `coarse_factor` (e.g. 0.25 -> 2 m/px) and scored at every coarse
//!   pixel; the best peaks after non-maximum suppression are re-scored at `fine_factor`
//!   (e.g. 0.5 m/px) in a small neighbourhood, the best one is refined to sub-pixel with a
//!   parabola fit per axis, peaks on the search border are flagged (MARSAUTOLOCO declares
//!   them failures), and a confidence is computed from the coarse response:
//!   `(s1 - s2) / (s1 - mean)` with `s1`, `s2` the two best peaks after suppression, in
//!   `[0, 1]` (0 for a flat response).
//!
//! Scratch memory: [`buffer_sizes`] gives the byte and `f32` counts a call needs; the
//! caller provides them (static arrays on the target).

use crate::geo::GeoRef;
use crate::image::{ImageView, ImageViewMut};
use crate::matcher::{Grid, MatchError, Matcher, OpCounts};
use core::num::{NonZeroU32, NonZeroUsize};

/// Largest number of candidates a [`Fix`] carries.
pub const MAX_CANDIDATES: usize = 8;

/// Errors of a localization.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LocalizeError {
    /// The matcher failed (bad sizes, all "no data", featureless template).
    Match(MatchError),
    /// The map's and the top-down image's resolutions differ (metres per pixel).
    ResolutionMismatch {
        /// Map, metres per pixel.
        map_m_per_px: f32,
        /// Top-down image, metres per pixel.
        top_m_per_px: f32,
    },
    /// The prior position (metres) is outside the map.
    PriorOutsideMap,
    /// The valid (non-hole) share of the top-down image is below the configured minimum.
    TooLittleCoverage {
        /// Valid share found, per mille.
        permille: u32,
    },
    /// Template size not a multiple of the coarse factor, or factors inconsistent
    /// (`coarse_factor` must be a multiple of `fine_factor`, both >= 1).
    BadConfig,
    /// The scratch buffers are smaller than [`buffer_sizes`] asks.
    ScratchTooSmall,
}

impl From<MatchError> for LocalizeError {
    fn from(e: MatchError) -> Self {
        LocalizeError::Match(e)
    }
}

/// Tuning of [`localize`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LocalizeConfig {
    /// Block-averaging factor of the dense coarse pass (pixels of the input per coarse
    /// pixel; 8 at 0.25 m/px gives 2 m/px).
    pub coarse_factor: usize,
    /// Block-averaging factor of the refinement pass (2 at 0.25 m/px gives 0.5 m/px).
    pub fine_factor: usize,
    /// Coarse peaks re-scored at the fine level (at most [`MAX_CANDIDATES`]).
    pub refine_peaks: usize,
    /// Non-maximum suppression radius between candidates, metres.
    pub nms_radius_m: f32,
    /// Minimum valid share of the top-down image, per mille (e.g. 50 = 5 %).
    pub min_coverage_permille: u32,
}

impl Default for LocalizeConfig {
    fn default() -> Self {
        Self {
            coarse_factor: 8,
            fine_factor: 2,
            refine_peaks: 3,
            nms_radius_m: 12.5,
            min_coverage_permille: 50,
        }
    }
}

/// One candidate position.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Candidate {
    /// Rover east, metres.
    pub x_m: f32,
    /// Rover north, metres.
    pub y_m: f32,
    /// Matcher score at this position (fine level when `refined`, else coarse).
    pub score: f32,
    /// Whether the position was re-scored at the fine level.
    pub refined: bool,
    /// The coarse score of the candidate's window (whatever `refined`): the coarse
    /// matcher's, or in the fix the CNN's cosine plus the relief stage's correlation.
    pub coarse: f32,
}

/// The result of [`localize`].
#[derive(Clone, Debug, PartialEq)]
pub struct Fix {
    /// Rover east, metres (sub-pixel refined).
    pub x_m: f32,
    /// Rover north, metres (sub-pixel refined).
    pub y_m: f32,
    /// Fine-level score of the fix.
    pub score: f32,
    /// Distinctiveness of the peak, `[0, 1]`: `(s1 - s2) / (s1 - mean)` on the coarse
    /// response after non-maximum suppression (0 = ambiguous or flat).
    pub confidence: f32,
    /// Best coarse score `s1`.
    pub peak_score: f32,
    /// Second coarse peak `s2` after suppression (equal to `s1` when there is none).
    pub second_score: f32,
    /// The peak lies on the border of the searched region: the true position may be outside
    /// it; treat the fix as a failure.
    pub on_border: bool,
    /// Best candidates, best first (refined ones by fine score, then the rest by coarse
    /// score).
    pub candidates: heapless::Vec<Candidate, MAX_CANDIDATES>,
    /// The coarse response grid (`step` = coarse factor, input pixels); after the call its
    /// scores are in `floats[..coarse_grid.len()]` (row-major, position `(c, r)` = template
    /// top-left at input pixel `(c * step, r * step)`).
    pub coarse_grid: Grid,
    /// Operations spent in the coarse pass (downsampling included).
    pub ops_coarse: OpCounts,
    /// Operations spent in the refinement pass (downsampling included).
    pub ops_fine: OpCounts,
}

/// Scratch sizes of one [`localize`] call: `(bytes, f32s)`.
///
/// `tw x th`: top-down image, pixels; `mw x mh`: map region, pixels.
pub fn buffer_sizes(
    tw: usize,
    th: usize,
    mw: usize,
    mh: usize,
    cfg: &LocalizeConfig,
) -> Result<(usize, usize), LocalizeError> {
    let l = Layout::new(tw, th, mw, mh, cfg)?;
    Ok((l.bytes(), l.floats()))
}

/// Sizes of every pyramid level of one call.
#[derive(Clone, Copy, Debug)]
struct Layout {
    cf: usize,
    ff: usize,
    /// Coarse template and map.
    ctw: usize,
    cth: usize,
    cmw: usize,
    cmh: usize,
    /// Fine template.
    ftw: usize,
    fth: usize,
    /// Fine neighbourhood radius (fine pixels) and fine map size.
    rad: usize,
    fmw: usize,
    fmh: usize,
}

impl Layout {
    fn new(
        tw: usize,
        th: usize,
        mw: usize,
        mh: usize,
        cfg: &LocalizeConfig,
    ) -> Result<Self, LocalizeError> {
        let (cf, ff) = (cfg.coarse_factor, cfg.fine_factor);
        if cf == 0 || ff == 0 || cf % ff != 0 || tw % cf != 0 || th % cf != 0 || tw == 0 {
            return Err(LocalizeError::BadConfig);
        }
        if th == 0 || mw < tw || mh < th {
            return Err(LocalizeError::Match(MatchError::WindowTooSmall));
        }
        Ok(Self {
            cf,
            ff,
            ctw: tw / cf,
            cth: th / cf,
            cmw: mw / cf,
            cmh: mh / cf,
            ftw: tw / ff,
            fth: th / ff,
            rad: cf / ff + 1,
            fmw: mw / ff,
            fmh: mh / ff,
        })
    }

    fn patch_w(&self) -> usize {
        (self.ftw + 2 * self.rad).min(self.fmw)
    }

    fn patch_h(&self) -> usize {
        (self.fth + 2 * self.rad).min(self.fmh)
    }

    fn bytes(&self) -> usize {
        2 * self.ctw * self.cth
            + self.cmw * self.cmh
            + 2 * self.ftw * self.fth
            + self.patch_w() * self.patch_h()
    }

    fn floats(&self) -> usize {
        let coarse = (self.cmw - self.ctw + 1) * (self.cmh - self.cth + 1);
        let fine = (2 * self.rad + 1) * (2 * self.rad + 1);
        coarse + fine
    }
}

/// Block-averages a template and its weights by `f`: each output pixel is the weighted
/// mean of its block (holes excluded) and its weight the block's mean weight (at least 1
/// when any pixel of the block is valid; 0 when none is).
pub fn downsample_weighted(
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
    f: usize,
    t_out: &mut ImageViewMut<'_>,
    w_out: &mut ImageViewMut<'_>,
    ops: &mut OpCounts,
) -> Result<(), LocalizeError> {
    let (ow, oh) = (t_out.width(), t_out.height());
    let area = block_area(f)?;
    if w_out.width() != ow
        || w_out.height() != oh
        || ow.saturating_mul(f) > template.width()
        || oh.saturating_mul(f) > template.height()
        || weight.width() != template.width()
        || weight.height() != template.height()
    {
        return Err(LocalizeError::BadConfig);
    }
    for oy in 0..oh {
        let (Some(t_row), Some(w_row)) = (t_out.row_mut(oy), w_out.row_mut(oy)) else {
            return Err(LocalizeError::BadConfig);
        };
        for (ox, (t_dst, w_dst)) in t_row.iter_mut().zip(w_row.iter_mut()).enumerate() {
            let (mut sw, mut swt) = (0u32, 0u32);
            let xs = ox * f;
            for y in oy * f..(oy + 1) * f {
                let t = template.row(y).and_then(|r| r.get(xs..xs + f));
                let w = weight.row(y).and_then(|r| r.get(xs..xs + f));
                let (Some(t), Some(w)) = (t, w) else {
                    return Err(LocalizeError::BadConfig);
                };
                for (&tv, &wv) in t.iter().zip(w) {
                    let (tv, wv) = (tv as u32, wv as u32);
                    sw += wv;
                    swt += wv * tv;
                }
            }
            let (tv, wv) = match (swt + sw / 2).checked_div(sw) {
                None => (0, 0),
                Some(t) => (t, ((sw + area.get() / 2) / area).clamp(1, 255)),
            };
            *t_dst = tv as u8;
            *w_dst = wv as u8;
        }
    }
    ops.downsample_px += (ow * oh * f * f) as u64;
    Ok(())
}

/// Block-averages the `out.width() x out.height()` blocks of `f x f` pixels of `src`
/// starting at pixel `(x0, y0)` (rounded mean).
pub fn downsample_mean(
    src: &ImageView<'_>,
    x0: usize,
    y0: usize,
    f: usize,
    out: &mut ImageViewMut<'_>,
    ops: &mut OpCounts,
) -> Result<(), LocalizeError> {
    let (ow, oh) = (out.width(), out.height());
    let area = block_area(f)?;
    let ends = |o: usize, n: usize| n.checked_mul(f).and_then(|e| e.checked_add(o));
    if ends(x0, ow).is_none_or(|e| e > src.width()) || ends(y0, oh).is_none_or(|e| e > src.height())
    {
        return Err(LocalizeError::BadConfig);
    }
    for oy in 0..oh {
        let Some(dst) = out.row_mut(oy) else {
            return Err(LocalizeError::BadConfig);
        };
        for (ox, d) in dst.iter_mut().enumerate() {
            let mut s = 0u32;
            for y in y0 + oy * f..y0 + (oy + 1) * f {
                let Some(row) = src.row(y) else {
                    return Err(LocalizeError::BadConfig);
                };
                let xs = x0 + ox * f;
                let Some(px) = row.get(xs..xs + f) else {
                    return Err(LocalizeError::BadConfig);
                };
                s += px.iter().map(|&v| v as u32).sum::<u32>();
            }
            *d = ((s + area.get() / 2) / area) as u8;
        }
    }
    ops.downsample_px += (ow * oh * f * f) as u64;
    Ok(())
}

/// Pixels in an `f x f` block, non-zero (`BadConfig` for `f == 0` or an area whose `u32`
/// sums could overflow: the weighted sum reaches `f^2 * 255 * 255`, so `f <= 257`).
fn block_area(f: usize) -> Result<NonZeroU32, LocalizeError> {
    f.checked_mul(f)
        .filter(|&a| a <= (u32::MAX / (255 * 255)) as usize)
        .and_then(|a| u32::try_from(a).ok())
        .and_then(NonZeroU32::new)
        .ok_or(LocalizeError::BadConfig)
}

/// World position (metres) of the rover when the template's top-left pixel lies at map
/// pixel `(col, row)` (continuous; the rover is at the template centre).
pub fn rover_position(geo: &GeoRef, col: f32, row: f32, tw: usize, th: usize) -> (f32, f32) {
    geo.to_world(col + 0.5 * tw as f32, row + 0.5 * th as f32)
}

/// Sliding-window scores (the study's search): the template scored against the map at
/// every `stride` pixels (row-major into `scores`). Returns the window grid.
pub fn window_search<M: Matcher + ?Sized>(
    matcher: &M,
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
    map: &ImageView<'_>,
    stride: usize,
    scores: &mut [f32],
    ops: &mut OpCounts,
) -> Result<Grid, LocalizeError> {
    Ok(matcher.dense(template, weight, map, stride, scores, ops)?)
}

/// Index of the window (of `grid`, `tw x th` windows) whose centre is nearest to the world
/// point `(x_m, y_m)`.
pub fn nearest_window(
    grid: &Grid,
    geo: &GeoRef,
    tw: usize,
    th: usize,
    x_m: f32,
    y_m: f32,
) -> usize {
    let (c, r) = geo.to_pixel(x_m, y_m);
    let s = grid.step() as f32;
    let ci = libm::roundf((c - 0.5 * tw as f32) / s).clamp(0.0, (grid.cols() - 1) as f32);
    let ri = libm::roundf((r - 0.5 * th as f32) / s).clamp(0.0, (grid.rows() - 1) as f32);
    ri as usize * grid.cols() + ci as usize
}

/// Rank (0 = best) of `scores[index]` among `scores`: the number of scores strictly
/// greater (ties count in the window's favour). `None` for an index out of range.
pub fn rank_of(scores: &[f32], index: usize) -> Option<usize> {
    let s = *scores.get(index)?;
    Some(scores.iter().filter(|&&v| v > s).count())
}

/// Best peaks of a response grid after non-maximum suppression (`radius` grid cells,
/// Chebyshev), best first: `(index, score)`.
fn nms_peaks(
    resp: &[f32],
    cols: usize,
    radius: usize,
    k: usize,
) -> heapless::Vec<(usize, f32), MAX_CANDIDATES> {
    let mut peaks: heapless::Vec<(usize, f32), MAX_CANDIDATES> = heapless::Vec::new();
    let Some(cols) = NonZeroUsize::new(cols) else {
        return peaks;
    };
    let k = k.min(MAX_CANDIDATES);
    while peaks.len() < k {
        let mut best: Option<(usize, f32)> = None;
        for (i, &s) in resp.iter().enumerate() {
            if !s.is_finite() || best.is_some_and(|(_, b)| s <= b) {
                continue;
            }
            let (c, r) = (i % cols, i / cols);
            let near = peaks.iter().any(|&(p, _)| {
                let (pc, pr) = (p % cols, p / cols);
                c.abs_diff(pc) <= radius && r.abs_diff(pr) <= radius
            });
            if !near {
                best = Some((i, s));
            }
        }
        match best {
            Some(b) => {
                if peaks.push(b).is_err() {
                    break;
                }
            }
            None => break,
        }
    }
    peaks
}

/// Stable insertion sort of a few candidates, best score first (`f32::total_cmp`); the
/// same order as `sort_unstable_by` gives for these short slices, without the standard
/// sort's panic paths.
fn sort_by_score_desc(c: &mut [Candidate]) {
    for i in 1..c.len() {
        for j in (1..=i).rev() {
            match c.get_mut(j - 1..=j) {
                Some([a, b]) if b.score.total_cmp(&a.score).is_gt() => core::mem::swap(a, b),
                _ => break,
            }
        }
    }
}

/// Splits a byte buffer into an image of `w x h`, returning the rest.
fn take_image(
    buf: &mut [u8],
    w: usize,
    h: usize,
) -> Result<(ImageViewMut<'_>, &mut [u8]), LocalizeError> {
    if buf.len() < w * h {
        return Err(LocalizeError::ScratchTooSmall);
    }
    let (a, b) = buf.split_at_mut(w * h);
    let img = ImageViewMut::new(a, w, h).map_err(|_| LocalizeError::ScratchTooSmall)?;
    Ok((img, b))
}

/// Coarse-to-fine localization of a top-down image in a map region.
///
/// - `template`, `weight`: the reprojected top-down image centred on the rover and its
///   weight mask (0 = no data), both `m_per_px` metres per pixel (`top_m_per_px`);
/// - `map`, `geo`: the orbital map region and its georeference (same resolution);
/// - `prior_x_m`, `prior_y_m`: the prior position, metres; must lie inside the map;
/// - `bytes`, `floats`: scratch of at least [`buffer_sizes`].
#[allow(clippy::too_many_arguments)]
pub fn localize<M: Matcher + ?Sized>(
    matcher: &M,
    template: &ImageView<'_>,
    weight: &ImageView<'_>,
    top_m_per_px: f32,
    map: &ImageView<'_>,
    geo: &GeoRef,
    prior_x_m: f32,
    prior_y_m: f32,
    cfg: &LocalizeConfig,
    bytes: &mut [u8],
    floats: &mut [f32],
) -> Result<Fix, LocalizeError> {
    let rel = (geo.m_per_px() - top_m_per_px).abs() / geo.m_per_px();
    if !(top_m_per_px.is_finite() && rel <= 1e-3) {
        return Err(LocalizeError::ResolutionMismatch {
            map_m_per_px: geo.m_per_px(),
            top_m_per_px,
        });
    }
    let (pc, pr) = geo.to_pixel(prior_x_m, prior_y_m);
    if !(pc >= 0.0 && pr >= 0.0 && pc < map.width() as f32 && pr < map.height() as f32) {
        return Err(LocalizeError::PriorOutsideMap);
    }
    if template.width() != weight.width() || template.height() != weight.height() {
        return Err(MatchError::MaskSizeMismatch.into());
    }
    let (tw, th) = (template.width(), template.height());
    let l = Layout::new(tw, th, map.width(), map.height(), cfg)?;
    // Coverage.
    let mut valid = 0usize;
    for y in 0..th {
        if let Some(r) = weight.row(y) {
            valid += r.iter().filter(|&&w| w != 0).count();
        }
    }
    if valid == 0 {
        return Err(MatchError::NoValidPixels.into());
    }
    let permille = (valid * 1000).checked_div(tw * th).unwrap_or(0) as u32;
    if permille < cfg.min_coverage_permille {
        return Err(LocalizeError::TooLittleCoverage { permille });
    }
    if bytes.len() < l.bytes() || floats.len() < l.floats() {
        return Err(LocalizeError::ScratchTooSmall);
    }

    // Coarse pass.
    let mut ops_c = OpCounts::default();
    let (mut ct, rest) = take_image(bytes, l.ctw, l.cth)?;
    let (mut cw, rest) = take_image(rest, l.ctw, l.cth)?;
    let (mut cm, rest) = take_image(rest, l.cmw, l.cmh)?;
    let (mut ft, rest) = take_image(rest, l.ftw, l.fth)?;
    let (mut fw, rest) = take_image(rest, l.ftw, l.fth)?;
    let (mut patch, _) = take_image(rest, l.patch_w(), l.patch_h())?;
    downsample_weighted(template, weight, l.cf, &mut ct, &mut cw, &mut ops_c)?;
    downsample_mean(map, 0, 0, l.cf, &mut cm, &mut ops_c)?;
    let (resp, fresp) = floats
        .split_at_mut_checked(l.floats() - (2 * l.rad + 1) * (2 * l.rad + 1))
        .ok_or(LocalizeError::ScratchTooSmall)?;
    let grid = matcher.dense(
        &ct.as_view(),
        &cw.as_view(),
        &cm.as_view(),
        1,
        resp,
        &mut ops_c,
    )?;
    let resp = resp
        .get(..grid.len())
        .ok_or(LocalizeError::ScratchTooSmall)?;
    let cols = NonZeroUsize::new(grid.cols()).ok_or(LocalizeError::ScratchTooSmall)?;
    let mean = resp.iter().sum::<f32>() / resp.len() as f32;
    let coarse_m = geo.m_per_px() * l.cf as f32;
    let nms_cells = (cfg.nms_radius_m / coarse_m).max(1.0) as usize;
    let peaks = nms_peaks(resp, grid.cols(), nms_cells, MAX_CANDIDATES);
    let Some(&(best_idx, s1)) = peaks.first() else {
        return Err(MatchError::NoValidPixels.into());
    };
    let s2 = peaks.get(1).map_or(s1, |p| p.1);
    let confidence = if s1 - mean > 1e-6 {
        ((s1 - s2) / (s1 - mean)).clamp(0.0, 1.0)
    } else {
        0.0
    };

    // Fine pass around the best peaks.
    let mut ops_f = OpCounts::default();
    downsample_weighted(template, weight, l.ff, &mut ft, &mut fw, &mut ops_f)?;
    let ratio = l.cf.checked_div(l.ff).ok_or(LocalizeError::BadConfig)?;
    let mut cands: heapless::Vec<Candidate, MAX_CANDIDATES> = heapless::Vec::new();
    let mut refined_n = 0usize;
    let mut best_fine: Option<(f32, f32, f32, usize)> = None; // (col_px, row_px, score, peak)
    for (pi, &(idx, cs)) in peaks.iter().enumerate() {
        let (cc, cr) = (idx % cols, idx / cols);
        if pi < cfg.refine_peaks.min(MAX_CANDIDATES) {
            let (fc, fr) = (cc * ratio, cr * ratio);
            let (pw, ph) = (patch.width(), patch.height());
            let px0 = fc.saturating_sub(l.rad).min(l.fmw - pw);
            let py0 = fr.saturating_sub(l.rad).min(l.fmh - ph);
            downsample_mean(map, px0 * l.ff, py0 * l.ff, l.ff, &mut patch, &mut ops_f)?;
            let g = matcher.dense(
                &ft.as_view(),
                &fw.as_view(),
                &patch.as_view(),
                1,
                fresp,
                &mut ops_f,
            )?;
            let fr_s = fresp.get(..g.len()).ok_or(LocalizeError::ScratchTooSmall)?;
            let (mut bi, mut bs) = (0usize, f32::NEG_INFINITY);
            for (i, &s) in fr_s.iter().enumerate() {
                if s > bs {
                    bi = i;
                    bs = s;
                }
            }
            let g_cols = NonZeroUsize::new(g.cols()).ok_or(LocalizeError::ScratchTooSmall)?;
            let (bc, br) = (bi % g_cols, bi / g_cols);
            let at = |c: usize, r: usize| fr_s.get(r * g.cols() + c).copied();
            let dx = match (bc.checked_sub(1).and_then(|c| at(c, br)), at(bc + 1, br)) {
                (Some(a), Some(b)) => crate::peak::parabola_offset(a, bs, b),
                _ => 0.0,
            };
            let dy = match (br.checked_sub(1).and_then(|r| at(bc, r)), at(bc, br + 1)) {
                (Some(a), Some(b)) => crate::peak::parabola_offset(a, bs, b),
                _ => 0.0,
            };
            let col = ((px0 + bc) as f32 + dx) * l.ff as f32;
            let row = ((py0 + br) as f32 + dy) * l.ff as f32;
            let (x, y) = rover_position(geo, col, row, tw, th);
            let _ = cands.push(Candidate {
                x_m: x,
                y_m: y,
                score: bs,
                refined: true,
                coarse: cs,
            });
            refined_n += 1;
            if best_fine.is_none_or(|b| bs > b.2) {
                best_fine = Some((col, row, bs, idx));
            }
        } else {
            let (x, y) = rover_position(geo, (cc * l.cf) as f32, (cr * l.cf) as f32, tw, th);
            let _ = cands.push(Candidate {
                x_m: x,
                y_m: y,
                score: cs,
                refined: false,
                coarse: cs,
            });
        }
    }
    // Refined first, by fine score.
    sort_by_score_desc(cands.get_mut(..refined_n).unwrap_or_default());
    let (col, row, score, idx) = best_fine.unwrap_or((
        (best_idx % cols * l.cf) as f32,
        (best_idx / cols * l.cf) as f32,
        s1,
        best_idx,
    ));
    let (cc, cr) = (idx % cols, idx / cols);
    let on_border = cc == 0 || cr == 0 || cc + 1 == grid.cols() || cr + 1 == grid.rows();
    let (x_m, y_m) = rover_position(geo, col, row, tw, th);
    Ok(Fix {
        x_m,
        y_m,
        score,
        confidence,
        peak_score: s1,
        second_score: s2,
        on_border,
        candidates: cands,
        coarse_grid: grid.with_step(l.cf)?,
        ops_coarse: ops_c,
        ops_fine: ops_f,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nms_suppresses_neighbours() {
        let mut r = [0.0f32; 100];
        r[55] = 1.0;
        r[56] = 0.9;
        r[11] = 0.5;
        let p = nms_peaks(&r, 10, 2, 2);
        assert_eq!(p[0].0, 55);
        assert_eq!(p[1].0, 11);
    }

    #[test]
    fn ranks() {
        let s = [0.1, 0.5, 0.3, 0.5];
        assert_eq!(rank_of(&s, 1), Some(0));
        assert_eq!(rank_of(&s, 2), Some(2));
        assert_eq!(rank_of(&s, 9), None);
    }
}
