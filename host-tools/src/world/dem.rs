//! A terrain backed by a real DEM and orthoimage (GeoTIFF) instead of the procedural
//! generator: [`World::from_geotiff`]. The renderer, the pipeline and everything else that
//! takes a [`World`] then draw that terrain.
//!
//! - Heights: bilinear between the DEM's pixel centres, clamped to the edge pixels outside
//!   the DEM (a flat continuation); no-data pixels take the mean valid height.
//! - Albedo: the orthoimage's gray levels linearized with the renderer's display gamma
//!   (`(g / 255)^2.2`) and scaled so that their mean is the procedural world's mean albedo
//!   (0.12), so the renderer's fixed exposure suits any product. A shaded orthoimage keeps
//!   its own shading (the rover's renders add their sun on top). Footprint-filtered albedo
//!   (mesh rings, orthographic pixels) is trilinear in a 2 x 2 box-filtered mip pyramid.
//!   Outside the orthoimage and on its no-data pixels the albedo is 0 (renders black).
//! - Frame: world `(x, y)` = CRS `(easting, northing)` minus [`DemTerrain::crs_offset_m`],
//!   which is `(0, 0)` when the rasters lie within 100 km of the CRS origin (orbfix's own
//!   exports round-trip unchanged) and otherwise the DEM's south-west corner rounded down to
//!   whole kilometres, so that the core's `f32` georeferences stay centimetre-exact.
//! - Orbital map: by default ([`MapSource::Ortho`]) map regions of a DEM world
//!   ([`crate::eval::pipeline::map_region`], so `orbfix map`, `orbfix eval` and the fix's map
//!   products) are the orthoimage itself, resampled to the map's grid
//!   ([`DemTerrain::ortho_map`]): the product a mission has; [`MapSource::Render`] renders the
//!   DEM with the orthoimage as albedo under the map's sun instead.

use super::zones::Zone;
use super::{HeightGrid, World, WorldConfig, MAX_GRID_PIXELS};
use crate::geotiff::{read_geotiff, Crs, GeoRaster, Georeference};
use anyhow::Context;
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Coordinates beyond this (metres) get a local offset (see the module docs).
const LOCAL_LIMIT_M: f64 = 100_000.0;

/// Display gamma used to linearize the orthoimage (the renderer's default).
const ORTHO_GAMMA: f64 = 2.2;

/// Where the orbital map of a DEM world comes from (see the module docs).
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum MapSource {
    /// The orthoimage's gray levels resampled to the map grid (no sun, no re-rendering).
    #[default]
    Ortho,
    /// The DEM rendered with the orthoimage as albedo under the map's sun.
    Render,
}

/// A north-up raster of `f32` in world coordinates (metres).
#[derive(Clone, Debug)]
struct Layer {
    w: usize,
    h: usize,
    /// North-west corner (world frame) and pixel size.
    geo: Georeference,
    v: Vec<f32>,
}

impl Layer {
    /// Bilinear sample at world `(x, y)` between pixel centres, clamped to the edge pixels.
    fn bilinear_clamped(&self, x: f64, y: f64) -> f64 {
        let (c, r) = self.geo.to_pixel(x, y);
        let c = (c - 0.5).clamp(0.0, (self.w - 1) as f64);
        let r = (r - 0.5).clamp(0.0, (self.h - 1) as f64);
        let (c0, r0) = (c.floor() as usize, r.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(self.w - 1), (r0 + 1).min(self.h - 1));
        let (fc, fr) = (c - c0 as f64, r - r0 as f64);
        let at = |c: usize, r: usize| self.v[r * self.w + c] as f64;
        let top = at(c0, r0) + (at(c1, r0) - at(c0, r0)) * fc;
        let bot = at(c0, r1) + (at(c1, r1) - at(c0, r1)) * fc;
        top + (bot - top) * fr
    }

    /// Whether world `(x, y)` lies on the raster.
    fn covers(&self, x: f64, y: f64) -> bool {
        let [w, s, e, n] = self.geo.extent(self.w, self.h);
        x >= w && x < e && y > s && y <= n
    }

