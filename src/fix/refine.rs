//! The refinement stage: masked, high-passed NCC of the top-down image against the map
//! around a coarse (CNN) window, in two levels, with a sub-pixel peak.
//!
//! Both images are high-passed at full resolution with the same box radius
//! ([`crate::matcher::prep::highpass`]: the top-down image under its mask here, the map on
//! the ground, as the map product's refinement plane), then block-averaged to the level's factor
//! ([`crate::localize::downsample_weighted`], [`crate::localize::downsample_mean`]). The
//! first level scores every level pixel within its reach of the CNN window, the second
//! every level pixel within its reach of the first level's best, and the parabola vertex
//! per axis of the second level's response ([`crate::peak`]) gives the sub-pixel position.

use super::scratch::RefineLayout;
use super::{FixConfig, FixError};
use crate::image::{ImageView, ImageViewMut};
use crate::localize::{downsample_mean, downsample_weighted};
use crate::matcher::ncc::Ncc;
use crate::matcher::prep::{highpass, rectify};
use crate::matcher::{Matcher, OpCounts};
use crate::peak::peak_offset_2d;

/// The result of refining one coarse window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refined {
    /// Top-left column of the best template position, map pixels (sub-pixel).
    pub col: f32,
    /// Top-left row, map pixels (sub-pixel).
    pub row: f32,
    /// NCC score of the fine level's best position, `[-1, 1]`.
    pub score: f32,
    /// The best position of either level lies on the edge of its searched range (the NCC
    /// peak is not inside the reach: not trusted by [`super::RefineMode::Auto`]).
    pub at_edge: bool,
}

/// The two levels' templates and weights, built once per fix.
pub struct Templates<'b> {
    t0: ImageView<'b>,
    w0: ImageView<'b>,
    t1: ImageView<'b>,
    w1: ImageView<'b>,
}

fn split_image(buf: &mut [u8], w: usize, h: usize) -> Result<(&mut [u8], &mut [u8]), FixError> {
    w.checked_mul(h)
        .and_then(|len| buf.split_at_mut_checked(len))
        .ok_or(FixError::ScratchTooSmall { buffer: "work" })
}

fn view_mut(buf: &mut [u8], w: usize, h: usize) -> Result<ImageViewMut<'_>, FixError> {
    ImageViewMut::new(buf, w, h).map_err(|_| FixError::ScratchTooSmall { buffer: "work" })
}

/// Builds the templates: high-pass of `top` under `mask` into the phase area, then both
/// levels' block averages into `persist`. `hp` is the high-pass scratch.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub fn build_templates<'b>(
    cfg: &FixConfig,
    layout: &RefineLayout,
    top: &ImageView<'_>,
    mask: &ImageView<'_>,
    hp: &mut [u32],
    persist: &'b mut [u8],
    phase: &mut [u8],
    ops: &mut OpCounts,
) -> Result<Templates<'b>, FixError> {
    let n = cfg.grid.n;
    let [l0, l1] = cfg.refine.levels;
    let (hp_top, _) = split_image(phase, n, n)?;
    let mut hp_view = view_mut(hp_top, n, n)?;
    highpass(top, Some(mask), cfg.highpass_radius_px(), &mut hp_view, hp)?;
    if cfg.refine.rectify {
        rectify(&mut hp_view);
    }
    let (a, b) = (layout.a, layout.b);
    let (t0, rest) = split_image(persist, a, a)?;
    let (w0, rest) = split_image(rest, a, a)?;
    let (t1, rest) = split_image(rest, b, b)?;
    let (w1, _) = split_image(rest, b, b)?;
    let src = hp_view.as_view();
    {
        let (mut tv, mut wv) = (view_mut(t0, a, a)?, view_mut(w0, a, a)?);
        downsample_weighted(&src, mask, l0.factor, &mut tv, &mut wv, ops)?;
        let (mut tv, mut wv) = (view_mut(t1, b, b)?, view_mut(w1, b, b)?);
        downsample_weighted(&src, mask, l1.factor, &mut tv, &mut wv, ops)?;
    }
    let img = |d: &'b [u8], s: usize| {
        ImageView::new(d, s, s).map_err(|_| FixError::ScratchTooSmall { buffer: "work" })
    };
    Ok(Templates {
        t0: img(t0, a)?,
        w0: img(w0, a)?,
        t1: img(t1, b)?,
        w1: img(w1, b)?,
    })
}

/// Positions searched along one axis: `centre +- reach` steps of `step` pixels, clipped to
/// `[lo, hi]` (top-left map pixels). Returns the first position, the count, and whether
/// either end was cut short of the reach.
fn axis_range(centre: usize, reach: usize, step: usize, lo: usize, hi: usize) -> (usize, usize) {
    let step = step.max(1);
    let below = (centre.saturating_sub(lo) / step).min(reach);
    let above = (hi.saturating_sub(centre) / step).min(reach);
    (centre.saturating_sub(below * step), below + above + 1)
}

