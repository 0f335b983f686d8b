//! The sums of coarse grids (over 1 m per pixel, boulders looked up per pixel): a window's
//! craters gathered once and summed into the pixels they reach ([`World::splat_window`]), and
//! one pixel's sum over its tile's craters ([`World::sum_pixel_coarse`]).

use super::base::Base;
use super::craters::Rays;
use super::footprint::{within, Feature, Filter};
use super::{Crater, World};

impl World {
    /// Sums of a coarse grid's window (pixels of tiles with a gathering rectangle; the rest
    /// is the caller's) into `acc_h`, `acc_a` (row-major, window-wide): the same additions in
    /// the same order per pixel as [`World::sum_pixel_coarse`] over each tile's own gathering
    /// — base sums, the pixel's background boulders, then every crater its tile's gathering
    /// visits, in gathering order, each fresh crater's boulders right after it — but with
    /// the craters gathered once for the whole window and summed into the pixels they reach
    /// as they are found.
    pub(super) fn splat_window(
        &self,
        win: &Window<'_>,
        filt: &Filter,
        base: Base<'_>,
        acc_h: &mut Vec<f64>,
        acc_a: &mut Vec<f64>,
    ) {
        let w = win.cols.len();
        let n = w * win.rows.len();
        acc_h.clear();
        acc_a.clear();
        acc_h.resize(n, 0.0);
        acc_a.resize(n, 0.0);
        let (nt, nb) = (win.col_x.len(), win.row_y.len());
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        let rocks = &self.rocks;
        let visits_rocks = k0 < rocks.class_count();
        let mut union: Option<[f64; 4]> = None;
        // Base sums and the pixels' own background boulders.
        for bi in 0..nb {
            let b = win.b0 + bi;
            for ti in 0..nt {
                let t = win.t0 + ti;
                let Some(r) = win.rects[bi * nt + ti] else {
                    continue;
                };
                union = Some(match union {
                    None => r,
                    Some(u) => [
                        u[0].min(r[0]),
                        u[1].min(r[1]),
                        u[2].max(r[2]),
                        u[3].max(r[3]),
                    ],
                });
                for r in (b * win.tile).max(win.rows.start)..((b + 1) * win.tile).min(win.rows.end)
                {
                    let y = win.ys[r - win.rs];
                    for c in
                        (t * win.tile).max(win.cols.start)..((t + 1) * win.tile).min(win.cols.end)
                    {
                        let x = win.xs[c - win.cs];
                        let q = (r - win.rows.start) * w + (c - win.cols.start);
                        let kb = (r - base.r0) * base.stride + (c - base.c0);
                        let mut acc = self.acc_from(base.h[kb], base.a[kb], filt);
                        if visits_rocks {
                            let point = filt.grown([x, y, x, y]);
                            rocks.visit_rect_from(point, k0, grow, |rk| {
                                acc.add(Feature::Rock(rk), x, y);
                            });
                        }
                        acc_h[q] = acc.h;
                        acc_a[q] = acc.a;
                    }
                }
            }
        }
        let Some(u) = union else {
            return;
        };
        // The cells each tile's gathering visits, per tile column / band and class.
        let nk = self.craters.class_count();
        let col_cells: Vec<(i64, i64)> = win
            .col_x
            .iter()
            .flat_map(|&(w, e)| (0..nk).map(move |k| (w, e, k)))
            .map(|(w, e, k)| self.craters.cell_range(k, w, e))
            .collect();
        let row_cells: Vec<(i64, i64)> = win
            .row_y
            .iter()
            .flat_map(|&(s, n)| (0..nk).map(move |k| (s, n, k)))
            .map(|(s, n, k)| self.craters.cell_range(k, s, n))
            .collect();
        let (x_first, y_first) = (win.col_x[0].0, win.row_y[0].1);
        // A crater adds nothing to a pixel farther than its reach (`add`'s first test),
        // and a crater that is not fresh nothing beyond its ejecta blanket (it has no
        // albedo terms or boulders): craters out of those distances of every pixel of the
        // window are skipped before they are drawn in full (the class's largest blanket
        // bounds the crater's, with a margin for rounding).
        let xw = &win.xs[win.cols.start - win.cs..win.cols.end - win.cs];
        let yw = &win.ys[win.rows.start - win.rs..win.rows.end - win.rs];
        // Squared distance to the nearest pixel centre along one axis (evenly spaced
        // centres: the nearest is within one of the rounded index), as `add` computes
        // `dx * dx`.
        let step = |at: &[f64]| {
            if at.len() >= 2 {
                (at[at.len() - 1] - at[0]) / (at.len() - 1) as f64
            } else {
                1.0
            }
        };
        let (sx, sy) = (step(xw), step(yw));
        let nearest2 = |v: f64, at: &[f64], step: f64| {
            // Rounded to the nearest index (`as` truncates; negatives clamp to 0 below).
            let i = (((v - at[0]) / step + 0.5) as i64).clamp(0, at.len() as i64 - 1) as usize;
            let mut d2 = f64::INFINITY;
            for &a in &at[i.saturating_sub(1)..(i + 2).min(at.len())] {
                let d = a - v;
                d2 = d2.min(d * d);
            }
            d2
        };
        let slack = filt.hf * core::f64::consts::SQRT_2;
        let keep = |k: usize, cx: f64, cy: f64, fresh: bool| {
            let reach = self.craters.class_reach(k) + if fresh { slack } else { 0.0 };
            let d2 = nearest2(cx, xw, sx) + nearest2(cy, yw, sy);
            d2 <= reach * reach * (1.0 + 1e-9)
        };
        self.craters
            .visit_rect_cells_if(u, !self.cfg.relief, keep, |k, ix, iy, c| {
                let reach = self.craters.class_reach(k);
                let (lx, hx) = (c.x_m - reach, c.x_m + reach);
                let (ly, hy) = (c.y_m - reach, c.y_m + reach);
                // Tiles whose rectangle meets the crater's reach square (a crater outside
                // it is not visited: its distance is at least `reach`): `partition_point`s,
                // searched from a guess on the tiles' pitch.
                let gx = |v: f64| ((v - x_first) / win.pitch).max(0.0) as usize;
                let gy = |v: f64| ((y_first - v) / win.pitch).max(0.0) as usize;
                let ta = partition_from(nt, gx(lx), |t| win.col_x[t].1 < lx);
                let tb = partition_from(nt, gx(hx), |t| win.col_x[t].0 <= hx);
                let ba = partition_from(nb, gy(hy), |b| win.row_y[b].0 > hy);
                let bb = partition_from(nb, gy(ly), |b| win.row_y[b].1 >= ly);
                let pre = filt.reach(Feature::Crater(c, None));
                // Drawn once for all the pixels (fresh craters only).
                let rays: Option<Rays> = (c.freshness > 0.0).then(|| c.rays());
                let fresh_rocks = rocks.crater_has_rocks(c);
                for bi in ba..bb {
                    let (iy0, iy1) = row_cells[bi * nk + k];
                    if iy < iy0 || iy > iy1 {
                        continue;
                    }
                    let b = win.b0 + bi;
                    for ti in ta..tb {
                        let (ix0, ix1) = col_cells[ti * nk + k];
                        if ix < ix0 || ix > ix1 {
                            continue;
                        }
                        let Some(rect) = win.rects[bi * nt + ti] else {
                            continue;
                        };
                        if !self.craters.reaches(rect, k, c) {
                            continue;
                        }

                        let t = win.t0 + ti;
                        let r_hi = ((b + 1) * win.tile).min(win.rows.end).min(win.ny);
                        for r in (b * win.tile).max(win.rows.start)..r_hi {
                            let y = win.ys[r - win.rs];
                            let c_hi = ((t + 1) * win.tile).min(win.cols.end).min(win.nx);
                            for col in (t * win.tile).max(win.cols.start)..c_hi {
                                let x = win.xs[col - win.cs];
                                // Where `add` would change nothing, it is skipped.
                                if !within(pre, x, y) {
                                    continue;
                                }
                                let q = (r - win.rows.start) * w + (col - win.cols.start);
                                let mut acc = self.acc_from(acc_h[q], acc_a[q], filt);
                                if acc.add(Feature::Crater(c, rays.as_ref()), x, y) && fresh_rocks {
                                    let point = filt.grown([x, y, x, y]);
                                    rocks.visit_crater_rect_from(c, point, k0, grow, |rk| {
                                        acc.add(Feature::Rock(rk), x, y);
                                    });
                                }
                                acc_h[q] = acc.h;
                                acc_a[q] = acc.a;
                            }
                        }
                    }
                }
            });
    }

