//! Tests of the stereo scales: which rows are matched at which level, and the groups of
//! disparities each level keeps.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::*;

/// The default rig without the horizon rows (`horizon_grade` 0), whose levels and
/// pairs these tests check (the horizon rows have their own test).
fn flat_rig() -> StereoParams {
    StereoParams {
        horizon_grade: 0.0,
        ..StereoParams::default()
    }
}

#[test]
fn near_rows_go_coarse_only_where_a_quarter_pixel_stays_below_the_limit() {
    let cam = CameraParams::default();
    let p = StereoParams {
        row_factor: 1,
        scale_error_m: 0.125,
        pair_rows_m: 0.0,
        ..flat_rig()
    };
    let s = Scales::new(&cam, &p, &Attitude::level(cam.tilt_deg), |_| true);
    assert!(s.used() >= 2, "the rig uses a coarser level");
    let (a, b) = s.rows_of_level(1);
    assert!(a < b && b == 180 && a % 2 == 0, "{a} {b}");
    // Every working row of level 1 has its quarter-pixel error (level 1) within the
    // limit; the row just above it does not.
    let g1 = s.level(1);
    for y in a..b {
        assert_eq!(s.level_of_row(y), 1);
        let e = g1.quarter_px_depth_error(y >> 1, cam.tilt_deg).unwrap();
        assert!(e <= p.scale_error_m, "{y} {e}");
    }
    let e_above = g1
        .quarter_px_depth_error((a >> 1) - 1, cam.tilt_deg)
        .unwrap();
    assert!(e_above > p.scale_error_m, "{e_above}");
    // Rows above stay at the working size; the first matched row is level 0's.
    assert_eq!(s.level_of_row(a - 1), 0);
    assert_eq!(s.first_active(), s.level(0).first_active());
    // At level 0 a quarter pixel stays within the same limit further out than at
    // level 1 (the far rows keep the finer scale).
    let e0 = s
        .level(0)
        .quarter_px_depth_error(a - 1, cam.tilt_deg)
        .unwrap();
    assert!(e0 < e_above / 1.9, "{e0} {e_above}");
    // Less work than matching every row at the working size.
    let one = Scales::new(
        &cam,
        &StereoParams {
            scale_levels: 0,
            ..p
        },
        &Attitude::level(cam.tilt_deg),
        |_| true,
    );
    assert_eq!(one.used(), 1);
    assert_eq!(one.rows_of_level(1), (180, 180));
    assert!(s.row_work(0, 180) < one.row_work(0, 180) * 3 / 4);
    assert_eq!(one.row_work(0, 180), one.level(0).row_work(0, 180));
}

#[test]
fn the_groups_kept_per_slot_are_each_levels_own() {
    let cam = CameraParams::default();
    for pair_rows_m in [0.0, 0.5] {
        let p = StereoParams {
            pair_rows_m,
            ..flat_rig()
        };
        let s = Scales::new(&cam, &p, &Attitude::level(cam.tilt_deg), |_| true);
        for l in 0..SLOTS + 1 {
            assert_eq!(s.max_groups(l), s.level(l).max_groups(), "slot {l}");
        }
        assert!(s.max_groups(0) > 0);
    }
}

#[test]
fn a_looser_limit_uses_the_coarsest_level_for_the_nearest_rows() {
    let cam = CameraParams::default();
    let p = StereoParams {
        scale_levels: 2,
        scale_error_m: 0.3,
        row_factor: 1,
        pair_rows_m: 0.0,
        ..flat_rig()
    };
    let s = Scales::new(&cam, &p, &Attitude::level(cam.tilt_deg), |_| true);
    assert_eq!(s.used(), 3);
    let (a1, b1) = s.rows_of_level(1);
    let (a2, b2) = s.rows_of_level(2);
    assert!(
        a1 < a2 && a2 < b2 && b2 == 180 && a2 % 4 == 0,
        "{a1} {a2} {b2}"
    );
    assert_eq!(b1, 180);
    assert_eq!(s.level_of_row(a2), 2);
    assert_eq!(s.level_of_row(a2 - 1), 1);
    assert_eq!(s.level_of_row(a1 - 1), 0);
    // A level that cannot be matched is not used, nor any coarser one.
    let t = Scales::new(&cam, &p, &Attitude::level(cam.tilt_deg), |g| {
        g.size().0 >= 160
    });
    assert_eq!(t.used(), 2);
    assert_eq!(t.rows_of_level(2), (180, 180));
}

