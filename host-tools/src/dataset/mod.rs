//! Datasets of rendered locations: the writer behind `orbfix generate` and the reader
//! ([`Dataset::open`]) that training and evaluation use. Layout and format: `docs/dataset.md`.
//!
//! Files: `config` (what is asked for: presets, ranges, the world or a DEM site, the
//! locations), `manifest` (`dataset.json`, `manifest.jsonl`, shards), `reader` (the
//! dataset read back); this file renders and writes the locations (`generate`).

mod config;
mod manifest;
mod reader;

pub use config::*;
pub use manifest::*;
pub use reader::*;

use crate::fsutil::{png_gray16, read_gray_png, write_atomic, write_png};
use crate::render::{self, ply};
use crate::world::dem::MapSource;
use crate::world::World;
use anyhow::{bail, Context};
use image::GrayImage;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Version of the generator; part of `dataset.json`. Bump when outputs change.
pub const GENERATOR_VERSION: &str = "orbfix-generate/2";

/// Names of the four views in dataset order.
pub const VIEW_NAMES: [&str; 4] = ["front", "right", "rear", "left"];

/// SplitMix64-style mixing of a seed and a stream index.
pub fn mix(seed: u64, stream: u64) -> u64 {
    let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(17);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Range image quantum, metres per count (16 bits: up to 1310.7 m).
pub const RANGE_M_PER_UNIT: f64 = 0.02;

/// What a `generate` run did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GenerateReport {
    /// Locations rendered now.
    pub rendered: usize,
    /// Locations found complete and kept (resume).
    pub skipped: usize,
    /// Manifest written.
    pub manifest: PathBuf,
}

fn location_complete(dir: &Path, cfg: &GenerateConfig, row: &ManifestRow) -> bool {
    let (w, h) = (cfg.render.camera.width_px, cfg.render.camera.height_px);
    let views_ok = row
        .views
        .iter()
        .all(|p| read_gray_png(&dir.join(p), Some((w, h))).is_ok());
    let sat_ok = read_gray_png(
        &dir.join(&row.satellite),
        Some((cfg.satellite_px, cfg.satellite_px)),
    )
    .is_ok();
    let range_ok = row.range.as_ref().is_none_or(|r| {
        r.iter().all(|p| {
            image::open(dir.join(p))
                .map(|i| i.width() == w && i.height() == h)
                .unwrap_or(false)
        })
    });
    let ply_ok = row
        .point_cloud
        .as_ref()
        .is_none_or(|p| dir.join(p).is_file());
    let right_ok = row.right.as_ref().is_none_or(|r| {
        r.iter()
            .all(|p| read_gray_png(&dir.join(p), Some((w, h))).is_ok())
    });
    views_ok && sat_ok && range_ok && ply_ok && right_ok
}

/// Renders and writes one location's files (atomically, each file).
pub fn render_location(
    world: &World,
    cfg: &GenerateConfig,
    dir: &Path,
    row: &ManifestRow,
    cache: Option<&render::terrain::TileCache>,
) -> anyhow::Result<()> {
    let mut pose = render::ground_pose(world, row.x_m, row.y_m, row.yaw_deg);
    pose.pitch_deg = row.pitch_deg as f32;
    pose.roll_deg = row.roll_deg as f32;
    let mut opts = cfg.render;
    opts.noise_seed = mix(cfg.seed ^ 0x006E_6F69_7365, row.index as u64);
    let (set, right) = match &cfg.stereo {
        Some(rig) => {
            let s =
                render::stereo::render_stereo_views(world, &pose, row.sun_view, &opts, rig, cache)
                    .with_context(|| format!("rendering stereo pairs of location {}", row.id))?;
            (s.left, Some(s.right))
        }
        None => (
            render::render_views_cached(world, &pose, row.sun_view, &opts, cache)
                .with_context(|| format!("rendering views of location {}", row.id))?,
            None,
        ),
    };
    let sat = match world.dem() {
        // The orbital map of a DEM site: the orthoimage resampled to the crop's grid, by the
        // code `orbfix map --dem` and `orbfix eval --dem` use.
        Some(d) if d.map_source() == MapSource::Ortho => {
            let m = crate::eval::pipeline::map_region(
                world,
                row.x_m,
                row.y_m,
                cfg.satellite_px as usize,
                cfg.satellite_m_per_px,
                row.sun_map,
                &opts,
            )
            .with_context(|| format!("satellite crop of location {}", row.id))?;
            GrayImage::from_raw(m.width as u32, m.height as u32, m.image)
                .context("satellite crop buffer has the wrong size")?
        }
        _ => {
            render::render_satellite_crop_cached(
                world,
                row.x_m,
                row.y_m,
                cfg.satellite_px,
                cfg.satellite_m_per_px,
                row.sun_map,
                &opts,
                cache,
            )
            .with_context(|| format!("rendering satellite crop of location {}", row.id))?
            .0
        }
    };
    if let Some(parent) = dir.join(&row.satellite).parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    for (img, p) in set.views.iter().zip(&row.views) {
        write_png(&dir.join(p), img)?;
    }
    if let (Some(imgs), Some(paths)) = (&right, &row.right) {
        for (img, p) in imgs.iter().zip(paths) {
            write_png(&dir.join(p), img)?;
        }
    }
    if let Some(paths) = &row.range {
        let (w, h) = (cfg.render.camera.width_px, cfg.render.camera.height_px);
        for (r, p) in set.range_m.iter().zip(paths) {
            let q: Vec<u16> = r
                .iter()
                .map(|&m| ((m as f64) / RANGE_M_PER_UNIT).round().clamp(0.0, 65535.0) as u16)
                .collect();
            write_atomic(&dir.join(p), &png_gray16(w, h, &q)?)?;
        }
    }
    if let Some(p) = &row.point_cloud {
        let mut pts = Vec::new();
        for k in 0..4 {
            pts.extend(ply::points_from_range(
                &set.cameras[k],
                &set.range_m[k],
                &set.views[k],
                4,
            ));
        }
        ply::write_ply(&dir.join(p), &pts)?;
    }
    write_png(&dir.join(&row.satellite), &sat)?;
    Ok(())
}

