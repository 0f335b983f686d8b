//! Tests of the core's fusion filter (`orbfix::fusion`): the innovation gate refuses a
//! confident fix far from the prediction, consistent fixes shrink the covariance and the
//! search radius, refused fixes widen it, the odometry carries the position and the heading
//! bias is learnt, and non-finite inputs are typed errors.

use orbfix::fix::{FixPath, FixReport, FixStatus, ReprojectionSummary};
use orbfix::fusion::*;
use orbfix::reproject::FrameStatus;

fn fix_at(x: f32, y: f32, bound: f32, status: FixStatus) -> FixReport {
    let mut r = FixReport::no_data(
        x,
        y,
        ReprojectionSummary {
            range: true,
            status: [FrameStatus::Ok; 4],
            valid_cells: 40_000,
            stereo: None,
        },
    );
    r.status = status;
    r.error_bound_m = bound;
    r.confidence = 0.9;
    r.path = FixPath::Ncc;
    r
}

fn leg(d: f32, h: f32) -> OdometryLeg {
    OdometryLeg {
        distance_m: d,
        heading_deg: h,
    }
}

/// A filter that has converged on (100, 200) with a few good fixes.
fn converged() -> Fusion {
    let mut f = Fusion::new(FusionConfig::default(), 103.0, 196.0).unwrap();
    for _ in 0..4 {
        let u = f.update(&fix_at(100.0, 200.0, 0.5, FixStatus::Ok)).unwrap();
        assert!(u.accepted(), "{u:?}");
    }
    f
}

#[test]
fn a_confident_fix_20_m_off_is_refused() {
    let mut f = converged();
    let before = f.position();
    assert!(f.sigma_major_m() < 0.5, "{}", f.sigma_major_m());
    f.predict(&leg(30.0, 90.0)).unwrap();
    let pred = f.position();
    assert!((pred.0 - 130.0).abs() < 0.5 && (pred.1 - 200.0).abs() < 0.5);
    let wrong = fix_at(pred.0 + 20.0, pred.1, 0.5, FixStatus::Ok);
    let u = f.update(&wrong).unwrap();
    assert!(!u.accepted());
    assert!(matches!(u.rejected, Some(RejectReason::Gate { mahalanobis2 }) if mahalanobis2 > 13.8));
    assert_eq!(
        f.position(),
        pred,
        "a refused fix must not move the estimate"
    );
    assert_ne!(before, pred);
    assert_eq!(f.rejected_count(), 1);
    assert_eq!(f.rejection_streak(), 1);
}

#[test]
fn a_fix_with_a_bad_status_is_refused_with_its_reason() {
    let mut f = converged();
    for s in [
        FixStatus::Ambiguous,
        FixStatus::NoData,
        FixStatus::OnBorder,
        FixStatus::SelfCheckFailed,
    ] {
        let p = f.position();
        let u = f.update(&fix_at(100.4, 200.0, 0.5, s)).unwrap();
        assert_eq!(u.rejected, Some(RejectReason::Status(s)));
        assert_eq!(f.position(), p);
    }
}

#[test]
fn consistent_fixes_shrink_the_covariance_and_the_search_radius() {
    let mut f = Fusion::new(FusionConfig::default(), 0.0, 0.0).unwrap();
    let r0 = f.search_radius_m();
    let s0 = f.sigma_major_m();
    assert!((s0 - 20.0).abs() < 1e-3);
    assert!(r0 > 60.0, "{r0}");
    let mut last = s0;
    for i in 0..5 {
        // Fixes scattered around (2, -1) within their bound.
        let z = fix_at(
            2.0 + 0.1 * i as f32,
            -1.0 - 0.05 * i as f32,
            0.5,
            FixStatus::Ok,
        );
        assert!(f.update(&z).unwrap().accepted());
        let s = f.sigma_major_m();
        assert!(s < last, "sigma {s} did not shrink from {last}");
        last = s;
    }
    // Five fixes of sigma 0.5/2.45 m: about 0.2/sqrt(5) = 0.09 m.
    assert!(last < 0.12, "{last}");
    let (x, y) = f.position();
    assert!((x - 2.2).abs() < 0.2 && (y + 1.1).abs() < 0.2, "{x} {y}");
    assert_eq!(
        f.search_radius_m(),
        FusionConfig::default().radius_min_m,
        "a tight estimate searches the smallest region"
    );
    assert!(f.search_radius_m() < r0);
}

