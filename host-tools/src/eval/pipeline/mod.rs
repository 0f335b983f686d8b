//! The whole pipeline on the built-in world: render the rover's four views, reproject them
//! with the core's LUT into the top-down image, render the orbital map region, and the
//! generated evaluation queries of the test zone.

use super::{MapRegion, TopDown};
use crate::render::{self, RenderOptions, Sun};
use crate::reproject::depth::{depth_images, drop_untextured_views, StereoNoise};
use crate::world::{zones, World};
use anyhow::Context;
use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::reproject::{self, Cell, GridSpec, Tap};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
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

/// Reprojects four views with depth (the renderer's range images as `u16` millimetre
/// depths, optionally with stereo noise) through the core's integer range reprojection.
pub fn reproject_views_range(
    set: &render::ViewSet,
    render_opts: &RenderOptions,
    pose: &orbfix::camera::RoverPose,
    grid: &GridSpec,
    range: &reproject::RangeOptions,
    noise: Option<StereoNoise>,
) -> anyhow::Result<TopDown> {
    let depths = depth_images(set, noise)?;
    reproject_depths_with(&set.views, &depths, render_opts, pose, grid, range).map(|(top, _)| top)
}

/// The core's range reprojection (default [`reproject::RangeOptions`]) of four views and
/// their `u16` millimetre depth images; also returns the core's report (frame status, pixel
/// and cell counts).
pub fn reproject_depths(
    views: &[image::GrayImage; 4],
    depths: &[Vec<u16>; 4],
    render_opts: &RenderOptions,
    pose: &orbfix::camera::RoverPose,
    grid: &GridSpec,
) -> anyhow::Result<(TopDown, reproject::RangeReport)> {
    let range = reproject::RangeOptions::default();
    reproject_depths_with(views, depths, render_opts, pose, grid, &range)
}

