//! Footprint-filtered sampling: the features that reach a query point ([`Feature`],
//! [`Item`]), the low-pass filter of a pixel footprint ([`Filter`]) and the accumulation of
//! height and albedo at a point ([`Acc`]).

use super::craters::Rays;
use super::{Crater, Rock, World};

/// A feature reaching a query, borrowed; a crater with its rays' directions when they were
/// drawn once for many points (`None`: drawn when needed).
#[derive(Clone, Copy)]
pub(super) enum Feature<'a> {
    Crater(&'a Crater, Option<&'a Rays>),
    Rock(&'a Rock),
}

/// A feature reaching a tile, owned (fresh craters with their rays drawn).
#[derive(Clone, Copy)]
pub(super) enum Item {
    Crater(Crater, Option<Rays>),
    Rock(Rock),
}

impl Item {
    /// `f` owned; the rays of a fresh crater drawn once.
    #[inline]
    pub(super) fn of(f: Feature<'_>) -> Self {
        match f {
            Feature::Crater(c, _) => Item::Crater(*c, (c.freshness > 0.0).then(|| c.rays())),
            Feature::Rock(r) => Item::Rock(*r),
        }
    }

    #[inline]
    pub(super) fn as_feature(&self) -> Feature<'_> {
        match self {
            Item::Crater(c, rays) => Feature::Crater(c, rays.as_ref()),
            Item::Rock(r) => Feature::Rock(r),
        }
    }
}

/// How samples integrate albedo over their footprint ([`World::sample_grid_filtered`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Filter {
    /// Side of the square footprint, metres (0: point samples).
    pub(super) fp: f64,
    /// Half of `fp`, metres.
    pub(super) hf: f64,
    /// Boulder classes before this one enter by their expected albedo (not visited).
    pub(super) first_rock_class: usize,
    /// Expected albedo of those classes' background boulders (per unit area).
    pub(super) rock_mean: f64,
    /// Expected albedo of those classes' fresh-crater boulders inside the rim.
    pub(super) fresh_rock_mean: f64,
    /// Smallest fresh crater with boulders, metres (infinite when there are none).
    pub(super) fresh_rock_d_min: f64,
    /// Largest boulder radius, metres.
    pub(super) max_rock_radius: f64,
    /// Reach factor of boulders in visits (equal-area squares reach further than discs).
    pub(super) grow: f64,
}

/// Boulder size classes no wider than this many footprints enter footprint-filtered grids by
/// their expected albedo instead of one by one (fine grids; coarse ones: one footprint).
const MEAN_FIELD_ROCK_FOOTPRINTS: f64 = 0.5;

/// From this footprint on (metres; the renderer's mesh rings from 0.8 m, i.e. beyond about
/// 43 m and any 50 m top-down image), classes no wider than one footprint enter by their mean.
const MEAN_FIELD_COARSE_M: f64 = 0.75;

impl Filter {
    /// Point samples: exactly the unfiltered world.
    pub(super) const POINT: Filter = Filter {
        fp: 0.0,
        hf: 0.0,
        first_rock_class: 0,
        rock_mean: 0.0,
        fresh_rock_mean: 0.0,
        fresh_rock_d_min: f64::INFINITY,
        max_rock_radius: 0.0,
        grow: 1.0,
    };

    pub(super) fn new(world: &World, footprint_m: f64) -> Self {
        if !(footprint_m.is_finite() && footprint_m > 0.0) {
            return Self::POINT;
        }
        let rocks = &world.rocks;
        let mut first = 0;
        let mut mean = 0.0;
        // Coarse footprints take every class no wider than the footprint by its mean:
        // visiting boulders is most of their cost.
        let limit = if footprint_m >= MEAN_FIELD_COARSE_M {
            footprint_m
        } else {
            MEAN_FIELD_ROCK_FOOTPRINTS * footprint_m
        };
        while let Some(d) = rocks.class_d_max(first) {
            if d > limit {
                break;
            }
            mean += rocks.class_mean_albedo(first);
            first += 1;
        }
        let n = rocks.class_count();
        Self {
            fp: footprint_m,
            hf: 0.5 * footprint_m,
            first_rock_class: first,
            rock_mean: mean,
            fresh_rock_mean: mean * rocks.fresh_factor(),
            fresh_rock_d_min: if n == 0 {
                f64::INFINITY
            } else {
                world.cfg.fresh_crater_rock_d_min_m
            },
            max_rock_radius: rocks
                .class_d_max(n.wrapping_sub(1))
                .map_or(0.0, |d| 0.5 * d),
            // sqrt(pi / 2): corner of the equal-area square of a disc, in radii.
            grow: 1.2534,
        }
    }

    /// `rect` grown by half the footprint on every side.
    #[inline]
    pub(super) fn grown(&self, rect: [f64; 4]) -> [f64; 4] {
        if self.hf > 0.0 {
            let h = self.hf;
            [rect[0] - h, rect[1] - h, rect[2] + h, rect[3] + h]
        } else {
            rect
        }
    }
}

impl Filter {
    /// Centre of `f` and the squared distance from it within which [`Acc::add`] may change a
    /// sum: `add` at a point as far or farther returns false and changes nothing (this is
    /// its first test, computed the same way), so callers may skip it there.
    #[inline]
    pub(super) fn reach(&self, f: Feature<'_>) -> [f64; 3] {
        match f {
            Feature::Crater(c, _) => {
                let e = c.ejecta_extent_radii * c.radius_m();
                let r = if self.fp > 0.0 {
                    e + self.hf * core::f64::consts::SQRT_2
                } else {
                    e
                };
                [c.x_m, c.y_m, r * r]
            }
            Feature::Rock(r) => {
                let rr = 0.5 * r.diameter_m;
                let q = if self.fp > 0.0 {
                    self.grow * rr + self.hf * core::f64::consts::SQRT_2
                } else {
                    rr
                };
                [r.x_m, r.y_m, q * q]
            }
        }
    }
}

