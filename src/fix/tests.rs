//! Tests of the one fix's choices: the acceptance confidence by depth source, the bound of a
//! weak NCC, which refined peak is kept with stereo depth, and settings refused up front.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::*;

#[test]
fn flat_ground_and_stereo_fixes_need_the_stricter_confidence() {
    let cfg = FixConfig::default();
    assert!(cfg.accept_confidence_flat > cfg.accept_confidence);
    assert_eq!(
        accept_threshold(&cfg, &Depth::Flat),
        cfg.accept_confidence_flat
    );
    assert_eq!(
        accept_threshold(&cfg, &Depth::Images([None; 4])),
        cfg.accept_confidence
    );
    assert!(cfg.accept_confidence_stereo > cfg.accept_confidence);
    assert_eq!(
        accept_threshold(&cfg, &Depth::Stereo([None; 4])),
        cfg.accept_confidence_stereo
    );
    // The larger of the two applies on flat ground and with stereo.
    let mut loose = cfg;
    loose.accept_confidence_flat = 0.0;
    loose.accept_confidence_stereo = 0.0;
    assert_eq!(
        accept_threshold(&loose, &Depth::Flat),
        cfg.accept_confidence
    );
    assert_eq!(
        accept_threshold(&loose, &Depth::Stereo([None; 4])),
        cfg.accept_confidence
    );
    // A bad value is a named configuration error.
    for bad in [f32::NAN, -0.1, 1.5, f32::INFINITY] {
        let mut c = cfg;
        c.accept_confidence_flat = bad;
        assert_eq!(
            c.validate(),
            Err(FixError::BadConfig {
                field: "accept_confidence_flat"
            })
        );
        let mut c = cfg;
        c.accept_confidence_stereo = bad;
        assert_eq!(
            c.validate(),
            Err(FixError::BadConfig {
                field: "accept_confidence_stereo"
            })
        );
    }
}

#[test]
fn weak_ncc_states_the_cnn_bound() {
    let cfg = FixConfig::default();
    let (ncc, cnn) = (cfg.bounds.ncc_m, cfg.bounds.cnn_m);
    assert_eq!(error_bound(&cfg, FixPath::Ncc, 0.8), ncc);
    assert_eq!(error_bound(&cfg, FixPath::Ncc, cfg.refine.min_ncc), ncc);
    assert_eq!(error_bound(&cfg, FixPath::Ncc, MIN_NCC_STEREO), cnn);
    assert_eq!(error_bound(&cfg, FixPath::Cnn, 0.9), cnn);
    assert_eq!(error_bound(&cfg, FixPath::None, 0.0), cnn);
}

#[test]
fn stereo_keeps_weaker_ncc() {
    let cfg = FixConfig::default();
    assert_eq!(min_ncc(&cfg, &Depth::Flat), cfg.refine.min_ncc);
    assert_eq!(min_ncc(&cfg, &Depth::Images([None; 4])), cfg.refine.min_ncc);
    assert_eq!(
        min_ncc(&cfg, &Depth::Stereo([None; 4])),
        config::MIN_NCC_STEREO
    );
    assert!(MIN_NCC_STEREO < cfg.refine.min_ncc);
    let mut bad = cfg;
    bad.refine.min_ncc_stereo = f32::NAN;
    assert!(bad.validate().is_err());
}

#[test]
fn only_stereo_depth_keeps_the_cnn_best_within_the_margin() {
    let mut cfg = FixConfig::default();
    cfg.refine.ncc_margin_stereo = 0.05;
    assert!(cfg.validate().is_ok());
    assert_eq!(ncc_margin(&cfg, &Depth::Stereo([None; 4])), 0.05);
    assert_eq!(ncc_margin(&cfg, &Depth::Flat), 0.0);
    assert_eq!(ncc_margin(&cfg, &Depth::Images([None; 4])), 0.0);
    for v in [f32::NAN, -0.01, 1.5, f32::INFINITY] {
        let mut bad = cfg;
        bad.refine.ncc_margin_stereo = v;
        assert!(
            matches!(
                bad.validate(),
                Err(FixError::BadConfig {
                    field: "refine.ncc_margin_stereo"
                })
            ),
            "{v}"
        );
    }
}

#[test]
fn range_options_the_range_stage_refuses_are_refused_up_front() {
    let cfg = FixConfig::default();
    let mut bad = cfg;
    bad.range.fill_min_neighbours = 9;
    assert!(
        matches!(bad.validate(), Err(FixError::BadConfig { field }) if field.starts_with("range ("))
    );
    let mut bad = cfg;
    bad.range.max_depth_m = 0.0;
    assert!(
        matches!(bad.validate(), Err(FixError::BadConfig { field }) if field.starts_with("range.depth_scale_m"))
    );
    let mut bad = cfg;
    bad.range.max_column_stride = 0;
    assert!(bad.validate().is_err());
    let mut ok = cfg;
    ok.range.fill_min_neighbours = 8;
    assert!(ok.validate().is_ok());
}