/// Generates (or resumes) a dataset into `dir`; with `shard`, only that shard's locations
/// and its own manifest `manifest-I-of-N.jsonl`. `progress`: show a progress bar.
pub fn generate(
    cfg: &GenerateConfig,
    dir: &Path,
    shard: Option<Shard>,
    progress: bool,
) -> anyhow::Result<GenerateReport> {
    cfg.validate()?;
    // The world first: a bad DEM or orthoimage is reported before anything is written.
    let world = cfg.world()?;
    let info = DatasetInfo::of(cfg, &world)?;
    std::fs::create_dir_all(dir).with_context(|| {
        format!(
            "cannot create output folder {} (check the path and permissions)",
            dir.display()
        )
    })?;
    let info_path = dir.join("dataset.json");
    let info_json = serde_json::to_string_pretty(&info)? + "\n";
    if info_path.exists() {
        let old = std::fs::read_to_string(&info_path)
            .with_context(|| format!("cannot read {}", info_path.display()))?;
        let old_v: serde_json::Value = serde_json::from_str(&old).with_context(|| {
            format!(
                "{} is corrupt; delete the folder or choose another --out",
                info_path.display()
            )
        })?;
        let new_v: serde_json::Value = serde_json::from_str(&info_json)?;
        if old_v != new_v {
            bail!(
                "{} holds a dataset made with other options or another generator version (seed, preset, size, suns, DEM/orthoimage files or `generator_version` in dataset.json differ); use another --out or delete it",
                dir.display()
            );
        }
    } else {
        write_atomic(&info_path, info_json.as_bytes())
            .with_context(|| format!("cannot write into {} (is it writable?)", dir.display()))?;
    }
    let shard = shard.unwrap_or(Shard { index: 0, count: 1 });
    let mine: Vec<usize> = (0..cfg.total()).filter(|i| shard.owns(*i)).collect();
    let rows: Vec<ManifestRow> = mine
        .iter()
        .map(|&i| cfg.location(&world, i))
        .collect::<anyhow::Result<_>>()?;
    let bar = if progress {
        indicatif::ProgressBar::new(rows.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {pos}/{len} locations, {per_sec}, ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    // Far terrain shared between locations (about 64 M nodes, 512 MB at most).
    let cache = render::terrain::TileCache::new(1 << 26);
    let rendered = AtomicUsize::new(0);
    let skipped = AtomicUsize::new(0);
    rows.par_iter().try_for_each(|row| -> anyhow::Result<()> {
        if location_complete(dir, cfg, row) {
            skipped.fetch_add(1, Ordering::Relaxed);
        } else {
            render_location(&world, cfg, dir, row, Some(&cache))?;
            rendered.fetch_add(1, Ordering::Relaxed);
        }
        bar.inc(1);
        Ok(())
    })?;
    bar.finish();
    let name = if shard.count == 1 {
        "manifest.jsonl".to_string()
    } else {
        shard.manifest_name()
    };
    let manifest = dir.join(name);
    write_atomic(&manifest, manifest_text(&rows)?.as_bytes())?;
    Ok(GenerateReport {
        rendered: rendered.into_inner(),
        skipped: skipped.into_inner(),
        manifest,
    })
}
