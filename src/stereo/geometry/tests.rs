//! Tests of the stereo geometry: the rows' disparity ranges hold the flat ground and the
//! relief above it, skip the sky, follow the rover's attitude, and the windows follow the ground.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::*;
use crate::camera::{Camera, RoverPose, View};

/// The default rig without the horizon rows (`horizon_grade` 0): the flat ground's
/// ranges these tests check (the horizon rows have their own test).
fn flat_rig() -> StereoParams {
    StereoParams {
        horizon_grade: 0.0,
        ..StereoParams::default()
    }
}

#[test]
fn flat_ground_inside_each_range_and_sky_skipped() {
    let cam = CameraParams::default();
    // Rows at the working size (`row_factor` 1); `row_factor` 2 below. Relief +0.5 m.
    // Disparities, not residuals (the shear: `windows_follow_the_flat_ground`).
    let p = StereoParams {
        row_factor: 1,
        relief_above_m: 0.5,
        ground_shear: false,
        ..flat_rig()
    };
    let r = RowRanges::new(&cam, &p, 0);
    let f = r.focal_px();
    assert!((f - 160.0).abs() < 1e-3);
    let first = r.first_active();
    // Horizon at yn = -tan(15 deg) - margin: about row 90 - 43 - a few (row 35); rows
    // 35-41 could see ground only beyond the 35.4 m range, even 0.5 m up with 2 deg of
    // pitch and roll (their largest disparity below f B / Zmax), so row 42 is the first.
    assert_eq!(first, 42, "first row that can see the square");
    let above = |v: f32| {
        let yn = (v + 0.5 - 90.0) / f;
        let (tm, m) = ((15f32 + 2.0).to_radians(), 2f32.to_radians());
        let s_hi = libm::sinf(tm) + yn * libm::cosf(tm) + libm::sinf(m);
        f * 0.3 * s_hi / 1.5
    };
    let zmax = libm::sqrtf(p.max_ground_range_m * p.max_ground_range_m + 16.0);
    assert!(above(41.0) < f * 0.3 / zmax && above(42.0) >= f * 0.3 / zmax);
    let t = 15f32.to_radians();
    for v in first..180 {
        let (lo, hi) = r.row(v).unwrap();
        let yn = (v as f32 + 0.5 - 90.0) / f;
        let s = libm::sinf(t) + yn * libm::cosf(t);
        let z = 2.0 / s;
        let d = f * 0.3 / z;
        if s > 0.0 && z * libm::cosf(t) < 35.0 {
            assert!(
                lo as f32 + 1.0 <= d && d <= hi as f32 - 1.0,
                "{v}: {lo} {d} {hi}"
            );
        }
    }
    // The bottom row: flat ground at ~19 px; relief +0.5 m: 26 px, -2 m: 9.6 px.
    let (lo, hi) = r.row(179).unwrap();
    assert!(
        (6..=9).contains(&lo) && (27..=32).contains(&hi),
        "{lo} {hi}"
    );
    assert!(r.row(0).is_none());
    assert!(r.max_disparities() >= hi - r.row(first).unwrap().0);
    // Rows reduced twice more: half the rows, the same columns and focal length; row
    // `q` covers working rows `2q, 2q + 1`, and the flat ground of both lies inside
    // its range.
    let r2 = RowRanges::new(&cam, &StereoParams { row_factor: 2, ..p }, 0);
    assert_eq!(r2.size(), (320, 90));
    assert_eq!(r2.focal_px(), f);
    let mut rows = 0;
    for q in 0..90 {
        let Some((lo, hi)) = r2.row(q) else {
            assert!(r.row(2 * q + 1).is_none() || r.row(2 * q).is_none(), "{q}");
            continue;
        };
        for v in [2 * q, 2 * q + 1] {
            let yn = (v as f32 + 0.5 - 90.0) / f;
            let s = libm::sinf(t) + yn * libm::cosf(t);
            let z = 2.0 / s;
            if s > 0.0 && z * libm::cosf(t) < 35.0 {
                let d = f * 0.3 / z;
                assert!(
                    lo as f32 + 0.5 <= d && d <= hi as f32 - 0.5,
                    "{q} {v}: {lo} {d} {hi}"
                );
                rows += 1;
            }
        }
    }
    assert!(rows > 100, "{rows}");
}

