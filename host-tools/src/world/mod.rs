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

mod craters;
pub mod dem;
mod hash;
mod noise;
mod rocks;
pub mod zones;

pub use craters::{Crater, Degradation};
pub use rocks::Rock;

use craters::CraterField;
use noise::Fbm;
use rayon::prelude::*;
use rocks::RockField;
use serde::{Deserialize, Serialize};

/// Parameters of the terrain model. `Default` is the lunar mare-like world of the project.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WorldConfig {
    /// Whether the terrain has relief. `false`: height is 0 everywhere (albedo unchanged).
    pub relief: bool,

    /// Wavelength of the largest relief noise octave, metres.
    pub noise_wavelength_m: f64,
    /// Amplitude of the largest relief noise octave, metres.
    pub noise_amplitude_m: f64,
    /// Number of relief octaves (each halves the wavelength), at most 16.
    pub noise_octaves: u32,
    /// Amplitude falls as `wavelength^hurst` (0.5 rough .. 1.2 smooth).
    pub noise_hurst: f64,

    /// Crater density: cumulative number of craters wider than 1 m, per square metre; the
    /// size-frequency distribution is `N(>D) = crater_density_per_m2 * D^-crater_exponent`
    /// (`D` in metres).
    pub crater_density_per_m2: f64,
    /// Exponent `b` of the cumulative size-frequency distribution `N(>D) ~ D^-b`.
    pub crater_exponent: f64,
    /// Smallest crater diameter, metres.
    pub crater_d_min_m: f64,
    /// Largest crater diameter, metres.
    pub crater_d_max_m: f64,
    /// Fraction of craters that are fresh (sharp, bright, blocky).
    pub crater_fresh_fraction: f64,
    /// Fraction of craters that are old (shallow, rounded); the rest are mature.
    pub crater_old_fraction: f64,
    /// Depth / diameter of a pristine crater.
    pub crater_depth_ratio_fresh: f64,
    /// Depth / diameter of the most degraded crater.
    pub crater_depth_ratio_old: f64,
    /// Rim height / diameter of a pristine crater.
    pub crater_rim_ratio_fresh: f64,
    /// Rim height / diameter of the most degraded crater.
    pub crater_rim_ratio_old: f64,
    /// Outer edge of the ejecta blanket (and of the bright halo and rays), in crater radii.
    pub ejecta_extent_radii: f64,

    /// Background boulder density: cumulative number of boulders wider than 1 m per square
    /// metre (`N(>D) = rock_density_per_m2 * D^-rock_exponent`).
    pub rock_density_per_m2: f64,
    /// Exponent of the boulders' cumulative size distribution.
    pub rock_exponent: f64,
    /// Smallest boulder diameter, metres.
    pub rock_d_min_m: f64,
    /// Largest boulder diameter, metres.
    pub rock_d_max_m: f64,
    /// Boulder density on and around fresh craters, as a multiple of the background (added
    /// to it), inside the rim; it falls as `rho^-3` outside.
    pub fresh_crater_rock_factor: f64,
    /// Smallest fresh crater that carries its own boulders, metres.
    pub fresh_crater_rock_d_min_m: f64,

    /// Mean normal albedo of the regolith.
    pub albedo_mean: f64,
    /// Amplitude of the regional (250 m and 60 m wavelength) albedo variation.
    pub albedo_regional_amplitude: f64,
    /// Amplitude of the fine (4 m and 1 m wavelength) albedo grain.
    pub albedo_fine_amplitude: f64,
    /// Albedo added by a fresh crater's halo and rays (at full freshness).
    pub fresh_crater_albedo_boost: f64,
    /// Mean albedo added on a boulder.
    pub rock_albedo_boost: f64,
}