    /// The next mip level: 2 x 2 box means (edge pixels average what exists).
    fn halved(&self) -> Layer {
        let (w, h) = (self.w.div_ceil(2), self.h.div_ceil(2));
        let mut v = vec![0f32; w * h];
        v.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
            for (c, out) in row.iter_mut().enumerate() {
                let (mut s, mut n) = (0.0f32, 0.0f32);
                for rr in 2 * r..(2 * r + 2).min(self.h) {
                    for cc in 2 * c..(2 * c + 2).min(self.w) {
                        s += self.v[rr * self.w + cc];
                        n += 1.0;
                    }
                }
                *out = s / n;
            }
        });
        let geo = Georeference::new(
            self.geo.origin_x_m(),
            self.geo.origin_y_m(),
            2.0 * self.geo.m_per_px(),
        )
        .unwrap_or(self.geo);
        Layer { w, h, geo, v }
    }
}

/// A mip pyramid of `base` down to 1 x 1 (level 0 = `base`).
fn pyramid(base: Layer) -> Vec<Layer> {
    let mut levels = vec![base];
    while let Some(last) = levels.last() {
        if last.w == 1 && last.h == 1 {
            break;
        }
        let next = last.halved();
        levels.push(next);
    }
    levels
}

/// Trilinear sample of a pyramid over a `footprint_m` square at world `(x, y)` (a bilinear
/// point sample for footprints up to the base pixel); 0 off the base raster.
fn sample_pyramid(levels: &[Layer], x: f64, y: f64, footprint_m: f64) -> f64 {
    let base = &levels[0];
    if !base.covers(x, y) {
        return 0.0;
    }
    let ratio = footprint_m / base.geo.m_per_px();
    if !(ratio.is_finite() && ratio > 1.0) {
        return base.bilinear_clamped(x, y);
    }
    let lvl = ratio.log2().min((levels.len() - 1) as f64);
    let l0 = lvl.floor() as usize;
    let l1 = (l0 + 1).min(levels.len() - 1);
    let a0 = levels[l0].bilinear_clamped(x, y);
    let a1 = levels[l1].bilinear_clamped(x, y);
    a0 + (a1 - a0) * (lvl - l0 as f64)
}

/// A DEM + orthoimage terrain (see the module docs). Built by [`DemTerrain::from_rasters`]
/// or [`World::from_geotiff`].
#[derive(Clone, Debug)]
pub struct DemTerrain {
    height: Layer,
    /// Albedo mip pyramid, level 0 = the orthoimage's pixels.
    albedo: Vec<Layer>,
    /// The orthoimage's gray levels (0..=255; no-data 0), mip pyramid as `albedo`.
    gray: Vec<Layer>,
    /// Where map regions come from.
    map_source: MapSource,
    /// The region both rasters cover, `[west, south, east, north]`, world metres.
    extent: [f64; 4],
    offset: (f64, f64),
    crs: Crs,
    fill_m: f64,
}

