//! Training and evaluation pairs generated on the fly from the procedural world.
//!
//! **Proxy** for the rover side (the LUT reprojection of rendered ground views is not wired
//! into training yet): both sides are orthographic renders of the world sampled with
//! `World::sample_grid` (Lambertian shading of the height field times the albedo, no cast
//! shadows):
//! - satellite side: a 50 m window at 0.390625 m/px (128 px) under the map's sun;
//! - rover side: the 200 x 200 top-down grid at 0.25 m/px under the view's sun, with the
//!   reprojection's validity pattern (nothing within 2.1 m of the rover: the cameras, 2 m
//!   high, tilted 15 deg down with a 58.7 deg vertical field, see the ground from ~2.04 m),
//!   resolution falling off with range (3x3 box blur beyond 12.5 m, 5x5 beyond 20 m: the
//!   radial ground footprint of a camera pixel grows as range^2), exposure jitter, sensor
//!   noise, and optionally one missing view (a 90 deg sector around its look direction).
//!
//! Both sides then go through the core's [`orbfix::nn::input::prepare_input`], exactly as
//! on board.

use crate::world::World;
use orbfix::nn::input::{prepare_input, INPUT_LEN};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Side of a window, metres.
pub const WINDOW_M: f64 = 50.0;
/// Satellite window side, pixels (0.390625 m/px).
pub const SAT_SIDE: usize = 128;
/// Rover top-down grid side, pixels (0.25 m/px).
pub const ROVER_SIDE: usize = 200;
/// Radius around the rover the cameras cannot see, metres.
pub const BLIND_RADIUS_M: f64 = 2.1;

/// Sun direction: elevation above the horizon and azimuth clockwise from north (towards
/// the sun), degrees (`docs/frames.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Degrees above the horizon.
    pub elevation_deg: f64,
    /// Degrees clockwise from north.
    pub azimuth_deg: f64,
}

pub use crate::world::zones::Zone;

/// Training zone (`world::zones::TRAIN`, 2 x 2 km).
pub const TRAIN_ZONE: Zone = crate::world::zones::TRAIN;
/// Validation zone (`world::zones::VALIDATION`, disjoint from training).
pub const VAL_ZONE: Zone = crate::world::zones::VALIDATION;
/// Test zone (`world::zones::TEST`, disjoint from both).
pub const TEST_ZONE: Zone = crate::world::zones::TEST;

/// A uniform random point at least `margin` metres inside `zone`.
pub fn sample_in(zone: &Zone, rng: &mut StdRng, margin: f64) -> (f64, f64) {
    let z = zone.inset(margin);
    (
        rng.random_range(z.x_min_m..z.x_max_m),
        rng.random_range(z.y_min_m..z.y_max_m),
    )
}

/// Orthographic render, `side x side` pixels of `m_per_px`, centred on `(cx, cy)`,
/// north-up (`docs/frames.md`), 8-bit.
pub fn render_ortho(
    world: &World,
    cx: f64,
    cy: f64,
    side: usize,
    m_per_px: f64,
    sun: Sun,
) -> Vec<u8> {
    let g = side + 2;
    let half = side as f64 / 2.0;
    // Heights and albedo at pixel centres, with a one-pixel border for the gradient.
    let grid = world.sample_grid(
        cx - (half + 1.0) * m_per_px,
        cy + (half + 1.0) * m_per_px,
        m_per_px,
        g,
        g,
    );
    let h = &grid.height_m;
    let (e, a) = (sun.elevation_deg.to_radians(), sun.azimuth_deg.to_radians());
    let s = [e.cos() * a.sin(), e.cos() * a.cos(), e.sin()];
    let flat = s[2].max(0.05);
    let mut out = vec![0u8; side * side];
    for r in 0..side {
        for c in 0..side {
            let (gr, gc) = (r + 1, c + 1);
            let hx = (h[gr * g + gc + 1] - h[gr * g + gc - 1]) as f64 / (2.0 * m_per_px);
            // North is up (row - 1).
            let hy = (h[(gr - 1) * g + gc] - h[(gr + 1) * g + gc]) as f64 / (2.0 * m_per_px);
            let n = (hx * hx + hy * hy + 1.0).sqrt();
            let shade = ((-hx * s[0] - hy * s[1] + s[2]) / n).max(0.0);
            let albedo = grid.albedo[gr * g + gc] as f64;
            let v = 96.0 * albedo / 0.12 * shade / flat;
            out[r * side + c] = v.clamp(0.0, 255.0) as u8;
        }
    }
    out
}

