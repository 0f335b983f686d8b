//! The crater field: the size-frequency distribution (octave classes, a power law in each,
//! Poisson counts per grid cell) and the craters placed from it, a pure function of the
//! seed and the cell.

use super::super::hash::{cell_hash, cell_of, layer_key, mix64, Rng};
use super::super::WorldConfig;
use super::{rect_dist2, shape_of, unit_f64, Crater, Degradation};

/// Cumulative Poisson table: `cdf[n] = P(count <= n)`.
pub(crate) fn poisson_cdf(lambda: f64) -> Vec<f64> {
    let mut cdf = Vec::new();
    if lambda.is_nan() || lambda <= 0.0 || !lambda.is_finite() {
        cdf.push(1.0);
        return cdf;
    }
    let mut p = libm::exp(-lambda);
    let mut acc = 0.0;
    for n in 0..256u32 {
        acc += p;
        cdf.push(acc);
        if 1.0 - acc < 1e-12 && f64::from(n) > lambda {
            break;
        }
        p *= lambda / f64::from(n + 1);
    }
    cdf
}

/// Count for a uniform draw `u` in `[0, 1)`.
#[inline]
pub(crate) fn poisson_draw(cdf: &[f64], u: f64) -> usize {
    for (n, &c) in cdf.iter().enumerate() {
        if u < c {
            return n;
        }
    }
    cdf.len()
}

/// Diameter for a uniform draw `u` from the truncated power law `N(>D) ~ D^-b` on `[da, db)`.
#[inline]
pub(crate) fn power_law_diameter(u: f64, da: f64, db: f64, b: f64) -> f64 {
    if b == 2.0 {
        let (a, c) = (1.0 / (da * da), 1.0 / (db * db));
        1.0 / (a - u * (a - c)).sqrt()
    } else {
        let (a, c) = (libm::pow(da, -b), libm::pow(db, -b));
        libm::pow(a - u * (a - c), -1.0 / b)
    }
}

/// Segments of the tabulated inverse CDF of [`PowerLaw`].
const POWER_LAW_SEGMENTS: usize = 256;

/// The truncated power law `N(>D) ~ D^-b` on `[da, db)`, sampled by its inverse CDF: exact
/// (`sqrt`) for `b = 2`, otherwise linear interpolation in a table built once with `libm`
/// (relative error below 1e-5 on an octave bin; no `pow` on the hot path).
#[derive(Clone, Debug)]
pub(crate) struct PowerLaw {
    da: f64,
    /// `1 / da^2` and `1 / db^2`, as [`power_law_diameter`] computes them for `b = 2`.
    inv_da2: f64,
    inv_db2: f64,
    table: Vec<f64>,
}

impl PowerLaw {
    pub(crate) fn new(da: f64, db: f64, b: f64) -> Self {
        let table = if b == 2.0 {
            Vec::new()
        } else {
            (0..=POWER_LAW_SEGMENTS)
                .map(|i| power_law_diameter(i as f64 / POWER_LAW_SEGMENTS as f64, da, db, b))
                .collect()
        };
        Self {
            da,
            inv_da2: 1.0 / (da * da),
            inv_db2: 1.0 / (db * db),
            table,
        }
    }

    /// Diameter for a uniform draw `u` in `[0, 1)`.
    #[inline]
    pub(crate) fn diameter(&self, u: f64) -> f64 {
        if self.table.is_empty() {
            // `power_law_diameter(u, da, db, 2.0)` with its two constants kept.
            let (a, c) = (self.inv_da2, self.inv_db2);
            return 1.0 / (a - u * (a - c)).sqrt();
        }
        let t = u * POWER_LAW_SEGMENTS as f64;
        let i = (t as usize).min(POWER_LAW_SEGMENTS - 1);
        let f = t - i as f64;
        match (self.table.get(i), self.table.get(i + 1)) {
            (Some(&lo), Some(&hi)) => lo + f * (hi - lo),
            _ => self.da,
        }
    }
}

/// Octave size classes `[d, 2d)` from `d_min` up to `d_max`.
pub(crate) fn octave_bins(d_min: f64, d_max: f64) -> Vec<(f64, f64)> {
    let mut bins = Vec::new();
    let mut d = d_min;
    while d < d_max && bins.len() < 64 {
        let hi = if 2.0 * d < d_max { 2.0 * d } else { d_max };
        bins.push((d, hi));
        d *= 2.0;
    }
    bins
}

#[derive(Clone, Debug)]
struct CraterClass {
    d_max: f64,
    law: PowerLaw,
    /// Cell size, metres.
    cell: f64,
    /// Largest reach of a crater of this class (ejecta edge), metres.
    reach: f64,
    cdf: Vec<f64>,
    key: u64,
}

/// All craters of a world.
#[derive(Clone, Debug)]
pub(crate) struct CraterField {
    classes: Vec<CraterClass>,
    extent: f64,
    fresh_fraction: f64,
    old_fraction: f64,
    depth_fresh: f64,
    depth_old: f64,
    rim_fresh: f64,
    rim_old: f64,
}

