//! What `orbfix generate` is asked for ([`GenerateConfig`]: presets, ranges, the world or a
//! DEM site) and how it maps to locations.

use super::{mix, ManifestRow, VIEW_NAMES};
use crate::render::{self, RenderOptions, Sun};
use crate::world::dem::MapSource;
use crate::world::zones::{self, Split, Zone};
use crate::world::World;
use anyhow::{ensure, Context};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

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
pub(super) fn round_to(v: f64, decimals: usize) -> f64 {
    format!("{v:.decimals$}").parse().unwrap_or(v)
}
