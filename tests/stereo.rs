//! Tests of the core's stereo matcher (`orbfix::stereo`) on synthetic pairs with known
//! disparity: coverage, accuracy, band independence, no data on textureless ground, errors.

use orbfix::camera::*;
use orbfix::image::ImageView;
use orbfix::reproject::FrameStatus;
use orbfix::stereo::*;
fn hash(x: i64, y: i64) -> f32 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h % 1000) as f32 / 1000.0
}

/// Value noise: a random grid every 3 px, bilinear, 40..215.
fn texture(x: f32, y: f32) -> f32 {
    let (gx, gy) = (x / 3.0, y / 3.0);
    let (ix, iy) = (libm::floorf(gx), libm::floorf(gy));
    let (fx, fy) = (gx - ix, gy - iy);
    let (ix, iy) = (ix as i64, iy as i64);
    let a = hash(ix, iy) * (1.0 - fx) + hash(ix + 1, iy) * fx;
    let b = hash(ix, iy + 1) * (1.0 - fx) + hash(ix + 1, iy + 1) * fx;
    40.0 + 175.0 * (a * (1.0 - fy) + b * fy)
}

/// Full-resolution flat-ground disparity of row `v` (pixels), 0 above the horizon.
fn flat_disparity(cam: &CameraParams, baseline: f32, v: usize) -> f32 {
    let f = cam.focal_px();
    let t = cam.tilt_deg.to_radians();
    let yn = (v as f32 + 0.5 - 0.5 * cam.height_px as f32) / f;
    let s = libm::sinf(t) + yn * libm::cosf(t);
    (f * baseline * s / cam.height_m).max(0.0)
}

/// A rectified pair of textured flat ground (sky rows textured too), with `flat` gray
/// for columns below `flat_cols` of the left image (and their right counterparts).
fn ground_pair(cam: &CameraParams, baseline: f32, flat_cols: usize) -> (Vec<u8>, Vec<u8>) {
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    let mut l = vec![0u8; w * h];
    let mut r = vec![0u8; w * h];
    for v in 0..h {
        let d = flat_disparity(cam, baseline, v);
        for u in 0..w {
            let x = u as f32 + 0.5;
            let y = v as f32;
            let tl = if u < flat_cols { 128.0 } else { texture(x, y) };
            let xr = x + d;
            let tr = if xr < flat_cols as f32 {
                128.0
            } else {
                texture(xr, y)
            };
            l[v * w + u] = libm::roundf(tl) as u8;
            r[v * w + u] = libm::roundf(tr) as u8;
        }
    }
    (l, r)
}

struct Run {
    rig: StereoRig,
    bytes: Vec<u8>,
    words: Vec<u16>,
}

fn setup(params: &StereoParams) -> Run {
    let cam = CameraParams::default();
    let rig = StereoRig::new(&cam, params).unwrap();
    let s = rig.buffer_sizes();
    Run {
        rig,
        bytes: vec![0; s.bytes],
        words: vec![0; s.words],
    }
}

#[test]
fn flat_ground_disparity_and_depth() {
    // Every column decided, every other one with the ones between filled, and the default
    // (every other one, every fourth in the near rows); relief searched 0.5 m and 1 m above.
    // Near rows of the working size in pairs, or not.
    for (column_step, near_column_step) in [(1, 1), (2, 2), (2, 4)] {
        for relief_above_m in [0.5, 1.0] {
            for pair_rows_m in [0.0, 0.25] {
                flat_ground_with(StereoParams {
                    column_step,
                    near_column_step,
                    relief_above_m,
                    pair_rows_m,
                    ..StereoParams::default()
                });
            }
        }
    }
}

