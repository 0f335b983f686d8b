//! A window of a grid filled tile by tile ([`World::fill_window`]): the grid's tiles each
//! gather the features that reach them and every pixel sums its tile's features in the one
//! fixed order, so that a pixel's value does not depend on the window; the tile sizes of
//! fine and coarse grids.

use super::base::Base;
use super::coarse::Window;
use super::footprint::{within, Feature, Filter, Item};
use super::World;

impl World {
    /// Fills pixels `cols x rows` of the grid `g` (not empty, inside the grid) into `out`
    /// (heights, albedo, row stride; pixel `(c, r)` at `(r - rows.start) * stride + c -
    /// cols.start`), exactly as sampling the whole grid would: the grid's tiles (whole
    /// tiles of [`GridSpec::tile`] pixels from its north-west corner, partial ones at the
    /// east and south edges) each gather the craters (and, on fine grids, the boulders) that
    /// reach them, then every pixel sums its tile's features in the one fixed order, so a
    /// pixel's value does not depend on the window. Coarse grids gather the craters of the
    /// window's tiles at once and hand each tile the ones its own gathering would have
    /// visited (the same cell and distance tests, in the same order): most cells of small
    /// crater classes are then visited once, not once per tile.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fill_window(
        &self,
        g: &GridSpec,
        filt: &Filter,
        cols: std::ops::Range<usize>,
        rows: std::ops::Range<usize>,
        base: Option<Base<'_>>,
        scratch: &mut Scratch,
        (hs, als, stride): (&mut [f32], &mut [f32], usize),
    ) {
        let tile = g.tile();
        let rocks_per_pixel = g.m > FINE_GRID_M_PER_PX;
        let w = cols.len();
        let Scratch {
            xs,
            ys,
            bh,
            ba,
            tmp,
            items,
            pre,
            acc_h,
            acc_a,
            rects,
        } = scratch;
        // Pixel centres of the window's tiles (columns from the first tile's start).
        let (t0, t1) = (cols.start / tile, (cols.end - 1) / tile + 1);
        let (b0, b1) = (rows.start / tile, (rows.end - 1) / tile + 1);
        let cs = t0 * tile;
        let ce = (t1 * tile).min(g.nx);
        xs.clear();
        xs.extend((cs..ce).map(|c| g.ox + (c as f64 + 0.5) * g.m));
        let rs = b0 * tile;
        let re = (b1 * tile).min(g.ny);
        ys.clear();
        ys.extend((rs..re).map(|r| g.oy - (r as f64 + 0.5) * g.m));
        // The sums before features, row by row (vectorized noise), unless given.
        let base = match base {
            Some(b) => b,
            None => {
                bh.clear();
                bh.resize(w * rows.len(), 0.0);
                ba.clear();
                ba.resize(w * rows.len(), 0.0);
                tmp.clear();
                tmp.resize(w, 0.0);
                let xw = &xs[cols.start - cs..cols.end - cs];
                for (k, r) in rows.clone().enumerate() {
                    let span = k * w..(k + 1) * w;
                    self.base_row(
                        xw,
                        ys[r - rs],
                        filt,
                        &mut bh[span.clone()],
                        &mut ba[span],
                        tmp,
                    );
                }
                Base {
                    h: bh,
                    a: ba,
                    stride: w,
                    c0: cols.start,
                    r0: rows.start,
                }
            }
        };
        // Each tile: its pixel centres, its gathering rectangle (None: pixels evaluated one
        // by one, as for a single-pixel or non-finite tile).
        let tile_rect = |t: usize, b: usize| {
            let xt = &xs[t * tile - cs..((t + 1) * tile).min(g.nx) - cs];
            let yt = &ys[b * tile - rs..((b + 1) * tile).min(g.ny) - rs];
            let (xa, xb, ya, yb) = (xt[0], xt[xt.len() - 1], yt[0], yt[yt.len() - 1]);
            let finite = xa.is_finite() && xb.is_finite() && ya.is_finite() && yb.is_finite();
            let single = xt.len() == 1 && yt.len() == 1;
            (finite && !single)
                .then(|| filt.grown([xa.min(xb), ya.min(yb), xa.max(xb), ya.max(yb)]))
        };
        let (nt, nb) = (t1 - t0, b1 - b0);
        // Binned when the tiles' rectangles run east and south in order (the usual grid:
        // finite, positive spacing), so that a crater finds its tiles by bisection.
        let ordered = g.m > 0.0
            && xs.iter().chain(ys.iter()).all(|v| v.is_finite())
            && xs.windows(2).all(|p| p[0] < p[1])
            && ys.windows(2).all(|p| p[0] > p[1]);
        let binned = rocks_per_pixel && nt * nb > 1 && ordered;
        if binned {
            // One gathering over the union of the tiles' rectangles; each crater is summed
            // into the pixels of the tiles whose own gathering visits it, as it is found.
            rects.clear();
            for b in b0..b1 {
                for t in t0..t1 {
                    rects.push(tile_rect(t, b));
                }
            }
            // Tile rectangles by column (west, east edges, both increasing) and by band row
            // (south, north edges, both decreasing); a tile's rectangle is its column's and
            // its row's (`tile_rect` grows each side alone).
            let col_x: Vec<(f64, f64)> = (t0..t1)
                .map(|t| {
                    let xa = xs[t * tile - cs];
                    let xb = xs[((t + 1) * tile).min(g.nx) - 1 - cs];
                    let r = filt.grown([xa, 0.0, xb, 0.0]);
                    (r[0], r[2])
                })
                .collect();
            let row_y: Vec<(f64, f64)> = (b0..b1)
                .map(|b| {
                    let ya = ys[b * tile - rs];
                    let yb = ys[((b + 1) * tile).min(g.ny) - 1 - rs];
                    let r = filt.grown([0.0, yb, 0.0, ya]);
                    (r[1], r[3])
                })
                .collect();
            let win = Window {
                cols: cols.clone(),
                rows: rows.clone(),
                tile,
                t0,
                b0,
                nx: g.nx,
                ny: g.ny,
                xs: &xs[..],
                cs,
                ys: &ys[..],
                rs,
                rects: &rects[..],
                col_x: &col_x,
                row_y: &row_y,
                pitch: tile as f64 * g.m,
            };
            self.splat_window(&win, filt, base, acc_h, acc_a);
            for b in b0..b1 {
                for t in t0..t1 {
                    let rect = rects[(b - b0) * nt + (t - t0)];
                    for r in (b * tile).max(rows.start)..((b + 1) * tile).min(rows.end) {
                        for c in (t * tile).max(cols.start)..((t + 1) * tile).min(cols.end) {
                            let q = (r - rows.start) * w + (c - cols.start);
                            let (h, a) = match rect {
                                Some(_) => (acc_h[q], acc_a[q].clamp(0.0, 1.0)),
                                None => self.eval(xs[c - cs], ys[r - rs], true, true, filt),
                            };
                            let k = (r - rows.start) * stride + (c - cols.start);
                            hs[k] = h as f32;
                            als[k] = a as f32;
                        }
                    }
                }
            }
            return;
        }
        for b in b0..b1 {
            let yt = &ys[b * tile - rs..((b + 1) * tile).min(g.ny) - rs];
            let r_lo = (b * tile).max(rows.start);
            let r_hi = ((b + 1) * tile).min(rows.end);
            for t in t0..t1 {
                let xt = &xs[t * tile - cs..((t + 1) * tile).min(g.nx) - cs];
                let c_lo = (t * tile).max(cols.start);
                let c_hi = ((t + 1) * tile).min(cols.end);
                let rect = tile_rect(t, b);
                if let Some(rect) = rect {
                    items.clear();
                    if rocks_per_pixel {
                        self.craters.visit_rect(rect, !self.cfg.relief, |c| {
                            items.push(Item::of(Feature::Crater(c, None)))
                        });
                    } else {
                        self.features(rect, !self.cfg.relief, filt, |f| items.push(Item::of(f)));
                    }
                    pre.clear();
                    pre.extend(items.iter().map(|it| filt.reach(it.as_feature())));
                }
                if let (Some(_), false) = (rect, rocks_per_pixel) {
                    // Fine tiles: feature by feature over the tile's pixels (each pixel
                    // still sums its features in their order); the height of a crater that
                    // is not fresh (its only term in a filtered sum) four pixels at a time.
                    let wt = c_hi - c_lo;
                    acc_h.clear();
                    acc_a.clear();
                    for r in r_lo..r_hi {
                        let kb = (r - base.r0) * base.stride + (c_lo - base.c0);
                        acc_h.extend_from_slice(&base.h[kb..kb + wt]);
                        acc_a.extend_from_slice(&base.a[kb..kb + wt]);
                    }
                    let xv = &xt[c_lo - t * tile..c_hi - t * tile];
                    let heights_only = self.cfg.relief && filt.fp > 0.0;
                    for (it, &p) in items.iter().zip(pre.iter()) {
                        let plain = match it {
                            Item::Crater(c, _)
                                if heights_only && (c.freshness <= 0.0 || c.freshness.is_nan()) =>
                            {
                                Some(c)
                            }
                            _ => None,
                        };
                        for r in r_lo..r_hi {
                            let y = yt[r - b * tile];
                            let q0 = (r - r_lo) * wt;
                            if let Some(c) = plain {
                                c.add_heights(xv, y, &mut acc_h[q0..q0 + wt]);
                                continue;
                            }
                            for (j, &x) in xv.iter().enumerate() {
                                // Features whose `add` would do nothing here are skipped.
                                if within(p, x, y) {
                                    let mut acc = self.acc_from(acc_h[q0 + j], acc_a[q0 + j], filt);
                                    acc.add(it.as_feature(), x, y);
                                    acc_h[q0 + j] = acc.h;
                                    acc_a[q0 + j] = acc.a;
                                }
                            }
                        }
                    }
                    for r in r_lo..r_hi {
                        for c in c_lo..c_hi {
                            let q = (r - r_lo) * wt + (c - c_lo);
                            let k = (r - rows.start) * stride + (c - cols.start);
                            hs[k] = acc_h[q] as f32;
                            als[k] = acc_a[q].clamp(0.0, 1.0) as f32;
                        }
                    }
                    continue;
                }
                for r in r_lo..r_hi {
                    let y = yt[r - b * tile];
                    for c in c_lo..c_hi {
                        let x = xt[c - t * tile];
                        let kb = (r - base.r0) * base.stride + (c - base.c0);
                        let (h, a) = match rect {
                            None => self.eval(x, y, true, true, filt),
                            // (Coarse tiles only: fine ones are summed above.) Features
                            // whose `add` would do nothing here are skipped.
                            Some(_) => self.sum_pixel_coarse(
                                x,
                                y,
                                (base.h[kb], base.a[kb]),
                                items
                                    .iter()
                                    .zip(pre.iter())
                                    .filter_map(|(it, &p)| match it {
                                        Item::Crater(c, rays) if within(p, x, y) => {
                                            Some((c, rays.as_ref()))
                                        }
                                        _ => None,
                                    }),
                                filt,
                            ),
                        };
                        let k = (r - rows.start) * stride + (c - cols.start);
                        hs[k] = h as f32;
                        als[k] = a as f32;
                    }
                }
            }
        }
    }
}