/// Whether `(x, y)` lies within a [`Filter::reach`] `[cx, cy, reach2]`: `dx^2 + dy^2` as
/// [`Acc::add`] computes it.
#[inline]
pub(super) fn within([cx, cy, reach2]: [f64; 3], x: f64, y: f64) -> bool {
    let (dx, dy) = (x - cx, y - cy);
    dx * dx + dy * dy < reach2
}

/// Fraction (0..1) of the `fp`-wide square centred at offset `(dx, dy)` from a disc of radius
/// `rr` that the disc covers: for discs smaller than the square, the exact overlap of the
/// square with the disc's equal-area square (area-preserving: summed over a grid it is the
/// disc's area); for larger discs, a linear ramp one footprint wide across the edge.
#[inline]
fn disc_coverage(dx: f64, dy: f64, r2: f64, rr: f64, fp: f64) -> f64 {
    if rr >= fp {
        let t = 0.5 + (rr - r2.sqrt()) / fp;
        return t.clamp(0.0, 1.0);
    }
    // Half side of the equal-area square: rr sqrt(pi) / 2.
    let h = rr * 0.886_226_925_452_758;
    let hf = 0.5 * fp;
    let lim = 2.0 * h; // h < hf here
    let ox = (hf + h - dx.abs()).clamp(0.0, lim);
    let oy = (hf + h - dy.abs()).clamp(0.0, lim);
    ox * oy / (fp * fp)
}

/// Height and albedo summed over the layers of one sample.
pub(super) struct Acc<'f> {
    pub(super) h: f64,
    pub(super) a: f64,
    pub(super) relief: bool,
    pub(super) want_a: bool,
    pub(super) boost: f64,
    pub(super) filt: &'f Filter,
}

impl Acc<'_> {
    /// Adds the contribution of `f` at `(x, y)` metres (nothing if `f` does not cover it);
    /// whether `f` covers the point (with a footprint: reaches into the footprint).
    #[inline]
    pub(super) fn add(&mut self, f: Feature<'_>, x: f64, y: f64) -> bool {
        if self.filt.fp > 0.0 {
            return self.add_filtered(f, x, y);
        }
        match f {
            Feature::Crater(c, _) => {
                let (dx, dy) = (x - c.x_m, y - c.y_m);
                let r2 = dx * dx + dy * dy;
                let e = c.ejecta_extent_radii * c.radius_m();
                if r2 < e * e {
                    if self.relief {
                        self.h += c.height_at(r2);
                    }
                    if self.want_a {
                        self.a += c.albedo_at(dx, dy, r2, self.boost);
                    }
                    return true;
                }
                false
            }
            Feature::Rock(r) => {
                let (dx, dy) = (x - r.x_m, y - r.y_m);
                let r2 = dx * dx + dy * dy;
                let rr = 0.5 * r.diameter_m;
                if r2 < rr * rr {
                    if self.relief {
                        self.h += r.height_at(r2);
                    }
                    if self.want_a {
                        self.a += r.albedo_boost;
                    }
                    return true;
                }
                false
            }
        }
    }

    /// [`Acc::add`] with the footprint filter: point heights, area-averaged albedo.
    #[inline]
    fn add_filtered(&mut self, f: Feature<'_>, x: f64, y: f64) -> bool {
        let filt = self.filt;
        match f {
            Feature::Crater(c, rays) => {
                let (dx, dy) = (x - c.x_m, y - c.y_m);
                let r2 = dx * dx + dy * dy;
                let e = c.ejecta_extent_radii * c.radius_m();
                let reach = e + filt.hf * core::f64::consts::SQRT_2;
                if r2 >= reach * reach {
                    return false;
                }
                if self.relief && r2 < e * e {
                    self.h += c.height_at(r2);
                }
                if self.want_a && c.freshness > 0.0 {
                    self.a += c.albedo_filtered_with(dx, dy, self.boost, filt.fp, rays);
                    if filt.fresh_rock_mean > 0.0
                        && c.freshness > 0.0
                        && c.diameter_m >= filt.fresh_rock_d_min
                    {
                        // The crater's own small boulders by their expected value: full
                        // density inside the rim, rho^-3 outside, none past the blanket.
                        let rc = c.radius_m();
                        let outer = e - filt.max_rock_radius;
                        if r2 < outer * outer {
                            let rho2 = r2 / (rc * rc);
                            let w = if rho2 <= 1.0 {
                                1.0
                            } else {
                                1.0 / (rho2 * rho2.sqrt())
                            };
                            self.a += filt.fresh_rock_mean * w;
                        }
                    }
                }
                true
            }
            Feature::Rock(r) => {
                let (dx, dy) = (x - r.x_m, y - r.y_m);
                let r2 = dx * dx + dy * dy;
                let rr = 0.5 * r.diameter_m;
                // Nothing of the disc (or its equal-area square) reaches the footprint.
                let reach = filt.grow * rr + filt.hf * core::f64::consts::SQRT_2;
                if r2 >= reach * reach {
                    return false;
                }
                if self.relief && r2 < rr * rr {
                    self.h += r.height_at(r2);
                }
                if self.want_a {
                    let cov = disc_coverage(dx, dy, r2, rr, filt.fp);
                    if cov > 0.0 {
                        self.a += r.albedo_boost * cov;
                        return true;
                    }
                }
                r2 < rr * rr
            }
        }
    }

    #[inline]
    pub(super) fn finish(&self) -> (f64, f64) {
        (self.h, self.a.clamp(0.0, 1.0))
    }
}
