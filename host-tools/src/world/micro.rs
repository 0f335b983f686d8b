//! Near-field micro-relief of the regolith: centimetre-scale roughness, clods and small
//! angular rocks, a pure function of `(seed, x, y)` like the rest of the world.
//!
//! The main height field ([`super::World::height_m`]) stops at 1 m craters and 0.2 m
//! boulders, so a ground view of the first metres reads as smooth plaster. Real regolith is
//! textured down to millimetres, and stereo lives on that texture. This layer adds, on top
//! of the main height field:
//! - **roughness**: fractal gradient noise, wavelengths from 0.32 m down to 1 cm, amplitude
//!   8 mm at 0.32 m falling as `wavelength^0.8`: slopes of 5-10 deg per octave;
//! - **clods**: soil aggregates, radius 0.8-3 cm, in 0.15 m cells with probability 0.45;
//! - **pebbles**: angular rock fragments, radius 2-10 cm (power law), in 0.5 m cells with
//!   probability 0.35, brighter than the soil;
//! - **albedo grain**: +-6 % multiplicative albedo noise following the 8 cm roughness
//!   octave (crests a little brighter than hollows).
//!
//! Rocks are polygonal pyramids, truncated: `N` (5-8) facet planes with hashed directions
//! and distances give a polygon distance `rho` (0 at the centre, 1 on the base outline) and
//! the height `h min(1, k (1 - rho))`: flat facets meeting at sharp edges, as fractured
//! rock is, not the rounded mounds of the boulder layer.
//!
//! The layer is small next to the renderer's mesh (at most about 8 cm tall), so it is not
//! part of [`super::World::height_m`] or the range images: the renderer draws it as a
//! texture of the ground views near the rover (normals, albedo and cast shadows on a
//! centimetre grid, `render::detail`). Orbital images (0.25 m pixels and coarser) average
//! it out.

use super::hash::{cell_hash, cell_of, layer_key, Rng};
use super::noise::Fbm;

/// Layer numbers of the micro-relief (distinct from the other layers of the world).
const ROUGHNESS_LAYER: u64 = 0x5100;
const CLOD_LAYER: u64 = 0x5300;
const PEBBLE_LAYER: u64 = 0x5400;
const PIT_LAYER: u64 = 0x5500;

/// Largest number of facets of a rock.
pub const MAX_FACETS: usize = 8;

/// One small rock or clod of the micro-relief.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicroRock {
    /// Centre, world east, metres.
    pub x_m: f64,
    /// Centre, world north, metres.
    pub y_m: f64,
    /// Radius bounding the base outline, metres (no point of the rock is farther).
    pub radius_m: f64,
    /// Height of the top above the ground, metres.
    pub height_m: f64,
    /// Steepness of the flanks: the top is flat where `k (1 - rho) >= 1`.
    pub k: f64,
    /// Albedo multiplier on the rock (1 = the soil's).
    pub albedo_mul: f64,
    /// Facet planes: unit outward direction `(ux, uy)` divided by the plane's distance from
    /// the centre (metres^-1); only the first `facets` are used.
    pub planes: [(f64, f64); MAX_FACETS],
    /// Number of facet planes, 5..=8.
    pub facets: usize,
}

impl MicroRock {
    /// Height above the ground (metres) at `(x, y)`; 0 outside the base outline.
    #[inline]
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.x_m, y - self.y_m);
        let mut rho = 0.0f64;
        for &(a, b) in &self.planes[..self.facets] {
            rho = rho.max(dx * a + dy * b);
        }
        if rho >= 1.0 {
            0.0
        } else {
            self.height_m * (self.k * (1.0 - rho)).min(1.0)
        }
    }
}

/// One small impact pit of the micro-relief: a parabolic bowl with a raised rim whose
/// ejecta fall off as `rho^-3` out to two radii (the world's crater profile in miniature).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicroPit {
    /// Centre, world east, metres.
    pub x_m: f64,
    /// Centre, world north, metres.
    pub y_m: f64,
    /// Radius of the rim crest, metres.
    pub radius_m: f64,
    /// Depth of the floor below the surrounding ground, metres.
    pub depth_m: f64,
    /// Height of the rim crest above the surrounding ground, metres.
    pub rim_m: f64,
}

