//! Reading a dataset back ([`Dataset::open`]): what training and evaluation use.

use super::manifest::{read_info, read_manifest};
use super::{DatasetInfo, ManifestRow};
use crate::fsutil::read_gray_png;
use crate::world::zones::Split;
use anyhow::{ensure, Context};
use image::GrayImage;
use std::path::{Path, PathBuf};

/// A dataset on disk.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// Its folder.
    pub dir: PathBuf,
    /// `dataset.json`.
    pub info: DatasetInfo,
    /// `manifest.jsonl`, sorted by id.
    pub rows: Vec<ManifestRow>,
}

impl Dataset {
    /// Opens `dir`: reads `dataset.json` and `manifest.jsonl` (clear errors if missing or
    /// corrupt). Images are loaded on demand.
    pub fn open(dir: impl AsRef<Path>) -> anyhow::Result<Self> {
        let dir = dir.as_ref().to_path_buf();
        let info = read_info(&dir)?;
        let mp = dir.join("manifest.jsonl");
        ensure!(
            mp.exists(),
            "{} has no manifest.jsonl: the run is unfinished (run `orbfix generate` again to resume) or sharded (run `orbfix generate --combine --out {}`)",
            dir.display(),
            dir.display()
        );
        let rows = read_manifest(&mp)?;
        Ok(Self { dir, info, rows })
    }

    /// Rows of one split.
    pub fn split(&self, split: Split) -> impl Iterator<Item = &ManifestRow> {
        self.rows.iter().filter(move |r| r.split == split)
    }

    /// View image size (width, height), pixels.
    pub fn view_size(&self) -> (u32, u32) {
        let c = &self.info.config.render.camera;
        (c.width_px, c.height_px)
    }

    /// The four views of a row (front, right, rear, left), size-checked.
    pub fn load_views(&self, row: &ManifestRow) -> anyhow::Result<[GrayImage; 4]> {
        let s = Some(self.view_size());
        Ok([
            read_gray_png(&self.dir.join(&row.views[0]), s)?,
            read_gray_png(&self.dir.join(&row.views[1]), s)?,
            read_gray_png(&self.dir.join(&row.views[2]), s)?,
            read_gray_png(&self.dir.join(&row.views[3]), s)?,
        ])
    }

    /// The right images of a row's stereo pairs (front, right, rear, left), size-checked;
    /// an error if the dataset has none (generate it with `--stereo`).
    pub fn load_right(&self, row: &ManifestRow) -> anyhow::Result<[GrayImage; 4]> {
        let paths = row.right.as_ref().with_context(|| {
            format!(
                "location {} has no right images: generate the dataset with --stereo",
                row.id
            )
        })?;
        let s = Some(self.view_size());
        Ok([
            read_gray_png(&self.dir.join(&paths[0]), s)?,
            read_gray_png(&self.dir.join(&paths[1]), s)?,
            read_gray_png(&self.dir.join(&paths[2]), s)?,
            read_gray_png(&self.dir.join(&paths[3]), s)?,
        ])
    }

    /// The satellite crop of a row, size-checked.
    pub fn load_satellite(&self, row: &ManifestRow) -> anyhow::Result<GrayImage> {
        let n = self.info.config.satellite_px;
        read_gray_png(&self.dir.join(&row.satellite), Some((n, n)))
    }
}
