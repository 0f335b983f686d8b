//! Real training pairs: rover-side top-down images from the **real** pipeline (the four
//! ground views rendered with [`crate::render::render_views_cached`], reprojected by the
//! flight core's range reprojection, [`crate::eval::pipeline::reproject_views_range`]), and
//! satellite crops from the orthographic renderer the evaluation uses for its maps
//! ([`crate::render::render_satellite_crop_cached`], cast shadows included), both through the
//! core's [`prepare_input`].
//!
//! Per location (deterministic for `(seed, index)`): a uniform point of the zone (80 m
//! inside), heading 0-360 deg; map sun elevation 20-60 deg, any azimuth; view sun: with
//! probability `cross_sun_p` elevation 15-60 deg and azimuth 30-180 deg from the map's
//! (either side), else the map's sun; with probability `missing_view_p` one view missing
//! (its 90 deg sector of the top-down image masked out). Satellite: one 100 m x 100 m crop
//! (400 px at 0.25 m/px) under the map sun, centred on the truth.
//!
//! Windows are cut from the crop when a batch is drawn ([`sample_triplet`], [`Sampling`]):
//! the positive is the 50 m window centred within `pos_radius_m` of the truth (the dense
//! search evaluates windows every 4 m, so the nearest one is at most 2.8 m away), the hard
//! negative one centred `neg_min_m`-`neg_max_m` away in a random direction (the same crater
//! field, the wrong place; nearer offsets drawn more often). Every epoch therefore sees new
//! positives and negatives of the same rendered locations.
//!
//! With `stereo` the views are rendered as stereo pairs and each location also keeps the
//! rover input the fix makes from its **own stereo depth** ([`orbfix::fix::top_down`] with
//! [`orbfix::fix::Depth::Stereo`], the fix's first stage itself): the network then learns
//! the sparser, noisier top-down images of the stereo path as well as the exact-depth ones;
//! a batch draws either with equal probability.
//!
//! The set is cached under `dir` as one file per location (rover input, `i8` 4096; with
//! stereo the stereo rover input, `i8` 4096; satellite crop, `u8` 400 x 400 row-major,
//! north up: 164,096 or 168,192 bytes), written atomically, so building is resumable:
//! existing files of the right size are kept. Locations whose inputs are unusable (flat /
//! too little coverage) are redrawn (up to 8 attempts).

use super::data::{Triplet, Zone};
use crate::eval::pipeline::reproject_views_range;
use crate::render::{self, terrain::TileCache, RenderOptions, Sun};
use crate::world::World;
use anyhow::{ensure, Context, Result};
use orbfix::nn::input::{prepare_input, INPUT_LEN};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Satellite crop side around a location, pixels (100 m at 0.25 m/px).
const CROP_PX: usize = 400;
/// Window side, pixels (50 m at 0.25 m/px).
const WIN_PX: usize = 200;
/// Metres per pixel of both sides.
const M_PER_PX: f64 = 0.25;
/// Largest window offset the crop allows, metres (half the crop minus half a window).
pub const MAX_OFFSET_M: f64 = (CROP_PX - WIN_PX) as f64 / 2.0 * M_PER_PX;
/// Bytes of one cached location: rover input, then the satellite crop.
pub const RECORD_LEN: usize = INPUT_LEN + CROP_PX * CROP_PX;
/// Bytes of one cached location of a stereo set: rover input, stereo rover input, crop.
pub const RECORD_LEN_STEREO: usize = 2 * INPUT_LEN + CROP_PX * CROP_PX;

/// One cached location.
#[derive(Clone, Debug)]
pub struct RealLoc {
    /// Rover side: the prepared top-down input (exact depth).
    pub rover: [i8; INPUT_LEN],
    /// Rover side from the fix's own stereo depth (stereo sets only).
    pub rover_stereo: Option<[i8; INPUT_LEN]>,
    /// Satellite crop centred on the truth, `CROP_PX x CROP_PX` at 0.25 m/px, north up.
    pub crop: Vec<u8>,
}

/// How positives and hard negatives are cut from a location's crop, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sampling {
    /// Largest offset of the positive window's centre from the truth.
    pub pos_radius_m: f64,
    /// Smallest offset of the hard negative's centre.
    pub neg_min_m: f64,
    /// Largest offset of the hard negative's centre (at most [`MAX_OFFSET_M`]).
    pub neg_max_m: f64,
}

impl Default for Sampling {
    fn default() -> Self {
        Self {
            pos_radius_m: 2.5,
            neg_min_m: 5.0,
            neg_max_m: 25.0,
        }
    }
}