impl MicroPit {
    /// Radius beyond which the pit changes nothing, metres.
    #[inline]
    pub fn reach_m(&self) -> f64 {
        2.0 * self.radius_m
    }

    /// Height change (metres) at `(x, y)`.
    #[inline]
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.x_m, y - self.y_m);
        let rho2 = (dx * dx + dy * dy) / (self.radius_m * self.radius_m);
        if rho2 >= 4.0 {
            0.0
        } else if rho2 < 1.0 {
            -self.depth_m + (self.depth_m + self.rim_m) * rho2
        } else {
            // rim (rho^-3 - 1/8) / (1 - 1/8)
            let rho3 = rho2 * rho2.sqrt();
            self.rim_m * (1.0 / rho3 - 0.125) / 0.875
        }
    }
}

/// One size class of pits: at most one pit per square cell.
#[derive(Clone, Copy, Debug)]
struct PitClass {
    key: u64,
    cell: f64,
    p: f64,
    r_min: f64,
    r_max: f64,
}

/// One size class of rocks: at most one rock per square cell.
#[derive(Clone, Copy, Debug)]
struct RockClass {
    key: u64,
    /// Cell side, metres.
    cell: f64,
    /// Probability that a cell holds a rock.
    p: f64,
    /// Radius range, metres, and the power-law exponent of the cumulative size law.
    r_min: f64,
    r_max: f64,
    exponent: f64,
    /// Height as a fraction of the radius, range.
    h_lo: f64,
    h_hi: f64,
    /// Albedo multiplier range.
    a_lo: f64,
    a_hi: f64,
}

/// The micro-relief layer of a world.
#[derive(Clone, Debug)]
pub struct MicroRelief {
    /// One single-octave noise per roughness octave, coarsest first, with its wavelength
    /// and amplitude (metres).
    roughness: Vec<(f64, f64, Fbm)>,
    classes: [RockClass; 2],
    pits: [PitClass; 3],
}

/// Wavelength of the coarsest roughness octave, metres.
const ROUGHNESS_WAVELENGTH_M: f64 = 0.32;
/// Roughness amplitude at 0.32 m wavelength, metres.
const ROUGHNESS_AMPLITUDE_M: f64 = 0.008;
/// Amplitude falls as wavelength^hurst.
const ROUGHNESS_HURST: f64 = 0.8;
/// Octaves of roughness: 0.32 m down to 1 cm.
const ROUGHNESS_OCTAVES: u32 = 6;
/// Relative albedo amplitude of the grain.
const GRAIN_AMPLITUDE: f64 = 0.06;
/// Wavelength of the roughness octave the grain follows, metres.
const GRAIN_WAVELENGTH_M: f64 = 0.08;

impl MicroRelief {
    /// The micro-relief of world `seed`.
    pub fn new(seed: u64) -> Self {
        let mut roughness = Vec::new();
        let mut wl = ROUGHNESS_WAVELENGTH_M;
        for k in 0..ROUGHNESS_OCTAVES {
            let amp = ROUGHNESS_AMPLITUDE_M * libm::pow(wl / 0.32, ROUGHNESS_HURST);
            roughness.push((
                wl,
                amp,
                Fbm::new(seed, ROUGHNESS_LAYER + k as u64, wl, amp, 1, 0.0),
            ));
            wl *= 0.5;
        }
        let classes = [
            RockClass {
                key: layer_key(seed, CLOD_LAYER),
                cell: 0.15,
                p: 0.45,
                r_min: 0.008,
                r_max: 0.03,
                exponent: 1.5,
                h_lo: 0.35,
                h_hi: 0.7,
                a_lo: 0.95,
                a_hi: 1.15,
            },
            RockClass {
                key: layer_key(seed, PEBBLE_LAYER),
                cell: 0.5,
                p: 0.35,
                r_min: 0.02,
                r_max: 0.10,
                exponent: 2.5,
                h_lo: 0.35,
                h_hi: 0.6,
                a_lo: 1.1,
                a_hi: 1.5,
            },
        ];
        // Pits of 4 cm to 1 m across, about N(>D) = 0.05 D^-2 per m^2 (below the world's
        // 1 m craters on the same equilibrium slope, somewhat sparser).
        let pits = [
            PitClass {
                key: layer_key(seed, PIT_LAYER),
                cell: 0.25,
                p: 0.55,
                r_min: 0.02,
                r_max: 0.06,
            },
            PitClass {
                key: layer_key(seed, PIT_LAYER + 1),
                cell: 0.7,
                p: 0.5,
                r_min: 0.06,
                r_max: 0.18,
            },
            PitClass {
                key: layer_key(seed, PIT_LAYER + 2),
                cell: 2.0,
                p: 0.55,
                r_min: 0.18,
                r_max: 0.5,
            },
        ];
        Self {
            roughness,
            classes,
            pits,
        }
    }

