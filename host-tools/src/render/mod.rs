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

pub mod detail;
pub mod ortho;
pub mod ply;
mod pose;
pub mod raster;
mod shade;
pub mod shadow;
pub mod stereo;
pub mod terrain;

pub use pose::{ground_pose, ground_pose_on, terrain_pose, tilt_deg};

use crate::world::micro::MicroRelief;
use crate::world::{HeightGrid, Rock, World};
use image::GrayImage;
use orbfix::camera::{Camera, CameraError, CameraParams, RoverPose, View};
use orbfix::geo::GeoRef;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

pub use ortho::{render_ortho, render_ortho_cached};

/// What the renderer draws: a height field with an albedo texture. [`World`] is one; tests
/// use their own (e.g. a flat plane with a bright marker).
pub trait Surface: Sync {
    /// Elevation at `(x, y)`, metres.
    fn height_m(&self, x: f64, y: f64) -> f64;
    /// Normal albedo at `(x, y)`, 0..1.
    fn albedo(&self, x: f64, y: f64) -> f64;
    /// Heights and albedo on a north-up grid (conventions of [`World::sample_grid`]).
    fn sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> HeightGrid {
        let mut height_m = Vec::with_capacity(nx * ny);
        let mut albedo = Vec::with_capacity(nx * ny);
        for r in 0..ny {
            let y = origin_y_m - (r as f64 + 0.5) * m_per_px;
            for c in 0..nx {
                let x = origin_x_m + (c as f64 + 0.5) * m_per_px;
                height_m.push(self.height_m(x, y) as f32);
                albedo.push(self.albedo(x, y) as f32);
            }
        }
        HeightGrid {
            origin_x_m,
            origin_y_m,
            m_per_px,
            nx,
            ny,
            height_m,
            albedo,
        }
    }

    /// As [`Surface::sample_grid`], with each pixel's albedo averaged over its square
    /// footprint of side `footprint_m` metres (see [`World::sample_grid_filtered`]). The
    /// renderer asks for footprint = node spacing (mesh levels) or pixel size (orthographic
    /// renders). Default: point samples.
    fn sample_grid_filtered(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
    ) -> HeightGrid {
        let _ = footprint_m;
        self.sample_grid(origin_x_m, origin_y_m, m_per_px, nx, ny)
    }

    /// The surface's centimetre-scale micro-relief, drawn as the near-field texture of the
    /// ground views ([`detail`]). Default: none.
    fn micro(&self) -> Option<&MicroRelief> {
        None
    }

    /// Calls `f` for every boulder of the height field whose footprint reaches into `rect`
    /// (`[x0, y0, x1, y1]` metres), so that the near-field texture can draw them finer than
    /// the mesh ([`detail`]). Default: none.
    fn visit_boulders(&self, rect: [f64; 4], f: &mut dyn FnMut(&Rock)) {
        let _ = (rect, f);
    }

    /// Pixels `cols x rows` (inside the grid) of [`Surface::sample_grid_filtered`] with the
    /// same arguments, bit for bit: heights and albedo, row-major, `cols.len()` wide. The
    /// default samples the whole grid and copies the window; [`World`] samples only what
    /// the window needs.
    #[allow(clippy::too_many_arguments)]
    fn sample_grid_window(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
        cols: std::ops::Range<usize>,
        rows: std::ops::Range<usize>,
    ) -> (Vec<f32>, Vec<f32>) {
        let g = self.sample_grid_filtered(origin_x_m, origin_y_m, m_per_px, nx, ny, footprint_m);
        let (mut h, mut a) = (Vec::new(), Vec::new());
        if cols.end <= g.nx && rows.end <= g.ny {
            for r in rows {
                h.extend_from_slice(&g.height_m[r * g.nx + cols.start..r * g.nx + cols.end]);
                a.extend_from_slice(&g.albedo[r * g.nx + cols.start..r * g.nx + cols.end]);
            }
        }
        (h, a)
    }
}

impl Surface for World {
    fn height_m(&self, x: f64, y: f64) -> f64 {
        World::height_m(self, x, y)
    }
    fn albedo(&self, x: f64, y: f64) -> f64 {
        World::albedo(self, x, y)
    }
    fn sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> HeightGrid {
        World::sample_grid(self, origin_x_m, origin_y_m, m_per_px, nx, ny)
    }
    fn sample_grid_filtered(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
    ) -> HeightGrid {
        World::sample_grid_filtered(self, origin_x_m, origin_y_m, m_per_px, nx, ny, footprint_m)
    }
    fn micro(&self) -> Option<&MicroRelief> {
        World::micro(self)
    }
    fn visit_boulders(&self, rect: [f64; 4], f: &mut dyn FnMut(&Rock)) {
        World::visit_boulders(self, rect, f)
    }

