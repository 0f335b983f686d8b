//! The planned drive ([`plan`]): straight legs and turns through the test zone, and what
//! the drifting odometry and the heading sensor report at each stop.

use super::TraverseOptions;
use crate::eval::pipeline::make_queries;
use crate::render::Sun;
use crate::world::zones;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Odometry model, per unit of `odometry_drift`: scale error (standard deviation, a
/// constant of the drive).
pub(super) const SCALE_PER_DRIFT: f32 = 0.5;
/// Initial heading bias, radians per unit of drift (0.02: 0.8 deg).
pub(super) const BIAS0_PER_DRIFT: f32 = 0.7;
/// Heading bias random walk, radians per square-root metre per unit of drift (0.02: the
/// heading wanders by 1.8 deg over 1 km, which alone drifts by about 2 % of the distance).
pub(super) const BIAS_WALK_PER_DRIFT: f32 = 0.05;
/// Cross- and along-track position random walk, metres per square-root metre per unit of
/// drift.
pub(super) const WALK_PER_DRIFT: f32 = 0.5;

/// One stop of the planned drive with what the rover's sensors said.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct PlannedStop {
    /// Stop number.
    pub stop: usize,
    /// True position `(east, north)`, metres.
    pub truth_m: (f64, f64),
    /// True heading at the stop (that of the leg driven to it), degrees.
    pub heading_deg: f64,
    /// Distance driven from the start, metres.
    pub distance_m: f64,
    /// The leg to this stop as the odometry measured it (none for the first stop).
    pub odometry_leg: Option<(f64, f64)>,
    /// The heading estimate given to the fix, degrees.
    pub heading_estimate_deg: f64,
    /// The comparison's heading estimate (its own sigma), degrees.
    pub compare_heading_deg: Option<f64>,
    /// Suns of the rover views and of the map.
    pub sun_rover: Sun,
    /// Sun of the map.
    pub sun_map: Sun,
}

/// The whole planned drive: the truth, the odometry's legs and the start prior.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Plan {
    /// Start prior (truth plus an error of `start_sigma_m`), metres.
    pub start_prior_m: (f64, f64),
    /// Stops in order.
    pub stops: Vec<PlannedStop>,
}

/// Plans the drive of `o` (deterministic in the seed): legs of `leg_min_m..leg_max_m`
/// with turns of up to 45 deg, turning back towards the zone's centre when a leg would leave
/// the inner test zone (100 m margin); the odometry of each leg (scale error, heading bias
/// with a random walk, position random walk); the heading estimates.
pub fn plan(o: &TraverseOptions) -> anyhow::Result<Plan> {
    o.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed ^ 0x7472_6176_6572_7365);
    let z = zones::zone(zones::Split::Test);
    let margin = 100.0;
    let (x0, x1) = (z.x_min_m + margin, z.x_max_m - margin);
    let (y0, y1) = (z.y_min_m + margin, z.y_max_m - margin);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let normal = |s: f64| Normal::new(0.0, s.max(0.0)).map_err(|e| anyhow::anyhow!("{e}"));
    let unit = normal(1.0)?;
    let f = o.odometry_drift;
    let scale = 1.0 + SCALE_PER_DRIFT as f64 * f * unit.sample(&mut rng);
    let mut bias = BIAS0_PER_DRIFT as f64 * f * unit.sample(&mut rng);
    let suns = make_queries(o.seed ^ 0x7375_6e73, o.stops, o.condition);
    let mut pos = (
        rng.random_range(x0 + 100.0..x1 - 100.0),
        rng.random_range(y0 + 100.0..y1 - 100.0),
    );
    let mut heading: f64 = rng.random_range(0.0..360.0);
    let start_prior_m = (
        pos.0 + o.start_sigma_m * unit.sample(&mut rng),
        pos.1 + o.start_sigma_m * unit.sample(&mut rng),
    );
    let mut stops = Vec::with_capacity(o.stops);
    let mut distance = 0.0;
    for i in 0..o.stops {
        let mut leg = None;
        if i > 0 {
            let d = rng.random_range(o.leg_min_m..=o.leg_max_m);
            let mut h = heading + rng.random_range(-45.0..45.0);
            let next = |h: f64| {
                let r = h.to_radians();
                (pos.0 + d * r.sin(), pos.1 + d * r.cos())
            };
            let inside = |p: (f64, f64)| p.0 >= x0 && p.0 <= x1 && p.1 >= y0 && p.1 <= y1;
            if !inside(next(h)) {
                h = (cx - pos.0).atan2(cy - pos.1).to_degrees() + rng.random_range(-30.0..30.0);
            }
            let h = h.rem_euclid(360.0);
            // Odometry: true heading = odometry heading + bias.
            let walk = WALK_PER_DRIFT as f64 * f * d.sqrt();
            let along = d * scale + walk * unit.sample(&mut rng);
            let cross = walk * unit.sample(&mut rng);
            let d_odo = (along * along + cross * cross).sqrt();
            let h_odo = h - bias.to_degrees() + cross.atan2(along).to_degrees();
            bias += BIAS_WALK_PER_DRIFT as f64 * f * d.sqrt() * unit.sample(&mut rng);
            pos = next(h);
            heading = h;
            distance += d;
            leg = Some((d_odo, h_odo.rem_euclid(360.0)));
        }
        let est = heading + o.heading_sigma_deg * unit.sample(&mut rng);
        // Drawn whether or not it is used: the comparison does not change the drive.
        let cmp_draw: f64 = unit.sample(&mut rng);
        let cmp = o.compare_heading_sigma_deg.map(|s| heading + s * cmp_draw);
        let q = suns
            .get(i)
            .ok_or_else(|| anyhow::anyhow!("sun of stop {i}"))?;
        stops.push(PlannedStop {
            stop: i,
            truth_m: pos,
            heading_deg: heading,
            distance_m: distance,
            odometry_leg: leg,
            heading_estimate_deg: est.rem_euclid(360.0),
            compare_heading_deg: cmp.map(|c| c.rem_euclid(360.0)),
            sun_rover: q.sun_rover,
            sun_map: q.sun_map,
        });
    }
    Ok(Plan {
        start_prior_m,
        stops,
    })
}