impl DemTerrain {
    /// The terrain of a DEM (heights in metres) and an orthoimage (any supported sample
    /// type; gray levels 0..=255 for u8). Both must be in the same CRS and overlap.
    pub fn from_rasters(dem: &GeoRaster, ortho: &GeoRaster) -> anyhow::Result<Self> {
        anyhow::ensure!(
            dem.crs.same_crs(&ortho.crs),
            "the DEM is in {} but the orthoimage in {}: reproject one onto the other's CRS \
             (gdalwarp -t_srs)",
            dem.crs.describe(),
            ortho.crs.describe()
        );
        let valid: Vec<f32> = dem
            .values
            .iter()
            .copied()
            .filter(|v| !dem.is_nodata(*v))
            .collect();
        anyhow::ensure!(
            !valid.is_empty(),
            "the DEM has no valid height (all pixels are no-data)"
        );
        let fill_m = valid.iter().map(|&v| v as f64).sum::<f64>() / valid.len() as f64;
        let de = dem.georef.extent(dem.width, dem.height);
        let oe = ortho.georef.extent(ortho.width, ortho.height);
        let far = de.iter().any(|v| v.abs() > LOCAL_LIMIT_M);
        let offset = if far {
            (
                (de[0] / 1000.0).floor() * 1000.0,
                (de[1] / 1000.0).floor() * 1000.0,
            )
        } else {
            (0.0, 0.0)
        };
        let local = |g: &Georeference| {
            Georeference::new(
                g.origin_x_m() - offset.0,
                g.origin_y_m() - offset.1,
                g.m_per_px(),
            )
            .map_err(|e| anyhow::anyhow!("{e}"))
        };
        let height = Layer {
            w: dem.width,
            h: dem.height,
            geo: local(&dem.georef)?,
            v: dem
                .values
                .iter()
                .map(|&v| if dem.is_nodata(v) { fill_m as f32 } else { v })
                .collect(),
        };
        // Albedo: linearized gray, scaled to the procedural world's mean albedo.
        let peak = if ortho.kind == crate::geotiff::SampleKind::U8 {
            255.0
        } else {
            ortho
                .values
                .iter()
                .filter(|v| !ortho.is_nodata(**v))
                .fold(0f32, |m, &v| m.max(v)) as f64
        };
        anyhow::ensure!(
            peak > 0.0,
            "the orthoimage is black everywhere: it cannot serve as albedo"
        );
        let lin: Vec<f32> = ortho
            .values
            .iter()
            .map(|&v| {
                if ortho.is_nodata(v) {
                    0.0
                } else {
                    (v.max(0.0) as f64 / peak).powf(ORTHO_GAMMA) as f32
                }
            })
            .collect();
        let mean = lin.iter().map(|&v| v as f64).sum::<f64>() / lin.len() as f64;
        anyhow::ensure!(mean > 0.0, "the orthoimage is black everywhere");
        let k = WorldConfig::default().albedo_mean / mean;
        let base = Layer {
            w: ortho.width,
            h: ortho.height,
            geo: local(&ortho.georef)?,
            v: lin
                .iter()
                .map(|&v| (v as f64 * k).min(1.0) as f32)
                .collect(),
        };
        let gray = pyramid(Layer {
            w: ortho.width,
            h: ortho.height,
            geo: base.geo,
            v: ortho
                .values
                .iter()
                .map(|&v| {
                    if ortho.is_nodata(v) {
                        0.0
                    } else {
                        (v.max(0.0) as f64 / peak * 255.0).min(255.0) as f32
                    }
                })
                .collect(),
        });
        let albedo = pyramid(base);
        let extent = [
            de[0].max(oe[0]) - offset.0,
            de[1].max(oe[1]) - offset.1,
            de[2].min(oe[2]) - offset.0,
            de[3].min(oe[3]) - offset.1,
        ];
        anyhow::ensure!(
            extent[0] < extent[2] && extent[1] < extent[3],
            "the DEM ({de:?}) and the orthoimage ({oe:?}) do not overlap (CRS metres)"
        );
        Ok(Self {
            height,
            albedo,
            gray,
            map_source: MapSource::default(),
            extent,
            offset,
            crs: dem.crs.clone(),
            fill_m,
        })
    }

    /// `[west, south, east, north]` (world metres) of the region both rasters cover.
    pub fn extent_m(&self) -> [f64; 4] {
        self.extent
    }

    /// What to add to world `(x, y)` to get CRS `(easting, northing)`, metres.
    pub fn crs_offset_m(&self) -> (f64, f64) {
        self.offset
    }

    /// The CRS of the rasters.
    pub fn crs(&self) -> &Crs {
        &self.crs
    }

    /// Mean valid height of the DEM (the value of its no-data pixels), metres.
    pub fn fill_height_m(&self) -> f64 {
        self.fill_m
    }

