//! The baseline matchers (masked NCC, L1, L2; the study's window search and the dense
//! coarse-to-fine localizer) run through the core localizer on owned images: their
//! preprocessing options and the ranking of the study's windows.

use super::{describe, Localization, MapRegion, MatcherSpec, TopDown};
use anyhow::bail;
use orbfix::image::{ImageView, ImageViewMut};
use orbfix::localize::{self, LocalizeConfig};
use orbfix::matcher::{distance_weights, Grid, OpCounts};
use std::time::Instant;

/// The weights a matcher sees for a top-down mask.
pub fn weights_for(spec: &MatcherSpec, top: &TopDown) -> anyhow::Result<Vec<u8>> {
    let mut mask = top.mask.clone();
    if let Some(r) = spec.max_range_m {
        let r_px = (r / top.m_per_px) as f64;
        let c = top.n as f64 / 2.0;
        for (i, m) in mask.iter_mut().enumerate() {
            let (x, y) = ((i % top.n) as f64 + 0.5 - c, (i / top.n) as f64 + 0.5 - c);
            if x * x + y * y > r_px * r_px {
                *m = 0;
            }
        }
    }
    let top = &TopDown {
        mask,
        image: Vec::new(),
        ..*top
    };
    match spec.distance_weighting_px {
        None => Ok(top.mask.clone()),
        Some(r0) => {
            let mut out = vec![0u8; top.n * top.n];
            let m = ImageView::new(&top.mask, top.n, top.n)
                .map_err(|e| anyhow::anyhow!("bad top-down mask: {e}"))?;
            let mut o = ImageViewMut::new(&mut out, top.n, top.n)
                .map_err(|e| anyhow::anyhow!("bad weight buffer: {e}"))?;
            distance_weights(&m, &mut o, r0)
                .map_err(|e| anyhow::anyhow!("distance weighting failed: {e}"))?;
            Ok(out)
        }
    }
}

/// The images a matcher sees: top-down image, its weights and the map, pre-processed.
pub struct Prepared {
    /// Top-down image (high-passed if the matcher asks).
    pub top: Vec<u8>,
    /// Weights (mask, range cut, distance weighting).
    pub weights: Vec<u8>,
    /// Map (high-passed if the matcher asks).
    pub map: Vec<u8>,
}

fn baseline_highpass_image(
    img: &[u8],
    mask: Option<&[u8]>,
    w: usize,
    h: usize,
    radius: usize,
) -> anyhow::Result<Vec<u8>> {
    let src = ImageView::new(img, w, h).map_err(|e| anyhow::anyhow!("bad image: {e}"))?;
    let m = match mask {
        Some(m) => Some(ImageView::new(m, w, h).map_err(|e| anyhow::anyhow!("bad mask: {e}"))?),
        None => None,
    };
    let mut out = vec![0u8; w * h];
    let mut o = ImageViewMut::new(&mut out, w, h).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut scratch = vec![0u32; orbfix::matcher::prep::highpass_buffer_len(w)];
    orbfix::matcher::prep::highpass(&src, m.as_ref(), radius, &mut o, &mut scratch)
        .map_err(|e| anyhow::anyhow!("high-pass failed: {e}"))?;
    Ok(out)
}

/// Pre-processes a query's images for a matcher.
pub fn prepare(spec: &MatcherSpec, top: &TopDown, map: &MapRegion) -> anyhow::Result<Prepared> {
    let weights = weights_for(spec, top)?;
    let equalized;
    let top = if spec.equalize_rings {
        let mut img = top.image.clone();
        let mask: Vec<u8> = top
            .mask
            .iter()
            .map(|&m| if m != 0 { 255 } else { 0 })
            .collect();
        let ring = ((1.0 / top.m_per_px).round() as u32).max(1);
        orbfix::reproject::equalize_rings(&mut img, &mask, top.n, ring);
        equalized = TopDown {
            image: img,
            ..top.clone()
        };
        &equalized
    } else {
        top
    };
    match spec.highpass_m {
        None => Ok(Prepared {
            top: top.image.clone(),
            weights,
            map: map.image.clone(),
        }),
        Some(r_m) => {
            let r = ((r_m / top.m_per_px).round() as usize).max(1);
            Ok(Prepared {
                top: baseline_highpass_image(&top.image, Some(&weights), top.n, top.n, r)?,
                map: baseline_highpass_image(&map.image, None, map.width, map.height, r)?,
                weights,
            })
        }
    }
}

