//! The evaluation harness end to end on the built-in world at small sizes, and the host's
//! handling of bad maps.

use orbfix::camera::CameraParams;
use orbfix::localize::LocalizeConfig;
use orbfix_host::eval::pipeline::{Condition, PipelineOptions, Reprojection};
use orbfix_host::eval::run::{run_eval, EvalConfig};
use orbfix_host::eval::{load_map, localize_top_down, matcher_by_name, MapRegion, TopDown};

fn small(reprojection: Reprojection) -> PipelineOptions {
    let mut p = PipelineOptions {
        reprojection,
        map_px: 800,
        ..PipelineOptions::default()
    };
    p.render.camera = CameraParams {
        width_px: 320,
        height_px: 180,
        ..CameraParams::default()
    }
    .into();
    p
}

#[test]
fn eval_runs_the_whole_pipeline_and_reports() {
    let cfg = EvalConfig {
        seed: 3,
        queries: 2,
        condition: Condition::SameSun,
        matchers: vec!["ncc-hp2".into(), "l1".into(), "fix".into()],
        localize: LocalizeConfig::default(),
        stride_px: 50,
        pipeline: small(Reprojection::Range),
        keep_examples: 1,
        flat_world: false,
        weights: orbfix::nn::model::SHIPPED_WEIGHTS.to_vec(),
        max_tilt_deg: None,
    };
    let out = run_eval(&cfg, false).unwrap();
    assert_eq!(out.reports.len(), 3);
    // The fix matcher reports what its users read: acceptance, wrong-but-confident fixes,
    // bound coverage and the exact configuration.
    let f = out.reports[2].fix.as_ref().expect("fix statistics");
    assert!(f.config.contains("FixConfig") && (0.0..=1.0).contains(&f.accepted_share));
    assert!(out.reports[2]
        .per_query
        .iter()
        .all(|q| q.status.is_some() && q.path.is_some()));
    // Each fix lists its candidates, each at its own distance from the truth; the fix's own
    // position is one of them when the refinement took it.
    for q in &out.reports[2].per_query {
        assert!(!q.candidates.is_empty());
        for c in &q.candidates {
            let d = ((c.at_m.0 - q.truth_m.0).powi(2) + (c.at_m.1 - q.truth_m.1).powi(2)).sqrt();
            assert!((c.error_m - d).abs() < 1e-6 && c.score.is_finite());
        }
        if q.path.as_deref() == Some("ncc") {
            assert!(q
                .candidates
                .iter()
                .any(|c| c.refined && (c.error_m - q.error_m).abs() < 1e-3));
        }
    }
    assert!(out.reports[0].fix.is_none() && out.reports[0].per_query[0].candidates.is_empty());
    assert_eq!(out.examples.len(), 1);
    let r = &out.reports[0];
    assert_eq!((r.queries, r.windows_per_query), (2, 13 * 13));
    let v = serde_json::to_value(r).unwrap();
    for k in [
        "matcher",
        "seed",
        "condition",
        "queries",
        "windows_per_query",
        "recall_at",
        "median_error_m",
        "p95_error_m",
        "pairs",
    ] {
        assert!(v.get(k).is_some(), "report lacks {k}");
    }
    for k in ["1", "5", "10"] {
        let x = v["recall_at"][k].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&x));
    }
    assert!(v["pairs"]["auc"].as_f64().is_some() && v["pairs"]["error_rate"].as_f64().is_some());
    // With true-3D reprojection the high-passed NCC fix is sub-metre on this world.
    assert!(
        r.median_error_m < 1.0,
        "median error {} m: {:?}",
        r.median_error_m,
        r.per_query
    );
    // Every query's truth is inside the searched region.
    for q in &r.per_query {
        assert!(q.true_window < 169);
        assert!(
            (q.prior_m.0 - q.truth_m.0).abs() <= 100.0
                && (q.prior_m.1 - q.truth_m.1).abs() <= 100.0
        );
    }
}