    fn sample_grid_window(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
        cols: std::ops::Range<usize>,
        rows: std::ops::Range<usize>,
    ) -> (Vec<f32>, Vec<f32>) {
        World::sample_grid_window(
            self,
            origin_x_m,
            origin_y_m,
            m_per_px,
            nx,
            ny,
            footprint_m,
            cols,
            rows,
        )
    }
}

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
    #[serde(default = "default_detail_range_m")]
    pub detail_range_m: f64,
    /// Texel side of the micro-relief texture, metres; 0 = from the focal length
    /// ([`detail::cell_for_focal`]: the pixel footprint at 8 m, 1..4 cm).
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

/// Fast gray mapping: `255 * clamp(r, 0, 1) ^ (1 / gamma)` by a table over `sqrt(r)`
/// (4096 steps, linear interpolation; within 0.05 gray levels of [`RenderOptions::gray`]).
#[derive(Clone, Debug)]
pub struct GrayMap {
    table: Vec<f32>,
}

impl GrayMap {
    const N: usize = 4096;

    /// The table for `gamma`.
    pub fn new(gamma: f64) -> Self {
        let table = (0..=Self::N + 1)
            .map(|i| {
                let t = (i as f64 / Self::N as f64).min(1.0);
                (255.0 * (t * t).powf(1.0 / gamma)) as f32
            })
            .collect();
        Self { table }
    }

    /// Gray level (0..255, not rounded) of a linear radiance.
    #[inline]
    pub fn gray(&self, radiance: f64) -> f32 {
        self.gray_at(Self::position(radiance))
    }

    /// Table position (0..=4096) of a linear radiance: the first step of [`Self::gray`],
    /// free of lookups (vectorizes).
    #[inline(always)]
    pub(crate) fn position(radiance: f64) -> f64 {
        radiance.clamp(0.0, 1.0).sqrt() * Self::N as f64
    }

    /// Gray level at table position `t` from [`Self::position`]: the rest of [`Self::gray`].
    #[inline(always)]
    pub(crate) fn gray_at(&self, t: f64) -> f32 {
        let i = (t as usize).min(Self::N);
        let f = (t - i as f64) as f32;
        self.table[i] * (1.0 - f) + self.table[i + 1] * f
    }
}

/// The four views of a rover plus their range images.
#[derive(Clone, Debug)]
pub struct ViewSet {
    /// Gray images, order front, right, rear, left.
    pub views: [GrayImage; 4],
    /// Range (distance from the optical centre along the pixel's ray), metres, row-major,
    /// one per view; 0 where the pixel sees sky.
    pub range_m: [Vec<f32>; 4],
    /// The cameras that made them.
    pub cameras: [Camera; 4],
}

/// Renders the four ground views (front, right, rear, left) of a rover.
pub fn render_views(
    world: &dyn Surface,
    pose: &RoverPose,
    sun: Sun,
    opts: &RenderOptions,
) -> Result<[GrayImage; 4], RenderError> {
    Ok(render_views_with_range(world, pose, sun, opts)?.views)
}

/// Renders the four ground views with their range images.
pub fn render_views_with_range(
    world: &dyn Surface,
    pose: &RoverPose,
    sun: Sun,
    opts: &RenderOptions,
) -> Result<ViewSet, RenderError> {
    render_views_cached(world, pose, sun, opts, None)
}

/// As [`render_views_with_range`], sharing far terrain between calls through `cache` (one
/// cache per world; results are identical with or without it). Use it when rendering many
/// locations of one world: far terrain is then sampled once.
pub fn render_views_cached(
    world: &dyn Surface,
    pose: &RoverPose,
    sun: Sun,
    opts: &RenderOptions,
    cache: Option<&terrain::TileCache>,
) -> Result<ViewSet, RenderError> {
    let cams = view_cameras(pose, opts)?;
    let jobs: Vec<(Camera, u64, f64)> = cams
        .iter()
        .enumerate()
        .map(|(k, c)| (*c, k as u64 + 1, 1.0))
        .collect();
    let out = render_jobs(world, pose, sun, opts, cache, &jobs)?;
    let mut it = out.into_iter();
    let mut next = || {
        it.next()
            .unwrap_or_else(|| (GrayImage::new(1, 1), Vec::new()))
    };
    let (v0, r0) = next();
    let (v1, r1) = next();
    let (v2, r2) = next();
    let (v3, r3) = next();
    Ok(ViewSet {
        views: [v0, v1, v2, v3],
        range_m: [r0, r1, r2, r3],
        cameras: cams,
    })
}

/// The four view cameras (front, right, rear, left) of a rover at `pose`.
pub fn view_cameras(pose: &RoverPose, opts: &RenderOptions) -> Result<[Camera; 4], RenderError> {
    let params = opts.camera_params();
    Ok([
        Camera::new(&params, pose, View::Front)?,
        Camera::new(&params, pose, View::Right)?,
        Camera::new(&params, pose, View::Rear)?,
        Camera::new(&params, pose, View::Left)?,
    ])
}