/// A grid being sampled: north-west corner, metres per pixel, size.
#[derive(Clone, Copy, Debug)]
pub(super) struct GridSpec {
    pub(super) ox: f64,
    pub(super) oy: f64,
    pub(super) m: f64,
    pub(super) nx: usize,
    pub(super) ny: usize,
}

impl GridSpec {
    /// Side of the tiles that gather features, pixels.
    pub(super) fn tile(&self) -> usize {
        if self.m > FINE_GRID_M_PER_PX {
            ((COARSE_TILE_MAX_M / self.m) as usize).clamp(2, TILE)
        } else {
            ((FINE_TILE_MAX_M / self.m) as usize).clamp(1, TILE)
        }
    }
}

/// Buffers reused from window to window.
#[derive(Default)]
pub(super) struct Scratch {
    xs: Vec<f64>,
    ys: Vec<f64>,
    bh: Vec<f64>,
    ba: Vec<f64>,
    tmp: Vec<f64>,
    items: Vec<Item>,
    pre: Vec<[f64; 3]>,
    acc_h: Vec<f64>,
    acc_a: Vec<f64>,
    rects: Vec<Option<[f64; 4]>>,
}

/// Largest side of the tiles `sample_grid` gathers features for, pixels.
const TILE: usize = 16;

/// Fine grids (at most this many metres per pixel) gather craters and boulders per tile;
/// coarser ones gather craters per tile and look boulders up per pixel.
const FINE_GRID_M_PER_PX: f64 = 1.0;

/// Largest ground side of a fine grid's tile, metres: a tile gathers every boulder cell it
/// touches (cells of 0.4 m and up).
const FINE_TILE_MAX_M: f64 = 4.0;

/// Largest ground side of a coarse grid's tile, metres (bounds the list of small craters
/// each pixel walks).
const COARSE_TILE_MAX_M: f64 = 8.0;