    /// DEM pixel size, metres.
    pub fn dem_m_per_px(&self) -> f64 {
        self.height.geo.m_per_px()
    }

    /// Orthoimage pixel size, metres.
    pub fn ortho_m_per_px(&self) -> f64 {
        self.albedo[0].geo.m_per_px()
    }

    /// The covered region shrunk by `margin_m` on every side, as a zone for drawing rover
    /// locations (`None` when nothing is left). For an evaluation, a margin of
    /// `PRIOR_OFFSET_M + map side / 2` (100 + 150 = 250 m by default) keeps every map
    /// region on the rasters.
    pub fn location_zone(&self, margin_m: f64) -> Option<Zone> {
        let [w, s, e, n] = self.extent;
        let z = Zone {
            name: "dem",
            x_min_m: w + margin_m,
            y_min_m: s + margin_m,
            x_max_m: e - margin_m,
            y_max_m: n - margin_m,
        };
        (z.x_min_m < z.x_max_m && z.y_min_m < z.y_max_m).then_some(z)
    }

    /// Height (bilinear, metres) and albedo (0..1, averaged over a `footprint_m` square;
    /// a bilinear point sample for `footprint_m <= ` the orthoimage pixel) at world `(x, y)`.
    pub fn sample(&self, x: f64, y: f64, footprint_m: f64) -> (f64, f64) {
        if !(x.is_finite() && y.is_finite()) {
            return (self.fill_m, 0.0);
        }
        (
            self.height.bilinear_clamped(x, y),
            self.albedo_at(x, y, footprint_m),
        )
    }

    fn albedo_at(&self, x: f64, y: f64, footprint_m: f64) -> f64 {
        sample_pyramid(&self.albedo, x, y, footprint_m)
    }

    /// Where this terrain's map regions come from.
    pub fn map_source(&self) -> MapSource {
        self.map_source
    }

    /// The orthoimage resampled to a `width x height` map grid whose north-west corner and
    /// pixel size are `geo` (world metres): at each pixel centre the gray level averaged over
    /// the map pixel (trilinear in the gray pyramid; bilinear when the map's pixels are no
    /// larger than the orthoimage's), rounded; 0 off the orthoimage and on its no-data pixels.
    pub fn ortho_map(&self, geo: &orbfix::geo::GeoRef, width: usize, height: usize) -> Vec<u8> {
        let (ox, oy, m) = (
            geo.origin_x_m() as f64,
            geo.origin_y_m() as f64,
            geo.m_per_px() as f64,
        );
        let mut out = vec![0u8; width * height];
        if width == 0 {
            return out;
        }
        out.par_chunks_mut(width).enumerate().for_each(|(r, row)| {
            let y = oy - (r as f64 + 0.5) * m;
            for (c, px) in row.iter_mut().enumerate() {
                let g = sample_pyramid(&self.gray, ox + (c as f64 + 0.5) * m, y, m);
                *px = g.round().clamp(0.0, 255.0) as u8;
            }
        });
        out
    }

    /// Fills `grid`'s heights and albedo at its pixel centres (rows in parallel).
    pub(super) fn fill_grid(&self, grid: &mut HeightGrid, footprint_m: f64) {
        let (ox, oy, m, nx) = (grid.origin_x_m, grid.origin_y_m, grid.m_per_px, grid.nx);
        if nx == 0 || grid.nx * grid.ny > MAX_GRID_PIXELS {
            return;
        }
        grid.height_m
            .par_chunks_mut(nx)
            .zip(grid.albedo.par_chunks_mut(nx))
            .enumerate()
            .for_each(|(r, (hs, als))| {
                let y = oy - (r as f64 + 0.5) * m;
                for (c, (h, a)) in hs.iter_mut().zip(als.iter_mut()).enumerate() {
                    let (hv, av) = self.sample(ox + (c as f64 + 0.5) * m, y, footprint_m);
                    *h = hv as f32;
                    *a = av as f32;
                }
            });
    }
}