/// Scores one level: the template `(t, w)` at every level pixel of the positions
/// `x0 + i f`, `y0 + j f` (`cols x rows`, map pixels) using `region_hp` (the high-passed
/// region whose top-left is map pixel `(rx, ry)`), into `out`. Returns the best index and
/// score.
#[allow(clippy::too_many_arguments)]
fn score_level(
    t: &ImageView<'_>,
    w: &ImageView<'_>,
    region_hp: &ImageView<'_>,
    (rx, ry): (usize, usize),
    (x0, y0): (usize, usize),
    (cols, rows): (usize, usize),
    f: usize,
    patch: &mut [u8],
    out: &mut [f32],
    ops: &mut OpCounts,
) -> Result<(usize, f32), FixError> {
    let (pw, ph) = (cols - 1 + t.width(), rows - 1 + t.height());
    let (pbuf, _) = split_image(patch, pw, ph)?;
    let mut pv = view_mut(pbuf, pw, ph)?;
    downsample_mean(region_hp, x0 - rx, y0 - ry, f, &mut pv, ops)?;
    let g = Ncc::default().dense(t, w, &pv.as_view(), 1, out, ops)?;
    let scores = out.get(..g.len()).ok_or(FixError::ScratchTooSmall {
        buffer: "refine_floats",
    })?;
    let (mut bi, mut bs) = (0usize, f32::NEG_INFINITY);
    for (i, &s) in scores.iter().enumerate() {
        if s > bs {
            (bi, bs) = (i, s);
        }
    }
    Ok((bi, bs))
}

/// Refines the coarse window whose top-left is map pixel `(wx, wy)` on the map product's
/// refinement plane `plane` (the map high-passed on the ground with this configuration's
/// settings: [`crate::map_product::write_refine_plane`]). The searched positions keep the
/// template inside the region of `layout.region_w x layout.region_h` pixels around the
/// window (clipped to the map), where every high-pass box of the plane is whole.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub fn refine_window(
    cfg: &FixConfig,
    layout: &RefineLayout,
    templates: &Templates<'_>,
    plane: &ImageView<'_>,
    (wx, wy): (usize, usize),
    phase: &mut [u8],
    floats: &mut [f32],
    ops: &mut OpCounts,
) -> Result<Refined, FixError> {
    let n = cfg.grid.n;
    let [l0, l1] = cfg.refine.levels;
    let (mw, mh) = (plane.width(), plane.height());
    let margin = cfg.refine_margin_px();
    let (rw, rh) = (layout.region_w, layout.region_h);
    let rx = wx.saturating_sub(margin).min(mw - rw);
    let ry = wy.saturating_sub(margin).min(mh - rh);
    let region_hp = plane
        .sub(rx, ry, rw, rh)
        .ok_or(FixError::ScratchTooSmall { buffer: "work" })?;
    // Template top-left positions that keep the template inside the region.
    let (lo_x, hi_x) = (rx, rx + rw - n);
    let (lo_y, hi_y) = (ry, ry + rh - n);

    // Level 0 around the CNN window.
    let (f0, f1) = (l0.factor, l1.factor);
    let (x0, c0) = axis_range(wx.max(lo_x).min(hi_x), l0.reach_px, f0, lo_x, hi_x);
    let (y0, r0) = axis_range(wy.max(lo_y).min(hi_y), l0.reach_px, f0, lo_y, hi_y);
    let patch_buf = phase;
    let (bi, _) = score_level(
        &templates.t0,
        &templates.w0,
        &region_hp,
        (rx, ry),
        (x0, y0),
        (c0, r0),
        f0,
        patch_buf,
        floats,
        ops,
    )?;
    let c0 = c0.max(1);
    let (bc, br) = (bi % c0, bi / c0);
    let edge0 = bc == 0 || br == 0 || bc + 1 == c0 || br + 1 == r0;
    let (bx, by) = (x0 + bc * f0, y0 + br * f0);

    // Level 1 around the level-0 best.
    let (x1, c1) = axis_range(bx, l1.reach_px, f1, lo_x, hi_x);
    let (y1, r1) = axis_range(by, l1.reach_px, f1, lo_y, hi_y);
    let (bi, bs) = score_level(
        &templates.t1,
        &templates.w1,
        &region_hp,
        (rx, ry),
        (x1, y1),
        (c1, r1),
        f1,
        patch_buf,
        floats,
        ops,
    )?;
    let c1 = c1.max(1);
    let (bc, br) = (bi % c1, bi / c1);
    let edge1 = bc == 0 || br == 0 || bc + 1 == c1 || br + 1 == r1;
    let scores = floats.get(..c1 * r1).unwrap_or_default();
    let at = |c: usize, r: usize| {
        if c < c1 && r < r1 {
            scores.get(r * c1 + c).copied()
        } else {
            None
        }
    };
    let (dx, dy) = peak_offset_2d(at, bc, br);
    Ok(Refined {
        col: x1 as f32 + (bc as f32 + dx) * f1 as f32,
        row: y1 as f32 + (br as f32 + dy) * f1 as f32,
        score: bs,
        at_edge: edge0 || edge1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_ranges_clip_to_the_map() {
        assert_eq!(axis_range(100, 5, 4, 0, 1000), (80, 11));
        assert_eq!(axis_range(6, 5, 4, 0, 1000), (2, 7));
        assert_eq!(axis_range(100, 5, 4, 0, 104), (80, 7));
        assert_eq!(axis_range(0, 2, 2, 0, 0), (0, 1));
    }
}
