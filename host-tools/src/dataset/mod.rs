//! Datasets of rendered locations: the writer behind `orbfix generate` and the reader
//! ([`Dataset::open`]) that training and evaluation use. Layout and format: `docs/dataset.md`.

use crate::fsutil::{png_gray16, read_gray_png, write_atomic, write_png};
use crate::render::{self, ply, RenderOptions, Sun};
use crate::world::dem::MapSource;
use crate::world::zones::{self, Split, Zone};
use crate::world::World;
use anyhow::{bail, ensure, Context};
use image::GrayImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Version of the generator; part of `dataset.json`. Bump when outputs change.
pub const GENERATOR_VERSION: &str = "orbfix-generate/2";

/// Names of the four views in dataset order.
pub const VIEW_NAMES: [&str; 4] = ["front", "right", "rear", "left"];

/// Size presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// A handful of small locations: seconds, for CI.
    Smoke,
    /// 1,000 locations at 640 x 360.
    Small,
    /// The study: 606,000 locations at 1920 x 1080, splits 93 / 5 / 2 %.
    Paper,
}

/// An inclusive range of degrees drawn uniformly per location (`a == b`: fixed).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DegRange {
    /// Low end, degrees.
    pub min_deg: f64,
    /// High end, degrees.
    pub max_deg: f64,
}

impl DegRange {
    /// A fixed value.
    pub fn fixed(v: f64) -> Self {
        Self {
            min_deg: v,
            max_deg: v,
        }
    }

    /// Parses `A` or `A..B` (degrees).
    pub fn parse(s: &str) -> anyhow::Result<Self> {
        let num = |t: &str| -> anyhow::Result<f64> {
            let v: f64 = t.trim().parse().with_context(|| {
                format!("'{t}' is not a number of degrees (expected A or A..B)")
            })?;
            ensure!(v.is_finite(), "'{t}' is not a finite number of degrees");
            Ok(v)
        };
        let r = match s.split_once("..") {
            Some((a, b)) => Self {
                min_deg: num(a)?,
                max_deg: num(b)?,
            },
            None => Self::fixed(num(s)?),
        };
        ensure!(
            r.min_deg <= r.max_deg,
            "range '{s}' is empty (A must be <= B)"
        );
        Ok(r)
    }

    fn draw(&self, rng: &mut ChaCha8Rng) -> f64 {
        if self.max_deg > self.min_deg {
            rng.random_range(self.min_deg..self.max_deg)
        } else {
            self.min_deg
        }
    }
}

/// Everything that defines a dataset's content.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GenerateConfig {
    /// Size preset it came from.
    pub preset: Preset,
    /// World and sampling seed.
    pub seed: u64,
    /// Zero relief, same albedo.
    pub flat: bool,
    /// Locations per split: train, validation, test.
    pub counts: [usize; 3],
    /// Renderer settings (camera size, photometry, exposure, noise sigma).
    pub render: RenderOptions,
    /// Satellite crop side, pixels.
    pub satellite_px: u32,
    /// Satellite crop resolution, metres per pixel.
    pub satellite_m_per_px: f64,
    /// Sun of the ground views: elevation range.
    pub sun_view_elevation: DegRange,
    /// Sun of the ground views: azimuth range.
    pub sun_view_azimuth: DegRange,
    /// Sun of the satellite crop: elevation range.
    pub sun_map_elevation: DegRange,
    /// Sun of the satellite crop: azimuth range.
    pub sun_map_azimuth: DegRange,
    /// Write a 16-bit range image per view.
    pub range: bool,
    /// Write a PLY point cloud per location (from the range images, every 4th pixel).
    pub point_cloud: bool,
    /// Largest rover pitch and roll, degrees: each drawn uniformly in `[-A, A]` per location
    /// (0: level rover).
    #[serde(default)]
    pub max_attitude_deg: f64,
    /// Stereo pairs: also render each view's right camera (`docs/frames.md`), if set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stereo: Option<render::stereo::StereoRender>,
    /// A real DEM + orthoimage site instead of the procedural world (`--dem`/`--ortho`), if
    /// set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dem: Option<DemSite>,
}

/// Default [`DemSite::margin_m`], metres: a 300 m map around any location stays on the
/// rasters (as the procedural zones' location areas, [`zones::MAP_HALF_EXTENT_M`]).
pub const DEFAULT_DEM_MARGIN_M: f64 = zones::MAP_HALF_EXTENT_M;

