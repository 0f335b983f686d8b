//! Real training pairs: rover-side top-down images from the **real** pipeline (the four
//! ground views rendered with [`crate::render::render_views_cached`], reprojected by the
//! flight core's range reprojection, [`crate::eval::pipeline::reproject_views_range`]), and
//! satellite windows from the orthographic renderer the evaluation uses for its maps
//! ([`crate::render::render_satellite_crop_cached`], cast shadows included), both through the
//! core's [`prepare_input`].
//!
//! Per location (deterministic for `(seed, index)`): a uniform point of the zone (80 m
//! inside), heading 0-360 deg; map sun elevation 20-60 deg, any azimuth; view sun: with
//! probability `cross_sun_p` elevation 15-60 deg and azimuth 30-180 deg from the map's
//! (either side), else the map's sun; with probability `missing_view_p` one view missing
//! (its 90 deg sector of the top-down image masked out). Satellite: one 100 m x 100 m crop
//! (400 px at 0.25 m/px) under the map sun, cut into the positive (the 50 m window centred
//! within 6 m of the truth, uniform over that disc: the study's window grid leaves the truth
//! up to 8.8 m from the nearest window's centre, so the embedding must tolerate such offsets)
//! and a hard negative (centred 12.5-25 m from the truth in a random direction: the
//! neighbouring windows).
//!
//! The set is cached under `dir` as one 12,288-byte file per location (rover, positive, hard
//! negative inputs, `i8` each 4096), written atomically, so building is resumable: existing
//! files are kept. Locations whose inputs are unusable (flat / too little coverage) are
//! redrawn (up to 8 attempts).

use super::data::{Triplet, Zone};
use crate::eval::pipeline::reproject_views_range;
use crate::render::{self, terrain::TileCache, RenderOptions, Sun};
use crate::world::World;
use anyhow::{Context, Result};
use orbfix::nn::input::{prepare_input, INPUT_LEN};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Satellite crop side around a location, pixels (100 m at 0.25 m/px).
const CROP_PX: usize = 400;
/// Window side, pixels (50 m at 0.25 m/px).
const WIN_PX: usize = 200;
/// Metres per pixel of both sides.
const M_PER_PX: f64 = 0.25;
/// Largest offset of the positive window's centre from the truth, metres.
pub const POS_JITTER_M: f64 = 6.0;
/// Bytes of one cached location.
pub const RECORD_LEN: usize = 3 * INPUT_LEN;

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
pub fn real_triplet(
    world: &World,
    cache: &TileCache,
    opts: &RenderOptions,
    spec: &RealSpec,
    index: u64,
) -> Result<Option<Triplet>> {
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
        let dist = rng.random_range(12.5..25.0);
        let ang: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let jit = POS_JITTER_M * rng.random_range(0.0f64..1.0).sqrt();
        let jang: f64 = rng.random_range(0.0..std::f64::consts::TAU);

        let pose = render::ground_pose(world, x, y, heading);
        let set = render::render_views_cached(world, &pose, view_sun, opts, Some(cache))
            .with_context(|| format!("rendering the views at ({x:.1}, {y:.1}) m"))?;
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
        let c = (CROP_PX - WIN_PX) / 2;
        let off = |v: f64| (c as f64 + v / M_PER_PX).round() as usize;
        let pos = crop(&sat, CROP_PX, off(jit * jang.sin()), off(-jit * jang.cos()));
        // East is +column, north is -row.
        let neg = crop(&sat, CROP_PX, off(dist * ang.sin()), off(-dist * ang.cos()));
        let mut t = Triplet {
            rover: [0; INPUT_LEN],
            positive: [0; INPUT_LEN],
            hard_negative: [0; INPUT_LEN],
        };
        let ok = prepare_input(&top.image, Some(&top.mask), top.n, &mut t.rover).is_ok()
            && prepare_input(&pos, None, WIN_PX, &mut t.positive).is_ok()
            && prepare_input(&neg, None, WIN_PX, &mut t.hard_negative).is_ok();
        if ok {
            return Ok(Some(t));
        }
    }
    Ok(None)
}

/// Builds (or completes) the cached set of `n` locations in `dir`, rayon-parallel; returns
/// how many were rendered now.
pub fn build(dir: &Path, spec: &RealSpec, n: usize, progress: bool) -> Result<usize> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let world = World::new(spec.world_seed);
    let cache = TileCache::new(1 << 24);
    let opts = RenderOptions::default();
    let todo: Vec<usize> = (0..n)
        .filter(|&i| {
            std::fs::metadata(record_path(dir, i))
                .map(|m| m.len() as usize != RECORD_LEN)
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
        let t = real_triplet(&world, &cache, &opts, spec, i as u64)?;
        let mut rec = Vec::with_capacity(RECORD_LEN);
        // An unusable location is stored as all zeros (no gradient signal, keeps indices).
        let t = t.unwrap_or(Triplet {
            rover: [0; INPUT_LEN],
            positive: [0; INPUT_LEN],
            hard_negative: [0; INPUT_LEN],
        });
        for part in [&t.rover, &t.positive, &t.hard_negative] {
            rec.extend(part.iter().map(|&v| v as u8));
        }
        crate::fsutil::write_atomic(&record_path(dir, i), &rec)?;
        bar.inc(1);
        Ok(())
    })?;
    bar.finish_and_clear();
    Ok(todo.len())
}

/// Loads every cached location of `dir` (`loc_*.bin`, in index order), checking sizes.
pub fn load(dir: &Path) -> Result<Vec<Triplet>> {
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
        anyhow::ensure!(
            b.len() == RECORD_LEN,
            "{} is {} bytes, expected {RECORD_LEN} (truncated? delete it and rebuild)",
            p.display(),
            b.len()
        );
        let mut t = Triplet {
            rover: [0; INPUT_LEN],
            positive: [0; INPUT_LEN],
            hard_negative: [0; INPUT_LEN],
        };
        for (k, dst) in [&mut t.rover, &mut t.positive, &mut t.hard_negative]
            .into_iter()
            .enumerate()
        {
            for (d, &s) in dst.iter_mut().zip(&b[k * INPUT_LEN..(k + 1) * INPUT_LEN]) {
                *d = s as i8;
            }
        }
        if t.rover.iter().any(|&v| v != 0) {
            out.push(t);
        }
    }
    Ok(out)
}