fn box_blur(img: &[u8], side: usize, radius: usize) -> Vec<u8> {
    let mut out = vec![0u8; img.len()];
    for r in 0..side {
        for c in 0..side {
            let (r0, r1) = (r.saturating_sub(radius), (r + radius).min(side - 1));
            let (c0, c1) = (c.saturating_sub(radius), (c + radius).min(side - 1));
            let mut s = 0u32;
            for rr in r0..=r1 {
                s += img[rr * side + c0..=rr * side + c1]
                    .iter()
                    .map(|&v| v as u32)
                    .sum::<u32>();
            }
            let n = ((r1 - r0 + 1) * (c1 - c0 + 1)) as u32;
            out[r * side + c] = ((s + n / 2) / n) as u8;
        }
    }
    out
}

/// Augmentations of the rover side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoverAug {
    /// Rover heading, degrees clockwise from north.
    pub heading_deg: f64,
    /// Index (0 front, 1 right, 2 rear, 3 left) of a view that is missing.
    pub missing_view: Option<usize>,
    /// Exposure gain.
    pub gain: f64,
    /// Exposure offset, grey levels.
    pub offset: f64,
    /// Sensor noise standard deviation, grey levels.
    pub noise: f64,
}

/// Proxy rover top-down grid (200 x 200 at 0.25 m/px) and validity mask at `(x, y)`.
pub fn rover_proxy(
    world: &World,
    x: f64,
    y: f64,
    sun: Sun,
    aug: &RoverAug,
    rng: &mut StdRng,
) -> (Vec<u8>, Vec<u8>) {
    let side = ROVER_SIDE;
    let mpp = WINDOW_M / side as f64;
    let sharp = render_ortho(world, x, y, side, mpp, sun);
    let b1 = box_blur(&sharp, side, 1);
    let b2 = box_blur(&sharp, side, 2);
    let noise = Normal::new(0.0, aug.noise.max(1e-9)).ok();
    let half = side as f64 / 2.0;
    let mut img = vec![0u8; side * side];
    let mut mask = vec![0u8; side * side];
    for r in 0..side {
        for c in 0..side {
            let dx = (c as f64 + 0.5 - half) * mpp;
            let dy = -(r as f64 + 0.5 - half) * mpp;
            let range = dx.hypot(dy);
            let i = r * side + c;
            let mut valid = range >= BLIND_RADIUS_M;
            if let Some(k) = aug.missing_view {
                let az = dx.atan2(dy).to_degrees();
                let look = aug.heading_deg + 90.0 * k as f64;
                let d = (az - look).rem_euclid(360.0);
                if !(45.0..315.0).contains(&d) {
                    valid = false;
                }
            }
            let v = if range > 20.0 {
                b2[i]
            } else if range > 12.5 {
                b1[i]
            } else {
                sharp[i]
            };
            let n = noise.map(|d| d.sample(rng)).unwrap_or(0.0);
            img[i] = (v as f64 * aug.gain + aug.offset + n).clamp(0.0, 255.0) as u8;
            mask[i] = valid as u8;
        }
    }
    (img, mask)
}

/// Random sun: elevation 15..60 deg, any azimuth.
pub fn random_sun(rng: &mut StdRng) -> Sun {
    Sun {
        elevation_deg: rng.random_range(15.0..60.0),
        azimuth_deg: rng.random_range(0.0..360.0),
    }
}