/// As [`reproject_depths`] with explicit range options.
pub fn reproject_depths_with(
    views: &[image::GrayImage; 4],
    depths: &[Vec<u16>; 4],
    render_opts: &RenderOptions,
    pose: &orbfix::camera::RoverPose,
    grid: &GridSpec,
    range: &reproject::RangeOptions,
) -> anyhow::Result<(TopDown, reproject::RangeReport)> {
    let params = render_opts.camera_params();
    let mut frames: [Option<ImageView<'_>>; 4] = [None; 4];
    let mut dviews: [Option<reproject::DepthView<'_>>; 4] = [None; 4];
    for ((f, dv), (v, d)) in frames
        .iter_mut()
        .zip(dviews.iter_mut())
        .zip(views.iter().zip(depths))
    {
        let (w, h) = (v.width() as usize, v.height() as usize);
        *f = Some(
            ImageView::new(v.as_raw(), w, h).map_err(|e| anyhow::anyhow!("bad view image: {e}"))?,
        );
        *dv = Some(
            reproject::DepthView::new(d, w, h)
                .map_err(|e| anyhow::anyhow!("bad depth image ({w} x {h} expected): {e}"))?,
        );
    }
    let n = grid.n;
    let mut scratch = vec![0u32; reproject::range_scratch_len(n)];
    let mut out = vec![0u8; n * n];
    let mut mask = vec![0u8; n * n];
    let report = reproject::reproject_range(
        &frames,
        &dviews,
        &params,
        pose,
        grid,
        range,
        &mut scratch,
        &mut out,
        &mut mask,
    )
    .map_err(|e| anyhow::anyhow!("range reprojection failed: {e}"))?;
    Ok((
        TopDown {
            image: out,
            mask,
            n,
            m_per_px: grid.m_per_px,
        },
        report,
    ))
}

/// Places every pixel with a range at its 3D point and averages gray levels per grid cell
/// (host `f32`/`f64` reference of the core's [`reproject::reproject_range`], kept for tests;
/// no hole filling; cells no pixel reaches are "no data").
pub fn reproject_by_range(
    set: &render::ViewSet,
    pose: &orbfix::camera::RoverPose,
    grid: &GridSpec,
) -> TopDown {
    let n = grid.n;
    let m = grid.m_per_px as f64;
    let mut sum = vec![0u64; n * n];
    let mut cnt = vec![0u32; n * n];
    for ((img, range), cam) in set.views.iter().zip(&set.range_m).zip(&set.cameras) {
        let w = img.width() as usize;
        for (i, (&g, &r)) in img.as_raw().iter().zip(range).enumerate() {
            if r <= 0.0 {
                continue;
            }
            let d = cam.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let px = cam.centre.x as f64 + r as f64 * d.x as f64;
            let py = cam.centre.y as f64 + r as f64 * d.y as f64;
            let c = ((px - pose.x_m as f64) / m + n as f64 / 2.0).floor();
            let rr = ((pose.y_m as f64 - py) / m + n as f64 / 2.0).floor();
            if c >= 0.0 && rr >= 0.0 && (c as usize) < n && (rr as usize) < n {
                let k = rr as usize * n + c as usize;
                sum[k] += g as u64;
                cnt[k] += 1;
            }
        }
    }
    let image = sum
        .iter()
        .zip(&cnt)
        .map(|(&s, &c)| {
            if c == 0 {
                0
            } else {
                ((s + c as u64 / 2) / c as u64) as u8
            }
        })
        .collect();
    let mask = cnt.iter().map(|&c| if c == 0 { 0 } else { 255 }).collect();
    TopDown {
        image,
        mask,
        n,
        m_per_px: grid.m_per_px,
    }
}

/// Reprojects four views (front, right, rear, left) to a top-down image with the core LUT.
pub fn reproject_views(
    views: &[image::GrayImage; 4],
    render_opts: &RenderOptions,
    pose: &orbfix::camera::RoverPose,
    grid: &GridSpec,
) -> anyhow::Result<TopDown> {
    let params = render_opts.camera_params();
    let mut frames: [Option<ImageView<'_>>; 4] = [None; 4];
    for (f, v) in frames.iter_mut().zip(views) {
        *f = Some(
            ImageView::new(v.as_raw(), v.width() as usize, v.height() as usize)
                .map_err(|e| anyhow::anyhow!("bad view image: {e}"))?,
        );
    }
    let n = grid.n;
    let mut cells = vec![Cell::EMPTY; reproject::table_len(n)];
    let mut extra = vec![Tap::EMPTY; reproject::table_len(n) / 4 + 1];
    let mut out = vec![0u8; n * n];
    let mut mask = vec![0u8; n * n];
    reproject::reproject_top_down(
        &frames, &params, pose, grid, &mut cells, &mut extra, &mut out, &mut mask,
    )
    .map_err(|e| anyhow::anyhow!("reprojection failed: {e}"))?;
    Ok(TopDown {
        image: out,
        mask,
        n,
        m_per_px: grid.m_per_px,
    })
}

/// The `size_px x size_px` orbital map region centred on `(cx, cy)` metres: rendered under
/// `sun`, or for a DEM world whose map source is [`crate::world::dem::MapSource::Ortho`] (the
/// default) the orthoimage itself resampled to the grid (`sun` and `opts` then unused).
pub fn map_region(
    world: &World,
    cx: f64,
    cy: f64,
    size_px: usize,
    m_per_px: f64,
    sun: Sun,
    opts: &RenderOptions,
) -> anyhow::Result<MapRegion> {
    if let Some(dem) = world
        .dem()
        .filter(|d| d.map_source() == crate::world::dem::MapSource::Ortho)
    {
        let geo = GeoRef::centred(cx as f32, cy as f32, size_px, size_px, m_per_px as f32)
            .map_err(|e| {
                anyhow::anyhow!("bad map georeference around ({cx:.1}, {cy:.1}) m: {e}")
            })?;
        return Ok(MapRegion {
            width: size_px,
            height: size_px,
            image: dem.ortho_map(&geo, size_px, size_px),
            geo,
        });
    }
    let (img, geo) =
        render::render_satellite_crop(world, cx, cy, size_px as u32, m_per_px, sun, opts)
            .with_context(|| format!("rendering the map around ({cx:.1}, {cy:.1}) m"))?;
    Ok(MapRegion {
        width: img.width() as usize,
        height: img.height() as usize,
        image: img.into_raw(),
        geo,
    })
}

/// Lighting of an evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Condition {
    /// The study's setting: map and rover under one sun, 30 deg elevation, azimuth 135 deg.
    SameSun,
    /// Map sun: elevation 20-60 deg, azimuth 0-360 deg; rover sun: elevation 20-60 deg,
    /// azimuth 60-180 deg away from the map's (either side), drawn per query.
    CrossSun,
}

impl Condition {
    /// Its name in reports.
    pub fn name(&self) -> &'static str {
        match self {
            Condition::SameSun => "same-sun",
            Condition::CrossSun => "cross-sun",
        }
    }
}

/// One generated query: a rover stop in the test zone and its prior.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Query {
    /// Query number.
    pub id: usize,
    /// True rover east, metres.
    pub x_m: f64,
    /// True rover north, metres.
    pub y_m: f64,
    /// Heading, degrees clockwise from north.
    pub heading_deg: f64,
    /// Prior east (centre of the map region), metres.
    pub prior_x_m: f64,
    /// Prior north, metres.
    pub prior_y_m: f64,
    /// Sun of the rover's views.
    pub sun_rover: Sun,
    /// Sun of the orbital map.
    pub sun_map: Sun,
}