fn flat_ground_with(p: StereoParams) {
    let cam = CameraParams::default();
    let (l, r) = ground_pair(&cam, p.baseline_m, 0);
    let (lv, rv) = (
        ImageView::new(&l, 640, 360).unwrap(),
        ImageView::new(&r, 640, 360).unwrap(),
    );
    let mut run = setup(&p);
    let (w, h) = run.rig.output_size();
    assert_eq!((w, h), (320, 180));
    let mut disp = vec![0u16; w * h];
    let rep = run
        .rig
        .image(
            &lv,
            Some(&rv),
            16,
            true,
            &mut run.bytes,
            &mut run.words,
            &mut disp,
        )
        .unwrap();
    let first = run.rig.ranges().first_active();
    let (mut n, mut good, mut err_sum, mut cand) = (0usize, 0usize, 0.0f32, 0usize);
    for y in 0..h {
        // True disparity at the working size: the mean of the two full rows.
        let dt = 0.25
            * (flat_disparity(&cam, p.baseline_m, 2 * y)
                + flat_disparity(&cam, p.baseline_m, 2 * y + 1));
        for x in 0..w {
            let d = disp[y * w + x];
            if y < first {
                assert_eq!(d, 0, "sky row {y} matched");
                continue;
            }
            // Ground within range, columns with a full window inside both images.
            if dt < 1.5 || x < 40 || x + 4 >= w {
                continue;
            }
            cand += 1;
            if d == 0 {
                continue;
            }
            n += 1;
            // Error in pixels of the row's level (coarser levels: 2^l working pixels; the
            // paired rows have the working size's columns).
            let sc = run.rig.scales();
            let e = (d as f32 / 16.0 - dt).abs() / (1 << sc.col_shift(sc.level_of_row(y))) as f32;
            err_sum += e;
            good += usize::from(e <= 0.5);
        }
    }
    assert!(n as f32 > 0.85 * cand as f32, "coverage {n} of {cand}");
    assert!(
        good as f32 > 0.97 * n as f32,
        "{good} of {n} within 0.5 px of their level"
    );
    assert!(
        err_sum / (n as f32) < 0.15,
        "mean error {}",
        err_sum / n as f32
    );
    assert_eq!(rep.valid as usize, disp.iter().filter(|&&d| d != 0).count());
    assert!(rep.pixel_disparities > 0 && rep.cost_updates > rep.pixel_disparities / 2);

    // Depth: f B / d in millimetres at the bottom rows (~2.6 m), matched at a coarser
    // level: within what a quarter pixel of that level may cost (`scale_error_m`).
    let mut depth = vec![0u16; w * 10];
    run.rig
        .depth_band(
            &lv,
            Some(&rv),
            170,
            180,
            &mut run.bytes,
            &mut run.words,
            &mut depth,
        )
        .unwrap();
    let y = 175;
    let t = 15f32.to_radians();
    let yn = (2.0 * y as f32 + 1.0 - 180.0) / 320.0;
    let z_true = 2000.0 / (libm::sinf(t) + yn * libm::cosf(t));
    let mut zs: Vec<u16> = depth[5 * w + 40..5 * w + 300]
        .iter()
        .copied()
        .filter(|&z| z > 0)
        .collect();
    zs.sort_unstable();
    // Of the 260 columns: a wider range above the ground leaves fewer left columns whose
    // every candidate window lies inside the right image.
    let least = if p.relief_above_m > 0.5 { 180 } else { 200 };
    assert!(zs.len() > least, "{} {:?}", zs.len(), p);
    let med = zs[zs.len() / 2] as f32;
    assert!(run.rig.scales().level_of_row(y) > 0);
    assert!(
        (med - z_true).abs() < 1000.0 * p.scale_error_m,
        "{med} vs {z_true}"
    );
}

#[test]
fn bands_do_not_change_the_result() {
    let cam = CameraParams::default();
    let p = StereoParams::default();
    let (l, r) = ground_pair(&cam, p.baseline_m, 0);
    let (lv, rv) = (
        ImageView::new(&l, 640, 360).unwrap(),
        ImageView::new(&r, 640, 360).unwrap(),
    );
    let mut run = setup(&p);
    let (w, h) = run.rig.output_size();
    let mut a = vec![0u16; w * h];
    let mut b = vec![0u16; w * h];
    run.rig
        .image(
            &lv,
            Some(&rv),
            h,
            true,
            &mut run.bytes,
            &mut run.words,
            &mut a,
        )
        .unwrap();
    run.rig
        .image(
            &lv,
            Some(&rv),
            7,
            true,
            &mut run.bytes,
            &mut run.words,
            &mut b,
        )
        .unwrap();
    assert!(a.iter().filter(|&&d| d != 0).count() > 10_000);
    assert!(a == b);
}

#[test]
fn textureless_ground_gives_no_data() {
    let cam = CameraParams::default();
    let p = StereoParams::default();
    let (l, r) = ground_pair(&cam, p.baseline_m, 300);
    let (lv, rv) = (
        ImageView::new(&l, 640, 360).unwrap(),
        ImageView::new(&r, 640, 360).unwrap(),
    );
    let mut run = setup(&p);
    let (w, h) = run.rig.output_size();
    let mut d = vec![0u16; w * h];
    run.rig
        .image(
            &lv,
            Some(&rv),
            32,
            true,
            &mut run.bytes,
            &mut run.words,
            &mut d,
        )
        .unwrap();
    // Columns 0..150 (full 0..300) are uniform gray: nothing there (the window reaches
    // 3 pixels of the row's level into the texture: 3 working pixels at the working size,
    // 12 at level 2, plus the level pixel it lies in).
    let flat_hits = (0..h)
        .map(|y| {
            let l = run.rig.scales().level_of_row(y);
            let reach = (usize::from(p.radius_px) + 1) << l;
            d[y * w..y * w + 150 - reach]
                .iter()
                .filter(|&&v| v != 0)
                .count()
        })
        .sum::<usize>();
    assert_eq!(flat_hits, 0);
    let tex_hits = (0..h)
        .map(|y| {
            d[y * w + 160..y * w + 316]
                .iter()
                .filter(|&&v| v != 0)
                .count()
        })
        .sum::<usize>();
    assert!(tex_hits > 5_000, "{tex_hits}");
}

