//! Everything that controls a render besides the world, the pose and the sun
//! ([`RenderOptions`]: camera rig, photometry, exposure and gray mapping, sensor noise, mesh
//! and shadow reach, near-field detail), its checks, the radiance and gray levels it gives,
//! and the serializable mirror of the camera parameters ([`CameraParamsDef`]).

use super::{Photometry, RenderError};
use image::GrayImage;
use orbfix::camera::CameraParams;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Everything that controls a render besides the world, the pose and the sun.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderOptions {
    /// The rover's camera rig (size, HFOV, height, tilt).
    pub camera: CameraParamsDef,
    /// Photometric function.
    pub photometry: Photometry,
    /// Fixed exposure: radiance scale before the gray mapping (same for ground and orbit).
    pub exposure: f64,
    /// Display gamma of the gray mapping.
    pub gamma: f64,
    /// Light in shadow relative to a sun-facing surface (earthshine, scattering), unitless.
    pub ambient: f64,
    /// Standard deviation of additive Gaussian sensor noise, gray levels (0 = none).
    pub noise_sigma: f64,
    /// Seed of the noise generator (deterministic).
    pub noise_seed: u64,
    /// Mesh cell size of the innermost ring, metres.
    pub near_cell_m: f64,
    /// Target projected size of a mesh cell, pixels (sets where rings coarsen).
    pub lod_px_per_cell: f64,
    /// Farthest terrain drawn, metres (beyond it: black sky).
    pub max_range_m: f64,
    /// Farthest distance a cast shadow is traced towards the sun, metres.
    pub shadow_reach_m: f64,
    /// Orthographic renders: samples per pixel side (1..=4), averaged (box filter). 1 (the
    /// default) samples pixel centres; 2 is closer to a real sensor and costs 4x.
    pub ortho_supersample: u32,
    /// Half side of the square around the rover where the ground views show the world's
    /// micro-relief ([`detail`]), metres; 0 = none (the mesh's smooth shading only).
    ///
    /// [`detail`]: super::detail
    #[serde(default = "default_detail_range_m")]
    pub detail_range_m: f64,
    /// Texel side of the micro-relief texture, metres; 0 = from the focal length
    /// ([`detail::cell_for_focal`]: the pixel footprint at 8 m, 1..4 cm).
    ///
    /// [`detail::cell_for_focal`]: super::detail::cell_for_focal
    #[serde(default)]
    pub detail_cell_m: f64,
}

fn default_detail_range_m() -> f64 {
    10.0
}

/// Serializable mirror of [`CameraParams`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraParamsDef {
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f32,
    /// Optical centre above the ground, metres.
    pub height_m: f32,
    /// Downward tilt, degrees.
    pub tilt_deg: f32,
}

impl From<CameraParams> for CameraParamsDef {
    fn from(c: CameraParams) -> Self {
        Self {
            width_px: c.width_px,
            height_px: c.height_px,
            hfov_deg: c.hfov_deg,
            height_m: c.height_m,
            tilt_deg: c.tilt_deg,
        }
    }
}

impl From<CameraParamsDef> for CameraParams {
    fn from(c: CameraParamsDef) -> Self {
        Self {
            width_px: c.width_px,
            height_px: c.height_px,
            hfov_deg: c.hfov_deg,
            height_m: c.height_m,
            tilt_deg: c.tilt_deg,
        }
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            camera: CameraParams::default().into(),
            photometry: Photometry::LunarLambert { weight: 0.5 },
            exposure: 3.5,
            gamma: 2.2,
            ambient: 0.02,
            noise_sigma: 0.0,
            noise_seed: 0,
            near_cell_m: 0.1,
            lod_px_per_cell: 3.0,
            max_range_m: 1000.0,
            shadow_reach_m: 300.0,
            ortho_supersample: 1,
            detail_range_m: default_detail_range_m(),
            detail_cell_m: 0.0,
        }
    }
}

impl RenderOptions {
    /// The camera parameters as the core's type.
    pub fn camera_params(&self) -> CameraParams {
        self.camera.into()
    }

