//! The generated evaluation queries: rover stops in a zone with their priors and suns
//! ([`Query`], [`Condition`]), all of them or only those a rover could drive onto.

use super::WHEELBASE_M;
use crate::render::{self, Sun};
use crate::world::{zones, World};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Lighting of an evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Condition {
    /// The study's setting: map and rover under one sun, 30 deg elevation, azimuth 135 deg.
    SameSun,
    /// Map sun: elevation 20-60 deg, azimuth 0-360 deg; rover sun: elevation 20-60 deg,
    /// azimuth 60-180 deg away from the map's (either side), drawn per query.
    CrossSun,
}

impl Condition {
    /// Its name in reports.
    pub fn name(&self) -> &'static str {
        match self {
            Condition::SameSun => "same-sun",
            Condition::CrossSun => "cross-sun",
        }
    }
}

/// One generated query: a rover stop in the test zone and its prior.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Query {
    /// Query number.
    pub id: usize,
    /// True rover east, metres.
    pub x_m: f64,
    /// True rover north, metres.
    pub y_m: f64,
    /// Heading, degrees clockwise from north.
    pub heading_deg: f64,
    /// Prior east (centre of the map region), metres.
    pub prior_x_m: f64,
    /// Prior north, metres.
    pub prior_y_m: f64,
    /// Sun of the rover's views.
    pub sun_rover: Sun,
    /// Sun of the orbital map.
    pub sun_map: Sun,
}

/// Largest prior offset from the truth along each axis, metres (the 441 window centres span
/// +-125 m, so the truth always lies inside the searched region but rarely at its centre).
pub const PRIOR_OFFSET_M: f64 = 100.0;

/// `n` queries of `seed` in the test zone (truth at least 150 m inside the zone).
pub fn make_queries(seed: u64, n: usize, condition: Condition) -> Vec<Query> {
    make_queries_in(&zones::zone(zones::Split::Test), 150.0, seed, n, condition)
}

/// Stops of the query stream drawn for each drivable one, at most: [`drivable_queries`] gives
/// up beyond `n` times this.
pub const DRAWS_PER_DRIVABLE: usize = 20;

/// `n` queries of [`make_queries`]'s stream (`seed`, the test zone) at which a rover standing
/// on the terrain ([`render::terrain_pose`], [`WHEELBASE_M`]) tilts at most `max_tilt_deg`
/// ([`render::tilt_deg`]): terrain it could drive onto. Steeper stops are skipped; the ones
/// kept keep their place in the stream (`id`). Fails when fewer than `n` of the first
/// [`DRAWS_PER_DRIVABLE`] `n` stops qualify.
pub fn drivable_queries(
    world: &World,
    seed: u64,
    n: usize,
    condition: Condition,
    max_tilt_deg: f64,
) -> anyhow::Result<Vec<Query>> {
    let draws = n.saturating_mul(DRAWS_PER_DRIVABLE);
    let kept: Vec<Query> = make_queries(seed, draws, condition)
        .into_iter()
        .filter(|q| {
            let pose =
                render::terrain_pose(world, q.x_m, q.y_m, q.heading_deg, WHEELBASE_M, WHEELBASE_M);
            render::tilt_deg(&pose) <= max_tilt_deg
        })
        .take(n)
        .collect();
    anyhow::ensure!(
        kept.len() == n,
        "only {} of the first {draws} stops of seed {seed} tilt at most {max_tilt_deg} deg; \
         allow a steeper tilt or ask for fewer stops",
        kept.len()
    );
    Ok(kept)
}

/// `n` queries of `seed` with the truth at least `margin` metres inside `z` (e.g. a DEM's
/// [`crate::world::dem::DemTerrain::location_zone`]).
pub fn make_queries_in(
    z: &zones::Zone,
    margin: f64,
    seed: u64,
    n: usize,
    condition: Condition,
) -> Vec<Query> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6c6f_6361_6c69_7a65);
    (0..n)
        .map(|id| {
            let x_m = rng.random_range(z.x_min_m + margin..z.x_max_m - margin);
            let y_m = rng.random_range(z.y_min_m + margin..z.y_max_m - margin);
            let heading_deg = rng.random_range(0.0..360.0);
            let prior_x_m = x_m + rng.random_range(-PRIOR_OFFSET_M..PRIOR_OFFSET_M);
            let prior_y_m = y_m + rng.random_range(-PRIOR_OFFSET_M..PRIOR_OFFSET_M);
            let (sun_rover, sun_map) = match condition {
                Condition::SameSun => (Sun::default(), Sun::default()),
                Condition::CrossSun => {
                    let map_az: f64 = rng.random_range(0.0..360.0);
                    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    let rov_az = (map_az + sign * rng.random_range(60.0..180.0)).rem_euclid(360.0);
                    (
                        Sun {
                            elevation_deg: rng.random_range(20.0..60.0),
                            azimuth_deg: rov_az,
                        },
                        Sun {
                            elevation_deg: rng.random_range(20.0..60.0),
                            azimuth_deg: map_az,
                        },
                    )
                }
            };
            Query {
                id,
                x_m,
                y_m,
                heading_deg,
                prior_x_m,
                prior_y_m,
                sun_rover,
                sun_map,
            }
        })
        .collect()
}