#[test]
fn featureless_map_gives_no_confident_fix() {
    let n = 200;
    let mut top = TopDown {
        image: vec![0; n * n],
        mask: vec![255; n * n],
        n,
        m_per_px: 0.25,
    };
    for (i, v) in top.image.iter_mut().enumerate() {
        *v = ((i * 37) % 200 + (i / n) % 50) as u8;
    }
    let geo = orbfix::geo::GeoRef::centred(0.0, 0.0, 600, 600, 0.25).unwrap();
    let flat = MapRegion {
        image: vec![100; 600 * 600],
        width: 600,
        height: 600,
        geo,
    };
    for name in ["ncc", "ncc-hp2", "ncc-dist"] {
        let loc = localize_top_down(
            &matcher_by_name(name).unwrap(),
            &top,
            &flat,
            (0.0, 0.0),
            &LocalizeConfig::default(),
            50,
        )
        .unwrap();
        assert_eq!(loc.fix.confidence, 0.0, "{name}");
    }
}

#[test]
fn bad_maps_are_reported_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("map.png");
    image::GrayImage::from_pixel(40, 30, image::Luma([9]))
        .save(&png)
        .unwrap();
    // No georeference file.
    let e = load_map(&png, &dir.path().join("missing.json")).unwrap_err();
    assert!(format!("{e:#}").contains("orbfix map"), "{e:#}");
    // A JSON without the georeference fields.
    let meta = dir.path().join("map.json");
    std::fs::write(&meta, r#"{"width_px": 40}"#).unwrap();
    let e = load_map(&png, &meta).unwrap_err();
    assert!(format!("{e:#}").contains("origin_x_m"), "{e:#}");
    // Bad resolution.
    std::fs::write(
        &meta,
        r#"{"origin_x_m":0,"origin_y_m":0,"m_per_px":0,"width_px":40,"height_px":30}"#,
    )
    .unwrap();
    assert!(format!("{:#}", load_map(&png, &meta).unwrap_err()).contains("georeference"));
    // Size mismatch.
    std::fs::write(
        &meta,
        r#"{"origin_x_m":0,"origin_y_m":0,"m_per_px":0.25,"width_px":41,"height_px":30}"#,
    )
    .unwrap();
    assert!(format!("{:#}", load_map(&png, &meta).unwrap_err()).contains("41 x 30"));
    // Truncated PNG.
    std::fs::write(
        &meta,
        r#"{"origin_x_m":0,"origin_y_m":0,"m_per_px":0.25,"width_px":40,"height_px":30}"#,
    )
    .unwrap();
    let bytes = std::fs::read(&png).unwrap();
    std::fs::write(&png, &bytes[..bytes.len() / 2]).unwrap();
    assert!(format!("{:#}", load_map(&png, &meta).unwrap_err()).contains("map image"));
    // Unknown matcher and option.
    assert!(matcher_by_name("ncc-zz").is_err());
    assert!(matcher_by_name("ncc-hp-3").is_err());
    assert!(matcher_by_name("ncc-hp2-r20-dist").is_ok());
}

#[test]
fn drivable_stops_skip_the_steep_ones_and_keep_their_place_in_the_stream() {
    use orbfix_host::eval::pipeline::{drivable_queries, make_queries, WHEELBASE_M};
    use orbfix_host::render::{terrain_pose, tilt_deg};
    let world = orbfix_host::world::World::new(5);
    let stream = make_queries(5, 400, Condition::CrossSun);
    let tilt = |q: &orbfix_host::eval::pipeline::Query| {
        tilt_deg(&terrain_pose(
            &world,
            q.x_m,
            q.y_m,
            q.heading_deg,
            WHEELBASE_M,
            WHEELBASE_M,
        ))
    };
    // The test zone has steep stops at rover scale: the filter has something to skip.
    assert!(stream.iter().take(20).any(|q| tilt(q) > 15.0));
    let kept = drivable_queries(&world, 5, 20, Condition::CrossSun, 15.0).unwrap();
    assert_eq!(kept.len(), 20);
    let want: Vec<usize> = stream
        .iter()
        .filter(|q| tilt(q) <= 15.0)
        .take(20)
        .map(|q| q.id)
        .collect();
    assert_eq!(kept.iter().map(|q| q.id).collect::<Vec<_>>(), want);
    for q in &kept {
        // The same stop, sun and prior as in the stream.
        let s = &stream[q.id];
        assert!(
            q.x_m == s.x_m
                && q.prior_x_m == s.prior_x_m
                && q.sun_map.azimuth_deg == s.sun_map.azimuth_deg
        );
    }
    // Too strict a limit for the stops asked: a clear error, not fewer stops.
    let e = drivable_queries(&world, 5, 50, Condition::CrossSun, 0.01).unwrap_err();
    assert!(e.to_string().contains("tilt at most"), "{e}");
}
