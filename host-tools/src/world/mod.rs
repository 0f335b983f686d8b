//! The procedural lunar world: a pure function of `(seed, x, y)`.
//!
//! Nothing is stored: any region is sampled lazily, so an 8 x 8 km world costs no memory.
//! World frame: `x` east, `y` north, `z` up, metres (`docs/frames.md`). The model, its
//! parameters and its measured cost are described in `docs/world.md`.
//!
//! Height = fractal gradient noise (rolling relief) + impact craters (power-law sizes, bowl,
//! raised rim, ejecta, degradation states) + boulders (power-law sizes, denser around fresh
//! craters). Albedo = regolith noise + bright halos and rays of fresh craters + brighter
//! boulders. Placement uses only integer hashes and exact `f64` arithmetic (`+ - * / sqrt
//! floor`), plus the `libm` crate (deterministic Rust) for the few `pow`/`exp` evaluated when a
//! world is built, so a world is bit-identical on every machine.
//!
//! Files: `config` (the model's parameters and errors), `noise`, `craters`, `rocks` (the
//! layers), `footprint` (point and footprint-filtered evaluation of the features that reach
//! a point), `grid` (sampled rasters), `zones` (training / test zones), `dem` (a real DEM
//! site instead of the procedural terrain); this file holds [`World`] and its sampling.

mod config;
mod craters;
pub mod dem;
mod footprint;
mod grid;
mod hash;
mod noise;
mod rocks;
pub mod zones;

pub use config::{WorldConfig, WorldError};
pub use craters::{Crater, Degradation};
pub use grid::HeightGrid;
pub use rocks::Rock;

use craters::CraterField;
use footprint::{Acc, Feature, Filter, Item};
use grid::check_rect;
use noise::Fbm;
use rayon::prelude::*;
use rocks::RockField;

/// A procedural lunar terrain. Cheap to clone (a few small tables); `Send + Sync`.
#[derive(Clone, Debug)]
pub struct World {
    seed: u64,
    cfg: WorldConfig,
    relief: Fbm,
    albedo_regional: Fbm,
    albedo_fine: Fbm,
    craters: CraterField,
    rocks: RockField,
    /// A DEM + orthoimage drawn instead of the procedural terrain ([`World::from_geotiff`]).
    dem: Option<std::sync::Arc<dem::DemTerrain>>,
}

/// Noise layer numbers (distinct from the crater and rock layers).
const RELIEF_LAYER: u64 = 1;
const ALBEDO_REGIONAL_LAYER: u64 = 2;
const ALBEDO_FINE_LAYER: u64 = 3;

impl World {
    /// The world of `seed` with the default lunar configuration.
    pub fn new(seed: u64) -> Self {
        Self::build(seed, WorldConfig::default())
    }

    /// The world of `seed` with `cfg`. An invalid `cfg` (see [`WorldConfig::validate`]) is
    /// replaced by the default configuration, keeping only its `relief` flag; use
    /// [`World::try_with_config`] to get the error instead.
    pub fn with_config(seed: u64, cfg: WorldConfig) -> Self {
        match Self::try_with_config(seed, cfg.clone()) {
            Ok(w) => w,
            Err(_) => Self::build(
                seed,
                WorldConfig {
                    relief: cfg.relief,
                    ..WorldConfig::default()
                },
            ),
        }
    }

    /// The world of `seed` with `cfg`, or the reason `cfg` is invalid.
    pub fn try_with_config(seed: u64, cfg: WorldConfig) -> Result<Self, WorldError> {
        cfg.validate()?;
        Ok(Self::build(seed, cfg))
    }

    /// The default world of `seed` without relief: height 0 everywhere (no craters, rocks or
    /// noise in the height), but exactly the same albedo as [`World::new`]`(seed)`. For
    /// geometric checks of the reprojection (`--flat`).
    pub fn flat(seed: u64) -> Self {
        Self::build(
            seed,
            WorldConfig {
                relief: false,
                ..WorldConfig::default()
            },
        )
    }

