//! Window-first localization for matchers that score whole 50 m windows (the CNNs), where
//! the core's coarse-to-fine NCC path (which downsamples the template by the coarse factor,
//! e.g. to 25 px) does not apply: the CNN needs the full `n x n` top-down image (>= 64 px).
//!
//! 1. The study's window search: every `stride_px`-th window of the map (441 at 12.5 m),
//!    scored once (in flight, the window embeddings depend only on the map and are
//!    precomputed).
//! 2. Refinement: around each of the `REFINE_WINDOWS` best windows (non-maximum suppressed at
//!    one stride), a dense search of the same matcher at `FINE_STEP_PX` (8 px = 2 m at
//!    0.25 m/px) over +-`FINE_REACH_PX` (32 px = 8 m, i.e. the window's whole cell and a
//!    margin).
//! 3. Sub-step peak: a parabola through the best fine score and its two neighbours, per
//!    axis (clamped to half a step).
//!
//! Confidence: `(s1 - s2) / (s1 - mean)` over the window scores, `s1` the best fine score,
//! `s2` the best window score more than one stride (12.5 m) from the fix, `mean` the mean
//! window score; clamped to `[0, 1]` (the core's definition, on the window response).
//! `on_border`: the fine peak lies on an edge of its search grid that the map edge cut.
//!
//! A top-down image the CNN cannot embed (fewer than 1/8 of its 64 x 64 input cells valid,
//! or no contrast) gives **no fix**: the result is reported at the prior with confidence 0
//! and `on_border` set (counted as a declared failure), its window scores all -1.

use super::{Localization, MapRegion, MatcherSpec, TopDown};
use orbfix::image::ImageView;
use orbfix::localize::{Candidate, Fix};
use orbfix::matcher::{Grid, MatchError, OpCounts};
use std::time::Instant;

/// Windows refined by the dense search.
pub const REFINE_WINDOWS: usize = 3;
/// Step of the dense refinement, pixels of the map (8 px = 2 m at 0.25 m/px).
pub const FINE_STEP_PX: usize = 8;
/// Reach of the dense refinement around a window's position, pixels (32 px = 8 m).
pub const FINE_REACH_PX: usize = 32;

/// One refined candidate: top-left `(col, row)` of the best position in map pixels
/// (sub-step, fractional), its score, and whether it lies on a map-cut edge.
struct Refined {
    col: f64,
    row: f64,
    score: f32,
    on_border: bool,
}

fn parabola(l: f32, c: f32, r: f32) -> f64 {
    let den = (l - 2.0 * c + r) as f64;
    if den.abs() < 1e-12 || !den.is_finite() {
        return 0.0;
    }
    (0.5 * (l - r) as f64 / den).clamp(-0.5, 0.5)
}

fn refine(
    spec: &MatcherSpec,
    t: &ImageView<'_>,
    w: &ImageView<'_>,
    m: &ImageView<'_>,
    (c0, r0): (usize, usize),
    ops: &mut OpCounts,
) -> anyhow::Result<Refined> {
    let n = t.width();
    let (mw, mh) = (m.width(), m.height());
    let x0 = c0.saturating_sub(FINE_REACH_PX);
    let y0 = r0.saturating_sub(FINE_REACH_PX);
    let x1 = (c0 + FINE_REACH_PX).min(mw - n);
    let y1 = (r0 + FINE_REACH_PX).min(mh - n);
    // Whole steps from (x0, y0) that stay inside the map.
    let cols = (x1 - x0) / FINE_STEP_PX + 1;
    let rows = (y1 - y0) / FINE_STEP_PX + 1;
    let region = m
        .sub(
            x0,
            y0,
            n + (cols - 1) * FINE_STEP_PX,
            n + (rows - 1) * FINE_STEP_PX,
        )
        .ok_or_else(|| anyhow::anyhow!("refinement region outside the map"))?;
    let mut out = vec![0f32; cols * rows];
    let g = spec
        .matcher
        .dense(t, w, &region, FINE_STEP_PX, &mut out, ops)
        .map_err(|e| anyhow::anyhow!("dense refinement failed: {e:?}"))?;
    let mut best = 0usize;
    for (i, s) in out.iter().enumerate() {
        if *s > out[best] {
            best = i;
        }
    }
    let (bc, br) = (best % g.cols, best / g.cols);
    let at = |c: usize, r: usize| out[r * g.cols + c];
    let dx = if bc > 0 && bc + 1 < g.cols {
        parabola(at(bc - 1, br), at(bc, br), at(bc + 1, br))
    } else {
        0.0
    };
    let dy = if br > 0 && br + 1 < g.rows {
        parabola(at(bc, br - 1), at(bc, br), at(bc, br + 1))
    } else {
        0.0
    };
    let cut_w = c0 < FINE_REACH_PX && x0 == 0;
    let cut_n = r0 < FINE_REACH_PX && y0 == 0;
    let cut_e = c0 + FINE_REACH_PX > mw - n;
    let cut_s = r0 + FINE_REACH_PX > mh - n;
    let on_border = (bc == 0 && cut_w)
        || (br == 0 && cut_n)
        || (bc + 1 == g.cols && cut_e)
        || (br + 1 == g.rows && cut_s);
    Ok(Refined {
        col: x0 as f64 + (bc as f64 + dx) * FINE_STEP_PX as f64,
        row: y0 as f64 + (br as f64 + dy) * FINE_STEP_PX as f64,
        score: out[best],
        on_border,
    })
}

