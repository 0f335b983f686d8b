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
//! site instead of the procedural terrain). [`World`]'s sampling, one concern a file:
//! `point` (height and albedo at a point), `base` (the sums before features: noise relief
//! and regolith albedo), `features` (the craters and boulders of a rectangle),
//! `grid_sampling` (grids and windows of grids), `tiles` (a window filled tile by tile) and
//! `coarse` (coarse grids: a window's craters gathered once). This file holds [`World`] and
//! its construction.

mod base;
mod coarse;
mod config;
mod craters;
pub mod dem;
mod features;
mod footprint;
mod grid;
mod grid_sampling;
mod hash;
pub mod micro;
mod noise;
mod point;
mod rocks;
mod tiles;
pub mod zones;

pub use config::{WorldConfig, WorldError};
pub use craters::{Crater, Degradation};
pub use grid::HeightGrid;
pub use grid_sampling::MAX_GRID_PIXELS;
pub use rocks::Rock;

use craters::CraterField;
use noise::Fbm;
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
    /// Centimetre-scale roughness, clods and pebbles ([`World::micro`]).
    micro: std::sync::Arc<micro::MicroRelief>,
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
            micro: std::sync::Arc::new(micro::MicroRelief::new(seed)),
        }
    }

    /// The micro-relief of the regolith (roughness, clods, pebbles), drawn by the renderer
    /// as the near-field texture of the ground views; `None` for a world without relief
    /// ([`World::flat`]) and for a DEM site, whose surface is the DEM's own.
    pub fn micro(&self) -> Option<&micro::MicroRelief> {
        if self.cfg.relief && self.dem.is_none() {
            Some(&self.micro)
        } else {
            None
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
}
