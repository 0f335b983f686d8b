//! Window-first localization for matchers that score whole 50 m windows (the CNNs), where
//! the core's coarse-to-fine NCC path (which downsamples the template by the coarse factor,
//! e.g. to 25 px) does not apply: the CNN needs the full `n x n` top-down image (>= 64 px).
//!
//! 1. Dense response: the matcher scores a window every `DENSE_STEP_PX` (16 px = 4 m at
//!    0.25 m/px) over the whole map (63 x 63 = 3969 windows for a 300 m map). In flight these
//!    window embeddings depend only on the map and are precomputed (docs/matcher.md). The
//!    study's 441 windows are ranked by the best dense score in their cell (the evaluation's
//!    "dense R@k", [`super::window_cell_scores`]).
//! 2. The study's window search (`stride_px`, 441 windows at 12.5 m), each window scored at
//!    its own centre only: reported as the study's ranking ("R@k").
//! 3. Refinement: around each of the `REFINE_WINDOWS` best dense positions (non-maximum
//!    suppressed at one window stride), a dense search of the same matcher at `FINE_STEP_PX`
//!    (4 px = 1 m) over +-`FINE_REACH_PX` (16 px = 4 m: the dense step's whole cell).
//! 4. Sub-step peak: a parabola through the best fine score and its two neighbours, per
//!    axis (clamped to half a step).
//!
//! Confidence: `(s1 - s2) / (s1 - mean)` over the dense response, `s1` the best fine score,
//! `s2` the best dense score more than one window stride (12.5 m) from the fix, `mean` the
//! mean dense score; clamped to `[0, 1]`.
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

/// Step of the dense response over the whole map, pixels (16 px = 4 m at 0.25 m/px).
pub const DENSE_STEP_PX: usize = 16;
/// Dense peaks refined.
pub const REFINE_WINDOWS: usize = 3;
/// Step of the refinement, pixels of the map (4 px = 1 m at 0.25 m/px).
pub const FINE_STEP_PX: usize = 4;
/// Reach of the refinement around a dense peak, pixels (16 px = 4 m: one dense step).
pub const FINE_REACH_PX: usize = 16;

/// One refined candidate: top-left `(col, row)` of the best position in map pixels
/// (sub-step, fractional), its score, and whether it lies on a map-cut edge.
struct Refined {
    col: f64,
    row: f64,
    score: f32,
    on_border: bool,
    /// Every position scored: `(col, row)` top-left in map pixels and score.
    samples: Vec<(usize, usize, f32)>,
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
    let (bc, br) = (best % g.cols(), best / g.cols());
    let at = |c: usize, r: usize| out[r * g.cols() + c];
    let dx = if bc > 0 && bc + 1 < g.cols() {
        parabola(at(bc - 1, br), at(bc, br), at(bc + 1, br))
    } else {
        0.0
    };
    let dy = if br > 0 && br + 1 < g.rows() {
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
        || (bc + 1 == g.cols() && cut_e)
        || (br + 1 == g.rows() && cut_s);
    Ok(Refined {
        col: x0 as f64 + (bc as f64 + dx) * FINE_STEP_PX as f64,
        row: y0 as f64 + (br as f64 + dy) * FINE_STEP_PX as f64,
        score: out[best],
        on_border,
        samples: out
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                (
                    x0 + i % g.cols() * FINE_STEP_PX,
                    y0 + i / g.cols() * FINE_STEP_PX,
                    s,
                )
            })
            .collect(),
    })
}

fn no_fix(
    prior: (f64, f64),
    dense_grid: Grid,
    window_grid: Grid,
    ops: OpCounts,
    elapsed_s: f64,
) -> Localization {
    let fix = Fix {
        x_m: prior.0 as f32,
        y_m: prior.1 as f32,
        score: -1.0,
        confidence: 0.0,
        peak_score: -1.0,
        second_score: -1.0,
        on_border: true,
        candidates: Default::default(),
        coarse_grid: dense_grid,
        ops_coarse: ops,
        ops_fine: OpCounts::default(),
    };
    Localization {
        fix,
        coarse_response: vec![-1.0; dense_grid.len()],
        window_scores: vec![-1.0; window_grid.len()],
        window_grid,
        window_ops: ops,
        dense_s: elapsed_s,
        windows_s: 0.0,
        fine_samples: Vec::new(),
    }
}

