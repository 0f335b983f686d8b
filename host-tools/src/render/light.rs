//! The light of a render: the sun as seen from the terrain ([`Sun`]) and the photometric
//! function of the surface ([`Photometry`]).

use super::RenderError;
use serde::{Deserialize, Serialize};

/// The sun as seen from the terrain.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sun {
    /// Degrees above the horizon, in [0, 90].
    pub elevation_deg: f64,
    /// Degrees clockwise from north towards the sun, in [0, 360).
    pub azimuth_deg: f64,
}

impl Default for Sun {
    /// The study's sun: 30 deg elevation; from the south-east (135 deg).
    fn default() -> Self {
        Self {
            elevation_deg: 30.0,
            azimuth_deg: 135.0,
        }
    }
}

impl Sun {
    /// A checked sun: elevation in [0, 90] deg, azimuth in [0, 360) deg, both finite.
    pub fn new(elevation_deg: f64, azimuth_deg: f64) -> Result<Self, RenderError> {
        let s = Self {
            elevation_deg,
            azimuth_deg,
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(self.elevation_deg.is_finite() && (0.0..=90.0).contains(&self.elevation_deg)) {
            return Err(RenderError::Sun(format!(
                "elevation {} deg is not in [0, 90]",
                self.elevation_deg
            )));
        }
        if !(self.azimuth_deg.is_finite() && (0.0..360.0).contains(&self.azimuth_deg)) {
            return Err(RenderError::Sun(format!(
                "azimuth {} deg is not in [0, 360)",
                self.azimuth_deg
            )));
        }
        Ok(())
    }

    /// Unit vector towards the sun, world frame (x east, y north, z up).
    pub fn direction(&self) -> [f64; 3] {
        let e = self.elevation_deg.to_radians();
        let a = self.azimuth_deg.to_radians();
        [e.cos() * a.sin(), e.cos() * a.cos(), e.sin()]
    }
}

/// Photometric function: reflected light per unit albedo as a function of incidence `i`
/// (sun) and emission `e` (viewer) angles to the surface normal.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum Photometry {
    /// `cos i`.
    Lambert,
    /// Lommel-Seeliger, normalized to 1 at `i = e = 0`: `2 cos i / (cos i + cos e)`.
    LommelSeeliger,
    /// Lunar-Lambert (McEwen): `(1 - w) cos i + w * 2 cos i / (cos i + cos e)`.
    LunarLambert {
        /// Weight `w` of the Lommel-Seeliger term, in [0, 1].
        weight: f64,
    },
}

impl Photometry {
    /// Value for `cos i`, `cos e` (unitless; 0 where the sun is below the local horizon).
    pub fn eval(&self, cos_i: f64, cos_e: f64) -> f64 {
        if cos_i <= 0.0 {
            return 0.0;
        }
        let ls = |ci: f64, ce: f64| 2.0 * ci / (ci + ce.max(0.0)).max(1e-9);
        match *self {
            Photometry::Lambert => cos_i,
            Photometry::LommelSeeliger => ls(cos_i, cos_e),
            Photometry::LunarLambert { weight } => {
                (1.0 - weight) * cos_i + weight * ls(cos_i, cos_e)
            }
        }
    }
}
