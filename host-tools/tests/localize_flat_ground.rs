//! The chain camera -> core reprojection -> core localization on a flat textured ground
//! (no renderer needed): the orbital map is the ground texture sampled orthographically,
//! so the right answer is known exactly and every frame convention is exercised.

use orbfix::camera::{CameraParams, RoverPose};
use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::localize::{nearest_window, rank_of, LocalizeConfig};
use orbfix::reproject::{reproject_top_down, table_len, Cell, GridSpec, Tap, DEFAULT_EXTRA};
use orbfix_host::eval::{localize_top_down, matcher_by_name, MapRegion, TopDown};
use orbfix_host::reproject::reference::render_flat_ground;

fn hash(i: i64, j: i64) -> f64 {
    let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z ^= z >> 32;
    (z % 10_000) as f64 / 10_000.0
}

/// Non-periodic value noise with 6 m and 1.5 m cells, gray levels.
fn albedo(x: f64, y: f64) -> f64 {
    let mut v = 0.0;
    for (cell, amp, k) in [(6.0, 150.0, 0i64), (1.5, 100.0, 7777)] {
        let (fx, fy) = (x / cell, y / cell);
        let (ix, iy) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - ix, fy - iy);
        let (ix, iy) = (ix as i64 + k, iy as i64);
        let a = hash(ix, iy) * (1.0 - tx) + hash(ix + 1, iy) * tx;
        let b = hash(ix, iy + 1) * (1.0 - tx) + hash(ix + 1, iy + 1) * tx;
        v += amp * (a * (1.0 - ty) + b * ty);
    }
    v.clamp(0.0, 255.0)
}

fn top_down(params: &CameraParams, pose: &RoverPose) -> TopDown {
    let frames = render_flat_ground(params, pose, albedo).unwrap();
    let views = frames.each_ref().map(|f| {
        Some(ImageView::new(f.as_raw(), f.width() as usize, f.height() as usize).unwrap())
    });
    let grid = GridSpec::default();
    let n = grid.n;
    let mut cells = vec![Cell::EMPTY; table_len(n)];
    let mut extra = vec![Tap::EMPTY; DEFAULT_EXTRA];
    let (mut out, mut mask) = (vec![0u8; n * n], vec![0u8; n * n]);
    reproject_top_down(
        &views, params, pose, &grid, &mut cells, &mut extra, &mut out, &mut mask,
    )
    .unwrap();
    TopDown {
        image: out,
        mask,
        n,
        m_per_px: grid.m_per_px,
    }
}

fn map(cx: f64, cy: f64, px: usize, m_per_px: f64) -> MapRegion {
    let geo = GeoRef::centred(cx as f32, cy as f32, px, px, m_per_px as f32).unwrap();
    let mut image = vec![0u8; px * px];
    for r in 0..px {
        for c in 0..px {
            let (x, y) = geo.to_world(c as f32 + 0.5, r as f32 + 0.5);
            image[r * px + c] = albedo(x as f64, y as f64).round() as u8;
        }
    }
    MapRegion {
        image,
        width: px,
        height: px,
        geo,
    }
}

#[test]
fn reprojected_views_localize_to_the_truth() {
    // Smaller camera for test speed; the study's geometry (2 m, 15 deg down, 90 deg HFOV).
    let params = CameraParams {
        width_px: 320,
        height_px: 180,
        ..CameraParams::default()
    };
    // 200 m map at 0.25 m/px (800 px): 13 x 13 windows of 50 m at 12.5 m.
    let (px, mpp) = (800usize, 0.25);
    let region = map(110.0, -40.0, px, mpp);
    let cfg = LocalizeConfig::default();
    for (k, &(x, y, heading)) in [(150.0, -10.0, 0.0), (70.0, -95.0, 133.0)]
        .iter()
        .enumerate()
    {
        let pose = RoverPose::level(x as f32, y as f32, 0.0, heading as f32);
        let top = top_down(&params, &pose);
        let valid = top.mask.iter().filter(|&&m| m != 0).count();
        assert!(
            valid > top.n * top.n / 4,
            "reprojection left {valid} valid pixels"
        );
        for name in ["ncc", "ncc-dist"] {
            let spec = matcher_by_name(name).unwrap();
            let loc = localize_top_down(&spec, &top, &region, (110.0, -40.0), &cfg, 50).unwrap();
            let err = ((loc.fix.x_m as f64 - x).powi(2) + (loc.fix.y_m as f64 - y).powi(2)).sqrt();
            assert!(
                err < 0.5,
                "stop {k} {name}: error {err:.2} m, fix {:?}",
                loc.fix
            );
            assert!(!loc.fix.on_border);
            assert!(
                loc.fix.confidence > 0.2,
                "confidence {}",
                loc.fix.confidence
            );
            assert_eq!(loc.window_grid.len(), 13 * 13);
            let tw = nearest_window(
                &loc.window_grid,
                &region.geo,
                top.n,
                top.n,
                x as f32,
                y as f32,
            );
            let rank = rank_of(&loc.window_scores, tw).unwrap();
            eprintln!(
                "stop {k} {name}: error {err:.3} m, rank {rank}, confidence {:.2}",
                loc.fix.confidence
            );
            // Windows are up to 6.25 m off the truth: sharp textures decorrelate there.
            assert!(rank < 10, "stop {k} {name}: rank {rank}");
        }
    }
}

#[test]
fn bad_inputs_give_clear_errors() {
    let region = map(0.0, 0.0, 400, 0.25);
    let spec = matcher_by_name("ncc").unwrap();
    let n = 200;
    let empty = TopDown {
        image: vec![0; n * n],
        mask: vec![0; n * n],
        n,
        m_per_px: 0.25,
    };
    let e = localize_top_down(
        &spec,
        &empty,
        &region,
        (0.0, 0.0),
        &LocalizeConfig::default(),
        50,
    )
    .unwrap_err();
    assert!(format!("{e:#}").contains("no data"), "{e:#}");
    let mut tex = TopDown {
        image: vec![0; n * n],
        mask: vec![255; n * n],
        n,
        m_per_px: 0.25,
    };
    for (i, v) in tex.image.iter_mut().enumerate() {
        *v = (i * 7 % 251) as u8;
    }
    let e = localize_top_down(
        &spec,
        &tex,
        &region,
        (500.0, 0.0),
        &LocalizeConfig::default(),
        50,
    )
    .unwrap_err();
    assert!(format!("{e:#}").contains("outside the map"), "{e:#}");
    let coarse = TopDown {
        m_per_px: 0.5,
        ..tex.clone()
    };
    let e = localize_top_down(
        &spec,
        &coarse,
        &region,
        (0.0, 0.0),
        &LocalizeConfig::default(),
        50,
    )
    .unwrap_err();
    assert!(format!("{e:#}").contains("m/px"), "{e:#}");
    assert!(matcher_by_name("sift").is_err());
}