impl World {
    /// A world whose terrain is a real DEM and orthoimage (single-band GeoTIFFs in one
    /// projected CRS in metres; `docs/interop.md`) instead of the procedural
    /// generator: heights, albedo, grids and renders all come from the rasters. Crater and
    /// boulder lists are empty; world coordinates are the CRS's minus
    /// [`DemTerrain::crs_offset_m`].
    pub fn from_geotiff(dem_path: &Path, ortho_path: &Path) -> anyhow::Result<World> {
        let dem = read_geotiff(dem_path).context("reading the DEM")?;
        let ortho = read_geotiff(ortho_path).context("reading the orthoimage")?;
        let terrain = DemTerrain::from_rasters(&dem, &ortho).with_context(|| {
            format!(
                "combining {} and {}",
                dem_path.display(),
                ortho_path.display()
            )
        })?;
        Ok(World::with_dem(terrain))
    }

    /// A world drawn from `terrain` (see [`World::from_geotiff`]).
    pub fn with_dem(terrain: DemTerrain) -> World {
        let mut w = World::build(0, WorldConfig::default());
        w.dem = Some(Arc::new(terrain));
        w
    }

    /// Chooses where the map regions of a DEM world come from (no effect on the procedural
    /// world).
    pub fn set_dem_map_source(&mut self, source: MapSource) {
        if let Some(d) = self.dem.as_mut() {
            Arc::make_mut(d).map_source = source;
        }
    }

