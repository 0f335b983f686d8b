//! Cast shadows by a horizon sweep along the sun azimuth.
//!
//! For each level of a [`Terrain`], a lattice rotated so that its lines run towards the sun
//! covers the level's square. Along a line, with `a` the distance towards the sun and
//! `g(a) = h(a) - a tan(elevation)`, a point is in shadow exactly when some point nearer the
//! sun has a larger `g`: one running maximum per line, O(1) per sample. Lines are first
//! extended `reach` metres towards the sun over the coarser levels so that shadows cast from
//! outside the square are caught. The mask is 0 (shadow) / 1 (lit) at lattice nodes and
//! bilinear in between (soft edges one lattice cell wide). Ground and orbit renders use this
//! same function.

use super::terrain::Terrain;
use super::Sun;
use rayon::prelude::*;

#[derive(Clone, Debug)]
struct Lattice {
    bounds: [f64; 4],
    cx: f64,
    cy: f64,
    m: f64,
    /// Horizontal unit vector towards the sun.
    s: (f64, f64),
    /// Horizontal unit vector perpendicular (sun to the left of it... any fixed choice).
    p: (f64, f64),
    a0: f64,
    b0: f64,
    na: usize,
    nb: usize,
    lit: Vec<f32>,
}

impl Lattice {
    #[inline]
    fn lit(&self, x: f64, y: f64) -> f32 {
        let dx = x - self.cx;
        let dy = y - self.cy;
        let fa = ((dx * self.s.0 + dy * self.s.1) - self.a0) / self.m;
        let fb = ((dx * self.p.0 + dy * self.p.1) - self.b0) / self.m;
        let ia = (fa.max(0.0) as usize).min(self.na - 2);
        let ib = (fb.max(0.0) as usize).min(self.nb - 2);
        let ta = (fa - ia as f64).clamp(0.0, 1.0) as f32;
        let tb = (fb - ib as f64).clamp(0.0, 1.0) as f32;
        let i = ib * self.na + ia;
        let l = &self.lit;
        let r0 = l[i] * (1.0 - ta) + l[i + 1] * ta;
        let r1 = l[i + self.na] * (1.0 - ta) + l[i + self.na + 1] * ta;
        r0 * (1.0 - tb) + r1 * tb
    }
}

/// Cast-shadow mask of a terrain for one sun.
#[derive(Clone, Debug)]
pub struct ShadowField {
    lattices: Vec<Lattice>,
}

impl ShadowField {
    /// Traces shadows for every level of `terrain` (or only the first `max_levels`).
    pub fn build(terrain: &Terrain, sun: &Sun, reach_m: f64) -> Self {
        Self::build_levels(terrain, sun, reach_m, usize::MAX)
    }

