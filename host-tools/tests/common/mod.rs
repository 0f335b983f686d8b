//! What the fix's integration tests share: one stop rendered from the world.
//!
//! Each test binary that declares `mod common;` compiles this file on its own and uses part
//! of it, hence `dead_code` allowed.
#![allow(dead_code)]

use orbfix_host::eval::pipeline::{
    map_region, observe_raw, Observation, PipelineOptions, Reprojection,
};
use orbfix_host::eval::MapRegion;
use orbfix_host::fix::{build_map_product, MapProductOptions};
use orbfix_host::render::Sun;
use orbfix_host::world::{zones, World};

/// A rendered stop: the rover's observation, the map around its prior and the map product
/// built from that map with the shipped weights. Positions in world metres.
pub struct Stop {
    pub obs: Observation,
    pub map: MapRegion,
    pub product: Vec<u8>,
    pub truth: (f64, f64),
    pub prior: (f64, f64),
}

/// A stop in the test zone of world 4 (heading 63 deg) with a 120 m map (480 px) around a
/// prior 17 m off the truth, observed through `reprojection` (stereo pairs rendered for
/// [`Reprojection::Stereo`]).
pub fn stop(reprojection: Reprojection) -> Stop {
    let z = zones::zone(zones::Split::Test);
    let truth = (z.x_min_m + 300.0, z.y_min_m + 420.0);
    let prior = (truth.0 + 12.0, truth.1 - 12.0);
    let opts = PipelineOptions {
        reprojection,
        map_px: 480,
        ..PipelineOptions::default()
    };
    stop_on(&World::new(4), truth, prior, 63.0, &opts)
}

/// A stop on `world` at `truth` (heading `heading_deg`, default sun) with a map of
/// `opts.map_px` pixels at 0.25 m around `prior`, observed as `opts` says.
pub fn stop_on(
    world: &World,
    truth: (f64, f64),
    prior: (f64, f64),
    heading_deg: f64,
    opts: &PipelineOptions,
) -> Stop {
    let obs = observe_raw(world, truth.0, truth.1, heading_deg, Sun::default(), opts).unwrap();
    let map = map_region(
        world,
        prior.0,
        prior.1,
        opts.map_px,
        0.25,
        Sun::default(),
        &opts.render,
    )
    .unwrap();
    let product = build_map_product(
        &map,
        orbfix::nn::model::SHIPPED_WEIGHTS,
        &MapProductOptions::default(),
    )
    .unwrap();
    Stop {
        obs,
        map,
        product,
        truth,
        prior,
    }
}