    fn build(seed: u64, cfg: WorldConfig) -> Self {
        let relief = Fbm::new(
            seed,
            RELIEF_LAYER,
            cfg.noise_wavelength_m,
            cfg.noise_amplitude_m,
            cfg.noise_octaves,
            cfg.noise_hurst,
        );
        let half = 0.5 * cfg.albedo_regional_amplitude;
        let albedo_regional = Fbm::new(seed, ALBEDO_REGIONAL_LAYER, 250.0, half * 1.2, 2, 1.0);
        let albedo_fine = Fbm::new(
            seed,
            ALBEDO_FINE_LAYER,
            4.0,
            0.5 * cfg.albedo_fine_amplitude * 1.2,
            2,
            0.0,
        );
        let craters = CraterField::new(seed, &cfg);
        let rocks = RockField::new(seed, &cfg);
        Self {
            seed,
            cfg,
            relief,
            albedo_regional,
            albedo_fine,
            craters,
            rocks,
            dem: None,
        }
    }

    /// The seed this world was made from.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The configuration of this world.
    pub fn config(&self) -> &WorldConfig {
        &self.cfg
    }

    /// Terrain elevation at `(x, y)` metres, in metres. 0 for non-finite input.
    pub fn height_m(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y, true, false, &Filter::POINT).0
    }

    /// Normal albedo at `(x, y)` metres, in `0..=1`. `albedo_mean` for non-finite input.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y, false, true, &Filter::POINT).1
    }

    /// `(height_m, albedo)` at `(x, y)` metres: both for about the price of one.
    pub fn sample(&self, x: f64, y: f64) -> (f64, f64) {
        self.eval(x, y, true, true, &Filter::POINT)
    }

    /// Samples a north-up grid of `nx x ny` pixels of `m_per_px` metres whose north-west
    /// corner is `(origin_x_m, origin_y_m)`: pixel `(col, row)` is sampled at its centre
    /// `(origin_x_m + (col + 0.5) m_per_px, origin_y_m - (row + 0.5) m_per_px)`
    /// (`docs/frames.md`). Rows in parallel (rayon). Empty (`nx = ny = 0`) when `nx` or `ny`
    /// is 0 or the grid would exceed [`MAX_GRID_PIXELS`]; non-finite pixel centres get
    /// height 0 and `albedo_mean`. [`World::try_sample_grid`] reports such input as errors.
    pub fn sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> HeightGrid {
        self.grid_with(origin_x_m, origin_y_m, m_per_px, nx, ny, &Filter::POINT)
    }

    /// As [`World::sample_grid`], but each pixel's albedo is the mean over its square
    /// footprint of side `footprint_m` metres centred on the pixel centre (a box filter, as
    /// a sensor integrates its pixel, or a mesh node stands for its cell): a boulder or a
    /// ray narrower than the footprint adds its area-weighted brightness instead of all or
    /// nothing, so grids of different spacings agree in the mean and do not alias. Heights
    /// stay point samples, except that the boulders taken by their mean are left
    /// out of them (bumps between the nodes: a level of detail). `footprint_m <= 0` (or not
    /// finite) is [`World::sample_grid`].
    ///
    /// How (docs/world.md): a boulder adds `boost x covered fraction`, the overlap of the
    /// footprint with the boulder's disc (an equal-area square for boulders smaller than the
    /// footprint, a linear edge ramp of one footprint for larger ones); boulder size classes
    /// no wider than half the footprint (one footprint from 0.75 m on) add their expected value (density x mean area x mean
    /// boost, `rho^-3`-weighted around fresh craters) instead of being visited; fresh
    /// craters' albedo is averaged over up to 4 x 4 samples of the footprint
    /// ([`Crater::albedo_filtered`]).
    pub fn sample_grid_filtered(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
    ) -> HeightGrid {
        let filt = Filter::new(self, footprint_m);
        self.grid_with(origin_x_m, origin_y_m, m_per_px, nx, ny, &filt)
    }

    /// Albedo (normal albedo, 0..1) averaged over the `footprint_m`-wide square centred at
    /// `(x, y)` metres, as [`World::sample_grid_filtered`]; [`World::albedo`] for
    /// `footprint_m <= 0`.
    pub fn albedo_filtered(&self, x: f64, y: f64, footprint_m: f64) -> f64 {
        let filt = Filter::new(self, footprint_m);
        self.eval(x, y, false, true, &filt).1
    }

    fn grid_with(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        filt: &Filter,
    ) -> HeightGrid {
        let (nx, ny) = match nx.checked_mul(ny) {
            Some(n) if n <= MAX_GRID_PIXELS => (nx, ny),
            _ => (0, 0),
        };
        let n = nx * ny;
        let mut grid = HeightGrid {
            origin_x_m,
            origin_y_m,
            m_per_px,
            nx,
            ny,
            height_m: vec![0.0; n],
            albedo: vec![0.0; n],
        };
        if n == 0 {
            return grid;
        }
        if let Some(d) = &self.dem {
            d.fill_grid(&mut grid, filt.fp);
            return grid;
        }
        let xs: Vec<f64> = (0..nx)
            .map(|c| origin_x_m + (c as f64 + 0.5) * m_per_px)
            .collect();
        let rocks_per_pixel = m_per_px > FINE_GRID_M_PER_PX;
        let tile = if rocks_per_pixel {
            ((COARSE_TILE_MAX_M / m_per_px) as usize).clamp(2, TILE)
        } else {
            ((FINE_TILE_MAX_M / m_per_px) as usize).clamp(1, TILE)
        };
        grid.height_m
            .par_chunks_mut(nx * tile)
            .zip(grid.albedo.par_chunks_mut(nx * tile))
            .enumerate()
            .for_each(|(band, (hs, als))| {
                let rows = hs.len() / nx;
                let ys: Vec<f64> = (0..rows)
                    .map(|r| origin_y_m - ((band * tile + r) as f64 + 0.5) * m_per_px)
                    .collect();
                // The sums before features, row by row (vectorized noise).
                let mut bh = vec![0.0; rows * nx];
                let mut ba = vec![0.0; rows * nx];
                let mut tmp = vec![0.0; nx];
                for (r, &y) in ys.iter().enumerate() {
                    let span = r * nx..(r + 1) * nx;
                    self.base_row(&xs, y, filt, &mut bh[span.clone()], &mut ba[span], &mut tmp);
                }
                let mut items = Vec::new();
                for (t, xt) in xs.chunks(tile).enumerate() {
                    self.fill_tile(
                        xt,
                        &ys,
                        &mut items,
                        (&bh, &ba),
                        hs,
                        als,
                        nx,
                        t * tile,
                        rocks_per_pixel,
                        filt,
                    );
                }
            });
        grid
    }

    /// [`World::sample_grid`] with its input checked: finite origin, positive finite
    /// resolution, non-empty and at most [`MAX_GRID_PIXELS`] pixels.
    pub fn try_sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> Result<HeightGrid, WorldError> {
        if !(origin_x_m.is_finite() && origin_y_m.is_finite()) {
            return Err(WorldError::BadQuery(format!(
                "grid origin ({origin_x_m}, {origin_y_m}) is not finite"
            )));
        }
        if !(m_per_px.is_finite() && m_per_px > 0.0) {
            return Err(WorldError::BadQuery(format!(
                "grid resolution {m_per_px} m/px must be positive and finite"
            )));
        }
        match nx.checked_mul(ny) {
            Some(n) if n > 0 && n <= MAX_GRID_PIXELS => {}
            _ => {
                return Err(WorldError::BadQuery(format!(
                    "grid of {nx} x {ny} pixels: need 1 ..= 2^28 pixels"
                )))
            }
        }
        Ok(self.sample_grid(origin_x_m, origin_y_m, m_per_px, nx, ny))
    }

    /// Every crater whose centre lies in `[x0, x1) x [y0, y1)` (metres) with diameter at
    /// least `d_min_m`, for statistics and overlays. The rectangle may span at most 10^8
    /// cells of the smallest wanted class.
    pub fn craters_in(
        &self,
        x0: f64,
        y0: f64,
        x1: f64,
        y1: f64,
        d_min_m: f64,
    ) -> Result<Vec<Crater>, WorldError> {
        let cell = self.cfg.ejecta_extent_radii * d_min_m.max(self.cfg.crater_d_min_m);
        check_rect(x0, y0, x1, y1, cell)?;
        if self.dem.is_some() {
            return Ok(Vec::new());
        }
        Ok(self.craters.in_rect(x0, y0, x1, y1, d_min_m))
    }

    /// Every background boulder (not those of fresh craters) whose centre lies in
    /// `[x0, x1) x [y0, y1)` metres. The rectangle may span at most 10^8 cells of the
    /// smallest class.
    pub fn rocks_in(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Result<Vec<Rock>, WorldError> {
        check_rect(x0, y0, x1, y1, 2.0 * self.cfg.rock_d_min_m)?;
        if self.dem.is_some() {
            return Ok(Vec::new());
        }
        Ok(self.rocks.in_rect(x0, y0, x1, y1))
    }

    /// The distance (metres) beyond which no crater reaches: the largest crater's ejecta.
    pub fn max_feature_reach_m(&self) -> f64 {
        self.craters.max_reach()
    }

    /// Calls `f` for every crater and boulder that reaches into `rect` (`[x0, y0, x1, y1]`
    /// metres), in the one fixed order in which their contributions are summed.
    /// With a footprint filter, `rect` must already be grown by half the footprint, and
    /// boulder classes below `filt.first_rock_class` are skipped (they enter by their mean).
    #[inline]
    fn features(
        &self,
        rect: [f64; 4],
        fresh_only: bool,
        filt: &Filter,
        mut f: impl FnMut(Feature<'_>),
    ) {
        let rocks = &self.rocks;
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        rocks.visit_rect_from(rect, k0, grow, |r| f(Feature::Rock(r)));
        self.craters.visit_rect(rect, fresh_only, |c| {
            f(Feature::Crater(c));
            if rocks.crater_has_rocks(c) {
                rocks.visit_crater_rect_from(c, rect, k0, grow, |r| f(Feature::Rock(r)));
            }
        });
    }

    /// The sum before features: noise relief and regolith albedo.
    #[inline]
    fn base<'f>(&self, x: f64, y: f64, relief: bool, want_a: bool, filt: &'f Filter) -> Acc<'f> {
        let mut a = 0.0;
        if want_a {
            a = self.cfg.albedo_mean + self.albedo_regional.at(x, y) + self.albedo_fine.at(x, y);
            if filt.rock_mean > 0.0 {
                a += filt.rock_mean;
            }
        }
        Acc {
            h: if relief { self.relief.at(x, y) } else { 0.0 },
            a,
            relief,
            want_a,
            boost: self.cfg.fresh_crater_albedo_boost,
            filt,
        }
    }

    /// [`World::base`] (relief per the configuration, albedo wanted) at `(xs[i], y)`, bit for
    /// bit: heights into `h`, albedo into `a` (`tmp`: scratch as long as `xs`).
    fn base_row(
        &self,
        xs: &[f64],
        y: f64,
        filt: &Filter,
        h: &mut [f64],
        a: &mut [f64],
        tmp: &mut [f64],
    ) {
        if self.cfg.relief {
            self.relief.row(xs, y, h);
        } else {
            h.fill(0.0);
        }
        self.albedo_regional.row(xs, y, a);
        self.albedo_fine.row(xs, y, tmp);
        let mean = self.cfg.albedo_mean;
        for (a, &f) in a.iter_mut().zip(tmp.iter()) {
            *a = mean + *a + f;
        }
        if filt.rock_mean > 0.0 {
            for a in a.iter_mut() {
                *a += filt.rock_mean;
            }
        }
    }

    /// An accumulator starting from precomputed base sums (see [`World::base_row`]).
    #[inline]
    fn acc_from<'f>(&self, h: f64, a: f64, filt: &'f Filter) -> Acc<'f> {
        Acc {
            h,
            a,
            relief: self.cfg.relief,
            want_a: true,
            boost: self.cfg.fresh_crater_albedo_boost,
            filt,
        }
    }

    #[inline]
    fn eval(&self, x: f64, y: f64, want_h: bool, want_a: bool, filt: &Filter) -> (f64, f64) {
        if let Some(d) = &self.dem {
            return d.sample(x, y, filt.fp);
        }
        if !(x.is_finite() && y.is_finite()) {
            return (0.0, self.cfg.albedo_mean);
        }
        let relief = want_h && self.cfg.relief;
        if !relief && !want_a {
            return (0.0, 0.0);
        }
        let mut acc = self.base(x, y, relief, want_a, filt);
        self.features(filt.grown([x, y, x, y]), !relief, filt, |f| {
            acc.add(f, x, y);
        });
        acc.finish()
    }

    /// Fills one tile of a grid (pixel centres `xs` x `ys`, written at column `col0` of rows
    /// of `stride` pixels): gathers the craters (and, unless `rocks_per_pixel`, the boulders)
    /// reaching the tile once, then sums them per pixel in the same order as
    /// [`World::eval`], so the results are identical. With `rocks_per_pixel` (coarse grids,
    /// where a tile would touch many boulder cells for few pixels) each pixel looks its
    /// boulders up itself.
    #[allow(clippy::too_many_arguments)]
    fn fill_tile(
        &self,
        xs: &[f64],
        ys: &[f64],
        items: &mut Vec<Item>,
        (base_h, base_a): (&[f64], &[f64]),
        hs: &mut [f32],
        als: &mut [f32],
        stride: usize,
        col0: usize,
        rocks_per_pixel: bool,
        filt: &Filter,
    ) {
        let relief = self.cfg.relief;
        let (Some(&xa), Some(&xb), Some(&ya), Some(&yb)) =
            (xs.first(), xs.last(), ys.first(), ys.last())
        else {
            return;
        };
        let finite = xa.is_finite() && xb.is_finite() && ya.is_finite() && yb.is_finite();
        let single = xs.len() == 1 && ys.len() == 1;
        let gather = finite && !single;
        if gather {
            let rect = filt.grown([xa.min(xb), ya.min(yb), xa.max(xb), ya.max(yb)]);
            items.clear();
            if rocks_per_pixel {
                self.craters
                    .visit_rect(rect, !relief, |c| items.push(Item::Crater(*c)));
            } else {
                self.features(rect, !relief, filt, |f| {
                    items.push(match f {
                        Feature::Crater(c) => Item::Crater(*c),
                        Feature::Rock(r) => Item::Rock(*r),
                    })
                });
            }
        }
        for (r, &y) in ys.iter().enumerate() {
            for (c, &x) in xs.iter().enumerate() {
                let k = r * stride + col0 + c;
                let (h, a) = if !gather {
                    self.eval(x, y, true, true, filt)
                } else if rocks_per_pixel {
                    let mut acc = self.acc_from(base_h[k], base_a[k], filt);
                    let point = filt.grown([x, y, x, y]);
                    let (k0, grow) = (filt.first_rock_class, filt.grow);
                    let rocks = &self.rocks;
                    rocks.visit_rect_from(point, k0, grow, |rk| {
                        acc.add(Feature::Rock(rk), x, y);
                    });
                    for it in items.iter() {
                        if let Item::Crater(cr) = it {
                            if acc.add(Feature::Crater(cr), x, y) && rocks.crater_has_rocks(cr) {
                                rocks.visit_crater_rect_from(cr, point, k0, grow, |rk| {
                                    acc.add(Feature::Rock(rk), x, y);
                                });
                            }
                        }
                    }
                    acc.finish()
                } else {
                    let mut acc = self.acc_from(base_h[k], base_a[k], filt);
                    for it in items.iter() {
                        acc.add(it.as_feature(), x, y);
                    }
                    acc.finish()
                };
                hs[k] = h as f32;
                als[k] = a as f32;
            }
        }
    }
}

/// Largest grid `sample_grid` samples: 2^28 pixels (2 GiB of `f32` height and albedo).
pub const MAX_GRID_PIXELS: usize = 1 << 28;

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