    /// As [`ShadowField::build`] for the first `max_levels` levels only.
    pub fn build_levels(terrain: &Terrain, sun: &Sun, reach_m: f64, max_levels: usize) -> Self {
        // Sun at the zenith: no cast shadows.
        if sun.elevation_deg >= 89.999 {
            return Self {
                lattices: Vec::new(),
            };
        }
        let tan_e = sun.elevation_deg.to_radians().tan();
        let az = sun.azimuth_deg.to_radians();
        let s = (az.sin(), az.cos());
        let p = (az.cos(), -az.sin());
        let nested = terrain.nested();
        let covers: Vec<bool> = terrain.levels.iter().map(|l| l.covers_bounds()).collect();
        // An upper bound of every height the sweep interpolates (bilinear values lie between
        // their nodes'; the margin covers rounding).
        let h_max = terrain
            .levels
            .iter()
            .flat_map(|l| l.grid.height_m.iter())
            .fold(f64::NEG_INFINITY, |a, &h| a.max(h as f64));
        let h_bound = h_max + 1e-6 * (1.0 + h_max.abs());
        let lattices = terrain
            .levels
            .iter()
            .take(max_levels)
            .map(|level| {
                let b = level.bounds;
                let m = level.m();
                let cx = 0.5 * (b[0] + b[2]);
                let cy = 0.5 * (b[1] + b[3]);
                let half = 0.5 * (b[2] - b[0]).hypot(b[3] - b[1]) + m;
                let a0 = -half;
                let b0 = -half;
                let n = (2.0 * half / m).ceil() as usize + 2;
                let (na, nb) = (n, n);
                let mut lit = vec![1.0f32; na * nb];
                let a_max = a0 + (na - 1) as f64 * m;
                // Lowest `a` of the level's square over the band of `b` a lattice line is read
                // for (queries lie in the square; `lit` reads lines ib and ib + 1, so line j
                // serves b in [bj - m, bj + m); the band is taken twice as wide): nodes
                // farther from the sun are never read, so the sweep stops short of them
                // (2 nodes of margin).
                let (hw, hh) = (0.5 * (b[2] - b[0]), 0.5 * (b[3] - b[1]));
                let lower = |sa: f64, pb: f64, half: f64, bl: f64| {
                    // a >= (-half sign(sa) - b pb) / sa on the band [bl - 2m, bl + 2m].
                    if sa == 0.0 {
                        return f64::NEG_INFINITY;
                    }
                    let at = |bv: f64| (-half * sa.signum() - bv * pb) / sa;
                    at(bl - 2.0 * m).min(at(bl + 2.0 * m))
                };
                let first_read = |bl: f64| {
                    let lo = lower(s.0, p.0, hw, bl).max(lower(s.1, p.1, hh, bl));
                    let i = ((lo - a0) / m).floor() - 2.0;
                    if i.is_finite() && i > 0.0 {
                        (i as usize).min(na)
                    } else {
                        0
                    }
                };
                lit.par_chunks_mut(na).enumerate().for_each(|(j, row)| {
                    let bj = b0 + j as f64 * m;
                    let at = |a: f64| (cx + a * s.0 + bj * p.0, cy + a * s.1 + bj * p.1);
                    let mut hint = 0usize;
                    let mut first = |x: f64, y: f64| {
                        if nested {
                            terrain.first_containing(x, y, &mut hint)
                        } else {
                            0
                        }
                    };
                    let mut best = f64::NEG_INFINITY;
                    // Extension towards the sun, far to near, at the terrain's own spacing:
                    // the points first (each step is the spacing of the level there), then
                    // their heights near to far, until no farther point can raise the
                    // maximum (h - a tan e is below `h_bound - a tan e`, which falls with a).
                    let mut ext: Vec<(f64, f64, f64, usize)> = Vec::new();
                    let mut a = a_max + reach_m;
                    while a > a_max {
                        let (x, y) = at(a);
                        let f = first(x, y);
                        // The level there: the first containing the point when its lattice
                        // covers its square (no node coordinates needed yet).
                        let k = match covers.get(f) {
                            Some(true) => Some(f),
                            _ => terrain.locate_from(x, y, f).map(|(k, _, _)| k),
                        };
                        let step = match k {
                            Some(k) => {
                                ext.push((a, x, y, k));
                                terrain.levels[k].m()
                            }
                            None => m.max(reach_m / 64.0),
                        };
                        a -= step.max(m);
                    }
                    for &(a, x, y, k) in ext.iter().rev() {
                        if h_bound - a * tan_e < best {
                            break;
                        }
                        if let Some((k, fx, fy)) = terrain.locate_from(x, y, k) {
                            let h = terrain.levels[k].interpolate(fx, fy);
                            best = best.max(h - a * tan_e);
                        }
                    }
                    let i_min = first_read(bj);
                    // Nodes four at a time (from the sun side): their heights at once when
                    // all four lie in one level whose lattice covers its square, then the
                    // running maximum node by node.
                    let mut i_end = na;
                    while i_end > i_min {
                        let n4 = (i_end - i_min).min(4);
                        let mut pts = [(0.0, 0.0, 0.0); 4];
                        let mut lvl = [usize::MAX; 4];
                        for q in 0..n4 {
                            let a = a0 + (i_end - 1 - q) as f64 * m;
                            let (x, y) = at(a);
                            pts[q] = (a, x, y);
                            lvl[q] = first(x, y);
                        }
                        let k = lvl[0];
                        let same = n4 == 4
                            && nested
                            && lvl.iter().all(|&l| l == k)
                            && covers.get(k) == Some(&true);
                        let hs = if same {
                            terrain.levels[k]
                                .height4(pts.map(|p| p.1), pts.map(|p| p.2))
                                .map(|h| h.map(Some))
                        } else {
                            None
                        };
                        let hs = hs.unwrap_or_else(|| {
                            let mut h = [None; 4];
                            for q in 0..n4 {
                                let (_, x, y) = pts[q];
                                h[q] = terrain
                                    .locate_from(x, y, lvl[q])
                                    .map(|(k, fx, fy)| terrain.levels[k].interpolate(fx, fy));
                            }
                            h
                        });
                        for q in 0..n4 {
                            if let Some(h) = hs[q] {
                                let g = h - pts[q].0 * tan_e;
                                row[i_end - 1 - q] = if g >= best - 1e-3 { 1.0 } else { 0.0 };
                                best = best.max(g);
                            }
                        }
                        i_end -= n4;
                    }
                });
                Lattice {
                    bounds: b,
                    cx,
                    cy,
                    m,
                    s,
                    p,
                    a0,
                    b0,
                    na,
                    nb,
                    lit,
                }
            })
            .collect();
        Self { lattices }
    }

    /// Lit fraction at `(x, y)`: 0 in shadow, 1 lit (1 outside every level).
    #[inline]
    pub fn lit(&self, x: f64, y: f64) -> f32 {
        for l in &self.lattices {
            let b = l.bounds;
            if x >= b[0] && y >= b[1] && x <= b[2] && y <= b[3] {
                return l.lit(x, y);
            }
        }
        1.0
    }
}