/// Largest prior offset from the truth along each axis, metres (the 441 window centres span
/// +-125 m, so the truth always lies inside the searched region but rarely at its centre).
pub const PRIOR_OFFSET_M: f64 = 100.0;

/// `n` queries of `seed` in the test zone (truth at least 150 m inside the zone).
pub fn make_queries(seed: u64, n: usize, condition: Condition) -> Vec<Query> {
    make_queries_in(&zones::zone(zones::Split::Test), 150.0, seed, n, condition)
}

/// Stops of the query stream drawn for each drivable one, at most: [`drivable_queries`] gives
/// up beyond `n` times this.
pub const DRAWS_PER_DRIVABLE: usize = 20;

/// `n` queries of [`make_queries`]'s stream (`seed`, the test zone) at which a rover standing
/// on the terrain ([`render::terrain_pose`], [`WHEELBASE_M`]) tilts at most `max_tilt_deg`
/// ([`render::tilt_deg`]): terrain it could drive onto. Steeper stops are skipped; the ones
/// kept keep their place in the stream (`id`). Fails when fewer than `n` of the first
/// [`DRAWS_PER_DRIVABLE`] `n` stops qualify.
pub fn drivable_queries(
    world: &World,
    seed: u64,
    n: usize,
    condition: Condition,
    max_tilt_deg: f64,
) -> anyhow::Result<Vec<Query>> {
    let draws = n.saturating_mul(DRAWS_PER_DRIVABLE);
    let kept: Vec<Query> = make_queries(seed, draws, condition)
        .into_iter()
        .filter(|q| {
            let pose =
                render::terrain_pose(world, q.x_m, q.y_m, q.heading_deg, WHEELBASE_M, WHEELBASE_M);
            render::tilt_deg(&pose) <= max_tilt_deg
        })
        .take(n)
        .collect();
    anyhow::ensure!(
        kept.len() == n,
        "only {} of the first {draws} stops of seed {seed} tilt at most {max_tilt_deg} deg; \
         allow a steeper tilt or ask for fewer stops",
        kept.len()
    );
    Ok(kept)
}

/// `n` queries of `seed` with the truth at least `margin` metres inside `z` (e.g. a DEM's
/// [`crate::world::dem::DemTerrain::location_zone`]).
pub fn make_queries_in(
    z: &zones::Zone,
    margin: f64,
    seed: u64,
    n: usize,
    condition: Condition,
) -> Vec<Query> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6c6f_6361_6c69_7a65);
    (0..n)
        .map(|id| {
            let x_m = rng.random_range(z.x_min_m + margin..z.x_max_m - margin);
            let y_m = rng.random_range(z.y_min_m + margin..z.y_max_m - margin);
            let heading_deg = rng.random_range(0.0..360.0);
            let prior_x_m = x_m + rng.random_range(-PRIOR_OFFSET_M..PRIOR_OFFSET_M);
            let prior_y_m = y_m + rng.random_range(-PRIOR_OFFSET_M..PRIOR_OFFSET_M);
            let (sun_rover, sun_map) = match condition {
                Condition::SameSun => (Sun::default(), Sun::default()),
                Condition::CrossSun => {
                    let map_az: f64 = rng.random_range(0.0..360.0);
                    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    let rov_az = (map_az + sign * rng.random_range(60.0..180.0)).rem_euclid(360.0);
                    (
                        Sun {
                            elevation_deg: rng.random_range(20.0..60.0),
                            azimuth_deg: rov_az,
                        },
                        Sun {
                            elevation_deg: rng.random_range(20.0..60.0),
                            azimuth_deg: map_az,
                        },
                    )
                }
            };
            Query {
                id,
                x_m,
                y_m,
                heading_deg,
                prior_x_m,
                prior_y_m,
                sun_rover,
                sun_map,
            }
        })
        .collect()
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

/// The top-down image of a dataset location (its views reprojected with the core LUT at the
/// default 200 x 200 grid, 0.25 m/px) and its true position `(x, y)` metres.
pub fn dataset_top_down(
    dir: &std::path::Path,
    id: &str,
) -> anyhow::Result<(TopDown, Option<(f64, f64)>)> {
    let ds = crate::dataset::Dataset::open(dir)?;
    let row = ds
        .rows
        .iter()
        .find(|r| r.id == id || r.index.to_string() == id)
        .with_context(|| {
            format!(
                "location '{id}' is not in {} ({} locations, ids like '{}')",
                dir.display(),
                ds.rows.len(),
                ds.rows.first().map(|r| r.id.as_str()).unwrap_or("?")
            )
        })?;
    let views = ds.load_views(row)?;
    // The attitude the views were rendered with (a `--max-attitude` dataset).
    let pose = row.pose();
    let top = reproject_views(&views, &ds.info.config.render, &pose, &GridSpec::default())?;
    Ok((top, Some((row.x_m, row.y_m))))
}