/// A dataset's DEM site (`orbfix generate --dem DEM.tif --ortho ORTHO.tif`): the world is
/// [`World::from_geotiff`] (the same terrain `orbfix map --dem` and `orbfix eval --dem`
/// draw), locations are drawn in the rasters' common region shrunk by `margin_m`.
/// The files are identified by their length and CRC-32, so a changed file is another
/// dataset (resuming it is refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DemSite {
    /// The DEM GeoTIFF (absolute path).
    pub dem: PathBuf,
    /// Length of the DEM file, bytes.
    pub dem_bytes: u64,
    /// CRC-32 (IEEE) of the DEM file's bytes.
    pub dem_crc32: u32,
    /// The orthoimage GeoTIFF (absolute path).
    pub ortho: PathBuf,
    /// Length of the orthoimage file, bytes.
    pub ortho_bytes: u64,
    /// CRC-32 (IEEE) of the orthoimage file's bytes.
    pub ortho_crc32: u32,
    /// Where the satellite crops come from: the orthoimage resampled to the crop's grid
    /// (`ortho`, the default) or the DEM rendered under the row's `sun_map` (`render`).
    pub map: MapSource,
    /// Distance of every location from the edges of the rasters' common region, metres.
    pub margin_m: f64,
}

impl DemSite {
    /// Identifies a DEM and orthoimage pair (reads both files; clear errors for missing,
    /// unreadable or non-regular files). The rasters themselves are decoded by
    /// [`DemSite::world`].
    pub fn new(dem: &Path, ortho: &Path, map: MapSource, margin_m: f64) -> anyhow::Result<Self> {
        let id = |p: &Path, what: &str| -> anyhow::Result<(PathBuf, u64, u32)> {
            let meta = std::fs::metadata(p).with_context(|| {
                format!("cannot open the {what} {} (check the path)", p.display())
            })?;
            ensure!(
                meta.is_file(),
                "the {what} {} is not a regular file: give the path of a .tif file",
                p.display()
            );
            let bytes = std::fs::read(p)
                .with_context(|| format!("cannot read the {what} {}", p.display()))?;
            let abs = std::fs::canonicalize(p)
                .with_context(|| format!("cannot resolve the path of {}", p.display()))?;
            Ok((abs, bytes.len() as u64, orbfix::nn::weights::crc32(&bytes)))
        };
        let (dem, dem_bytes, dem_crc32) = id(dem, "DEM")?;
        let (ortho, ortho_bytes, ortho_crc32) = id(ortho, "orthoimage")?;
        Ok(Self {
            dem,
            dem_bytes,
            dem_crc32,
            ortho,
            ortho_bytes,
            ortho_crc32,
            map,
            margin_m,
        })
    }

    /// The site's world: [`World::from_geotiff`] with the map source set, after checking
    /// that the files are still the ones identified.
    pub fn world(&self) -> anyhow::Result<World> {
        for (p, len, crc, what) in [
            (&self.dem, self.dem_bytes, self.dem_crc32, "DEM"),
            (
                &self.ortho,
                self.ortho_bytes,
                self.ortho_crc32,
                "orthoimage",
            ),
        ] {
            let bytes = std::fs::read(p)
                .with_context(|| format!("cannot read the {what} {}", p.display()))?;
            ensure!(
                bytes.len() as u64 == len && orbfix::nn::weights::crc32(&bytes) == crc,
                "the {what} {} changed since the dataset was configured (length or CRC-32 differ)",
                p.display()
            );
        }
        let mut w = World::from_geotiff(&self.dem, &self.ortho)?;
        w.set_dem_map_source(self.map);
        Ok(w)
    }
}

/// What `dataset.json` records about a DEM site's frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DemFrame {
    /// The rasters' CRS, as orbfix describes it.
    pub crs: String,
    /// CRS (easting, northing) = world (x_m, y_m) + this, metres.
    pub crs_offset_m: [f64; 2],
    /// The rasters' common region, world metres: west, south, east, north.
    pub extent_m: [f64; 4],
}

