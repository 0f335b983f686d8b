//! Boulders: small rounded bumps with a power-law size distribution, scattered everywhere
//! and much denser on and around fresh craters (blocks thrown out by the impact).
//!
//! Same scheme as the craters: octave size classes, one grid layer per class with cells one
//! class-maximum diameter wide (a rock touches at most the 2 x 2 cells around a point), a
//! hashed Poisson count per cell. Fresh craters at least `fresh_crater_rock_d_min_m` wide
//! carry their own rock layers, keyed by the crater's id, thinning out as `rho^-3` beyond
//! the rim.

use super::craters::{
    octave_bins, poisson_cdf, poisson_draw, rect_dist2, unit_f64, Crater, PowerLaw,
};
use super::hash::{cell_hash, cell_of, layer_key, mix64, Rng};
use super::WorldConfig;

/// One boulder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rock {
    /// Centre, world east, metres.
    pub x_m: f64,
    /// Centre, world north, metres.
    pub y_m: f64,
    /// Diameter, metres.
    pub diameter_m: f64,
    /// Height of the top above the ground, metres.
    pub height_m: f64,
    /// Albedo added on the rock (normal albedo units).
    pub albedo_boost: f64,
}

impl Rock {
    /// Height (metres) at squared distance `r2` (m^2) from the centre: a half-buried
    /// ellipsoid, zero outside the footprint.
    #[inline]
    pub fn height_at(&self, r2: f64) -> f64 {
        let r = 0.5 * self.diameter_m;
        let q = 1.0 - r2 / (r * r);
        if q <= 0.0 {
            0.0
        } else {
            self.height_m * q.sqrt()
        }
    }
}

#[derive(Clone, Debug)]
struct RockClass {
    d_max: f64,
    /// Background rocks of this class per square metre.
    density_per_m2: f64,
    law: PowerLaw,
    cell: f64,
    cdf_background: Vec<f64>,
    cdf_fresh: Vec<f64>,
    key: u64,
}

/// All boulders of a world.
#[derive(Clone, Debug)]
pub(crate) struct RockField {
    classes: Vec<RockClass>,
    albedo_boost: f64,
    /// Smallest fresh crater that carries boulders, metres.
    fresh_d_min: f64,
    /// Largest rock radius, metres.
    max_radius: f64,
    /// Fresh-crater density factor.
    fresh_factor: f64,
    /// [`RockField::class_mean_albedo`] per class, computed once.
    mean_albedo: Vec<f64>,
}

const ROCK_LAYER: u64 = 0x2000;
const FRESH_ROCK_LAYER: u64 = 0x3000;

impl RockField {
    pub(crate) fn new(seed: u64, cfg: &WorldConfig) -> Self {
        let classes: Vec<RockClass> = octave_bins(cfg.rock_d_min_m, cfg.rock_d_max_m)
            .into_iter()
            .enumerate()
            .map(|(k, (da, db))| {
                let cell = db;
                let per_m2 = cfg.rock_density_per_m2
                    * (libm::pow(da, -cfg.rock_exponent) - libm::pow(db, -cfg.rock_exponent));
                RockClass {
                    d_max: db,
                    density_per_m2: per_m2,
                    law: PowerLaw::new(da, db, cfg.rock_exponent),
                    cell,
                    cdf_background: poisson_cdf(per_m2 * cell * cell),
                    cdf_fresh: poisson_cdf(per_m2 * cfg.fresh_crater_rock_factor * cell * cell),
                    key: layer_key(seed, ROCK_LAYER + k as u64),
                }
            })
            .collect();
        let max_radius = classes.last().map_or(0.0, |c| 0.5 * c.d_max);
        let mut field = Self {
            classes,
            albedo_boost: cfg.rock_albedo_boost,
            fresh_d_min: cfg.fresh_crater_rock_d_min_m,
            max_radius,
            fresh_factor: cfg.fresh_crater_rock_factor,
            mean_albedo: Vec::new(),
        };
        field.mean_albedo = (0..field.classes.len())
            .map(|k| field.mean_albedo_of(k))
            .collect();
        field
    }

