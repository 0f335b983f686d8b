//! The dataset's index files: `dataset.json` ([`DatasetInfo`]), the rows of
//! `manifest.jsonl` ([`ManifestRow`]), shards and their merge.

use super::{DemFrame, GenerateConfig, GENERATOR_VERSION, RANGE_M_PER_UNIT};
use crate::fsutil::write_atomic;
use crate::render::Sun;
use crate::world::zones::{self, Split};
use crate::world::World;
use anyhow::{ensure, Context};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One location of `manifest.jsonl`. Paths are relative to the dataset folder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ManifestRow {
    /// Zero-padded location number (sorts as text).
    pub id: String,
    /// Location number.
    pub index: usize,
    /// Split (zone) it lies in.
    pub split: Split,
    /// Rover east, metres.
    pub x_m: f64,
    /// Rover north, metres.
    pub y_m: f64,
    /// Terrain elevation under the rover, metres.
    pub ground_z_m: f64,
    /// Heading, degrees clockwise from north.
    pub yaw_deg: f64,
    /// Pitch, degrees, nose up positive (`docs/frames.md`); 0 unless `--max-attitude`.
    #[serde(default)]
    pub pitch_deg: f64,
    /// Roll, degrees, right side down positive; 0 unless `--max-attitude`.
    #[serde(default)]
    pub roll_deg: f64,
    /// Sun of the ground views.
    pub sun_view: Sun,
    /// Sun of the satellite crop.
    pub sun_map: Sun,
    /// The four views: front, right, rear, left (8-bit gray PNG).
    pub views: [String; 4],
    /// Satellite crop centred on the rover (8-bit gray PNG, north-up).
    pub satellite: String,
    /// Range images (16-bit gray PNG, 0.02 m per unit, 0 = sky), if generated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range: Option<[String; 4]>,
    /// Point cloud (binary PLY, world frame), if generated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_cloud: Option<String>,
    /// Right images of the stereo pairs (8-bit gray PNG; the views are the left images), if
    /// generated with `--stereo`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right: Option<[String; 4]>,
}

impl ManifestRow {
    /// The rover's pose at this location: position, ground height, heading and the pitch
    /// and roll it was rendered with (0 unless the dataset was made with `--max-attitude`).
    pub fn pose(&self) -> orbfix::camera::RoverPose {
        orbfix::camera::RoverPose {
            pitch_deg: self.pitch_deg as f32,
            roll_deg: self.roll_deg as f32,
            ..orbfix::camera::RoverPose::level(
                self.x_m as f32,
                self.y_m as f32,
                self.ground_z_m as f32,
                self.yaw_deg as f32,
            )
        }
    }
}

/// `dataset.json`: what made the dataset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetInfo {
    /// [`GENERATOR_VERSION`].
    pub generator_version: String,
    /// World seed.
    pub seed: u64,
    /// The full configuration (camera model, resolutions, suns, ...).
    pub config: GenerateConfig,
    /// Zones of the splits (metres, world frame): name, x_min, y_min, x_max, y_max.
    pub zones: Vec<(String, [f64; 4])>,
    /// Number of locations.
    pub total: usize,
    /// Range image unit, metres per count.
    pub range_m_per_unit: f64,
    /// The DEM site's CRS and frame (datasets made with `--dem`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dem_frame: Option<DemFrame>,
}

impl DatasetInfo {
    /// The info of a config rendered from `world` (`cfg.world()`). On a DEM site `zones`
    /// holds one zone, `dem`: the region locations are drawn in.
    pub fn of(cfg: &GenerateConfig, world: &World) -> anyhow::Result<Self> {
        let zones = match world.dem() {
            None => Split::ALL
                .iter()
                .map(|s| {
                    let z = zones::zone(*s);
                    (
                        z.name.to_string(),
                        [z.x_min_m, z.y_min_m, z.x_max_m, z.y_max_m],
                    )
                })
                .collect(),
            Some(_) => {
                let z = cfg.location_zone(world, Split::Train)?;
                vec![(
                    z.name.to_string(),
                    [z.x_min_m, z.y_min_m, z.x_max_m, z.y_max_m],
                )]
            }
        };
        Ok(Self {
            generator_version: GENERATOR_VERSION.into(),
            seed: cfg.seed,
            config: cfg.clone(),
            zones,
            total: cfg.total(),
            range_m_per_unit: RANGE_M_PER_UNIT,
            dem_frame: world.dem().map(|d| {
                let (ox, oy) = d.crs_offset_m();
                DemFrame {
                    crs: d.crs().describe(),
                    crs_offset_m: [ox, oy],
                    extent_m: d.extent_m(),
                }
            }),
        })
    }
}

