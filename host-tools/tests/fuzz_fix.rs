//! Property tests of the one fix's boundaries: the map-product parser on arbitrary and
//! mutated bytes, and `orbfix::fix::run` on arbitrary frame sizes, poses (NaN and infinities
//! included), depth sizes and settings. A panic is a failure (in the dev profile that
//! includes every integer overflow); the count of inputs tried is printed
//! (`cargo test --test fuzz_fix -- --nocapture`).

use orbfix::camera::{CameraParams, RoverPose};
use orbfix::fix::{self, Depth, FixConfig, FixInputs, NoClock};
use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::map_product::{CrcCheck, MapProduct};
use orbfix::nn::model::SHIPPED_WEIGHTS;
use orbfix::reproject::{DepthView, GridSpec};
use orbfix_host::eval::MapRegion;
use orbfix_host::fix::OwnedScratch;
use orbfix_host::fix::{build_map_product, MapProductOptions};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::sync::atomic::{AtomicUsize, Ordering};

fn runner(cases: u32) -> TestRunner {
    let cfg = Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    };
    TestRunner::new_with_rng(cfg, TestRng::from_seed(RngAlgorithm::ChaCha, &[11; 32]))
}

/// A small textured map product: 160 x 160 px at 0.25 m, 80 px windows every 16 px.
fn product() -> Vec<u8> {
    let (w, h) = (160usize, 160usize);
    let image: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as u32, (i / w) as u32);
            (40 + ((x * 7 + y * 13) ^ (x * y)) % 170) as u8
        })
        .collect();
    let map = MapRegion {
        image,
        width: w,
        height: h,
        geo: GeoRef::new(0.0, 40.0, 0.25).unwrap(),
    };
    build_map_product(
        &map,
        SHIPPED_WEIGHTS,
        &MapProductOptions {
            window_px: 80,
            step_px: 16,
            sun_deg: None,
            ..MapProductOptions::default()
        },
    )
    .unwrap()
}

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(0.0f32),
        -1e6f32..1e6f32,
        any::<f32>(),
    ]
}

#[test]
fn map_product_parser_never_panics_and_catches_every_mutation() {
    let good = product();
    let n = AtomicUsize::new(0);
    runner(400)
        .run(&proptest::collection::vec(any::<u8>(), 0..300), |bytes| {
            n.fetch_add(1, Ordering::Relaxed);
            let _ = MapProduct::parse(&bytes, CrcCheck::Verify);
            let _ = MapProduct::parse(&bytes, CrcCheck::Skip);
            Ok(())
        })
        .unwrap();
    runner(300)
        .run(
            &(0..good.len(), 1u8..=255, proptest::bool::ANY),
            |(at, x, truncate)| {
                n.fetch_add(1, Ordering::Relaxed);
                let mut b = good.clone();
                b[at] ^= x;
                prop_assert!(MapProduct::parse(&b, CrcCheck::Verify).is_err());
                let _ = MapProduct::parse(&b, CrcCheck::Skip);
                if truncate {
                    prop_assert!(MapProduct::parse(&good[..at], CrcCheck::Verify).is_err());
                }
                Ok(())
            },
        )
        .unwrap();
    println!(
        "map product parser: {} inputs, 0 crashes",
        n.load(Ordering::Relaxed)
    );
}

#[test]
fn the_fix_never_panics_on_hostile_inputs() {
    let good = product();
    let n = AtomicUsize::new(0);
    let strategy = (
        (1u32..200, 1u32..120),
        (
            prop_oneof![10.0f32..30.0, any_f32()],
            prop_oneof![10.0f32..30.0, any_f32()],
            prop_oneof![0.0f32..360.0, any_f32()],
        ),
        (
            prop_oneof![60.0f32..120.0, any_f32()],
            prop_oneof![1.0f32..3.0, any_f32()],
            prop_oneof![5.0f32..30.0, any_f32()],
        ),
        0usize..3,
        (0usize..9, any_f32(), 0u8..20),
        proptest::bool::ANY,
    );
    runner(120)
        .run(
            &strategy,
            |(
                (w, h),
                (x, y, heading),
                (hfov, cam_h, tilt),
                depth_kind,
                (peaks, hp_m, stride),
                crc,
            )| {
                n.fetch_add(1, Ordering::Relaxed);
                let params = CameraParams {
                    width_px: w,
                    height_px: h,
                    hfov_deg: hfov,
                    height_m: cam_h,
                    tilt_deg: tilt,
                };
                let pose = RoverPose::level(x, y, 0.0, heading);
                let len = (w * h) as usize;
                let frame = vec![128u8; len];
                let depth = vec![5000u16; len];
                let fv = ImageView::new(&frame, w as usize, h as usize).ok();
                let dv = DepthView::new(&depth, w as usize, h as usize).ok();
                let mut cfg = FixConfig {
                    grid: GridSpec::new(80, 0.25),
                    ..FixConfig::default()
                };
                cfg.refine.peaks = peaks;
                cfg.refine.highpass_m = hp_m;
                cfg.range.max_column_stride = stride;
                cfg.self_check.verify_map_crc = crc;
                let inputs = FixInputs {
                    params,
                    pose,
                    frames: [fv, fv, None, fv],
                    depth: match depth_kind {
                        0 => Depth::Flat,
                        1 => Depth::Images([dv, dv, dv, None]),
                        _ => Depth::Images([None; 4]),
                    },
                    map_product: &good,
                    weights: SHIPPED_WEIGHTS,
                };
                // Buffers sized for the valid default, whatever the settings say.
                let meta = *MapProduct::parse(&good, CrcCheck::Skip).unwrap().meta();
                let base = FixConfig {
                    grid: GridSpec::new(80, 0.25),
                    ..FixConfig::default()
                };
                let s = fix::fix_buffer_sizes(&base, &meta).unwrap();
                let mut bufs = OwnedScratch::new(&s);
                let mut scratch = bufs.scratch();
                if let Ok(r) = fix::run(&inputs, &cfg, &mut scratch, &mut NoClock) {
                    // Whatever it reports is finite or the prior's position.
                    prop_assert!(r.confidence.is_finite() && (0.0..=1.0).contains(&r.confidence));
                }
                Ok(())
            },
        )
        .unwrap();
    println!("fix::run: {} inputs, 0 crashes", n.load(Ordering::Relaxed));
}