#[test]
fn relief_above_grows_with_depth_from_its_near_bound() {
    let cam = CameraParams::default();
    let full = StereoParams {
        relief_above_near_m: f32::INFINITY,
        ..flat_rig()
    };
    let p = StereoParams {
        relief_above_near_m: 0.5,
        relief_above_grade: 0.05,
        ..full
    };
    let (a, b) = (RowRanges::new(&cam, &full, 0), RowRanges::new(&cam, &p, 0));
    let t = 15f32.to_radians();
    let f = a.focal_px();
    let mut narrower = 0;
    for v in 0..180 {
        let (Some((lo_a, hi_a)), Some((lo_b, hi_b))) = (a.row(v), b.row(v)) else {
            assert!(b.row(v).is_none(), "{v}");
            continue;
        };
        // Disparities (the shears may differ by whole pixels: the groups each touches).
        let abs = |r: &RowRanges, d: usize| d as i32 * 256 + r.shear_q8(v);
        let (ga, gb) = (a.shear_q8(v), b.shear_q8(v));
        assert_eq!((ga - gb) % 256, 0, "{v}");
        assert!(
            abs(&a, lo_a) == abs(&b, lo_b) && abs(&b, hi_b) <= abs(&a, hi_a),
            "{v}"
        );
        narrower += usize::from(abs(&b, hi_b) < abs(&a, hi_a));
        // A point on the row's centre ray (level rover) standing the bound's height
        // above the ground at its depth lies inside the range.
        let yn = (v as f32 + 0.5 - 90.0) / f;
        let s = libm::sinf(t) + yn * libm::cosf(t);
        if s <= 0.0 {
            continue;
        }
        // Depth with dz = h - Z s = min(1, 0.5 + 0.05 Z).
        let z = (1.5 / (s + 0.05)).max(1.0 / s);
        // The searched disparities are residuals of the shear.
        let d = f * 0.3 / z - b.shear_q8(v) as f32 / 256.0;
        if z < 35.0 {
            assert!(d <= hi_b as f32 - 1.0 + 1e-3, "{v}: {d} {hi_b}");
        }
    }
    // The near rows (flat ground within 10 m: the bound below 1 m) search fewer.
    assert!(narrower > 60, "{narrower}");
    // Off: a near bound at or above the full one changes nothing.
    let off = StereoParams {
        relief_above_near_m: 1.0,
        relief_above_grade: 0.3,
        ..full
    };
    assert_eq!(RowRanges::new(&cam, &off, 0), a);
}