/// Window search, dense refinement of the best windows and sub-step peak (module docs).
pub fn localize_windows(
    spec: &MatcherSpec,
    top: &TopDown,
    map: &MapRegion,
    prior: (f64, f64),
    stride_px: usize,
) -> anyhow::Result<Localization> {
    let p = super::prepare(spec, top, map)?;
    let n = top.n;
    let t =
        ImageView::new(&p.top, n, n).map_err(|e| anyhow::anyhow!("bad top-down image: {e:?}"))?;
    let w = ImageView::new(&p.weights, n, n)
        .map_err(|e| anyhow::anyhow!("bad top-down mask: {e:?}"))?;
    let m = ImageView::new(&p.map, map.width, map.height)
        .map_err(|e| anyhow::anyhow!("map image does not match its size: {e:?}"))?;
    anyhow::ensure!(
        map.width >= n && map.height >= n && stride_px > 0,
        "map {} x {} px is smaller than the {n} px top-down image (or stride 0)",
        map.width,
        map.height
    );
    let grid = Grid::new(n, n, map.width, map.height, stride_px)
        .map_err(|e| anyhow::anyhow!("window grid: {e:?}"))?;
    let mut window_scores = vec![0f32; grid.len()];
    let mut window_ops = OpCounts::default();
    let t0 = Instant::now();
    match spec
        .matcher
        .dense(&t, &w, &m, stride_px, &mut window_scores, &mut window_ops)
    {
        Ok(_) => {}
        Err(MatchError::NoValidPixels | MatchError::FeaturelessTemplate) => {
            window_scores.fill(-1.0);
            let fix = Fix {
                x_m: prior.0 as f32,
                y_m: prior.1 as f32,
                score: -1.0,
                confidence: 0.0,
                peak_score: -1.0,
                second_score: -1.0,
                on_border: true,
                candidates: Default::default(),
                coarse_grid: grid,
                ops_coarse: window_ops,
                ops_fine: OpCounts::default(),
            };
            return Ok(Localization {
                fix,
                coarse_response: window_scores.clone(),
                window_scores,
                window_grid: grid,
                window_ops,
                dense_s: 0.0,
                windows_s: t0.elapsed().as_secs_f64(),
            });
        }
        Err(e) => anyhow::bail!("window search failed: {e:?}"),
    }
    let windows_s = t0.elapsed().as_secs_f64();

    // Best windows, suppressing neighbours within one stride.
    let mut order: Vec<usize> = (0..grid.len()).collect();
    order.sort_by(|&a, &b| window_scores[b].total_cmp(&window_scores[a]));
    let mut picked: Vec<usize> = Vec::new();
    for &i in &order {
        if picked.len() == REFINE_WINDOWS {
            break;
        }
        let (c, r) = ((i % grid.cols) as i64, (i / grid.cols) as i64);
        let near = picked.iter().any(|&j| {
            let (cj, rj) = ((j % grid.cols) as i64, (j / grid.cols) as i64);
            (c - cj).abs() <= 1 && (r - rj).abs() <= 1
        });
        if !near {
            picked.push(i);
        }
    }
    let t1 = Instant::now();
    let mut ops_fine = OpCounts::default();
    let mut refined = Vec::with_capacity(picked.len());
    for &i in &picked {
        let (c, r) = (i % grid.cols * stride_px, i / grid.cols * stride_px);
        refined.push(refine(spec, &t, &w, &m, (c, r), &mut ops_fine)?);
    }
    let fine_s = t1.elapsed().as_secs_f64();
    refined.sort_by(|a, b| b.score.total_cmp(&a.score));
    let best = refined
        .first()
        .ok_or_else(|| anyhow::anyhow!("no window to refine"))?;
    let half = n as f64 / 2.0;
    let centre = |col: f64, row: f64| -> (f32, f32) {
        map.geo.to_world((col + half) as f32, (row + half) as f32)
    };
    let (fx, fy) = centre(best.col, best.row);
    // Confidence on the window response.
    let mean = window_scores.iter().map(|&s| s as f64).sum::<f64>() / grid.len() as f64;
    let far = stride_px as f64;
    let s2 = (0..grid.len())
        .filter(|&i| {
            let (c, r) = (
                (i % grid.cols * stride_px) as f64,
                (i / grid.cols * stride_px) as f64,
            );
            (c - best.col).hypot(r - best.row) > far
        })
        .map(|i| window_scores[i])
        .fold(f32::NEG_INFINITY, f32::max);
    let s1 = best.score as f64;
    let confidence = if s2.is_finite() && s1 - mean > 1e-9 {
        ((s1 - s2 as f64) / (s1 - mean)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut fix = Fix {
        x_m: fx,
        y_m: fy,
        score: best.score,
        confidence: confidence as f32,
        peak_score: window_scores[order[0]],
        second_score: if s2.is_finite() { s2 } else { best.score },
        on_border: best.on_border,
        candidates: Default::default(),
        coarse_grid: grid,
        ops_coarse: window_ops,
        ops_fine,
    };
    for r in &refined {
        let (x, y) = centre(r.col, r.row);
        // At most `REFINE_WINDOWS` (3) candidates: fits the core's bound.
        let _ = fix.candidates.push(Candidate {
            x_m: x,
            y_m: y,
            score: r.score,
            refined: true,
        });
    }
    Ok(Localization {
        fix,
        // The window response doubles as the coarse response (one score per cell).
        coarse_response: window_scores.clone(),
        window_scores,
        window_grid: grid,
        window_ops,
        dense_s: windows_s + fine_s,
        windows_s,
    })
}