/// Checks the inputs, prepares the terrain around the rover once (mesh levels, cast
/// shadows, node shading) and renders `jobs` over it ([`render_cameras`]).
pub(crate) fn render_jobs(
    world: &dyn Surface,
    pose: &RoverPose,
    sun: Sun,
    opts: &RenderOptions,
    cache: Option<&terrain::TileCache>,
    jobs: &[(Camera, u64, f64)],
) -> Result<Vec<(GrayImage, Vec<f32>)>, RenderError> {
    opts.validate()?;
    sun.validate()?;
    pose.validate()?;
    let params = opts.camera_params();
    let own;
    let cache = match cache {
        Some(c) => c,
        None => {
            own = terrain::TileCache::new(1 << 22);
            &own
        }
    };
    let terrain = terrain::Terrain::around_cached(
        world,
        pose.x_m as f64,
        pose.y_m as f64,
        opts,
        params.focal_px() as f64,
        Some(cache),
    );
    let shadow = shadow::ShadowField::build(&terrain, &sun, opts.shadow_reach_m);
    let attrs = raster::NodeAttrs::compute(&terrain, &shadow);
    let detail = near_field_detail(world, pose, &terrain, &sun, opts);
    Ok(render_cameras(
        &terrain,
        &attrs,
        detail.as_ref(),
        jobs,
        &sun,
        opts,
    ))
}

/// The near-field texture of a rover location ([`detail`]), if the surface has micro-relief
/// and `opts.detail_range_m > 0`.
pub fn near_field_detail(
    world: &dyn Surface,
    pose: &RoverPose,
    terrain: &terrain::Terrain,
    sun: &Sun,
    opts: &RenderOptions,
) -> Option<detail::DetailTexture> {
    let micro = world.micro()?;
    if opts.detail_range_m <= 0.0 {
        return None;
    }
    let cell = if opts.detail_cell_m > 0.0 {
        opts.detail_cell_m
    } else {
        detail::cell_for_focal(opts.camera_params().focal_px() as f64)
    };
    // At most 8192 texels across (checked for explicit cells; automatic ones are >= 1 cm).
    let half = opts.detail_range_m.min(4096.0 * cell);
    Some(detail::DetailTexture::build(
        world,
        micro,
        terrain,
        pose.x_m as f64,
        pose.y_m as f64,
        half,
        cell,
        sun,
        opts.shadow_reach_m,
    ))
}

/// Renders `jobs` (camera, noise stream, gain on the gray levels before quantization) in
/// parallel over one prepared terrain; results in job order (deterministic).
pub(crate) fn render_cameras(
    terrain: &terrain::Terrain,
    attrs: &raster::NodeAttrs,
    detail: Option<&detail::DetailTexture>,
    jobs: &[(Camera, u64, f64)],
    sun: &Sun,
    opts: &RenderOptions,
) -> Vec<(GrayImage, Vec<f32>)> {
    use rayon::prelude::*;
    jobs.par_iter()
        .map(|(cam, stream, gain)| {
            let (mut gray, range) = raster::render_view(terrain, attrs, detail, cam, sun, opts);
            if *gain != 1.0 {
                for g in &mut gray {
                    *g = (*g as f64 * gain).clamp(0.0, 255.0) as f32;
                }
            }
            (
                opts.finish(cam.width_px, cam.height_px, &gray, *stream),
                range,
            )
        })
        .collect()
}

/// A satellite crop `size_px x size_px` centred on `(x_m, y_m)` (`docs/frames.md`).
pub fn render_satellite_crop(
    world: &dyn Surface,
    x_m: f64,
    y_m: f64,
    size_px: u32,
    m_per_px: f64,
    sun: Sun,
    opts: &RenderOptions,
) -> Result<(GrayImage, GeoRef), RenderError> {
    render_satellite_crop_cached(world, x_m, y_m, size_px, m_per_px, sun, opts, None)
}

/// As [`render_satellite_crop`], sharing coarse terrain through `cache` (identical results).
#[allow(clippy::too_many_arguments)]
pub fn render_satellite_crop_cached(
    world: &dyn Surface,
    x_m: f64,
    y_m: f64,
    size_px: u32,
    m_per_px: f64,
    sun: Sun,
    opts: &RenderOptions,
    cache: Option<&terrain::TileCache>,
) -> Result<(GrayImage, GeoRef), RenderError> {
    let geo = GeoRef::centred(
        x_m as f32,
        y_m as f32,
        size_px as usize,
        size_px as usize,
        m_per_px as f32,
    )
    .map_err(|e| RenderError::Option(format!("bad satellite georeference: {e}")))?;
    let img = ortho::render_ortho_cached(world, &geo, size_px, size_px, sun, opts, cache)?;
    Ok((img, geo))
}