#[test]
fn horizon_rows_reach_rising_terrain_and_only_them_change() {
    let cam = CameraParams::default();
    let (t, h) = (cam.tilt_deg.to_radians(), cam.height_m);
    // Disparities, not residuals.
    let base = StereoParams {
        ground_shear: false,
        ..flat_rig()
    };
    let hz = StereoParams {
        horizon_grade: 0.3,
        ..base
    };
    let (a, b) = (RowRanges::new(&cam, &base, 0), RowRanges::new(&cam, &hz, 0));
    let f = a.focal_px();
    let zmax = libm::sqrtf(base.max_ground_range_m.powi(2) + (h + 2.0).powi(2));
    let s_of = |v: usize| {
        let yn = (v as f32 + 0.5 - 90.0) / f;
        libm::sinf(t) + yn * libm::cosf(t)
    };
    let (mut new_rows, mut checked) = (0, 0);
    for v in 0..180 {
        let s = s_of(v);
        // `s` over the row and 2 deg of pitch and roll reaches `s + 0.0707` to
        // `s + 0.0715` here (`s_hi`). Rows that can see flat ground within the range:
        // unchanged. Rows near that edge are left out of both checks.
        if s + 0.072 > h / zmax {
            if s + 0.0707 > h / zmax {
                assert_eq!(a.row(v), b.row(v), "row {v}");
            }
            continue;
        }
        if a.row(v).is_none() && b.row(v).is_some() {
            new_rows += 1;
        }
        // A slope rising 0.25 m per metre from under the rover, seen by the row's centre
        // ray at depth Z (`h - Z s = 0.25 Z`): inside the range when within Zmax.
        let z = h / (s + 0.25);
        if z > 0.0 && z < zmax {
            let d = f * 0.3 / z;
            let (lo, hi) = b
                .row(v)
                .expect("a horizon row that sees the slope is searched");
            assert!(
                lo as f32 + 1.0 <= d + 1e-3 && d <= hi as f32 - 1.0 + 1e-3,
                "{v}: {d}"
            );
            checked += 1;
        }
        // Nothing nearer than the grade allows (0.5 m + 0.3 Z up): the range ends there.
        if let Some((_, hi)) = b.row(v) {
            let z_near = 1.5 / (s + 0.3 + 0.076);
            assert!(hi as f32 <= f * 0.3 / z_near + 2.0 + 1e-3, "{v}: {hi}");
        }
    }
    // Rows above the flat ground's horizon and those whose flat ground lies beyond the
    // range: at grade 0.3 every row from the image's top (row 0) to row 39 is new.
    assert!(new_rows >= 25, "{new_rows}");
    assert!(checked >= 25, "{checked}");
    assert!(b.first_active() < a.first_active());
    assert!(b.row_work(0, 180) > a.row_work(0, 180));
    // Checked by the rig: a NaN or negative grade is refused.
    for g in [f32::NAN, -0.1, 11.0] {
        let p = StereoParams {
            horizon_grade: g,
            ..base
        };
        assert!(super::super::StereoRig::new(&cam, &p).is_err(), "{g}");
    }
}