/// A shard `index` of `count` (0-based: `index < count`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 0-based.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// Parses `I/N` with `0 <= I < N`.
    pub fn parse(s: &str) -> anyhow::Result<Self> {
        let (a, b) = s
            .split_once('/')
            .with_context(|| format!("shard '{s}' must be I/N, e.g. 0/8"))?;
        let index: usize = a
            .trim()
            .parse()
            .with_context(|| format!("shard index '{a}' is not a whole number"))?;
        let count: usize = b
            .trim()
            .parse()
            .with_context(|| format!("shard count '{b}' is not a whole number"))?;
        ensure!(count > 0, "shard count must be at least 1 (got {s})");
        ensure!(
            index < count,
            "shard {s}: the index is 0-based and must be below the count (0/{count} .. {}/{count})",
            count - 1
        );
        Ok(Self { index, count })
    }

    /// Whether location `i` belongs to this shard (round robin).
    pub fn owns(&self, i: usize) -> bool {
        i % self.count == self.index
    }

    /// This shard's manifest file name.
    pub fn manifest_name(&self) -> String {
        format!("manifest-{}-of-{}.jsonl", self.index, self.count)
    }
}

pub(super) fn manifest_text(rows: &[ManifestRow]) -> anyhow::Result<String> {
    let mut sorted: Vec<&ManifestRow> = rows.iter().collect();
    sorted.sort_by(|a, b| a.id.cmp(&b.id));
    let mut s = String::new();
    for r in sorted {
        s.push_str(&serde_json::to_string(r)?);
        s.push('\n');
    }
    Ok(s)
}

/// Merges the shard manifests `manifest-I-of-N.jsonl` of `dir` into `manifest.jsonl`
/// (sorted by id); fails, naming them, if shards are missing or incomplete.
pub fn combine_shards(dir: &Path) -> anyhow::Result<usize> {
    let info = read_info(dir)?;
    let mut counts = std::collections::BTreeSet::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("cannot list {}", dir.display()))? {
        let name = e?.file_name().to_string_lossy().to_string();
        if let Some(rest) = name
            .strip_prefix("manifest-")
            .and_then(|r| r.strip_suffix(".jsonl"))
        {
            if let Some((_, n)) = rest.split_once("-of-") {
                if let Ok(n) = n.parse::<usize>() {
                    counts.insert(n);
                }
            }
        }
    }
    ensure!(
        !counts.is_empty(),
        "{} has no shard manifests (manifest-I-of-N.jsonl): run the shards with --shard I/N first",
        dir.display()
    );
    ensure!(
        counts.len() == 1,
        "{} holds shard manifests of several shard counts {:?}: remove the stale ones",
        dir.display(),
        counts
    );
    let n = counts.into_iter().next().unwrap_or(1);
    // Rows are copied verbatim (parsed only to check them), so no float is re-printed.
    let mut lines: Vec<(String, String)> = Vec::new();
    let mut missing = Vec::new();
    for i in 0..n {
        let p = dir.join(Shard { index: i, count: n }.manifest_name());
        if !p.exists() {
            missing.push(format!("{i}/{n}"));
            continue;
        }
        let text =
            std::fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
        for (k, l) in text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
        {
            let row: ManifestRow = serde_json::from_str(l).with_context(|| {
                format!(
                    "{} line {}: not a valid manifest row (truncated?)",
                    p.display(),
                    k + 1
                )
            })?;
            lines.push((row.id, l.to_string()));
        }
    }
    ensure!(
        missing.is_empty(),
        "shards not finished yet: {} (run them, then combine again)",
        missing.join(", ")
    );
    lines.sort();
    lines.dedup_by(|a, b| a.0 == b.0);
    ensure!(
        lines.len() == info.total,
        "the shard manifests hold {} locations, the dataset has {}",
        lines.len(),
        info.total
    );
    let mut text = String::new();
    for (_, l) in &lines {
        text.push_str(l);
        text.push('\n');
    }
    write_atomic(&dir.join("manifest.jsonl"), text.as_bytes())?;
    Ok(lines.len())
}

pub(super) fn read_info(dir: &Path) -> anyhow::Result<DatasetInfo> {
    let p = dir.join("dataset.json");
    let s = std::fs::read_to_string(&p).with_context(|| {
        format!(
            "cannot read {} (is {} a dataset made by `orbfix generate`?)",
            p.display(),
            dir.display()
        )
    })?;
    serde_json::from_str(&s)
        .with_context(|| format!("{} is corrupt or from another version", p.display()))
}

pub(super) fn read_manifest(p: &Path) -> anyhow::Result<Vec<ManifestRow>> {
    let s = std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
    s.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(n, l)| {
            serde_json::from_str(l).with_context(|| {
                format!(
                    "{} line {}: not a valid manifest row (truncated?)",
                    p.display(),
                    n + 1
                )
            })
        })
        .collect()
}