    /// Height and albedo of one pixel of a coarse grid's tile: its base sums, its own
    /// background boulder look-up, then the tile's craters in their fixed order, each fresh
    /// crater's boulders (looked up by the pixel) right after it.
    #[inline]
    pub(super) fn sum_pixel_coarse<'c>(
        &self,
        x: f64,
        y: f64,
        (base_h, base_a): (f64, f64),
        craters: impl Iterator<Item = (&'c Crater, Option<&'c Rays>)>,
        filt: &Filter,
    ) -> (f64, f64) {
        let mut acc = self.acc_from(base_h, base_a, filt);
        let point = filt.grown([x, y, x, y]);
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        let rocks = &self.rocks;
        rocks.visit_rect_from(point, k0, grow, |rk| {
            acc.add(Feature::Rock(rk), x, y);
        });
        for (cr, rays) in craters {
            if acc.add(Feature::Crater(cr, rays), x, y) && rocks.crater_has_rocks(cr) {
                rocks.visit_crater_rect_from(cr, point, k0, grow, |rk| {
                    acc.add(Feature::Rock(rk), x, y);
                });
            }
        }
        acc.finish()
    }
}

/// `(0..len).partition_point(pred)` for a predicate true on a prefix, searched from `guess`.
#[inline]
fn partition_from(len: usize, guess: usize, pred: impl Fn(usize) -> bool) -> usize {
    let mut i = guess.min(len);
    while i > 0 && !pred(i - 1) {
        i -= 1;
    }
    while i < len && pred(i) {
        i += 1;
    }
    i
}

/// A window of a coarse grid being filled by [`World::splat_window`]: its pixels, the grid's
/// tiles it overlaps (from tile column `t0` and band `b0`) with their pixel centres (`xs`
/// from column `cs`, `ys` from row `rs`) and gathering rectangles (`rects`, band-major;
/// `col_x` / `row_y`: their west-east and south-north edges per tile column / band), and the
/// tiles' pitch in metres.
pub(super) struct Window<'a> {
    pub(super) cols: std::ops::Range<usize>,
    pub(super) rows: std::ops::Range<usize>,
    pub(super) tile: usize,
    pub(super) t0: usize,
    pub(super) b0: usize,
    pub(super) nx: usize,
    pub(super) ny: usize,
    pub(super) xs: &'a [f64],
    pub(super) cs: usize,
    pub(super) ys: &'a [f64],
    pub(super) rs: usize,
    pub(super) rects: &'a [Option<[f64; 4]>],
    pub(super) col_x: &'a [(f64, f64)],
    pub(super) row_y: &'a [(f64, f64)],
    pub(super) pitch: f64,
}
