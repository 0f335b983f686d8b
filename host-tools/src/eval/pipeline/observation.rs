//! What the rover sees at a stop ([`Observation`]: its four frames, their depth images on
//! the range and stereo paths, the stereo pairs' right images, its pose and rig), rendered by
//! [`observe_raw`], and its top-down image ([`top_down`], [`observe`]).

use super::{
    reproject_depths_with, reproject_views, PipelineOptions, Reprojection, RoverAttitude,
    WHEELBASE_M,
};
use crate::eval::TopDown;
use crate::render::{self, Sun};
use crate::reproject::depth::{depth_images, drop_untextured_views, StereoNoise};
use crate::world::World;
use anyhow::Context;
use orbfix::image::ImageView;

/// What the rover sees at a stop: its four frames, their depth images when the pipeline
/// has depth (the range path), the rig and the pose prior's attitude.
#[derive(Clone, Debug)]
pub struct Observation {
    /// Frames, front, right, rear, left.
    pub views: [image::GrayImage; 4],
    /// Depth images (`u16` millimetres along the optical axis, 0 = none), range path only
    /// (on the stereo path: the core's stereo depth, for the baseline matchers).
    pub depths: Option<[Vec<u16>; 4]>,
    /// The right images of the stereo pairs (stereo path only): the fix matches them
    /// itself.
    pub rights: Option<[image::GrayImage; 4]>,
    /// The renderer's exact depth images (range and stereo paths): the truth-depth fix
    /// beside the stereo one.
    pub truth_depths: Option<[Vec<u16>; 4]>,
    /// The rover's true pose (position, ground height, heading).
    pub pose: orbfix::camera::RoverPose,
    /// The camera rig.
    pub params: orbfix::camera::CameraParams,
}

impl Observation {
    /// The frames as core views.
    pub fn frames(&self) -> anyhow::Result<[Option<ImageView<'_>>; 4]> {
        let mut frames: [Option<ImageView<'_>>; 4] = [None; 4];
        for (f, v) in frames.iter_mut().zip(&self.views) {
            *f = Some(
                ImageView::new(v.as_raw(), v.width() as usize, v.height() as usize)
                    .map_err(|e| anyhow::anyhow!("bad view image: {e}"))?,
            );
        }
        Ok(frames)
    }

    /// The same stop with the renderer's exact depth (no stereo pairs), if it has it.
    pub fn with_truth_depth(&self) -> Option<Observation> {
        let truth = self.truth_depths.clone()?;
        Some(Observation {
            views: self.views.clone(),
            depths: Some(truth.clone()),
            rights: None,
            truth_depths: Some(truth),
            pose: self.pose,
            params: self.params,
        })
    }

    /// The right images as core views (stereo path), else `None`.
    pub fn right_frames(&self) -> anyhow::Result<Option<[Option<ImageView<'_>>; 4]>> {
        let Some(rights) = &self.rights else {
            return Ok(None);
        };
        let mut frames: [Option<ImageView<'_>>; 4] = [None; 4];
        for (f, v) in frames.iter_mut().zip(rights) {
            *f = Some(
                ImageView::new(v.as_raw(), v.width() as usize, v.height() as usize)
                    .map_err(|e| anyhow::anyhow!("bad right image: {e}"))?,
            );
        }
        Ok(Some(frames))
    }
}

/// Renders the four views at a rover stop (and their depth images on the range path).
pub fn observe_raw(
    world: &World,
    x_m: f64,
    y_m: f64,
    heading_deg: f64,
    sun: Sun,
    opts: &PipelineOptions,
) -> anyhow::Result<Observation> {
    let pose = match opts.attitude {
        RoverAttitude::Level => render::ground_pose(world, x_m, y_m, heading_deg),
        RoverAttitude::Terrain => {
            render::terrain_pose(world, x_m, y_m, heading_deg, WHEELBASE_M, WHEELBASE_M)
        }
    };
    let params = opts.render.camera_params();
    match opts.reprojection {
        Reprojection::Lut => {
            let views = render::render_views(world, &pose, sun, &opts.render)
                .with_context(|| format!("rendering the views at ({x_m:.1}, {y_m:.1}) m"))?;
            Ok(Observation {
                views,
                depths: None,
                rights: None,
                truth_depths: None,
                pose,
                params,
            })
        }
        Reprojection::Range => {
            let set = render::render_views_with_range(world, &pose, sun, &opts.render)
                .with_context(|| format!("rendering the views at ({x_m:.1}, {y_m:.1}) m"))?;
            // A noise stream per stop, from its position.
            let noise = opts.depth_noise.map(|n| StereoNoise {
                seed: n.seed ^ x_m.to_bits().rotate_left(17) ^ y_m.to_bits(),
                ..n
            });
            let mut depths = depth_images(&set, noise)?;
            drop_untextured_views(&mut depths, &set.views, opts.truth_min_texture)?;
            Ok(Observation {
                views: set.views,
                depths: Some(depths.clone()),
                rights: None,
                truth_depths: Some(depths),
                pose,
                params,
            })
        }
        Reprojection::Stereo => {
            let set = render::stereo::render_stereo_views(
                world,
                &pose,
                sun,
                &opts.render,
                &opts.stereo_rig,
                None,
            )
            .with_context(|| format!("rendering the stereo pairs at ({x_m:.1}, {y_m:.1}) m"))?;
            let depths = crate::reproject::depth::stereo_depth_images(
                &set.left.views,
                &set.right,
                &params,
                &pose,
                &opts.stereo_params(),
            )?;
            let mut truth = depth_images(&set.left, None)?;
            drop_untextured_views(&mut truth, &set.left.views, opts.truth_min_texture)?;
            Ok(Observation {
                views: set.left.views,
                depths: Some(depths),
                rights: Some(set.right),
                truth_depths: Some(truth),
                pose,
                params,
            })
        }
    }
}

/// The core's top-down image of an observation (LUT on flat ground, or range with its
/// depth images), for the baseline matchers.
pub fn top_down(obs: &Observation, opts: &PipelineOptions) -> anyhow::Result<TopDown> {
    match &obs.depths {
        None => reproject_views(&obs.views, &opts.render, &obs.pose, &opts.grid),
        Some(d) => reproject_depths_with(
            &obs.views,
            d,
            &opts.render,
            &obs.pose,
            &opts.grid,
            &opts.range,
        )
        .map(|(t, _)| t),
    }
}

/// Renders the four views at a rover stop and reprojects them to a top-down image.
pub fn observe(
    world: &World,
    x_m: f64,
    y_m: f64,
    heading_deg: f64,
    sun: Sun,
    opts: &PipelineOptions,
) -> anyhow::Result<TopDown> {
    top_down(&observe_raw(world, x_m, y_m, heading_deg, sun, opts)?, opts)
}