    /// Centre (metres) of the next rock of a cell, and the draw for the rest of it.
    #[inline]
    fn place(cls: &RockClass, ix: i64, iy: i64, rng: &mut Rng) -> (f64, f64, u64) {
        let pos = rng.next_u64();
        let shape = rng.next_u64();
        let x = (ix as f64 + (pos as u32) as f64 * (1.0 / 4_294_967_296.0)) * cls.cell;
        let y = (iy as f64 + ((pos >> 32) as u32) as f64 * (1.0 / 4_294_967_296.0)) * cls.cell;
        (x, y, shape)
    }

    #[inline]
    fn make(&self, cls: &RockClass, x: f64, y: f64, shape: u64) -> Rock {
        let ud = (shape as u32) as f64 * (1.0 / 4_294_967_296.0);
        let d = cls.law.diameter(ud);
        let uh = ((shape >> 32) & 0xffff) as f64 * (1.0 / 65536.0);
        let ua = (shape >> 48) as f64 * (1.0 / 65536.0);
        Rock {
            x_m: x,
            y_m: y,
            diameter_m: d,
            // 40 to 80 % of the radius sticks out.
            height_m: 0.5 * d * (0.4 + 0.4 * uh),
            albedo_boost: self.albedo_boost * (0.5 + ua),
        }
    }

    /// Calls `f(rock)` for every background rock whose footprint reaches into `rect`
    /// (`[x0, y0, x1, y1]` metres), in a fixed order, for the classes from `first_class` on
    /// and with every rock's reach scaled by `grow` (1 for point queries; more for
    /// footprint-filtered ones, whose equal-area squares reach `sqrt(pi / 2)` radii along
    /// the diagonals).
    #[inline]
    pub(crate) fn visit_rect_from(
        &self,
        rect: [f64; 4],
        first_class: usize,
        grow: f64,
        mut f: impl FnMut(&Rock),
    ) {
        let [x0, y0, x1, y1] = rect;
        for cls in self.classes.iter().skip(first_class) {
            let reach = 0.5 * cls.d_max * grow;
            for iy in cell_of(y0 - reach, cls.cell)..=cell_of(y1 + reach, cls.cell) {
                for ix in cell_of(x0 - reach, cls.cell)..=cell_of(x1 + reach, cls.cell) {
                    let h = cell_hash(cls.key, ix, iy);
                    let n = poisson_draw(&cls.cdf_background, unit_f64(h));
                    let mut rng = Rng::new(h);
                    for _ in 0..n {
                        let (rx, ry, shape) = Self::place(cls, ix, iy, &mut rng);
                        let d2 = rect_dist2(rect, rx, ry);
                        if d2 >= reach * reach {
                            continue;
                        }
                        let r = self.make(cls, rx, ry, shape);
                        let rr = 0.5 * r.diameter_m * grow;
                        if d2 < rr * rr {
                            f(&r);
                        }
                    }
                }
            }
        }
    }

    /// Number of size classes.
    pub(crate) fn class_count(&self) -> usize {
        self.classes.len()
    }

    /// Largest diameter of class `k`, metres (`None` past the last class).
    pub(crate) fn class_d_max(&self, k: usize) -> Option<f64> {
        self.classes.get(k).map(|c| c.d_max)
    }

    /// Expected albedo added by the background rocks of class `k` per unit area: the mean
    /// covered fraction (density x mean disc area) times the mean albedo boost. Multiply by
    /// the fresh-crater factor for a fresh crater's own layer inside its rim.
    pub(crate) fn class_mean_albedo(&self, k: usize) -> f64 {
        self.mean_albedo.get(k).copied().unwrap_or(0.0)
    }

    /// [`RockField::class_mean_albedo`], computed.
    fn mean_albedo_of(&self, k: usize) -> f64 {
        self.classes.get(k).map_or(0.0, |c| {
            // Mean of d^2 by the midpoint rule over the inverse CDF (256 steps).
            let n = 256;
            let mean_d2 = (0..n)
                .map(|i| {
                    let d = c.law.diameter((i as f64 + 0.5) / n as f64);
                    d * d
                })
                .sum::<f64>()
                / n as f64;
            c.density_per_m2 * core::f64::consts::FRAC_PI_4 * mean_d2 * self.albedo_boost
        })
    }