impl Sampling {
    /// Checks `0 <= pos_radius < neg_min <= neg_max <= MAX_OFFSET_M`.
    pub fn check(&self) -> Result<()> {
        ensure!(
            self.pos_radius_m >= 0.0
                && self.pos_radius_m < self.neg_min_m
                && self.neg_min_m <= self.neg_max_m
                && self.neg_max_m <= MAX_OFFSET_M,
            "window sampling needs 0 <= positive radius ({}) < negative minimum ({}) <= \
             negative maximum ({}) <= {MAX_OFFSET_M} m",
            self.pos_radius_m,
            self.neg_min_m,
            self.neg_max_m
        );
        Ok(())
    }
}

/// Cuts a positive and a hard negative from `loc` (see [`Sampling`]); `None` when a window
/// has no contrast.
pub fn sample_triplet(loc: &RealLoc, s: &Sampling, rng: &mut StdRng) -> Option<Triplet> {
    // Stereo sets: the exact-depth or the stereo rover input, with equal probability.
    let rover = match &loc.rover_stereo {
        Some(st) if rng.random_bool(0.5) => st,
        _ => &loc.rover,
    };
    let jit = s.pos_radius_m * rng.random_range(0.0f64..1.0).sqrt();
    let jang: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    // Nearer negatives more often (quadratic in a uniform draw).
    let u: f64 = rng.random_range(0.0..1.0);
    let dist = s.neg_min_m + (s.neg_max_m - s.neg_min_m) * u * u;
    let ang: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let c = (CROP_PX - WIN_PX) as f64 / 2.0;
    let off = |v: f64| (c + v / M_PER_PX).round().clamp(0.0, 2.0 * c) as usize;
    // East is +column, north is -row.
    let pos = crop(
        &loc.crop,
        CROP_PX,
        off(jit * jang.sin()),
        off(-jit * jang.cos()),
    );
    let neg = crop(
        &loc.crop,
        CROP_PX,
        off(dist * ang.sin()),
        off(-dist * ang.cos()),
    );
    let mut t = Triplet {
        rover: Box::new(*rover),
        positive: Box::new([0; INPUT_LEN]),
        hard_negative: Box::new([0; INPUT_LEN]),
    };
    let ok = prepare_input(&pos, None, WIN_PX, &mut t.positive).is_ok()
        && prepare_input(&neg, None, WIN_PX, &mut t.hard_negative).is_ok();
    ok.then_some(t)
}