    /// Checks every option; the error names the bad one.
    pub fn validate(&self) -> Result<(), RenderError> {
        self.camera_params().validate()?;
        if self.camera.width_px > 8192 || self.camera.height_px > 8192 {
            return Err(RenderError::Option(format!(
                "image size {}x{} is larger than 8192 px",
                self.camera.width_px, self.camera.height_px
            )));
        }
        let pos = |v: f64, name: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(RenderError::Option(format!(
                    "{name} = {v} must be finite and > 0"
                )))
            }
        };
        pos(self.exposure, "exposure")?;
        pos(self.gamma, "gamma")?;
        pos(self.near_cell_m, "near_cell_m")?;
        pos(self.lod_px_per_cell, "lod_px_per_cell")?;
        pos(self.max_range_m, "max_range_m")?;
        pos(self.shadow_reach_m, "shadow_reach_m")?;
        if !(self.detail_range_m.is_finite() && (0.0..=100.0).contains(&self.detail_range_m)) {
            return Err(RenderError::Option(format!(
                "detail_range_m = {} not in [0, 100]",
                self.detail_range_m
            )));
        }
        if !(self.detail_cell_m == 0.0
            || (self.detail_cell_m.is_finite() && (0.002..=0.5).contains(&self.detail_cell_m)))
        {
            return Err(RenderError::Option(format!(
                "detail_cell_m = {} must be 0 (automatic) or in [0.002, 0.5]",
                self.detail_cell_m
            )));
        }
        if self.detail_cell_m > 0.0 && self.detail_range_m / self.detail_cell_m > 8192.0 {
            return Err(RenderError::Option(format!(
                "detail_range_m / detail_cell_m = {} is over 8192 texels",
                self.detail_range_m / self.detail_cell_m
            )));
        }
        if !(1..=4).contains(&self.ortho_supersample) {
            return Err(RenderError::Option(format!(
                "ortho_supersample = {} not in 1..=4",
                self.ortho_supersample
            )));
        }
        if !(self.ambient.is_finite() && (0.0..=1.0).contains(&self.ambient)) {
            return Err(RenderError::Option(format!(
                "ambient = {} not in [0, 1]",
                self.ambient
            )));
        }
        if !(self.noise_sigma.is_finite() && self.noise_sigma >= 0.0) {
            return Err(RenderError::Option(format!(
                "noise_sigma = {} must be finite and >= 0",
                self.noise_sigma
            )));
        }
        if let Photometry::LunarLambert { weight } = self.photometry {
            if !(weight.is_finite() && (0.0..=1.0).contains(&weight)) {
                return Err(RenderError::Option(format!(
                    "lunar-Lambert weight {weight} not in [0, 1]"
                )));
            }
        }
        if self.max_range_m / self.near_cell_m > 1e6 {
            return Err(RenderError::Option(
                "max_range_m / near_cell_m is over 1e6".into(),
            ));
        }
        Ok(())
    }

    /// Linear radiance (before the gray mapping) of a surface point.
    ///
    /// `n`: unit normal; `sun`: unit vector to the sun; `view`: unit vector to the viewer;
    /// `lit`: 0 (shadow) ..1 (lit).
    #[inline]
    pub fn radiance(
        &self,
        albedo: f64,
        n: [f64; 3],
        sun: [f64; 3],
        view: [f64; 3],
        lit: f64,
    ) -> f64 {
        let ci = n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2];
        let ce = n[0] * view[0] + n[1] * view[1] + n[2] * view[2];
        self.exposure * albedo * (lit * self.photometry.eval(ci, ce) + self.ambient)
    }

    /// Gray level of a linear radiance: `255 * clamp(r, 0, 1) ^ (1 / gamma)`.
    #[inline]
    pub fn gray(&self, radiance: f64) -> f64 {
        255.0 * radiance.clamp(0.0, 1.0).powf(1.0 / self.gamma)
    }

    /// Quantizes gray levels (0..255 floats) to an image, adding the sensor noise if any,
    /// from a generator seeded with `noise_seed ^ stream` (deterministic).
    pub fn finish(&self, w: u32, h: u32, gray: &[f32], stream: u64) -> GrayImage {
        let mut out = GrayImage::new(w, h);
        let noise = if self.noise_sigma > 0.0 {
            Normal::new(0.0, self.noise_sigma).ok()
        } else {
            None
        };
        let mut rng =
            ChaCha8Rng::seed_from_u64(self.noise_seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        for (o, &g) in out.as_mut().iter_mut().zip(gray) {
            let mut v = g as f64;
            if let Some(n) = &noise {
                v += n.sample(&mut rng);
            }
            *o = v.round().clamp(0.0, 255.0) as u8;
        }
        out
    }
}