#[test]
fn refused_fixes_widen_the_search_radius() {
    let cfg = FusionConfig {
        radius_min_m: 1.0,
        ..FusionConfig::default()
    };
    let mut f = Fusion::new(cfg, 0.0, 0.0).unwrap();
    for _ in 0..4 {
        f.update(&fix_at(0.0, 0.0, 0.5, FixStatus::Ok)).unwrap();
    }
    let mut r = f.search_radius_m();
    for k in 1..=4 {
        let u = f.update(&fix_at(40.0, 0.0, 0.5, FixStatus::Ok)).unwrap();
        assert!(!u.accepted());
        let r2 = f.search_radius_m();
        assert!(
            r2 > r,
            "radius {r2} did not widen from {r} after {k} refusals"
        );
        r = r2;
    }
    assert_eq!(f.rejection_streak(), 4);
    // An accepted fix ends the streak.
    assert!(f
        .update(&fix_at(0.1, 0.0, 0.5, FixStatus::Ok))
        .unwrap()
        .accepted());
    assert_eq!(f.rejection_streak(), 0);
}

#[test]
fn odometry_grows_the_uncertainty_and_a_heading_bias_is_learnt() {
    // Truth: the odometry's headings are 2 deg short (true heading = odometry + 2 deg).
    let bias = 2.0f32;
    let cfg = FusionConfig {
        initial_bias_sigma_rad: 0.05,
        ..FusionConfig::default()
    };
    let mut f = Fusion::new(cfg, 0.0, 0.0).unwrap();
    f.update(&fix_at(0.0, 0.0, 0.5, FixStatus::Ok)).unwrap();
    let (mut tx, mut ty) = (0.0f32, 0.0f32);
    let mut drift_without_fix = 0.0;
    for i in 0..12 {
        let h = if i % 2 == 0 { 0.0 } else { 90.0 };
        let d = 40.0;
        let s0 = f.sigma_major_m();
        f.predict(&leg(d, h)).unwrap();
        assert!(f.sigma_major_m() > s0, "prediction must grow the ellipse");
        let th = (h + bias).to_radians();
        tx += d * th.sin();
        ty += d * th.cos();
        let (ex, ey) = f.position();
        drift_without_fix = ((ex - tx).powi(2) + (ey - ty).powi(2)).sqrt();
        assert!(f
            .update(&fix_at(tx, ty, 0.5, FixStatus::Ok))
            .unwrap()
            .accepted());
    }
    assert!(
        (f.heading_bias_deg() - bias).abs() < 0.3,
        "bias {} deg",
        f.heading_bias_deg()
    );
    // With the bias learnt, the last leg's prediction lands close to the truth (2 deg over
    // 40 m would be 1.4 m off).
    assert!(drift_without_fix < 0.5, "{drift_without_fix}");
}

#[test]
fn non_finite_inputs_are_typed_errors() {
    let mut f = converged();
    let before = f.clone();
    assert_eq!(
        f.predict(&leg(f32::NAN, 0.0)),
        Err(FusionError::NonFinite { what: "distance_m" })
    );
    assert_eq!(
        f.predict(&leg(10.0, f32::INFINITY)),
        Err(FusionError::NonFinite {
            what: "heading_deg"
        })
    );
    assert_eq!(
        f.predict(&leg(-1.0, 0.0)),
        Err(FusionError::NonFinite { what: "distance_m" })
    );
    assert_eq!(
        f.update(&fix_at(f32::NAN, 0.0, 0.5, FixStatus::Ok)),
        Err(FusionError::NonFinite { what: "fix x_m" })
    );
    assert_eq!(
        f.update(&fix_at(0.0, 0.0, f32::INFINITY, FixStatus::Ok)),
        Err(FusionError::NonFinite {
            what: "fix error_bound_m"
        })
    );
    assert_eq!(f, before, "a refused input must leave the filter unchanged");
    assert!(Fusion::new(FusionConfig::default(), f32::NAN, 0.0).is_err());
    let cfg = FusionConfig {
        gate_chi2: f32::NAN,
        ..FusionConfig::default()
    };
    assert_eq!(
        Fusion::new(cfg, 0.0, 0.0),
        Err(FusionError::BadConfig { field: "gate_chi2" })
    );
    let msg = FusionError::NonFinite { what: "distance_m" }.to_string();
    assert!(msg.contains("distance_m") && msg.contains("check"), "{msg}");
}