#[test]
fn ranges_follow_the_rovers_attitude() {
    let cam = CameraParams::default();
    let p = StereoParams {
        attitude_margin_deg: 0.5,
        ..flat_rig()
    };
    let level = RowRanges::with_rows(&cam, &p, 0, 1, &Attitude::level(cam.tilt_deg));
    let f = level.focal_px();
    // Whether the flat ground under working pixel `(u, v)` of `truth` lies inside row
    // `v`'s range of `r` (with the pixel of widening each side), when it is within the
    // ground range.
    let inside = |r: &RowRanges, truth: &Camera, u: usize, v: usize| -> Option<bool> {
        let (xn, yn) = ((u as f32 + 0.5 - 160.0) / f, (v as f32 + 0.5 - 90.0) / f);
        let m = &truth.world_to_cam;
        let s = -(m[(0, 2)] * xn + m[(1, 2)] * yn + m[(2, 2)]);
        if s <= 1e-3 {
            return None;
        }
        let z = cam.height_m / s;
        if z * libm::sqrtf(1.0 + xn * xn + yn * yn) > 35.0 {
            return None;
        }
        // The residual of the row's shear.
        let d = f * p.baseline_m / z - r.shear_q8(v) as f32 / 256.0;
        Some(
            r.row(v)
                .is_some_and(|(lo, hi)| lo as f32 + 1.0 <= d + 1e-3 && d <= hi as f32 - 1.0 + 1e-3),
        )
    };
    let mut checked = 0;
    let mut level_misses = 0;
    for (pitch, roll) in [(0.0, 0.0), (6.0, 0.0), (0.0, -6.0), (4.0, 5.0), (-8.0, 3.0)] {
        let pose = RoverPose {
            pitch_deg: pitch,
            roll_deg: roll,
            ..RoverPose::level(10.0, -4.0, 1.0, 37.0)
        };
        for view in View::ALL {
            let att = Attitude::of_view(&cam, &pose, view).unwrap();
            let r = RowRanges::with_rows(&cam, &p, 0, 1, &att);
            // The true attitude anywhere within the margin of the given one (a hair
            // inside it: the bound is exact for a level nominal, to fourth order
            // otherwise).
            for (dp, dr) in [
                (0.0, 0.0),
                (0.49, 0.49),
                (-0.49, 0.49),
                (0.49, -0.49),
                (-0.49, -0.49),
            ] {
                let at = RoverPose {
                    pitch_deg: pitch + dp,
                    roll_deg: roll + dr,
                    ..pose
                };
                let truth = Camera::new(&cam, &at, view).unwrap();
                for v in 0..180 {
                    for u in [0, 80, 160, 240, 319] {
                        if let Some(ok) = inside(&r, &truth, u, v) {
                            assert!(
                                ok,
                                "pitch {pitch} roll {roll} {view:?} +({dp}, {dr}): ({u}, {v})"
                            );
                            checked += 1;
                            level_misses +=
                                usize::from(inside(&level, &truth, u, v) == Some(false));
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 20_000, "{checked}");
    // The level rover's ranges miss the ground of a tilted one: the rig must follow
    // the attitude.
    assert!(level_misses > 1_000, "{level_misses}");
}

#[test]
fn windows_follow_the_flat_ground() {
    let cam = CameraParams::default();
    let on = flat_rig();
    assert!(on.ground_shear);
    let off = StereoParams {
        ground_shear: false,
        ..on
    };
    for (level, rows) in [(0u8, 1u32), (0, 2), (1, 2), (2, 2)] {
        let att = Attitude::level(cam.tilt_deg);
        let a = RowRanges::with_rows(&cam, &on, level, rows, &att);
        let b = RowRanges::with_rows(&cam, &off, level, rows, &att);
        let (w, h) = a.size();
        let (f, fr) = (a.focal_px(), a.focal_rows);
        let t = cam.tilt_deg.to_radians();
        // The level's rows: the flat ground's disparity grows by f B cos t / (h fr)
        // pixels per row, and the shear by the same (Q8).
        let slope = f * on.baseline_m * libm::cosf(t) / (cam.height_m * fr);
        let g = |v: usize| a.shear_q8(v) as f32 / 256.0;
        assert!(
            ((g(h - 1) - g(0)) / (h - 1) as f32 - slope).abs() < 0.01,
            "level {level} x{rows}"
        );
        assert_eq!(b.shear_q8(h - 1), 0);
        // The largest disparity searched is a disparity, not a residual.
        assert!(
            a.global_max().abs_diff(b.global_max()) <= 1,
            "level {level} x{rows}"
        );
        let mut residuals = [f32::INFINITY, f32::NEG_INFINITY];
        let mut checked = 0;
        for v in 0..h {
            let (Some((lo, hi)), Some(_)) = (a.row(v), b.row(v)) else {
                assert!(a.row(v).is_none() && b.row(v).is_none(), "{v}");
                continue;
            };
            // Each residual range holds the row's disparities less its shear, with the
            // widening pixel each side, and within the columns.
            let (d0, d1) = a.span(v).unwrap();
            assert_eq!(b.span(v), Some((d0, d1)));
            let (d0, d1) = (d0 - g(v), d1 - g(v));
            assert!(
                lo as f32 + 1.0 <= d0 + 1e-3 && d1 <= hi as f32 - 1.0 + 1e-3,
                "level {level} x{rows} row {v}: {lo}..{hi} vs {d0}..{d1}"
            );
            assert!(hi <= w - 2 * usize::from(on.radius_px) - 2 || hi == lo + 2);
            // The flat ground's residual is one value down the image.
            let yn = (v as f32 + 0.5 - a.cy) / fr;
            let s = libm::sinf(t) + yn * libm::cosf(t);
            if s > 0.0 {
                let r = f * on.baseline_m * s / cam.height_m - g(v);
                residuals = [residuals[0].min(r), residuals[1].max(r)];
                checked += 1;
            }
        }
        assert!(checked > 10, "level {level} x{rows}: {checked}");
        let spread = residuals[1] - residuals[0];
        assert!(spread < 0.05, "level {level} x{rows}: {residuals:?}");
    }
}