impl GenerateConfig {
    /// The preset's defaults for `seed`.
    pub fn preset(preset: Preset, seed: u64) -> Self {
        let mut render = RenderOptions::default();
        let (w, h, counts, sat_px, sat_m) = match preset {
            Preset::Smoke => (160, 90, [4, 1, 1], 100, 0.5),
            Preset::Small => (640, 360, [930, 50, 20], 200, 0.25),
            Preset::Paper => (1920, 1080, [563_580, 30_300, 12_120], 200, 0.25),
        };
        render.camera.width_px = w;
        render.camera.height_px = h;
        let sun = Sun::default();
        Self {
            preset,
            seed,
            flat: false,
            counts,
            render,
            satellite_px: sat_px,
            satellite_m_per_px: sat_m,
            sun_view_elevation: DegRange::fixed(sun.elevation_deg),
            sun_view_azimuth: DegRange::fixed(sun.azimuth_deg),
            sun_map_elevation: DegRange::fixed(sun.elevation_deg),
            sun_map_azimuth: DegRange::fixed(sun.azimuth_deg),
            max_attitude_deg: 0.0,
            range: false,
            point_cloud: false,
            stereo: None,
            dem: None,
        }
    }

    /// Total locations.
    pub fn total(&self) -> usize {
        self.counts.iter().sum()
    }

    /// Checks every option; errors say what to change.
    pub fn validate(&self) -> anyhow::Result<()> {
        self.render
            .validate()
            .context("bad camera/render options")?;
        ensure!(self.total() > 0, "the dataset has no locations");
        ensure!(
            self.max_attitude_deg.is_finite() && (0.0..=30.0).contains(&self.max_attitude_deg),
            "--max-attitude {} deg must be in [0, 30]",
            self.max_attitude_deg
        );
        ensure!(
            (1..=8192).contains(&self.satellite_px),
            "satellite size {} px must be in 1..=8192",
            self.satellite_px
        );
        ensure!(
            self.satellite_m_per_px.is_finite() && self.satellite_m_per_px > 0.0,
            "satellite resolution {} m/px must be > 0",
            self.satellite_m_per_px
        );
        for (r, name, lo, hi) in [
            (self.sun_view_elevation, "--sun-elevation", 0.0, 90.0),
            (self.sun_map_elevation, "--map-sun-elevation", 0.0, 90.0),
            (self.sun_view_azimuth, "--sun-azimuth", 0.0, 360.0),
            (self.sun_map_azimuth, "--map-sun-azimuth", 0.0, 360.0),
        ] {
            ensure!(
                r.min_deg.is_finite()
                    && r.max_deg.is_finite()
                    && r.min_deg >= lo
                    && r.max_deg <= hi,
                "{name} {}..{} deg is out of range: must lie in [{lo}, {hi}]",
                r.min_deg,
                r.max_deg
            );
        }
        ensure!(
            self.sun_view_azimuth.max_deg < 360.0 || self.sun_view_azimuth.min_deg < 360.0,
            "--sun-azimuth must be below 360"
        );
        if let Some(site) = &self.dem {
            ensure!(
                !self.flat,
                "--flat and --dem exclude each other: a DEM site has its own relief"
            );
            let half_crop = 0.5 * self.satellite_px as f64 * self.satellite_m_per_px;
            ensure!(
                site.margin_m.is_finite() && site.margin_m >= half_crop,
                "--dem-margin {} m must be at least half the satellite crop's side ({half_crop} m), \
                 so that every crop lies on the rasters",
                site.margin_m
            );
        }
        Ok(())
    }

    /// The world the dataset is rendered from: the procedural world of `seed`, or the DEM
    /// site's ([`DemSite::world`]; errors say what is wrong with the files).
    pub fn world(&self) -> anyhow::Result<World> {
        Ok(match &self.dem {
            Some(site) => site.world()?,
            None if self.flat => World::flat(self.seed),
            None => World::new(self.seed),
        })
    }

    /// Where locations of `split` are drawn: the split's zone inset by 150 m on the
    /// procedural world; on a DEM site the rasters' common region inset by
    /// [`DemSite::margin_m`], the same for every split (a DEM site has no zones).
    pub fn location_zone(&self, world: &World, split: Split) -> anyhow::Result<Zone> {
        match world.dem() {
            None => Ok(zones::zone(split).location_area()),
            Some(d) => {
                let margin = self
                    .dem
                    .as_ref()
                    .map_or(DEFAULT_DEM_MARGIN_M, |s| s.margin_m);
                let [w, s, e, n] = d.extent_m();
                d.location_zone(margin).with_context(|| {
                    format!(
                        "the DEM and orthoimage overlap on x {w:.1}..{e:.1}, y {s:.1}..{n:.1} \
                         (world metres), which is not wider than twice --dem-margin {margin} m: \
                         use a larger site or a smaller --dem-margin"
                    )
                })
            }
        }
    }

