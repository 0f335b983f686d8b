//! Renderer of the lunar world: the rover's four pinhole ground views (with range images
//! and point clouds) and orthographic north-up satellite images, under one lighting model.
//!
//! Lighting (the same function for ground and orbit, `docs/rendering.md`):
//! `radiance = exposure * albedo(x, y) * (lit(x, y) * photometric(n, sun, view) + ambient)`,
//! gray = `round(255 * clamp(radiance, 0, 1) ^ (1 / gamma))`, sky = 0. `lit` is a cast-shadow
//! mask computed by a horizon sweep along the sun azimuth ([`shadow`]).
//!
//! Ground views rasterize the height field as a triangle mesh of nested square grids
//! (0.1 m near the rover, doubling each ring out to `max_range_m`) with a z-buffer
//! ([`raster`]); the geometry is that of [`orbfix::camera::Camera`].
//!
//! Files besides the public modules: `surface` (what the renderer draws), `light` (the sun
//! and the photometric function), `options` (the render options, radiance and gray levels),
//! `gray_map` (the fast gray mapping), `views` (the rover's ground views), `satellite`
//! (satellite crops); this file holds [`RenderError`].

pub mod detail;
mod gray_map;
mod light;
mod options;
pub mod ortho;
pub mod ply;
mod pose;
pub mod raster;
mod satellite;
mod shade;
pub mod shadow;
pub mod stereo;
mod surface;
pub mod terrain;
mod views;

pub use gray_map::GrayMap;
pub use light::{Photometry, Sun};
pub use options::{CameraParamsDef, RenderOptions};
pub use ortho::{render_ortho, render_ortho_cached};
pub use pose::{ground_pose, ground_pose_on, terrain_pose, tilt_deg};
pub use satellite::{render_satellite_crop, render_satellite_crop_cached};
pub use surface::Surface;
pub(crate) use views::render_jobs;
pub use views::{
    near_field_detail, render_views, render_views_cached, render_views_with_range, view_cameras,
    ViewSet,
};

use orbfix::camera::CameraError;

/// Errors of the renderer; each says what was wrong.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RenderError {
    /// Camera or pose parameters rejected by the camera model.
    #[error("bad camera or pose: {0}")]
    Camera(CameraError),
    /// Sun elevation or azimuth not finite or out of range.
    #[error("bad sun: {0}")]
    Sun(String),
    /// Another option out of range.
    #[error("bad render option: {0}")]
    Option(String),
}

impl From<CameraError> for RenderError {
    fn from(e: CameraError) -> Self {
        RenderError::Camera(e)
    }
}