    /// The fresh-crater boulder density as a multiple of the background.
    pub(crate) fn fresh_factor(&self) -> f64 {
        self.fresh_factor
    }

    /// Whether `crater` carries its own boulders.
    #[inline]
    pub(crate) fn crater_has_rocks(&self, c: &Crater) -> bool {
        c.freshness > 0.0 && c.diameter_m >= self.fresh_d_min && !self.classes.is_empty()
    }

    /// Calls `f(rock)` for every boulder of fresh crater `c` whose footprint reaches into
    /// `rect`. The boulders lie wholly inside the crater's ejecta blanket, so a point a
    /// boulder covers is covered by the crater too.
    /// Classes from `first_class` on, reach scaled by `grow` (see
    /// [`RockField::visit_rect_from`]).
    #[inline]
    pub(crate) fn visit_crater_rect_from(
        &self,
        c: &Crater,
        rect: [f64; 4],
        first_class: usize,
        grow: f64,
        mut f: impl FnMut(&Rock),
    ) {
        let [x0, y0, x1, y1] = rect;
        let rc = c.radius_m();
        let outer = c.ejecta_extent_radii * rc - self.max_radius;
        if outer <= 0.0 {
            return;
        }
        for (k, cls) in self.classes.iter().enumerate().skip(first_class) {
            let key = mix64(c.id ^ layer_key(FRESH_ROCK_LAYER, k as u64));
            let reach = 0.5 * cls.d_max * grow;
            for iy in cell_of(y0 - reach, cls.cell)..=cell_of(y1 + reach, cls.cell) {
                for ix in cell_of(x0 - reach, cls.cell)..=cell_of(x1 + reach, cls.cell) {
                    let h = cell_hash(key, ix, iy);
                    let n = poisson_draw(&cls.cdf_fresh, unit_f64(h));
                    let mut rng = Rng::new(h);
                    for _ in 0..n {
                        let (rx, ry, shape) = Self::place(cls, ix, iy, &mut rng);
                        let keep = rng.f64();
                        let d2 = rect_dist2(rect, rx, ry);
                        if d2 >= reach * reach {
                            continue;
                        }
                        let r = self.make(cls, rx, ry, shape);
                        let rr = 0.5 * r.diameter_m * grow;
                        if d2 >= rr * rr {
                            continue;
                        }
                        let (ex, ey) = (r.x_m - c.x_m, r.y_m - c.y_m);
                        let d2 = ex * ex + ey * ey;
                        if d2 >= outer * outer {
                            continue;
                        }
                        // Full density inside the rim, then rho^-3.
                        let rho2 = d2 / (rc * rc);
                        if rho2 > 1.0 && keep * rho2 * rho2.sqrt() >= 1.0 {
                            continue;
                        }
                        f(&r);
                    }
                }
            }
        }
    }

    /// Every background rock whose centre lies in `[x0, x1) x [y0, y1)` (metres).
    pub(crate) fn in_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<Rock> {
        let mut out = Vec::new();
        for cls in &self.classes {
            for iy in cell_of(y0, cls.cell)..=cell_of(y1, cls.cell) {
                for ix in cell_of(x0, cls.cell)..=cell_of(x1, cls.cell) {
                    let h = cell_hash(cls.key, ix, iy);
                    let n = poisson_draw(&cls.cdf_background, unit_f64(h));
                    let mut rng = Rng::new(h);
                    for _ in 0..n {
                        let (rx, ry, shape) = Self::place(cls, ix, iy, &mut rng);
                        let r = self.make(cls, rx, ry, shape);
                        if r.x_m >= x0 && r.x_m < x1 && r.y_m >= y0 && r.y_m < y1 {
                            out.push(r);
                        }
                    }
                }
            }
        }
        out
    }
}