/// Runs the core on owned images: the study's window search (`stride_px` between windows)
/// and the coarse-to-fine fix.
pub fn localize_top_down(
    spec: &MatcherSpec,
    top: &TopDown,
    map: &MapRegion,
    prior: (f64, f64),
    cfg: &LocalizeConfig,
    stride_px: usize,
) -> anyhow::Result<Localization> {
    if top.image.len() != top.n * top.n || top.mask.len() != top.n * top.n {
        bail!(
            "top-down image is {} bytes and mask {} bytes, expected {} x {}",
            top.image.len(),
            top.mask.len(),
            top.n,
            top.n
        );
    }
    let p = prepare(spec, top, map)?;
    let t = ImageView::new(&p.top, top.n, top.n)
        .map_err(|e| anyhow::anyhow!("bad top-down image: {e}"))?;
    let w = ImageView::new(&p.weights, top.n, top.n)
        .map_err(|e| anyhow::anyhow!("bad top-down mask: {e}"))?;
    let m = ImageView::new(&p.map, map.width, map.height)
        .map_err(|e| anyhow::anyhow!("map image does not match its size: {e}"))?;
    let (nb, nf) = localize::buffer_sizes(top.n, top.n, map.width, map.height, cfg)
        .map_err(|e| anyhow::anyhow!("localization set-up rejected: {e}"))?;
    let mut bytes = vec![0u8; nb];
    let mut floats = vec![0f32; nf];
    let t0 = Instant::now();
    let fix = localize::localize(
        spec.matcher.as_ref(),
        &t,
        &w,
        top.m_per_px,
        &m,
        &map.geo,
        prior.0 as f32,
        prior.1 as f32,
        cfg,
        &mut bytes,
        &mut floats,
    )
    .map_err(|e| anyhow::anyhow!("localization failed: {}", describe(&e)))?;
    let dense_s = t0.elapsed().as_secs_f64();
    let coarse_response = floats[..fix.coarse_grid.len()].to_vec();
    let grid = Grid::new(top.n, top.n, map.width, map.height, stride_px)
        .map_err(|e| anyhow::anyhow!("window grid: {e}"))?;
    let mut window_scores = vec![0f32; grid.len()];
    let mut window_ops = OpCounts::default();
    let t1 = Instant::now();
    let window_grid = localize::window_search(
        spec.matcher.as_ref(),
        &t,
        &w,
        &m,
        stride_px,
        &mut window_scores,
        &mut window_ops,
    )
    .map_err(|e| anyhow::anyhow!("window search failed: {}", describe(&e)))?;
    let windows_s = t1.elapsed().as_secs_f64();
    Ok(Localization {
        fix,
        coarse_response,
        window_scores,
        window_grid,
        window_ops,
        dense_s,
        windows_s,
        fix_report: None,
    })
}

/// Window scores from the dense coarse response: each of the study's windows gets the best
/// coarse score of the rover positions in its cell (within half a stride of the window's
/// centre), so a window 6 m off a sharp texture is not penalised for its offset. Row-major
/// over `loc.window_grid`.
pub fn window_cell_scores(loc: &Localization) -> Vec<f32> {
    cell_scores(&loc.coarse_response, &loc.fix.coarse_grid, &loc.window_grid)
}

/// [`window_cell_scores`] of a response over grid `cg` for the windows of `wg`.
pub fn cell_scores(response: &[f32], cg: &Grid, wg: &Grid) -> Vec<f32> {
    let half = wg.step() as i64 / 2;
    let cell_of = |x: i64, y: i64| -> Option<usize> {
        // Cell (c, r) holds positions in [c step - half, c step + half).
        let c = (x + half).div_euclid(wg.step() as i64);
        let r = (y + half).div_euclid(wg.step() as i64);
        (c >= 0 && r >= 0 && (c as usize) < wg.cols() && (r as usize) < wg.rows())
            .then(|| r as usize * wg.cols() + c as usize)
    };
    let mut best = vec![f32::NEG_INFINITY; wg.len()];
    for (i, &s) in response.iter().enumerate().take(cg.len()) {
        let (x, y) = (
            (i % cg.cols() * cg.step()) as i64,
            (i / cg.cols() * cg.step()) as i64,
        );
        if let Some(k) = cell_of(x, y) {
            best[k] = best[k].max(s);
        }
    }
    best
}
