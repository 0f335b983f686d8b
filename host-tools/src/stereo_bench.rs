//! The stereo benchmark set: world-rendered stereo pairs at the core's working size, the
//! renderer's true disparity, the mask of pixels inside the top-down square, and the core's
//! disparity with its timing, written for `scripts/stereo_bench.py` (which runs OpenCV's
//! `StereoSGBM` and `StereoBM` on the same pairs and scores all three; `docs/stereo.md`).

use crate::fsutil::{png_gray16, write_atomic, write_png};
use crate::render::stereo::{render_stereo_views, true_disparity, StereoRender};
use crate::render::{self, RenderOptions, Sun};
use crate::world::zones::{self, Split};
use crate::world::World;
use anyhow::Context;
use image::GrayImage;
use orbfix::image::ImageView;
use orbfix::stereo::{downsample_row, StereoParams, StereoRig};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to render and match.
#[derive(Clone, Debug)]
pub struct StereoBenchOptions {
    /// World seed.
    pub seed: u64,
    /// Locations (four pairs each), drawn in the test zone.
    pub locations: usize,
    /// Renderer settings (size, sensor noise).
    pub render: RenderOptions,
    /// The rendered rig (baseline, right gain).
    pub rig: StereoRender,
    /// The core matcher's settings (its baseline is set from `rig`).
    pub params: StereoParams,
    /// Half side of the top-down square, metres (25: 50 m x 50 m).
    pub half_square_m: f64,
    /// Output band of the core, rows.
    pub band_rows: usize,
    /// Output folder.
    pub out: PathBuf,
}

/// One pair of the set (paths relative to the output folder).
#[derive(Clone, Debug, Serialize)]
pub struct Entry {
    /// Location and view, e.g. `003_front`.
    pub id: String,
    /// Reduced left image (8-bit PNG).
    pub left: String,
    /// Reduced right image.
    pub right: String,
    /// True disparity, 16-bit PNG, Q4 pixels at the working size, 0 = none (sky).
    pub truth: String,
    /// Pixels whose ground point lies inside the top-down square (8-bit PNG, 255 inside).
    pub mask: String,
    /// The core's disparity, 16-bit PNG, Q4, 0 = no data.
    pub core: String,
}

/// `index.json` of the set.
#[derive(Clone, Debug, Serialize)]
pub struct Index {
    /// Working size `(width, height)`, pixels.
    pub size: [usize; 2],
    /// Reduction of the rendered frames.
    pub downsample: u8,
    /// Rendered size.
    pub render_size: [u32; 2],
    /// Baseline, metres.
    pub baseline_m: f64,
    /// Right camera gain.
    pub right_gain: f64,
    /// Sensor noise, gray levels.
    pub noise_sigma: f64,
    /// Focal length at the working size, pixels.
    pub focal_px: f32,
    /// Largest disparity the core searches, pixels (OpenCV gets the next multiple of 16).
    pub max_disparity_px: usize,
    /// Core: milliseconds per view (one thread, release build).
    pub core_ms_per_view: f64,
    /// Core: winner-take-all pixel-disparities per view.
    pub core_pixel_disparities_per_view: f64,
    /// Core: column-cost updates per view.
    pub core_cost_updates_per_view: f64,
    /// Core: working memory of the band API, bytes (scratch, without the output band).
    pub core_working_bytes: usize,
    /// Core: output band bytes (`band_rows` rows of `u16`).
    pub core_band_bytes: usize,
    /// Output band rows.
    pub band_rows: usize,
    /// The core's settings.
    pub params: String,
    /// The pairs.
    pub entries: Vec<Entry>,
}

fn reduce(img: &GrayImage, k: usize) -> anyhow::Result<GrayImage> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let v = ImageView::new(img.as_raw(), w, h).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (wo, ho) = (w / k, h / k);
    let mut out = GrayImage::new(wo as u32, ho as u32);
    for (y, row) in out.as_mut().chunks_exact_mut(wo).enumerate() {
        downsample_row(&v, k, y, row);
    }
    Ok(out)
}

fn q4(d: &[f32]) -> Vec<u16> {
    d.iter()
        .map(|&v| {
            if v.is_finite() && v > 0.0 {
                (v * 16.0).round().clamp(1.0, 65535.0) as u16
            } else {
                0
            }
        })
        .collect()
}