/// Dense response, window ranking, refinement of the best peaks and sub-step peak (module
/// docs).
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
    let dgrid = Grid::new(n, n, map.width, map.height, DENSE_STEP_PX)
        .map_err(|e| anyhow::anyhow!("dense grid: {e:?}"))?;

    // 1. Dense response over the whole map.
    let t0 = Instant::now();
    let mut dense = vec![0f32; dgrid.len()];
    let mut dense_ops = OpCounts::default();
    match spec
        .matcher
        .dense(&t, &w, &m, DENSE_STEP_PX, &mut dense, &mut dense_ops)
    {
        Ok(_) => {}
        Err(MatchError::NoValidPixels | MatchError::FeaturelessTemplate) => {
            return Ok(no_fix(
                prior,
                dgrid,
                grid,
                dense_ops,
                t0.elapsed().as_secs_f64(),
            ));
        }
        Err(e) => anyhow::bail!("dense response failed: {e:?}"),
    }
    let dense_s = t0.elapsed().as_secs_f64();

    // 2. The study's windows, each scored at its centre only.
    let t1 = Instant::now();
    let mut window_scores = vec![0f32; grid.len()];
    let mut window_ops = OpCounts::default();
    spec.matcher
        .dense(&t, &w, &m, stride_px, &mut window_scores, &mut window_ops)
        .map_err(|e| anyhow::anyhow!("window search failed: {e:?}"))?;
    let windows_s = t1.elapsed().as_secs_f64();

    // 3. Best dense peaks, suppressing neighbours within one window stride.
    let mut order: Vec<usize> = (0..dgrid.len()).collect();
    order.sort_by(|&a, &b| dense[b].total_cmp(&dense[a]));
    let pos = |i: usize| {
        (
            (i % dgrid.cols() * DENSE_STEP_PX),
            (i / dgrid.cols() * DENSE_STEP_PX),
        )
    };
    let mut picked: Vec<usize> = Vec::new();
    for &i in &order {
        if picked.len() == REFINE_WINDOWS {
            break;
        }
        let (c, r) = pos(i);
        let near = picked.iter().any(|&j| {
            let (cj, rj) = pos(j);
            (c as f64 - cj as f64).hypot(r as f64 - rj as f64) < stride_px as f64
        });
        if !near {
            picked.push(i);
        }
    }
    let t2 = Instant::now();
    let mut ops_fine = OpCounts::default();
    let mut refined = Vec::with_capacity(picked.len());
    for &i in &picked {
        refined.push(refine(spec, &t, &w, &m, pos(i), &mut ops_fine)?);
    }
    let fine_s = t2.elapsed().as_secs_f64();
    refined.sort_by(|a, b| b.score.total_cmp(&a.score));
    let best = refined
        .first()
        .ok_or_else(|| anyhow::anyhow!("no dense peak to refine"))?;
    let half = n as f64 / 2.0;
    let centre = |col: f64, row: f64| -> (f32, f32) {
        map.geo.to_world((col + half) as f32, (row + half) as f32)
    };
    let (fx, fy) = centre(best.col, best.row);
    // Confidence on the dense response.
    let mean = dense.iter().map(|&s| s as f64).sum::<f64>() / dgrid.len() as f64;
    let s2 = (0..dgrid.len())
        .filter(|&i| {
            let (c, r) = pos(i);
            (c as f64 - best.col).hypot(r as f64 - best.row) > stride_px as f64
        })
        .map(|i| dense[i])
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
        peak_score: dense[order[0]],
        second_score: if s2.is_finite() { s2 } else { best.score },
        on_border: best.on_border,
        candidates: Default::default(),
        coarse_grid: dgrid,
        ops_coarse: dense_ops,
        ops_fine,
    };
    let mut fine_samples = Vec::new();
    for r in refined {
        let (x, y) = centre(r.col, r.row);
        // At most `REFINE_WINDOWS` (3) candidates: fits the core's bound.
        let _ = fix.candidates.push(Candidate {
            x_m: x,
            y_m: y,
            score: r.score,
            refined: true,
        });
        fine_samples.extend(r.samples);
    }
    Ok(Localization {
        fix,
        coarse_response: dense,
        window_scores,
        window_grid: grid,
        window_ops,
        dense_s: dense_s + fine_s,
        windows_s,
        fine_samples,
    })
}
