//! The terrain model's parameters ([`WorldConfig`]) and the errors of the world
//! ([`WorldError`]).

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