#[test]
fn bad_inputs_are_typed_errors() {
    let cam = CameraParams::default();
    for b in [0.0, f32::NAN, -0.3, f32::INFINITY] {
        let p = StereoParams {
            baseline_m: b,
            ..StereoParams::default()
        };
        assert_eq!(StereoRig::new(&cam, &p).err(), Some(StereoError::Baseline));
        assert!(stereo_buffer_sizes(&cam, &p).is_err());
    }
    for bad in [
        StereoParams {
            radius_px: 0,
            ..StereoParams::default()
        },
        StereoParams {
            column_step: 0,
            ..StereoParams::default()
        },
        StereoParams {
            column_step: 3,
            ..StereoParams::default()
        },
    ] {
        assert!(matches!(
            StereoRig::new(&cam, &bad),
            Err(StereoError::Param(_))
        ));
    }

    let p = StereoParams::default();
    let mut run = setup(&p);
    let (w, _) = run.rig.output_size();
    let (l, r) = ground_pair(&cam, p.baseline_m, 0);
    let lv = ImageView::new(&l, 640, 360).unwrap();
    let rv = ImageView::new(&r, 640, 360).unwrap();
    let mut out = vec![0u16; w * 8];
    let mut go = |left: &ImageView<'_>, right: Option<&ImageView<'_>>, out: &mut [u16]| {
        run.rig
            .depth_band(left, right, 100, 108, &mut run.bytes, &mut run.words, out)
    };
    assert_eq!(
        go(&lv, None, &mut out).err(),
        Some(StereoError::MissingRight)
    );
    let black = vec![0u8; 640 * 360];
    let bv = ImageView::new(&black, 640, 360).unwrap();
    assert_eq!(
        go(&lv, Some(&bv), &mut out).err(),
        Some(StereoError::Frame {
            side: Side::Right,
            status: FrameStatus::Black
        })
    );
    let white = vec![255u8; 640 * 360];
    let wv = ImageView::new(&white, 640, 360).unwrap();
    assert_eq!(
        go(&wv, Some(&rv), &mut out).err(),
        Some(StereoError::Frame {
            side: Side::Left,
            status: FrameStatus::Saturated
        })
    );
    let small = ImageView::new(&r, 320, 360).unwrap();
    assert!(matches!(
        go(&lv, Some(&small), &mut out),
        Err(StereoError::PairSize { .. })
    ));
    let both_small = ImageView::new(&l, 320, 360).unwrap();
    assert!(matches!(
        go(&both_small, Some(&small), &mut out),
        Err(StereoError::FrameSize { .. })
    ));
    assert!(matches!(
        go(&lv, Some(&rv), &mut out[..w]),
        Err(StereoError::BufferSize {
            buffer: StereoBuffer::Output,
            ..
        })
    ));
    assert!(go(&lv, Some(&rv), &mut out).is_ok());
    let e = run.rig.depth_band(
        &lv,
        Some(&rv),
        10,
        5,
        &mut run.bytes,
        &mut run.words,
        &mut out,
    );
    assert!(matches!(e, Err(StereoError::Rows { .. })));
    let e = run
        .rig
        .depth_band(&lv, Some(&rv), 0, 8, &mut [], &mut run.words, &mut out);
    assert!(matches!(
        e,
        Err(StereoError::BufferSize {
            buffer: StereoBuffer::Bytes,
            ..
        })
    ));
    // Messages are sentences without type names.
    let msg = std::format!("{}", StereoError::MissingRight);
    assert!(msg.starts_with("no right image") && !msg.contains("StereoError"));
}

#[test]
fn sizes_and_work_of_the_default_rig() {
    let cam = CameraParams::default();
    let p = StereoParams::default();
    let s = stereo_buffer_sizes(&cam, &p).unwrap();
    assert_eq!((s.out_width, s.out_height), (320, 180));
    // Within the 48 the fix's `StereoConfig::max_disparities` sizes its scratch for (20
    // since the defaults of 2026-12-07, the near rows coarser; 36 before).
    assert!(
        s.max_disparities >= 16 && s.max_disparities <= 48,
        "{}",
        s.max_disparities
    );
    // Per image: 3 reduced rows and `2 rv + 2` filtered rows.
    assert_eq!(s.bytes, 2 * 320 * (5 + 2 * usize::from(p.radius_rows_px)));
    // Disparities rounded up to groups of four lanes: column costs and aggregated costs on
    // `u32` words (one element of alignment slack), the right image's winners (costs and
    // indices) and disparity rows.
    let d4 = 4 * s.max_disparities.div_ceil(4);
    assert_eq!(s.words, 321 * d4 + 4 * 160 + 3 * 320 + 1);
    // 35,922 bytes with relief searched 1 m above the ground (28,218 at 0.5 m).
    assert!(s.working_bytes() < 36 * 1024, "{}", s.working_bytes());
}