    /// The DEM terrain of a world made by [`World::from_geotiff`], `None` for the
    /// procedural world.
    pub fn dem(&self) -> Option<&DemTerrain> {
        self.dem.as_deref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geotiff::SampleKind;

    fn raster(w: usize, h: usize, geo: Georeference, v: Vec<f32>, kind: SampleKind) -> GeoRaster {
        GeoRaster {
            width: w,
            height: h,
            values: v,
            kind,
            georef: geo,
            crs: Crs::world(),
            nodata: Some(-9999.0),
        }
    }

    #[test]
    fn heights_bilinear_albedo_normalized() {
        let geo = Georeference::new(100.0, 200.0, 2.0).unwrap();
        // Height = 3 * col + 5 * row (a plane), one no-data pixel.
        let mut hv: Vec<f32> = (0..16)
            .map(|i| (3 * (i % 4) + 5 * (i / 4)) as f32)
            .collect();
        hv[15] = -9999.0;
        let dem = raster(4, 4, geo, hv, SampleKind::F32);
        let ov: Vec<f32> = (0..64)
            .map(|i| if i % 2 == 0 { 200.0 } else { 100.0 })
            .collect();
        let ortho = raster(
            8,
            8,
            Georeference::new(100.0, 200.0, 1.0).unwrap(),
            ov,
            SampleKind::U8,
        );
        let t = DemTerrain::from_rasters(&dem, &ortho).unwrap();
        // Between pixel centres (0,0) at (101, 199) and (1,1) at (103, 197): 1.5 + 2.5.
        let (h, _) = t.sample(102.0, 198.0, 0.0);
        assert!((h - 4.0).abs() < 1e-9, "{h}");
        // Outside: clamped to the edge pixel.
        assert_eq!(t.sample(50.0, 199.0, 0.0).0, 0.0);
        assert_eq!(
            t.fill_height_m(),
            (0..15)
                .map(|i| (3 * (i % 4) + 5 * (i / 4)) as f64)
                .sum::<f64>()
                / 15.0
        );
        // Albedo: mean of the base level is the procedural mean; a wide footprint gives it.
        let mean = t.albedo[0].v.iter().map(|&v| v as f64).sum::<f64>() / 64.0;
        assert!((mean - 0.12).abs() < 1e-6, "{mean}");
        let (_, wide) = t.sample(104.0, 196.0, 2.0);
        assert!((wide - 0.12).abs() < 1e-6, "{wide}");
        let (_, bright) = t.sample(100.5, 199.5, 0.0);
        assert!(bright > 0.15, "{bright}");
        assert_eq!(t.sample(99.0, 199.0, 0.0).1, 0.0);
        assert_eq!(t.extent_m(), [100.0, 192.0, 108.0, 200.0]);
        assert_eq!(t.crs_offset_m(), (0.0, 0.0));
        assert!(t.location_zone(4.0).is_none());
        let z = t.location_zone(1.0).unwrap();
        assert_eq!((z.x_min_m, z.y_max_m), (101.0, 199.0));
    }

    #[test]
    fn world_from_dem_and_far_coordinates() {
        let geo = Georeference::new(500_123.0, 4_200_456.0, 1.0).unwrap();
        let hv: Vec<f32> = (0..100).map(|i| i as f32).collect();
        let dem = raster(10, 10, geo, hv, SampleKind::F32);
        let ortho = raster(10, 10, geo, vec![128.0; 100], SampleKind::U8);
        let t = DemTerrain::from_rasters(&dem, &ortho).unwrap();
        assert_eq!(t.crs_offset_m(), (500_000.0, 4_200_000.0));
        assert_eq!(t.extent_m(), [123.0, 446.0, 133.0, 456.0]);
        let w = World::with_dem(t);
        // Pixel (2, 3)'s centre: local (125.5, 452.5).
        assert_eq!(w.height_m(125.5, 452.5), 32.0);
        let g = w.sample_grid(124.0, 455.0, 1.0, 3, 2);
        assert_eq!(g.height_m, vec![11.0, 12.0, 13.0, 21.0, 22.0, 23.0]);
        assert!(g.albedo.iter().all(|&a| (a - 0.12).abs() < 1e-6));
        assert!(w
            .craters_in(0.0, 0.0, 100.0, 100.0, 1.0)
            .unwrap()
            .is_empty());
        let mut other = ortho.clone();
        other.crs.epsg = Some(32633);
        assert!(DemTerrain::from_rasters(&dem, &other)
            .unwrap_err()
            .to_string()
            .contains("reproject"));
    }

    #[test]
    fn exported_region_round_trips_through_geotiff_files() {
        use crate::geotiff::{write_dem_f32, write_ortho_u8};
        let dir = tempfile::tempdir().unwrap();
        let world = World::new(1);
        let geo = Georeference::new(3000.0, 2016.0, 0.5).unwrap();
        let g = world.sample_grid(3000.0, 2016.0, 0.5, 32, 32);
        let gray: Vec<u8> = g
            .albedo
            .iter()
            .map(|a| (a * 1000.0).min(255.0) as u8)
            .collect();
        let (dp, op) = (dir.path().join("d.tif"), dir.path().join("o.tif"));
        write_dem_f32(&dp, 32, 32, &g.height_m, &geo).unwrap();
        write_ortho_u8(&op, 32, 32, &gray, &geo).unwrap();
        let d = World::from_geotiff(&dp, &op).unwrap();
        assert_eq!(d.dem().unwrap().crs_offset_m(), (0.0, 0.0));
        for (c, r) in [(0, 0), (5, 17), (31, 31)] {
            let (x, y) = g.pixel_centre(c, r);
            assert_eq!(d.height_m(x, y), g.height_m[r * 32 + c] as f64);
            assert_eq!(d.height_m(x, y) as f32, world.height_m(x, y) as f32);
        }
        let pose = crate::render::ground_pose(&d, 3008.0, 2008.0, 0.0);
        assert!((pose.ground_z_m as f64 - d.height_m(3008.0, 2008.0)).abs() < 2.0);
        let dark = gray
            .iter()
            .position(|&v| v == *gray.iter().min().unwrap())
            .unwrap();
        let bright = gray
            .iter()
            .position(|&v| v == *gray.iter().max().unwrap())
            .unwrap();
        let at = |i: usize| {
            let (x, y) = g.pixel_centre(i % 32, i / 32);
            d.albedo(x, y)
        };
        assert!(at(bright) > at(dark));
        assert!(World::from_geotiff(&dp, &dir.path().join("missing.tif")).is_err());
    }
}