    /// Largest rock radius, metres.
    pub fn max_rock_radius_m(&self) -> f64 {
        self.classes.iter().map(|c| c.r_max).fold(0.0, f64::max)
    }

    /// Largest height of the layer above the ground it lies on, metres (rocks; the
    /// roughness is zero-mean and a few millimetres).
    pub fn max_height_m(&self) -> f64 {
        self.classes
            .iter()
            .map(|c| c.r_max * c.h_hi)
            .fold(0.0, f64::max)
    }

    /// Roughness height (metres, zero mean) and albedo multiplier of the soil grain (about
    /// 0.94..1.06) at `(x, y)`, summing only the octaves whose wavelength is at least
    /// `min_wavelength_m` (a level of detail: finer octaves would alias on a grid of a third
    /// of that spacing; without the grain's octave the multiplier is 1).
    #[inline]
    pub fn soil(&self, x: f64, y: f64, min_wavelength_m: f64) -> (f64, f64) {
        let mut h = 0.0;
        let mut grain = 1.0;
        for (wl, amp, o) in &self.roughness {
            if *wl < min_wavelength_m {
                break;
            }
            let v = o.at(x, y);
            if (*wl - GRAIN_WAVELENGTH_M).abs() < 1e-9 {
                grain += GRAIN_AMPLITUDE * v / amp;
            }
            h += v;
        }
        (h, grain)
    }

    /// [`MicroRelief::soil`] at `(xs[i], y)` for every `i`, bit for bit (the octaves in the
    /// same order, each a vectorized row of [`Fbm::row`]): heights into `h`, albedo
    /// multipliers into `grain`; `tmp` is scratch. All three as long as `xs`.
    pub fn soil_row(
        &self,
        xs: &[f64],
        y: f64,
        min_wavelength_m: f64,
        h: &mut [f64],
        grain: &mut [f64],
        tmp: &mut Vec<f64>,
    ) {
        let n = xs.len().min(h.len()).min(grain.len());
        let (xs, h, grain) = (&xs[..n], &mut h[..n], &mut grain[..n]);
        h.fill(0.0);
        grain.fill(1.0);
        tmp.clear();
        tmp.resize(n, 0.0);
        for (wl, amp, o) in &self.roughness {
            if *wl < min_wavelength_m {
                break;
            }
            o.row(xs, y, tmp);
            if (*wl - GRAIN_WAVELENGTH_M).abs() < 1e-9 {
                for (g, &v) in grain.iter_mut().zip(tmp.iter()) {
                    *g += GRAIN_AMPLITUDE * v / amp;
                }
            }
            for (s, &v) in h.iter_mut().zip(tmp.iter()) {
                *s += v;
            }
        }
    }

    /// Calls `f(rock)` for every clod and pebble whose base outline may reach into the
    /// rectangle `[x0, y0, x1, y1]` (metres), with radius at least `r_min_m`, in a fixed
    /// order (class, then row, then column).
    pub fn visit_rocks(&self, rect: [f64; 4], r_min_m: f64, mut f: impl FnMut(&MicroRock)) {
        let [x0, y0, x1, y1] = rect;
        for cls in &self.classes {
            if cls.r_max < r_min_m {
                continue;
            }
            let reach = cls.r_max;
            for iy in cell_of(y0 - reach, cls.cell)..=cell_of(y1 + reach, cls.cell) {
                for ix in cell_of(x0 - reach, cls.cell)..=cell_of(x1 + reach, cls.cell) {
                    if let Some(r) = Self::rock_of(cls, ix, iy) {
                        if r.radius_m >= r_min_m
                            && r.x_m + r.radius_m > x0
                            && r.x_m - r.radius_m < x1
                            && r.y_m + r.radius_m > y0
                            && r.y_m - r.radius_m < y1
                        {
                            f(&r);
                        }
                    }
                }
            }
        }
    }