#[test]
fn near_rows_are_the_coarser_rig_expanded_and_far_rows_the_working_size_rig() {
    let cam = CameraParams::default();
    // Rows at the working size (`row_factor` 1, the window square), so that the rig on
    // frames reduced by 4 is level 1.
    let p = StereoParams {
        row_factor: 1,
        radius_rows_px: 3,
        scale_error_m: 0.125,
        // No paired rows: every row either level 0's or level 1's.
        pair_rows_m: 0.0,
        ..StereoParams::default()
    };
    let (l, r) = ground_pair(&cam, p.baseline_m, 0);
    let (lv, rv) = (
        ImageView::new(&l, 640, 360).unwrap(),
        ImageView::new(&r, 640, 360).unwrap(),
    );
    let disparity = |p: &StereoParams| {
        let mut run = setup(p);
        let (w, h) = run.rig.output_size();
        let mut d = vec![0u16; w * h];
        run.rig
            .image(
                &lv,
                Some(&rv),
                23,
                true,
                &mut run.bytes,
                &mut run.words,
                &mut d,
            )
            .unwrap();
        (run.rig, d)
    };
    let (multi, a) = disparity(&p);
    let single = StereoParams {
        scale_levels: 0,
        ..p
    };
    let (_, b) = disparity(&single);
    let (_, c) = disparity(&StereoParams {
        downsample: 4,
        ..single
    });
    let sc = multi.scales();
    let (start, end) = sc.rows_of_level(1);
    assert!(
        start < end && end == 180,
        "near rows at level 1: {start}..{end}"
    );
    assert_eq!(
        sc.rows_of_level(2),
        (180, 180),
        "no row within 0.125 m at level 2"
    );
    // Far rows: the working-size rig's, exactly without the ground shear; with it (the
    // default) except where a window reaches the left border, whose search follows the
    // shear's whole-pixel constant, fitted to the rows each rig matches
    // (`RowRanges::fit_shear`): a few pixels of the first columns.
    let square = |p: &StereoParams| {
        disparity(&StereoParams {
            ground_shear: false,
            ..*p
        })
        .1
    };
    assert_eq!(square(&p)[..start * 320], square(&single)[..start * 320]);
    for y in 0..start {
        assert_eq!(
            a[y * 320 + 32..(y + 1) * 320],
            b[y * 320 + 32..(y + 1) * 320],
            "row {y}"
        );
    }
    let edge = (0..start * 320).filter(|&i| a[i] != b[i]).count();
    assert!(
        edge < start * 320 / 100,
        "{edge} pixels differ at the left border"
    );
    // Near rows: the rig on frames reduced by 4, each pixel covering 2 x 2 working pixels,
    // its disparity in working-size pixels; each of a coarse row's two working rows moved
    // towards its own distance (a quarter of the way to the next coarse row's disparity,
    // or along the flat ground): less than 1 working pixel, and closer to the flat ground
    // of the working row than the coarse row's own value on average.
    let mut near = 0;
    let (mut moved, mut gain) = (0u32, 0f64);
    for y in start..180 {
        // Q4 at the working size: the mean of the two full rows, halved.
        let truth = 16.0
            * 0.25
            * (flat_disparity(&cam, p.baseline_m, 2 * y)
                + flat_disparity(&cam, p.baseline_m, 2 * y + 1)) as f64;
        for x in 0..320 {
            let coarse = u32::from(c[(y / 2) * 160 + x / 2]) * 2;
            let got = u32::from(a[y * 320 + x]);
            assert_eq!(got == 0, coarse == 0, "row {y} column {x}");
            if coarse == 0 {
                continue;
            }
            assert!(
                got.abs_diff(coarse) < 16,
                "row {y} column {x}: {got} {coarse}"
            );
            moved += u32::from(got != coarse);
            gain += (coarse as f64 - truth).abs() - (got as f64 - truth).abs();
            near += 1;
        }
    }
    assert!(
        moved > near / 2 && gain > 0.0,
        "{moved} of {near} moved, gain {gain}"
    );
    assert!(near > 2_000, "{near}");
    // And they differ from the working-size rig's near rows (a coarser match).
    assert_ne!(a[start * 320..], b[start * 320..]);
}