impl Default for WorldConfig {
    fn default() -> Self {
        Self {
            relief: true,
            noise_wavelength_m: 800.0,
            noise_amplitude_m: 3.0,
            noise_octaves: 8,
            noise_hurst: 0.9,
            crater_density_per_m2: 0.08,
            crater_exponent: 2.0,
            crater_d_min_m: 1.0,
            crater_d_max_m: 300.0,
            crater_fresh_fraction: 0.15,
            crater_old_fraction: 0.45,
            crater_depth_ratio_fresh: 0.2,
            crater_depth_ratio_old: 0.04,
            crater_rim_ratio_fresh: 0.04,
            crater_rim_ratio_old: 0.004,
            ejecta_extent_radii: 2.5,
            rock_density_per_m2: 0.005,
            rock_exponent: 2.3,
            rock_d_min_m: 0.2,
            rock_d_max_m: 3.0,
            fresh_crater_rock_factor: 10.0,
            fresh_crater_rock_d_min_m: 6.0,
            albedo_mean: 0.12,
            albedo_regional_amplitude: 0.02,
            albedo_fine_amplitude: 0.008,
            fresh_crater_albedo_boost: 0.08,
            rock_albedo_boost: 0.04,
        }
    }
}

/// A configuration or query the world cannot honour.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WorldError {
    /// A configuration field is out of its range.
    #[error("world config: {field} = {value} is out of range: {expected}")]
    BadConfig {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// A query region or grid is not usable.
    #[error("world query: {0}")]
    BadQuery(String),
}

/// Largest expected count per cell a layer may have (keeps the Poisson tables short).
const MAX_PER_CELL: f64 = 100.0;