/// One triplet per location, deterministic for `seed` (validation and calibration sets);
/// locations whose windows have no contrast are skipped.
pub fn fixed_triplets(set: &[RealLoc], s: &Sampling, seed: u64) -> Vec<Triplet> {
    set.iter()
        .enumerate()
        .filter_map(|(i, loc)| {
            let mut rng =
                StdRng::seed_from_u64(seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            sample_triplet(loc, s, &mut rng)
        })
        .collect()
}

/// How a real set is drawn.
#[derive(Clone, Copy, Debug)]
pub struct RealSpec {
    /// World seed.
    pub world_seed: u64,
    /// Zone (train or validation).
    pub zone: Zone,
    /// Stream seed.
    pub seed: u64,
    /// Probability that the view's sun differs from the map's.
    pub cross_sun_p: f64,
    /// Probability of one missing view.
    pub missing_view_p: f64,
    /// Also keep the rover input of the fix's own stereo depth (stereo pairs rendered).
    pub stereo: bool,
}

fn record_path(dir: &Path, i: usize) -> PathBuf {
    dir.join(format!("loc_{i:06}.bin"))
}

fn crop(img: &[u8], side: usize, c0: usize, r0: usize) -> Vec<u8> {
    let mut out = vec![0u8; WIN_PX * WIN_PX];
    for r in 0..WIN_PX {
        let s = (r0 + r) * side + c0;
        out[r * WIN_PX..(r + 1) * WIN_PX].copy_from_slice(&img[s..s + WIN_PX]);
    }
    out
}

/// Masks out the 90 deg sector (azimuth from the rover, clockwise from north) around the
/// look direction of view `k` (0 front, 1 right, 2 rear, 3 left) of a rover at `heading_deg`.
fn mask_view(mask: &mut [u8], n: usize, heading_deg: f64, k: usize) {
    let half = n as f64 / 2.0;
    let look = heading_deg + 90.0 * k as f64;
    for (i, m) in mask.iter_mut().enumerate() {
        let dx = (i % n) as f64 + 0.5 - half;
        let dy = -((i / n) as f64 + 0.5 - half);
        let az = dx.atan2(dy).to_degrees();
        let d = (az - look).rem_euclid(360.0);
        if !(45.0..315.0).contains(&d) {
            *m = 0;
        }
    }
}

/// Renders location `index` of `spec`; `None` when every attempt was unusable.
pub fn real_location(
    world: &World,
    cache: &TileCache,
    opts: &RenderOptions,
    spec: &RealSpec,
    index: u64,
) -> Result<Option<RealLoc>> {
    for attempt in 0..8u64 {
        let mut rng = StdRng::seed_from_u64(
            spec.seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (attempt << 52),
        );
        let z = spec.zone.inset(80.0);
        let x = rng.random_range(z.x_min_m..z.x_max_m);
        let y = rng.random_range(z.y_min_m..z.y_max_m);
        let heading = rng.random_range(0.0..360.0);
        let map_sun = Sun {
            elevation_deg: rng.random_range(20.0..60.0),
            azimuth_deg: rng.random_range(0.0..360.0),
        };
        let view_sun = if rng.random_bool(spec.cross_sun_p) {
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            Sun {
                elevation_deg: rng.random_range(15.0..60.0),
                azimuth_deg: (map_sun.azimuth_deg + sign * rng.random_range(30.0..180.0))
                    .rem_euclid(360.0),
            }
        } else {
            map_sun
        };
        let missing = rng
            .random_bool(spec.missing_view_p)
            .then(|| rng.random_range(0..4usize));

        let pose = render::ground_pose(world, x, y, heading);
        let (set, rights) = if spec.stereo {
            let s = render::stereo::render_stereo_views(
                world,
                &pose,
                view_sun,
                opts,
                &render::stereo::StereoRender::default(),
                Some(cache),
            )
            .with_context(|| format!("rendering the stereo pairs at ({x:.1}, {y:.1}) m"))?;
            (s.left, Some(s.right))
        } else {
            let s = render::render_views_cached(world, &pose, view_sun, opts, Some(cache))
                .with_context(|| format!("rendering the views at ({x:.1}, {y:.1}) m"))?;
            (s, None)
        };
        let grid = orbfix::reproject::GridSpec::default();
        let mut top = reproject_views_range(
            &set,
            opts,
            &pose,
            &grid,
            &orbfix::reproject::RangeOptions::default(),
            None,
        )?;
        if let Some(k) = missing {
            mask_view(&mut top.mask, top.n, heading, k);
        }
        let stereo_top = match &rights {
            Some(r) => {
                let (img, mut m) = stereo_top_down(&set.views, r, opts, &pose)?;
                if let Some(k) = missing {
                    mask_view(&mut m, grid.n, heading, k);
                }
                Some((img, m))
            }
            None => None,
        };
        let (sat, _) = render::render_satellite_crop_cached(
            world,
            x,
            y,
            CROP_PX as u32,
            M_PER_PX,
            map_sun,
            opts,
            Some(cache),
        )
        .with_context(|| format!("rendering the satellite crop at ({x:.1}, {y:.1}) m"))?;
        let sat = sat.into_raw();
        let mut loc = RealLoc {
            rover: [0; INPUT_LEN],
            rover_stereo: None,
            crop: sat,
        };
        let c = (CROP_PX - WIN_PX) / 2;
        let mut centre = [0i8; INPUT_LEN];
        let mut ok = loc.crop.len() == CROP_PX * CROP_PX
            && prepare_input(&top.image, Some(&top.mask), top.n, &mut loc.rover).is_ok()
            && prepare_input(&crop(&loc.crop, CROP_PX, c, c), None, WIN_PX, &mut centre).is_ok();
        if let Some((img, m)) = &stereo_top {
            let mut st = [0i8; INPUT_LEN];
            ok &= prepare_input(img, Some(m), grid.n, &mut st).is_ok();
            loc.rover_stereo = Some(st);
        }
        if ok {
            return Ok(Some(loc));
        }
    }
    Ok(None)
}

/// The fix's own top-down image and mask from the stereo pairs (`views` left, `rights`
/// right): stage 1 of [`orbfix::fix::run`] alone ([`orbfix::fix::top_down`]) with the
/// default [`FixConfig`](orbfix::fix::FixConfig), the configuration `orbfix eval` runs.
fn stereo_top_down(
    views: &[image::GrayImage; 4],
    rights: &[image::GrayImage; 4],
    opts: &RenderOptions,
    pose: &orbfix::camera::RoverPose,
) -> Result<(Vec<u8>, Vec<u8>)> {
    use orbfix::fix::{top_down, top_down_buffer_sizes, Depth, FixConfig, FixInputs, NoClock};
    use orbfix::image::ImageView;
    let cfg = FixConfig::default();
    fn view(v: &image::GrayImage) -> Result<ImageView<'_>> {
        ImageView::new(v.as_raw(), v.width() as usize, v.height() as usize)
            .map_err(|e| anyhow::anyhow!("bad view image: {e}"))
    }
    let mut frames = [None; 4];
    let mut right = [None; 4];
    for k in 0..4 {
        frames[k] = Some(view(&views[k])?);
        right[k] = Some(view(&rights[k])?);
    }
    let inputs = FixInputs {
        params: opts.camera_params(),
        pose: *pose,
        frames,
        depth: Depth::Stereo(right),
        map_product: &[],
        weights: &[],
    };
    let z = top_down_buffer_sizes(&cfg).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut work = vec![0u32; z.work_words(&inputs.depth)];
    let (mut top, mut mask) = (vec![0u8; z.top], vec![0u8; z.mask]);
    top_down(&inputs, &cfg, &mut work, &mut top, &mut mask, &mut NoClock)
        .map_err(|e| anyhow::anyhow!("the fix's stereo top-down image: {e}"))?;
    Ok((top, mask))
}