    /// Calls `f(pit)` for every pit that may change the height inside the rectangle
    /// `[x0, y0, x1, y1]` (metres), in a fixed order (class, row, column).
    pub fn visit_pits(&self, rect: [f64; 4], mut f: impl FnMut(&MicroPit)) {
        let [x0, y0, x1, y1] = rect;
        for cls in &self.pits {
            let reach = 2.0 * cls.r_max;
            for iy in cell_of(y0 - reach, cls.cell)..=cell_of(y1 + reach, cls.cell) {
                for ix in cell_of(x0 - reach, cls.cell)..=cell_of(x1 + reach, cls.cell) {
                    let mut rng = Rng::new(cell_hash(cls.key, ix, iy));
                    if rng.f64() >= cls.p {
                        continue;
                    }
                    let x = (ix as f64 + rng.f64()) * cls.cell;
                    let y = (iy as f64 + rng.f64()) * cls.cell;
                    // Uniform in log radius: about equal numbers per octave of size.
                    let r = cls.r_min * libm::pow(cls.r_max / cls.r_min, rng.f64());
                    // Fresh (deep) to degraded (shallow): depth/D 0.2 .. 0.05.
                    let u = rng.f64();
                    let depth = 2.0 * r * (0.2 - 0.15 * u);
                    let rim = 2.0 * r * (0.04 - 0.03 * u);
                    let pit = MicroPit {
                        x_m: x,
                        y_m: y,
                        radius_m: r,
                        depth_m: depth,
                        rim_m: rim,
                    };
                    let e = pit.reach_m();
                    if x + e > x0 && x - e < x1 && y + e > y0 && y - e < y1 {
                        f(&pit);
                    }
                }
            }
        }
    }

    /// The rock of cell `(ix, iy)` of a class, if it holds one.
    fn rock_of(cls: &RockClass, ix: i64, iy: i64) -> Option<MicroRock> {
        let mut rng = Rng::new(cell_hash(cls.key, ix, iy));
        if rng.f64() >= cls.p {
            return None;
        }
        let x = (ix as f64 + rng.f64()) * cls.cell;
        let y = (iy as f64 + rng.f64()) * cls.cell;
        // Truncated power law N(>r) ~ r^-b on [r_min, r_max], by its inverse CDF.
        let u = rng.f64();
        let (a, b) = (
            libm::pow(cls.r_min, -cls.exponent),
            libm::pow(cls.r_max, -cls.exponent),
        );
        let r = libm::pow(a - u * (a - b), -1.0 / cls.exponent);
        let facets = 5 + (rng.next_u64() % 4) as usize;
        let mut planes = [(0.0, 0.0); MAX_FACETS];
        let turn = core::f64::consts::TAU / facets as f64;
        let start = rng.f64() * core::f64::consts::TAU;
        for (j, p) in planes.iter_mut().take(facets).enumerate() {
            let ang = start + turn * (j as f64 + 0.35 * (rng.f64() - 0.5));
            // Plane distance 0.45..0.65 of `r`: with at most 97 deg between neighbouring
            // planes, every corner of the outline lies within 0.65 / cos(48.6 deg) < r.
            let d = r * (0.45 + 0.2 * rng.f64());
            *p = (libm::sin(ang) / d, libm::cos(ang) / d);
        }
        let h = r * (cls.h_lo + (cls.h_hi - cls.h_lo) * rng.f64());
        let k = 1.5 + 1.5 * rng.f64();
        let albedo_mul = cls.a_lo + (cls.a_hi - cls.a_lo) * rng.f64();
        Some(MicroRock {
            x_m: x,
            y_m: y,
            radius_m: r,
            height_m: h,
            k,
            albedo_mul,
            planes,
            facets,
        })
    }
}
