//! The drive (`orbfix_host::traverse`) and the core's heading search on rendered stops: the
//! plan keeps its legs and zone, the odometry drifts as configured, a short drive fuses its
//! fixes and resumes to the same state, and the heading search recovers a heading error.

use orbfix::fix::{FixConfig, HeadingSearch, MAX_HEADINGS};
use orbfix_host::eval::pipeline::{PipelineOptions, Reprojection};
use orbfix_host::fix::FixRunner;
use orbfix_host::traverse::{plan, summarize, Traverse, TraverseOptions};
use orbfix_host::world::{zones, World};

mod common;
use common::{stop_on, Stop};

#[test]
fn the_plan_keeps_its_legs_and_zone_and_the_odometry_drifts() {
    let o = TraverseOptions {
        seed: 5,
        stops: 200,
        ..TraverseOptions::default()
    };
    let p = plan(&o).unwrap();
    assert_eq!(p.stops.len(), 200);
    let z = zones::zone(zones::Split::Test);
    let mut odo = p.start_prior_m;
    for w in p.stops.windows(2) {
        let (a, b) = (w[0], w[1]);
        let d = (b.truth_m.0 - a.truth_m.0).hypot(b.truth_m.1 - a.truth_m.1);
        assert!(
            (o.leg_min_m - 1e-6..=o.leg_max_m + 1e-6).contains(&d),
            "{d}"
        );
        assert!(z.contains(b.truth_m.0, b.truth_m.1));
        let (dd, h) = b.odometry_leg.unwrap();
        odo = (
            odo.0 + dd * h.to_radians().sin(),
            odo.1 + dd * h.to_radians().cos(),
        );
    }
    let last = p.stops.last().unwrap();
    assert!(last.distance_m > 7000.0, "{}", last.distance_m);
    // Drift since the start, against the configured 2 % of distance.
    let e0 = (
        p.start_prior_m.0 - p.stops[0].truth_m.0,
        p.start_prior_m.1 - p.stops[0].truth_m.1,
    );
    let drift = (odo.0 - last.truth_m.0 - e0.0).hypot(odo.1 - last.truth_m.1 - e0.1);
    let share = drift / last.distance_m;
    assert!(
        (0.001..0.06).contains(&share),
        "odometry drift {share} of the distance"
    );
    // Deterministic in the seed, different across seeds.
    assert_eq!(plan(&o).unwrap().stops[7].truth_m, p.stops[7].truth_m);
    let other = plan(&TraverseOptions {
        seed: 6,
        ..o.clone()
    })
    .unwrap();
    assert_ne!(other.stops[7].truth_m, p.stops[7].truth_m);
    assert!(plan(&TraverseOptions {
        odometry_drift: f64::NAN,
        ..o
    })
    .is_err());
}

#[test]
fn a_short_drive_fuses_its_fixes_and_resumes_to_the_same_state() {
    let o = TraverseOptions {
        seed: 3,
        stops: 3,
        ..TraverseOptions::default()
    };
    let weights = orbfix::nn::model::SHIPPED_WEIGHTS.to_vec();
    let mut t = Traverse::new(
        o.clone(),
        weights.clone(),
        FixConfig::default(),
        Reprojection::Range,
    )
    .unwrap();
    while t.records.len() < o.stops {
        t.step().unwrap();
    }
    let s = summarize(&t.records);
    assert_eq!(s.stops, 3);
    assert!(s.accepted >= 1, "{s:?}");
    assert_eq!(s.accepted_over_5m, 0, "{s:?}");
    // The start prior is about 10 m off; after an accepted fix the fused estimate is within
    // a metre, and it never is worse than the odometry alone at the last stop.
    let r0 = &t.records[0];
    assert!(r0.prior_error_m > 1.0, "{}", r0.prior_error_m);
    let last = t.records.last().unwrap();
    assert!(last.fused_error_m < 1.0, "{:?}", t.records);
    assert!(last.fused_error_m < last.odometry_error_m);
    // The first stop searches wide, later ones narrow once the fix is in.
    assert!(t.records[0].search_radius_m > last.search_radius_m);
    // Resuming from the records replays the filter without rendering.
    let mut u = Traverse::new(o, weights, FixConfig::default(), Reprojection::Range).unwrap();
    assert_eq!(u.resume(t.records.clone()).unwrap(), 3);
    assert_eq!(u.fusion().position(), t.fusion().position());
}

#[test]
fn the_heading_search_recovers_a_heading_error() {
    let world = World::new(4);
    let z = zones::zone(zones::Split::Test);
    let truth = (z.x_min_m + 300.0, z.y_min_m + 420.0);
    let heading = 63.0;
    let opts = PipelineOptions {
        map_px: 400,
        ..PipelineOptions::default()
    };
    let prior = (truth.0 + 3.0, truth.1 - 2.0);
    let Stop { obs, product, .. } = stop_on(&world, truth, prior, heading, &opts);
    let mut pose = obs.pose;
    pose.x_m = prior.0 as f32;
    pose.y_m = prior.1 as f32;
    pose.heading_deg = (heading + 3.0) as f32;
    let runner = FixRunner::shipped(FixConfig::default());
    let search = HeadingSearch::new(4, 1.0).unwrap();
    let (hf, _) = runner
        .run_heading_search(
            &obs.params,
            &pose,
            obs.frames().unwrap(),
            obs.depths.as_ref(),
            &product,
            &search,
        )
        .unwrap();
    assert_eq!(hf.tried, 9);
    assert_eq!(hf.scores.len(), 9);
    let herr = hf.heading_deg as f64 - heading;
    assert!(
        herr.abs() <= 1.0,
        "heading error after the search {herr} deg"
    );
    let err = (hf.report.x_m as f64 - truth.0).hypot(hf.report.y_m as f64 - truth.1);
    assert!(err < 0.5, "fix error {err} m");
    // The cost is counted: nine fixes' work.
    let one = runner
        .run(
            &obs.params,
            &pose,
            obs.frames().unwrap(),
            obs.depths.as_ref(),
            &product,
        )
        .unwrap();
    assert_eq!(hf.report.ops.embed_macs, 9 * one.report.ops.embed_macs);
    // Settings are checked.
    assert!(HeadingSearch::new(MAX_HEADINGS, 1.0).is_err());
    assert!(HeadingSearch::new(1, f32::NAN).is_err());
    assert!(HeadingSearch::for_sigma(0.5, 1.0, 1.0).unwrap().is_none());
    assert_eq!(
        HeadingSearch::for_sigma(2.0, 1.0, 1.0)
            .unwrap()
            .unwrap()
            .count(),
        9
    );
}