/// Random rover augmentation (missing view with probability `p_missing`).
pub fn random_aug(rng: &mut StdRng, p_missing: f64) -> RoverAug {
    RoverAug {
        heading_deg: rng.random_range(0.0..360.0),
        missing_view: if rng.random_bool(p_missing) {
            Some(rng.random_range(0..4))
        } else {
            None
        },
        gain: rng.random_range(0.85..1.15),
        offset: rng.random_range(-8.0..8.0),
        noise: rng.random_range(0.5..4.0),
    }
}

/// Network input of a satellite window centred on `(x, y)`; `None` if the window is flat.
pub fn sat_input(world: &World, x: f64, y: f64, sun: Sun) -> Option<[i8; INPUT_LEN]> {
    let img = render_ortho(world, x, y, SAT_SIDE, WINDOW_M / SAT_SIDE as f64, sun);
    let mut out = [0i8; INPUT_LEN];
    prepare_input(&img, None, SAT_SIDE, &mut out).ok()?;
    Some(out)
}

/// Network input of the rover side at `(x, y)`; `None` if unusable (flat / too masked).
pub fn rover_input(
    world: &World,
    x: f64,
    y: f64,
    sun: Sun,
    aug: &RoverAug,
    rng: &mut StdRng,
) -> Option<[i8; INPUT_LEN]> {
    let (img, mask) = rover_proxy(world, x, y, sun, aug, rng);
    let mut out = [0i8; INPUT_LEN];
    prepare_input(&img, Some(&mask), ROVER_SIDE, &mut out).ok()?;
    Some(out)
}

/// One training example: rover input, matching satellite input, a hard negative (satellite
/// window 12.5-25 m away in a random direction: same crater field, wrong place). The inputs
/// are boxed: a `Vec<Triplet>` built from an iterator then keeps no 12 KB items on the stack.
#[derive(Clone, Debug)]
pub struct Triplet {
    /// Rover side.
    pub rover: Box<[i8; INPUT_LEN]>,
    /// Satellite window centred on the rover.
    pub positive: Box<[i8; INPUT_LEN]>,
    /// Satellite window offset from the rover.
    pub hard_negative: Box<[i8; INPUT_LEN]>,
}

/// Deterministic triplet number `index` of stream `seed` in `zone`; `cross_sun_p` is the
/// probability that the rover's sun differs from the map's.
pub fn triplet(
    world: &World,
    zone: &Zone,
    seed: u64,
    index: u64,
    cross_sun_p: f64,
    p_missing: f64,
) -> Triplet {
    let mut attempt = 0u64;
    loop {
        let mut rng =
            StdRng::seed_from_u64(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ attempt << 48);
        attempt += 1;
        let (x, y) = sample_in(zone, &mut rng, 60.0);
        let map_sun = random_sun(&mut rng);
        let view_sun = if rng.random_bool(cross_sun_p) {
            random_sun(&mut rng)
        } else {
            map_sun
        };
        let aug = random_aug(&mut rng, p_missing);
        let dist = rng.random_range(12.5..25.0);
        let ang: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let rover = rover_input(world, x, y, view_sun, &aug, &mut rng);
        let pos = sat_input(world, x, y, map_sun);
        let neg = sat_input(world, x + dist * ang.sin(), y + dist * ang.cos(), map_sun);
        if let (Some(rover), Some(positive), Some(hard_negative)) = (rover, pos, neg) {
            return Triplet {
                rover: Box::new(rover),
                positive: Box::new(positive),
                hard_negative: Box::new(hard_negative),
            };
        }
        if attempt > 16 {
            // The world is flat everywhere we looked: return an all-zero example rather
            // than loop forever (it carries no gradient signal but keeps shapes).
            return Triplet {
                rover: Box::new([0; INPUT_LEN]),
                positive: Box::new([0; INPUT_LEN]),
                hard_negative: Box::new([0; INPUT_LEN]),
            };
        }
    }
}
