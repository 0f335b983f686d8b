//! Four views reprojected to a top-down image: through the core's LUT (flat ground) or its
//! integer range reprojection (with depth images), the host's floating-point reference of the
//! range reprojection, and the top-down image of a dataset location.

use crate::eval::TopDown;
use crate::render::{self, RenderOptions};
use crate::reproject::depth::{depth_images, StereoNoise};
use anyhow::Context;
use orbfix::image::ImageView;
use orbfix::reproject::{self, Cell, GridSpec, Tap};

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