/// Layer number of crater class `k` (distinct from the other layers of the world).
const CRATER_LAYER: u64 = 0x1000;

impl CraterField {
    pub(crate) fn new(seed: u64, cfg: &WorldConfig) -> Self {
        let extent = cfg.ejecta_extent_radii;
        let classes = octave_bins(cfg.crater_d_min_m, cfg.crater_d_max_m)
            .into_iter()
            .enumerate()
            .map(|(k, (da, db))| {
                let reach = extent * 0.5 * db;
                let cell = 2.0 * reach;
                let per_m2 = cfg.crater_density_per_m2
                    * (libm::pow(da, -cfg.crater_exponent) - libm::pow(db, -cfg.crater_exponent));
                CraterClass {
                    d_max: db,
                    law: PowerLaw::new(da, db, cfg.crater_exponent),
                    cell,
                    reach,
                    cdf: poisson_cdf(per_m2 * cell * cell),
                    key: layer_key(seed, CRATER_LAYER + k as u64),
                }
            })
            .collect();
        Self {
            classes,
            extent,
            fresh_fraction: cfg.crater_fresh_fraction,
            old_fraction: cfg.crater_old_fraction,
            depth_fresh: cfg.crater_depth_ratio_fresh,
            depth_old: cfg.crater_depth_ratio_old,
            rim_fresh: cfg.crater_rim_ratio_fresh,
            rim_old: cfg.crater_rim_ratio_old,
        }
    }

    /// Largest reach of any crater, metres.
    pub(crate) fn max_reach(&self) -> f64 {
        self.classes.last().map_or(0.0, |c| c.reach)
    }

    /// The crater from its two draws.
    #[inline]
    fn make(&self, cls: &CraterClass, cx: f64, cy: f64, shape: u64) -> Crater {
        let ud = (shape as u32) as f64 * (1.0 / 4_294_967_296.0);
        let deg = ((shape >> 32) as u32) as f64 * (1.0 / 4_294_967_296.0);
        let d = cls.law.diameter(ud);
        let depth = d * (self.depth_fresh + (self.depth_old - self.depth_fresh) * deg);
        let rim = d * (self.rim_fresh + (self.rim_old - self.rim_fresh) * deg);
        let state = if deg < self.fresh_fraction {
            Degradation::Fresh
        } else if deg >= 1.0 - self.old_fraction {
            Degradation::Old
        } else {
            Degradation::Mature
        };
        let freshness = if state == Degradation::Fresh {
            1.0 - deg / self.fresh_fraction
        } else {
            0.0
        };
        Crater {
            x_m: cx,
            y_m: cy,
            diameter_m: d,
            depth_m: depth,
            rim_m: rim,
            smoothing_m: (0.05 + 0.6 * deg) * (depth + rim),
            degradation: deg,
            state,
            freshness,
            ejecta_extent_radii: self.extent,
            id: mix64(shape ^ 0x243f_6a88_85a3_08d3),
        }
    }

    /// Calls `f(cx, cy, h, i)` for every crater of class `cls` in cell `(ix, iy)`: its
    /// centre (metres) and what [`shape_of`] needs to draw the rest, lazily (most craters a
    /// query visits are out of reach and never need it).
    #[inline]
    fn for_cell(&self, cls: &CraterClass, ix: i64, iy: i64, mut f: impl FnMut(f64, f64, u64, u64)) {
        let h = cell_hash(cls.key, ix, iy);
        let n = poisson_draw(&cls.cdf, unit_f64(h));
        let mut rng = Rng::new(h);
        for i in 0..n {
            let pos = rng.next_u64();
            let cx = (ix as f64 + (pos as u32) as f64 * (1.0 / 4_294_967_296.0)) * cls.cell;
            let cy = (iy as f64 + ((pos >> 32) as u32) as f64 * (1.0 / 4_294_967_296.0)) * cls.cell;
            f(cx, cy, h, i as u64);
        }
    }

    /// Calls `f(crater)` for every crater whose ejecta blanket reaches into the rectangle
    /// `[x0, x1] x [y0, y1]` (metres; a point when `x0 == x1` and `y0 == y1`), in a fixed
    /// order (class, cell row, cell column, index). With `fresh_only`, skips craters that are
    /// not fresh (albedo-only queries).
    #[inline]
    pub(crate) fn visit_rect(&self, rect: [f64; 4], fresh_only: bool, mut f: impl FnMut(&Crater)) {
        let [x0, y0, x1, y1] = rect;
        for cls in &self.classes {
            let reach2 = cls.reach * cls.reach;
            let ix0 = cell_of(x0 - cls.reach, cls.cell);
            let ix1 = cell_of(x1 + cls.reach, cls.cell);
            let iy0 = cell_of(y0 - cls.reach, cls.cell);
            let iy1 = cell_of(y1 + cls.reach, cls.cell);
            for iy in iy0..=iy1 {
                for ix in ix0..=ix1 {
                    self.for_cell(cls, ix, iy, |cx, cy, h, i| {
                        let r2 = rect_dist2(rect, cx, cy);
                        if r2 >= reach2 {
                            return;
                        }
                        let shape = shape_of(h, i);
                        if fresh_only {
                            let deg = ((shape >> 32) as u32) as f64 * (1.0 / 4_294_967_296.0);
                            if deg >= self.fresh_fraction {
                                return;
                            }
                        }
                        let c = self.make(cls, cx, cy, shape);
                        let e = c.ejecta_extent_radii * c.radius_m();
                        if r2 < e * e {
                            f(&c);
                        }
                    });
                }
            }
        }
    }