impl WorldConfig {
    /// Checks every field; the error names the first bad one and its allowed range.
    pub fn validate(&self) -> Result<(), WorldError> {
        let check = |field: &'static str, value: f64, lo: f64, hi: f64, expected: &'static str| {
            if value.is_finite() && value >= lo && value <= hi {
                Ok(())
            } else {
                Err(WorldError::BadConfig {
                    field,
                    value,
                    expected,
                })
            }
        };
        check(
            "noise_wavelength_m",
            self.noise_wavelength_m,
            1e-3,
            1e6,
            "1e-3 ..= 1e6 m",
        )?;
        check(
            "noise_amplitude_m",
            self.noise_amplitude_m,
            0.0,
            1e4,
            "0 ..= 1e4 m",
        )?;
        check(
            "noise_octaves",
            f64::from(self.noise_octaves),
            0.0,
            16.0,
            "0 ..= 16",
        )?;
        check("noise_hurst", self.noise_hurst, 0.0, 2.0, "0 ..= 2")?;
        check(
            "crater_density_per_m2",
            self.crater_density_per_m2,
            0.0,
            10.0,
            "0 ..= 10 per m^2",
        )?;
        check(
            "crater_exponent",
            self.crater_exponent,
            0.5,
            5.0,
            "0.5 ..= 5",
        )?;
        check(
            "crater_d_min_m",
            self.crater_d_min_m,
            0.05,
            1e4,
            "0.05 ..= 1e4 m",
        )?;
        check(
            "crater_d_max_m",
            self.crater_d_max_m,
            self.crater_d_min_m,
            1e4,
            ">= crater_d_min_m and <= 1e4 m",
        )?;
        check(
            "crater_fresh_fraction",
            self.crater_fresh_fraction,
            0.0,
            1.0,
            "0 ..= 1",
        )?;
        check(
            "crater_old_fraction",
            self.crater_old_fraction,
            0.0,
            1.0 - self.crater_fresh_fraction,
            "0 ..= 1 - crater_fresh_fraction",
        )?;
        for (f, v) in [
            ("crater_depth_ratio_fresh", self.crater_depth_ratio_fresh),
            ("crater_depth_ratio_old", self.crater_depth_ratio_old),
            ("crater_rim_ratio_fresh", self.crater_rim_ratio_fresh),
            ("crater_rim_ratio_old", self.crater_rim_ratio_old),
        ] {
            check(f, v, 0.0, 1.0, "0 ..= 1")?;
        }
        check(
            "ejecta_extent_radii",
            self.ejecta_extent_radii,
            1.2,
            8.0,
            "1.2 ..= 8 radii",
        )?;
        check(
            "rock_density_per_m2",
            self.rock_density_per_m2,
            0.0,
            10.0,
            "0 ..= 10 per m^2",
        )?;
        check("rock_exponent", self.rock_exponent, 0.5, 5.0, "0.5 ..= 5")?;
        check(
            "rock_d_min_m",
            self.rock_d_min_m,
            0.01,
            100.0,
            "0.01 ..= 100 m",
        )?;
        check(
            "rock_d_max_m",
            self.rock_d_max_m,
            self.rock_d_min_m,
            100.0,
            ">= rock_d_min_m and <= 100 m",
        )?;
        check(
            "fresh_crater_rock_factor",
            self.fresh_crater_rock_factor,
            0.0,
            1e3,
            "0 ..= 1000",
        )?;
        check(
            "fresh_crater_rock_d_min_m",
            self.fresh_crater_rock_d_min_m,
            0.0,
            1e5,
            "0 ..= 1e5 m",
        )?;
        check("albedo_mean", self.albedo_mean, 0.0, 1.0, "0 ..= 1")?;
        for (f, v) in [
            ("albedo_regional_amplitude", self.albedo_regional_amplitude),
            ("albedo_fine_amplitude", self.albedo_fine_amplitude),
            ("fresh_crater_albedo_boost", self.fresh_crater_albedo_boost),
            ("rock_albedo_boost", self.rock_albedo_boost),
        ] {
            check(f, v, 0.0, 1.0, "0 ..= 1")?;
        }
        // Expected counts per cell: the smallest class is the densest for exponents > 2.
        let per_cell = |k: f64, b: f64, da: f64, db: f64, cell: f64| {
            k * (libm::pow(da, -b) - libm::pow(da * 2.0, -b)).abs() * cell * cell / (db / da)
        };
        let d = self.crater_d_min_m;
        let lam = per_cell(
            self.crater_density_per_m2,
            self.crater_exponent,
            d,
            d,
            self.ejecta_extent_radii * 2.0 * d,
        );
        check(
            "crater_density_per_m2 (count per cell)",
            lam,
            0.0,
            MAX_PER_CELL,
            "at most 100 craters per cell: lower the density or raise crater_d_min_m",
        )?;
        let r = self.rock_d_min_m;
        let lam = per_cell(
            self.rock_density_per_m2 * (1.0 + self.fresh_crater_rock_factor),
            self.rock_exponent,
            r,
            r,
            2.0 * r,
        );
        check("rock_density_per_m2 (count per cell)", lam, 0.0, MAX_PER_CELL, "at most 100 rocks per cell: lower the density or the fresh factor, or raise rock_d_min_m")?;
        Ok(())
    }
}

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
                let mut items = Vec::new();
                for (t, xt) in xs.chunks(tile).enumerate() {
                    self.fill_tile(
                        xt,
                        &ys,
                        &mut items,
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
                let (h, a) = if !gather {
                    self.eval(x, y, true, true, filt)
                } else if rocks_per_pixel {
                    let mut acc = self.base(x, y, relief, true, filt);
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
                    let mut acc = self.base(x, y, relief, true, filt);
                    for it in items.iter() {
                        acc.add(it.as_feature(), x, y);
                    }
                    acc.finish()
                };
                let k = r * stride + col0 + c;
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

/// A feature reaching a query, borrowed.
#[derive(Clone, Copy)]
enum Feature<'a> {
    Crater(&'a Crater),
    Rock(&'a Rock),
}

/// A feature reaching a tile, owned.
#[derive(Clone, Copy)]
enum Item {
    Crater(Crater),
    Rock(Rock),
}

impl Item {
    #[inline]
    fn as_feature(&self) -> Feature<'_> {
        match self {
            Item::Crater(c) => Feature::Crater(c),
            Item::Rock(r) => Feature::Rock(r),
        }
    }
}

/// How samples integrate albedo over their footprint ([`World::sample_grid_filtered`]).
#[derive(Clone, Copy, Debug)]
struct Filter {
    /// Side of the square footprint, metres (0: point samples).
    fp: f64,
    /// Half of `fp`, metres.
    hf: f64,
    /// Boulder classes before this one enter by their expected albedo (not visited).
    first_rock_class: usize,
    /// Expected albedo of those classes' background boulders (per unit area).
    rock_mean: f64,
    /// Expected albedo of those classes' fresh-crater boulders inside the rim.
    fresh_rock_mean: f64,
    /// Smallest fresh crater with boulders, metres (infinite when there are none).
    fresh_rock_d_min: f64,
    /// Largest boulder radius, metres.
    max_rock_radius: f64,
    /// Reach factor of boulders in visits (equal-area squares reach further than discs).
    grow: f64,
}

/// Boulder size classes no wider than this many footprints enter footprint-filtered grids by
/// their expected albedo instead of one by one (fine grids; coarse ones: one footprint).
const MEAN_FIELD_ROCK_FOOTPRINTS: f64 = 0.5;

/// From this footprint on (metres; the renderer's mesh rings from 0.8 m, i.e. beyond about
/// 43 m and any 50 m top-down image), classes no wider than one footprint enter by their mean.
const MEAN_FIELD_COARSE_M: f64 = 0.75;

impl Filter {
    /// Point samples: exactly the unfiltered world.
    const POINT: Filter = Filter {
        fp: 0.0,
        hf: 0.0,
        first_rock_class: 0,
        rock_mean: 0.0,
        fresh_rock_mean: 0.0,
        fresh_rock_d_min: f64::INFINITY,
        max_rock_radius: 0.0,
        grow: 1.0,
    };

    fn new(world: &World, footprint_m: f64) -> Self {
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
    fn grown(&self, rect: [f64; 4]) -> [f64; 4] {
        if self.hf > 0.0 {
            let h = self.hf;
            [rect[0] - h, rect[1] - h, rect[2] + h, rect[3] + h]
        } else {
            rect
        }
    }
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
struct Acc<'f> {
    h: f64,
    a: f64,
    relief: bool,
    want_a: bool,
    boost: f64,
    filt: &'f Filter,
}

impl Acc<'_> {
    /// Adds the contribution of `f` at `(x, y)` metres (nothing if `f` does not cover it);
    /// whether `f` covers the point (with a footprint: reaches into the footprint).
    #[inline]
    fn add(&mut self, f: Feature<'_>, x: f64, y: f64) -> bool {
        if self.filt.fp > 0.0 {
            return self.add_filtered(f, x, y);
        }
        match f {
            Feature::Crater(c) => {
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
            Feature::Crater(c) => {
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
                    self.a += c.albedo_filtered(dx, dy, self.boost, filt.fp);
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
    fn finish(&self) -> (f64, f64) {
        (self.h, self.a.clamp(0.0, 1.0))
    }
}

fn check_rect(x0: f64, y0: f64, x1: f64, y1: f64, cell: f64) -> Result<(), WorldError> {
    if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) || x1 < x0 || y1 < y0
    {
        return Err(WorldError::BadQuery(format!(
            "rectangle [{x0}, {x1}) x [{y0}, {y1}) must be finite with x0 <= x1 and y0 <= y1"
        )));
    }
    let cells = ((x1 - x0) / cell + 2.0) * ((y1 - y0) / cell + 2.0);
    if cells > 1e8 {
        return Err(WorldError::BadQuery(format!(
            "rectangle [{x0}, {x1}) x [{y0}, {y1}) spans {cells:.0} cells of {cell} m: query smaller tiles"
        )));
    }
    Ok(())
}

/// A sampled north-up raster of height and albedo. Row-major, row 0 north, column 0 west;
/// georeference as `docs/frames.md` (north-west corner + metres per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct HeightGrid {
    /// World `x` of the west edge, metres.
    pub origin_x_m: f64,
    /// World `y` of the north edge, metres.
    pub origin_y_m: f64,
    /// Pixel size, metres per pixel.
    pub m_per_px: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// Elevation per pixel, metres, `ny * nx` row-major.
    pub height_m: Vec<f32>,
    /// Normal albedo per pixel, 0..1, `ny * nx` row-major.
    pub albedo: Vec<f32>,
}

impl HeightGrid {
    /// Index of pixel `(col, row)` in the row-major vectors, if inside.
    pub fn index(&self, col: usize, row: usize) -> Option<usize> {
        (col < self.nx && row < self.ny).then(|| row * self.nx + col)
    }

    /// World `(x, y)` metres of the centre of pixel `(col, row)`.
    pub fn pixel_centre(&self, col: usize, row: usize) -> (f64, f64) {
        (
            self.origin_x_m + (col as f64 + 0.5) * self.m_per_px,
            self.origin_y_m - (row as f64 + 0.5) * self.m_per_px,
        )
    }
}
