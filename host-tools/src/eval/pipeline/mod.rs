//! The whole pipeline on the built-in world: render the rover's four views, reproject them
//! with the core's LUT into the top-down image, render the orbital map region, and the
//! generated evaluation queries of the test zone.
//!
//! Files: `observation` (what the rover sees at a stop, and its top-down image),
//! `reprojection` (views to the core's top-down image: LUT, range, the host's reference),
//! `map` (the orbital map region), `queries` (the generated evaluation queries); this file
//! holds the pipeline's settings and one query run through it.

mod map;
mod observation;
mod queries;
mod reprojection;

pub use map::map_region;
pub use observation::{observe, observe_raw, top_down, Observation};
pub use queries::{
    drivable_queries, make_queries, make_queries_in, Condition, Query, DRAWS_PER_DRIVABLE,
    PRIOR_OFFSET_M,
};
pub use reprojection::{
    dataset_top_down, reproject_by_range, reproject_depths, reproject_depths_with, reproject_views,
    reproject_views_range,
};

use super::{MapRegion, TopDown};
use crate::render::{self, RenderOptions};
use crate::reproject::depth::StereoNoise;
use crate::world::World;
use orbfix::reproject::{self, GridSpec};
use serde::{Deserialize, Serialize};

/// How the four views become a top-down image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Reprojection {
    /// The flight core's integer LUT, flat-ground assumption (for rovers without depth).
    Lut,
    /// The flight core's integer range reprojection (`reproject_range`): each pixel placed
    /// at its true 3D point from a depth image (the renderer's range image converted to
    /// millimetre depths, i.e. what stereo or a point cloud would give), averaged per cell.
    Range,
    /// The same range path with depth from the rover's own stereo pairs (right views
    /// rendered too), computed by the core's stereo matcher inside the fix (its `stereo`
    /// stage, `orbfix::fix::Depth::Stereo`).
    Stereo,
}

impl Reprojection {
    /// The depth source in reports: `none` (flat ground), `truth` (the renderer's exact
    /// depth), `stereo` (the core's own stereo).
    pub fn depth_name(self) -> &'static str {
        match self {
            Reprojection::Lut => "none",
            Reprojection::Range => "truth",
            Reprojection::Stereo => "stereo",
        }
    }
}

/// Where the fix's depth comes from (`orbfix eval --depth`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum DepthSource {
    /// The rover's own stereo pairs, matched by the core inside the fix (`stereo` stage).
    Stereo,
    /// The renderer's exact depth images, as an external stereo engine would give them.
    Truth,
    /// No depth: flat ground under the rover (the lookup-table path).
    None,
}

impl DepthSource {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        self.reprojection().depth_name()
    }

    /// The reprojection path of this depth source.
    pub fn reprojection(self) -> Reprojection {
        match self {
            DepthSource::Stereo => Reprojection::Stereo,
            DepthSource::Truth => Reprojection::Range,
            DepthSource::None => Reprojection::Lut,
        }
    }
}

/// How the rover stands at a stop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum RoverAttitude {
    /// Level whatever the slope (pitch and roll 0).
    #[default]
    Level,
    /// Pitched and rolled by the terrain's slope under its wheels
    /// ([`render::terrain_pose`], a 2 m wheelbase and track); the fix is given that
    /// attitude, as an inertial unit would measure it.
    Terrain,
}

/// Wheelbase and track of the rover [`RoverAttitude::Terrain`] stands on the slope with,
/// metres.
pub const WHEELBASE_M: f64 = 2.0;

/// Pipeline settings shared by every query.
#[derive(Clone, Debug)]
pub struct PipelineOptions {
    /// How views become the top-down image.
    pub reprojection: Reprojection,
    /// Renderer options (camera rig, photometry, exposure, noise).
    pub render: RenderOptions,
    /// Top-down grid (200 x 200 at 0.25 m/px = 50 m by default).
    pub grid: GridSpec,
    /// Side of the orbital map region, pixels at `grid.m_per_px` (1200 = 300 m).
    pub map_px: usize,
    /// Stereo depth noise of the range path (`None`: exact depths, millimetre quantized).
    pub depth_noise: Option<StereoNoise>,
    /// Settings of the core's range reprojection (column stride, limits, hole filling).
    pub range: reproject::RangeOptions,
    /// The rendered stereo rig (baseline, right gain) of the stereo path.
    pub stereo_rig: render::stereo::StereoRender,
    /// The core's stereo matcher settings of the stereo path (its baseline is set from
    /// `stereo_rig`).
    pub stereo: orbfix::stereo::StereoParams,
    /// How the rover stands at each stop (level, or on the slope).
    pub attitude: RoverAttitude,
    /// Exact depth only where the frame has texture to match: the smallest gray-level
    /// standard deviation of a pixel's 15 x 15 window
    /// ([`crate::reproject::depth::drop_untextured`]); `None`: the exact depth everywhere.
    /// Applies to the renderer's exact depth images (range path, and the truth beside the
    /// stereo path).
    pub truth_min_texture: Option<f64>,
}

impl PipelineOptions {
    /// The matcher settings with the rendered rig's baseline.
    pub fn stereo_params(&self) -> orbfix::stereo::StereoParams {
        orbfix::stereo::StereoParams {
            baseline_m: self.stereo_rig.baseline_m as f32,
            ..self.stereo
        }
    }
}

impl Default for PipelineOptions {
    fn default() -> Self {
        Self {
            reprojection: Reprojection::Range,
            render: RenderOptions::default(),
            grid: GridSpec::default(),
            map_px: 1200,
            depth_noise: None,
            range: orbfix::fix::FixConfig::default().range,
            stereo_rig: render::stereo::StereoRender::default(),
            stereo: orbfix::fix::FixConfig::default().stereo.matcher,
            attitude: RoverAttitude::Level,
            truth_min_texture: None,
        }
    }
}

/// Renders the top-down image and the map region of a query.
pub fn render_query(
    world: &World,
    q: &Query,
    opts: &PipelineOptions,
) -> anyhow::Result<(TopDown, MapRegion)> {
    let (_, top, map) = render_query_full(world, q, opts)?;
    Ok((top, map))
}

/// Renders a query's observation, its top-down image and its map region.
pub fn render_query_full(
    world: &World,
    q: &Query,
    opts: &PipelineOptions,
) -> anyhow::Result<(Observation, TopDown, MapRegion)> {
    let obs = observe_raw(world, q.x_m, q.y_m, q.heading_deg, q.sun_rover, opts)?;
    let top = top_down(&obs, opts)?;
    let map = map_region(
        world,
        q.prior_x_m,
        q.prior_y_m,
        opts.map_px,
        opts.grid.m_per_px as f64,
        q.sun_map,
        &opts.render,
    )?;
    Ok((obs, top, map))
}
