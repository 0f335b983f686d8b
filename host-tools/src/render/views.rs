//! The rover's ground views: the four cameras of a pose, the terrain around the rover
//! prepared once (mesh levels, cast shadows, node shading, near-field texture) and the views
//! rendered over it in parallel, with their range images ([`ViewSet`]).

use super::{detail, raster, shadow, terrain, RenderError, RenderOptions, Sun, Surface};
use image::GrayImage;
use orbfix::camera::{Camera, RoverPose, View};

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