    /// The split of location `index` (train first, then validation, then test).
    pub fn split_of(&self, index: usize) -> Split {
        if index < self.counts[0] {
            Split::Train
        } else if index < self.counts[0] + self.counts[1] {
            Split::Validation
        } else {
            Split::Test
        }
    }

    /// The manifest row of location `index`: a pure function of the config and `index`.
    pub fn location(&self, world: &World, index: usize) -> anyhow::Result<ManifestRow> {
        let split = self.split_of(index);
        // Inside the zone's location area: the whole 300 m map region stays in the zone
        // (on a DEM site: the margin keeps it on the rasters).
        let z = self.location_zone(world, split)?;
        let mut rng = ChaCha8Rng::seed_from_u64(mix(self.seed, index as u64));
        let x = rng.random_range(z.x_min_m..z.x_max_m);
        let y = rng.random_range(z.y_min_m..z.y_max_m);
        let yaw = rng.random_range(0.0..360.0);
        let az = |r: &DegRange, rng: &mut ChaCha8Rng| round_to(r.draw(rng), 3).rem_euclid(360.0);
        let el = |r: &DegRange, rng: &mut ChaCha8Rng| round_to(r.draw(rng), 3);
        let sun_view = Sun::new(
            el(&self.sun_view_elevation, &mut rng),
            az(&self.sun_view_azimuth, &mut rng),
        )?;
        let sun_map = Sun::new(
            el(&self.sun_map_elevation, &mut rng),
            az(&self.sun_map_azimuth, &mut rng),
        )?;
        // Drawn last, so level datasets keep their rows whatever this option.
        let a = self.max_attitude_deg;
        let att = |rng: &mut ChaCha8Rng| {
            if a > 0.0 {
                round_to(rng.random_range(-a..=a), 3)
            } else {
                0.0
            }
        };
        let pitch = att(&mut rng);
        let roll = att(&mut rng);
        // Round to what the manifest keeps so that a row read back renders the same.
        let x = round_to(x, 3);
        let y = round_to(y, 3);
        let yaw = round_to(yaw, 3);
        let id = format!("{index:07}");
        let dir = format!("locations/{:04}", index / 1000);
        let views = VIEW_NAMES.map(|v| format!("{dir}/{id}_{v}.png"));
        Ok(ManifestRow {
            id: id.clone(),
            index,
            split,
            x_m: x,
            y_m: y,
            ground_z_m: round_to(world.height_m(x, y), 4),
            yaw_deg: yaw,
            pitch_deg: pitch,
            roll_deg: roll,
            sun_view,
            sun_map,
            views,
            satellite: format!("{dir}/{id}_sat.png"),
            range: self
                .range
                .then(|| VIEW_NAMES.map(|v| format!("{dir}/{id}_{v}_range.png"))),
            point_cloud: self.point_cloud.then(|| format!("{dir}/{id}_cloud.ply")),
            right: self
                .stereo
                .is_some()
                .then(|| VIEW_NAMES.map(|v| format!("{dir}/{id}_{v}_right.png"))),
        })
    }
}

/// Rounds to `decimals` places, giving the shortest decimal text in JSON.
fn round_to(v: f64, decimals: usize) -> f64 {
    format!("{v:.decimals$}").parse().unwrap_or(v)
}

/// SplitMix64-style mixing of a seed and a stream index.
pub fn mix(seed: u64, stream: u64) -> u64 {
    let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(17);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

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

/// Range image quantum, metres per count (16 bits: up to 1310.7 m).
pub const RANGE_M_PER_UNIT: f64 = 0.02;

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

fn manifest_text(rows: &[ManifestRow]) -> anyhow::Result<String> {
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

fn read_info(dir: &Path) -> anyhow::Result<DatasetInfo> {
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

fn read_manifest(p: &Path) -> anyhow::Result<Vec<ManifestRow>> {
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