#[test]
fn reduced_rows_cover_their_working_rows_at_their_own_ground_distance() {
    let cam = CameraParams::default();
    let p = StereoParams {
        row_factor: 2,
        ..flat_rig()
    };
    let s = Scales::new(&cam, &p, &Attitude::level(cam.tilt_deg), |_| true);
    assert_eq!((s.rows_per(0), s.rows_per(1), s.rows_per(2)), (2, 4, 8));
    assert_eq!(s.level(0).size(), (320, 90));
    // Every working row has a level; its level row lies inside that level's image.
    for y in s.first_active()..180 {
        let l = s.level_of_row(y);
        assert!(s.level(l).row(y / s.rows_per(l)).is_some(), "{y}");
    }
    let (a1, _) = s.rows_of_level(1);
    assert!(a1 % 4 == 0 && a1 < 180, "{a1}");
    // The scale takes a coarse row's flat-ground depth to each of its working rows'.
    let t = cam.tilt_deg.to_radians();
    let z = |c: f32| 2.0 / (libm::sinf(t) + (c - 90.0) / 160.0 * libm::cosf(t));
    let one = (1u32 << ROW_SCALE_BITS) as f32;
    let mut checked = 0;
    for l in 0..s.used() {
        let (a, b) = s.rows_of_level(l);
        let a = a.max(s.first_active());
        let m = s.rows_per(l);
        for y in a..b {
            let q = y / m;
            let zq = z((q as f32 + 0.5) * m as f32);
            let zy = z(y as f32 + 0.5);
            if !(zq > 0.0 && zy > 0.0 && zq < 50.0) {
                continue;
            }
            let f = s.row_scale_q15(l, q, y, true) as f32 / one;
            assert!((zq * f / zy - 1.0).abs() < 2e-3, "{l} {y}: {zq} {f} {zy}");
            let g = s.row_scale_q15(l, q, y, false) as f32 / one;
            assert!((f * g - 1.0).abs() < 1e-3, "{f} {g}");
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked}");
    // At the working size (level 0 of a `row_factor` 1 rig) the scale is 1.
    let s1 = Scales::new(
        &cam,
        &StereoParams { row_factor: 1, ..p },
        &Attitude::level(cam.tilt_deg),
        |_| true,
    );
    assert_eq!(s1.row_scale_q15(0, 100, 100, true), 1 << ROW_SCALE_BITS);
}

#[test]
fn near_rows_of_the_working_size_go_in_pairs_where_a_pair_spans_little_ground() {
    let cam = CameraParams::default();
    // Level 1 from a quarter pixel of 0.25 m (the default until 2026-12-07), so the
    // pairs have rows above it.
    let p = StereoParams {
        pair_rows_m: 0.25,
        scale_error_m: 0.25,
        ..flat_rig()
    };
    let s = Scales::new(&cam, &p, &Attitude::level(cam.tilt_deg), |_| true);
    let (a, b) = s.rows_of_level(PAIRED);
    let (a1, _) = s.rows_of_level(1);
    // Pairs from an even row down to the first row of level 1.
    assert!(a < b && b == 180 && a % 2 == 0 && a < a1, "{a} {b} {a1}");
    assert_eq!((s.rows_per(PAIRED), s.col_shift(PAIRED)), (2, 0));
    assert_eq!(s.reduction(PAIRED, 2), (2, 4));
    assert_eq!(s.radius_rows(PAIRED), usize::from(p.pair_radius_rows_px));
    assert_eq!(s.level(PAIRED).size(), (320, 90));
    assert_eq!(s.level(PAIRED).focal_px(), s.level(0).focal_px());
    assert!(s.slots().any(|l| l == PAIRED));
    // Every pair spans at most `pair_rows_m` of flat ground; the pair above more.
    let g = s.level(PAIRED);
    for y in a..a1 {
        assert_eq!(s.level_of_row(y), PAIRED, "{y}");
        let m = g.row_ground_span_m(y / 2, cam.tilt_deg).unwrap();
        assert!(m <= p.pair_rows_m, "{y} {m}");
    }
    let above = g.row_ground_span_m(a / 2 - 1, cam.tilt_deg).unwrap();
    assert!(above > p.pair_rows_m, "{above}");
    assert_eq!(s.level_of_row(a - 1), 0);
    // Two working rows' spans add up to their pair's.
    let (g0, q) = (s.level(0), a / 2 + 3);
    let two = g0.row_ground_span_m(2 * q, cam.tilt_deg).unwrap()
        + g0.row_ground_span_m(2 * q + 1, cam.tilt_deg).unwrap();
    let pair = g.row_ground_span_m(q, cam.tilt_deg).unwrap();
    assert!((two - pair).abs() < 1e-4, "{two} {pair}");
    // Less work than the same rig without pairs; none with `pair_rows_m` 0.
    let none = Scales::new(
        &cam,
        &StereoParams {
            pair_rows_m: 0.0,
            ..p
        },
        &Attitude::level(cam.tilt_deg),
        |_| true,
    );
    assert_eq!(none.rows_of_level(PAIRED), (180, 180));
    assert!(!none.slots().any(|l| l == PAIRED));
    assert!(s.row_work(0, 180) < none.row_work(0, 180) * 9 / 10);
}

#[test]
fn horizon_rows_go_to_level_1_only_when_asked_and_only_there() {
    let cam = CameraParams::default();
    let att = Attitude::level(cam.tilt_deg);
    let p = StereoParams {
        horizon_grade: 0.3,
        horizon_coarse: true,
        ..StereoParams::default()
    };
    let s = Scales::new(&cam, &p, &att, |_| true);
    let single = Scales::new(
        &cam,
        &StereoParams {
            horizon_coarse: false,
            ..p
        },
        &att,
        |_| true,
    );
    let (a, b) = s.rows_of_level(HORIZON);
    assert!(s.slots().any(|l| l == HORIZON));
    assert!(a < b && a % 2 == 0 && b % 2 == 0, "{a} {b}");
    assert_eq!((s.rows_per(HORIZON), s.col_shift(HORIZON)), (2, 1));
    assert_eq!(s.reduction(HORIZON, 2), (4, 4));
    assert_eq!(s.level(HORIZON).size(), s.level(1).size());
    assert_eq!(s.radius_rows(HORIZON), usize::from(p.pair_radius_rows_px));
    // Every row of the slot is a horizon row of level 1's image; the row below is not,
    // and the rows above (if any) see nothing.
    let g = s.level(HORIZON);
    for y in a..b {
        assert_eq!(s.level_of_row(y), HORIZON, "{y}");
        assert!(g.is_horizon_row(y / 2), "{y}");
        // Decided every `column_step`-th column of level 1, depths unscaled.
        assert_eq!(s.column_step(HORIZON, y / 2), usize::from(p.column_step));
        assert_eq!(
            s.row_scale_q15(HORIZON, y / 2, y, true),
            1 << ROW_SCALE_BITS
        );
    }
    assert!(!g.is_horizon_row(b / 2) && g.row(b / 2).is_some(), "{b}");
    assert!(a == 0 || g.row(a / 2 - 1).is_none(), "{a}");
    assert_eq!(s.first_active(), a);
    // Below, the rows are the rig's without the coarse horizon; the horizon rows there
    // are the same working rows.
    for y in b..180 {
        assert_eq!(s.level_of_row(y), single.level_of_row(y), "{y}");
    }
    // (The slot's boundary is the working rows' to within a level row.)
    let s0 = single.level(0);
    for y in 0..180 {
        if y + 1 < a || y > b {
            assert!(!s0.is_horizon_row(y), "{y} {a} {b}");
        } else if (a + 1..b.saturating_sub(1)).contains(&y) {
            assert!(s0.is_horizon_row(y), "{y} {a} {b}");
        }
    }
    // About a quarter of the horizon rows' work (half the columns, rows and
    // disparities, with the same pixel's widening on both sides).
    let (hw, sw) = (s.row_work(0, b), single.row_work(0, b));
    assert!(hw * 10 < sw * 4 && hw * 10 > sw, "{hw} {sw}");
    assert_eq!(s.row_work(b, 180), single.row_work(b, 180));
    // None without the horizon rows, and none unless asked.
    for q in [
        StereoParams {
            horizon_grade: 0.0,
            ..p
        },
        StereoParams {
            horizon_coarse: false,
            ..p
        },
    ] {
        let n = Scales::new(&cam, &q, &att, |_| true);
        assert!(!n.slots().any(|l| l == HORIZON));
        assert_eq!(n.rows_of_level(HORIZON), (180, 180));
        assert!((0..180).all(|y| n.level_of_row(y) != HORIZON));
    }
}