/// Builds (or completes) the cached set of `n` locations in `dir`, rayon-parallel; returns
/// how many were rendered now.
pub fn build(dir: &Path, spec: &RealSpec, n: usize, progress: bool) -> Result<usize> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let world = World::new(spec.world_seed);
    let cache = TileCache::new(1 << 24);
    let opts = RenderOptions::default();
    let len = if spec.stereo {
        RECORD_LEN_STEREO
    } else {
        RECORD_LEN
    };
    let todo: Vec<usize> = (0..n)
        .filter(|&i| {
            std::fs::metadata(record_path(dir, i))
                .map(|m| m.len() as usize != len)
                .unwrap_or(true)
        })
        .collect();
    let bar = if progress {
        indicatif::ProgressBar::new(todo.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} real locations (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    todo.par_iter().try_for_each(|&i| -> Result<()> {
        let loc = real_location(&world, &cache, &opts, spec, i as u64)?;
        let mut rec = Vec::with_capacity(len);
        // An unusable location is stored as all zeros (skipped on loading, keeps indices).
        match loc {
            Some(l) => {
                rec.extend(l.rover.iter().map(|&v| v as u8));
                if let Some(st) = &l.rover_stereo {
                    rec.extend(st.iter().map(|&v| v as u8));
                }
                rec.extend_from_slice(&l.crop);
            }
            None => rec.resize(len, 0),
        }
        crate::fsutil::write_atomic(&record_path(dir, i), &rec)?;
        bar.inc(1);
        Ok(())
    })?;
    bar.finish_and_clear();
    Ok(todo.len())
}

/// Loads every cached location of `dir` (`loc_*.bin`, in index order), checking sizes;
/// unusable (all-zero) locations are skipped.
pub fn load(dir: &Path) -> Result<Vec<RealLoc>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| {
            format!(
                "cannot read the real set {} (build it with `orbfix train --real-train N`)",
                dir.display()
            )
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("loc_") && n.ends_with(".bin"))
        })
        .collect();
    paths.sort();
    let mut out = Vec::with_capacity(paths.len());
    for p in paths {
        let b = std::fs::read(&p).with_context(|| format!("reading {}", p.display()))?;
        ensure!(
            b.len() == RECORD_LEN || b.len() == RECORD_LEN_STEREO,
            "{} is {} bytes, expected {RECORD_LEN} (or {RECORD_LEN_STEREO} for a stereo set; \
             truncated, or a set of an older format? delete it and rebuild with \
             `orbfix train --real-train N --build-only`)",
            p.display(),
            b.len()
        );
        let stereo = b.len() == RECORD_LEN_STEREO;
        let crop_at = if stereo { 2 * INPUT_LEN } else { INPUT_LEN };
        let mut loc = RealLoc {
            rover: [0; INPUT_LEN],
            rover_stereo: None,
            crop: b[crop_at..].to_vec(),
        };
        for (d, &s) in loc.rover.iter_mut().zip(&b[..INPUT_LEN]) {
            *d = s as i8;
        }
        if stereo {
            let mut st = [0i8; INPUT_LEN];
            for (d, &s) in st.iter_mut().zip(&b[INPUT_LEN..2 * INPUT_LEN]) {
                *d = s as i8;
            }
            loc.rover_stereo = Some(st);
        }
        if loc.rover.iter().any(|&v| v != 0) {
            out.push(loc);
        }
    }
    Ok(out)
}