/// Renders the set, runs the core on every pair and writes everything to `opts.out`.
pub fn run(opts: &StereoBenchOptions) -> anyhow::Result<Index> {
    anyhow::ensure!(opts.locations > 0, "--locations must be at least 1");
    let world = World::new(opts.seed);
    let cam = opts.render.camera_params();
    let params = StereoParams {
        baseline_m: opts.rig.baseline_m as f32,
        ..opts.params
    };
    let rig = StereoRig::new(&cam, &params).map_err(|e| anyhow::anyhow!("{e}"))?;
    let sizes = rig.buffer_sizes();
    let (w, h) = rig.output_size();
    let k = usize::from(params.downsample);
    let mut bytes = vec![0u8; sizes.bytes];
    let mut words = vec![0u16; sizes.words];
    let mut disp = vec![0u16; w * h];
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;
    let zone = zones::zone(Split::Test);
    let cache = render::terrain::TileCache::new(1 << 26);
    let sun = Sun::default();
    let mut entries = Vec::new();
    let (mut secs, mut pd, mut cu, mut views) = (0.0f64, 0u64, 0u64, 0usize);
    let bar = indicatif::ProgressBar::new(opts.locations as u64);
    for i in 0..opts.locations {
        // An even spread over the test zone, headings turning by 37 degrees.
        let fx = (i as f64 * 0.618_034).fract();
        let fy = (i as f64 * 0.381_966 + 0.5 / opts.locations as f64).fract();
        let x = zone.x_min_m + 50.0 + fx * (zone.x_max_m - zone.x_min_m - 100.0);
        let y = zone.y_min_m + 50.0 + fy * (zone.y_max_m - zone.y_min_m - 100.0);
        let pose = render::ground_pose(&world, x, y, (37.0 * i as f64) % 360.0);
        let mut ropts = opts.render;
        ropts.noise_seed = crate::dataset::mix(opts.seed, i as u64);
        let set = render_stereo_views(&world, &pose, sun, &ropts, &opts.rig, Some(&cache))?;
        for v in 0..4 {
            let id = format!("{i:03}_{}", crate::dataset::VIEW_NAMES[v]);
            let (l, r) = (&set.left.views[v], &set.right[v]);
            let lv = ImageView::new(l.as_raw(), l.width() as usize, l.height() as usize)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            let rv = ImageView::new(r.as_raw(), r.width() as usize, r.height() as usize)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            let t = Instant::now();
            let rep = rig
                .image(
                    &lv,
                    Some(&rv),
                    opts.band_rows,
                    true,
                    &mut bytes,
                    &mut words,
                    &mut disp,
                )
                .map_err(|e| anyhow::anyhow!("view {id}: {e}"))?;
            secs += t.elapsed().as_secs_f64();
            pd += rep.pixel_disparities;
            cu += rep.cost_updates;
            views += 1;
            let lcam = &set.left.cameras[v];
            let range = &set.left.range_m[v];
            let (truth, tw, th) = true_disparity(range, lcam, opts.rig.baseline_m, k)?;
            anyhow::ensure!((tw, th) == (w, h), "truth size differs from the core's");
            // Inside the square: every full-resolution pixel of the block.
            let mut mask = GrayImage::new(w as u32, h as u32);
            let fw = lcam.width_px as usize;
            for (i_out, m) in mask.as_mut().iter_mut().enumerate() {
                let (xo, yo) = (i_out % w, i_out / w);
                let mut inside = true;
                'b: for yy in yo * k..yo * k + k {
                    for xx in xo * k..xo * k + k {
                        let rr = range[yy * fw + xx];
                        if rr.is_nan() || rr <= 0.0 {
                            inside = false;
                            break 'b;
                        }
                        let ray = lcam.ray(xx as f32 + 0.5, yy as f32 + 0.5);
                        let p = lcam.centre + ray * rr;
                        if (p.x as f64 - x).abs() > opts.half_square_m
                            || (p.y as f64 - y).abs() > opts.half_square_m
                        {
                            inside = false;
                            break 'b;
                        }
                    }
                }
                *m = if inside { 255 } else { 0 };
            }
            let e = Entry {
                id: id.clone(),
                left: format!("{id}_L.png"),
                right: format!("{id}_R.png"),
                truth: format!("{id}_truth.png"),
                mask: format!("{id}_mask.png"),
                core: format!("{id}_core.png"),
            };
            let p = |s: &str| opts.out.join(s);
            write_png(&p(&e.left), &reduce(l, k)?)?;
            write_png(&p(&e.right), &reduce(r, k)?)?;
            write_atomic(&p(&e.truth), &png_gray16(w as u32, h as u32, &q4(&truth))?)?;
            write_png(&p(&e.mask), &mask)?;
            write_atomic(&p(&e.core), &png_gray16(w as u32, h as u32, &disp)?)?;
            entries.push(e);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let n = views.max(1) as f64;
    let index = Index {
        size: [w, h],
        downsample: params.downsample,
        render_size: [cam.width_px, cam.height_px],
        baseline_m: opts.rig.baseline_m,
        right_gain: opts.rig.right_gain,
        noise_sigma: opts.render.noise_sigma,
        focal_px: rig.ranges().focal_px(),
        max_disparity_px: rig.ranges().global_max(),
        core_ms_per_view: 1e3 * secs / n,
        core_pixel_disparities_per_view: pd as f64 / n,
        core_cost_updates_per_view: cu as f64 / n,
        core_working_bytes: sizes.working_bytes(),
        core_band_bytes: 2 * sizes.band_len(opts.band_rows),
        band_rows: opts.band_rows,
        params: format!("{params:?}"),
        entries,
    };
    write_atomic(
        &opts.out.join("index.json"),
        serde_json::to_string_pretty(&index)?.as_bytes(),
    )?;
    Ok(index)
}

/// Where [`run`] wrote the index.
pub fn index_path(out: &Path) -> PathBuf {
    out.join("index.json")
}