    /// [`CraterField::visit_rect`], also passing each crater's class and cell `(k, ix, iy)`
    /// (for [`CraterField::cell_range`] and [`CraterField::reaches`]).
    #[inline]
    ///
    /// Craters for which `keep(k, x, y, fresh)` is false are skipped (class, centre, and
    /// whether the crater may be fresh; asked before the crater is drawn in full).
    pub(crate) fn visit_rect_cells_if(
        &self,
        rect: [f64; 4],
        fresh_only: bool,
        mut keep: impl FnMut(usize, f64, f64, bool) -> bool,
        mut f: impl FnMut(usize, i64, i64, &Crater),
    ) {
        let [x0, y0, x1, y1] = rect;
        for (k, cls) in self.classes.iter().enumerate() {
            let reach2 = cls.reach * cls.reach;
            let ix0 = cell_of(x0 - cls.reach, cls.cell);
            let ix1 = cell_of(x1 + cls.reach, cls.cell);
            let iy0 = cell_of(y0 - cls.reach, cls.cell);
            let iy1 = cell_of(y1 + cls.reach, cls.cell);
            for iy in iy0..=iy1 {
                for ix in ix0..=ix1 {
                    self.for_cell(cls, ix, iy, |cx, cy, h, i| {
                        let r2 = rect_dist2(rect, cx, cy);
                        if r2 >= reach2 {
                            return;
                        }
                        let shape = shape_of(h, i);
                        let deg = ((shape >> 32) as u32) as f64 * (1.0 / 4_294_967_296.0);
                        let fresh = deg < self.fresh_fraction;
                        if fresh_only && !fresh {
                            return;
                        }
                        if !keep(k, cx, cy, fresh) {
                            return;
                        }
                        let c = self.make(cls, cx, cy, shape);
                        let e = c.ejecta_extent_radii * c.radius_m();
                        if r2 < e * e {
                            f(k, ix, iy, &c);
                        }
                    });
                }
            }
        }
    }

    /// Largest reach of class `k`'s craters, metres (0 past the last class).
    pub(crate) fn class_reach(&self, k: usize) -> f64 {
        self.classes.get(k).map_or(0.0, |c| c.reach)
    }

    /// Number of size classes.
    pub(crate) fn class_count(&self) -> usize {
        self.classes.len()
    }

    /// The cells `[i0, i1]` of class `k` that [`CraterField::visit_rect`] walks along one
    /// axis for a rectangle spanning `[lo, hi]` on it (`(1, 0)`, none, past the last class).
    #[inline]
    pub(crate) fn cell_range(&self, k: usize, lo: f64, hi: f64) -> (i64, i64) {
        self.classes.get(k).map_or((1, 0), |cls| {
            (
                cell_of(lo - cls.reach, cls.cell),
                cell_of(hi + cls.reach, cls.cell),
            )
        })
    }

    /// The distance tests by which [`CraterField::visit_rect`]`(rect, ..)` visits crater `c`
    /// of class `k` found in a cell it walks (see [`CraterField::cell_range`]; the
    /// freshness filter is the caller's), bit for bit.
    #[inline]
    pub(crate) fn reaches(&self, rect: [f64; 4], k: usize, c: &Crater) -> bool {
        let Some(cls) = self.classes.get(k) else {
            return false;
        };
        let r2 = rect_dist2(rect, c.x_m, c.y_m);
        let e = c.ejecta_extent_radii * c.radius_m();
        r2 < cls.reach * cls.reach && r2 < e * e
    }

    /// Every crater whose centre lies in `[x0, x1) x [y0, y1)` (metres) and whose diameter
    /// is at least `d_min_m`.
    pub(crate) fn in_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64, d_min_m: f64) -> Vec<Crater> {
        let mut out = Vec::new();
        for cls in self.classes.iter().filter(|c| c.d_max > d_min_m) {
            for iy in cell_of(y0, cls.cell)..=cell_of(y1, cls.cell) {
                for ix in cell_of(x0, cls.cell)..=cell_of(x1, cls.cell) {
                    self.for_cell(cls, ix, iy, |cx, cy, h, i| {
                        if cx >= x0 && cx < x1 && cy >= y0 && cy < y1 {
                            let c = self.make(cls, cx, cy, shape_of(h, i));
                            if c.diameter_m >= d_min_m {
                                out.push(c);
                            }
                        }
                    });
                }
            }
        }
        out
    }
}
