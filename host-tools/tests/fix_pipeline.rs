//! The one fix (`orbfix::fix::run`) end to end on stops rendered from the world: it finds
//! the rover, its paths and statuses mean what they say, and bad input is a clear error or
//! "no data", never a panic or a silent wrong answer.

use orbfix::fix::{FixConfig, FixPath, FixStatus, RefineMode};
use orbfix::map_product::{CrcCheck, MapProduct};
use orbfix_host::eval::pipeline::Reprojection;
use orbfix_host::fix::{FixRunner, MapProductOptions};
use orbfix_host::world::World;

mod common;
use common::{stop, Stop};

fn run(s: &Stop, cfg: FixConfig) -> orbfix_host::fix::FixOutcome {
    let mut pose = s.obs.pose;
    pose.x_m = s.prior.0 as f32;
    pose.y_m = s.prior.1 as f32;
    FixRunner::shipped(cfg)
        .run(
            &s.obs.params,
            &pose,
            s.obs.frames().unwrap(),
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap()
}

fn error(s: &Stop, r: &orbfix::fix::FixReport) -> f64 {
    (r.x_m as f64 - s.truth.0).hypot(r.y_m as f64 - s.truth.1)
}

#[test]
fn the_fix_finds_the_rover_and_says_how() {
    let s = stop(Reprojection::Range);
    let out = run(&s, FixConfig::default());
    let r = &out.report;
    assert_eq!(r.status, FixStatus::Ok, "{r:?}");
    assert_eq!(r.path, FixPath::Ncc);
    let e = error(&s, r);
    assert!(e < 0.5, "fix error {e} m");
    assert!(
        e <= r.error_bound_m as f64,
        "error {e} beyond the stated bound"
    );
    assert!(r.reprojection.range && r.coverage_permille > 300);
    assert_eq!(r.windows as usize, 18 * 18);
    assert!(r.ops.embed_macs > 0 && r.ops.match_elements > 0 && r.ops.refine_macs > 0);
    // The bare CNN: its sub-cell peak, coarser but in the right cell.
    let mut cnn = FixConfig::default();
    cnn.refine.mode = RefineMode::Cnn;
    let c = run(&s, cnn).report;
    assert_eq!(c.path, FixPath::Cnn);
    assert!(error(&s, &c) < 3.0, "cnn error {}", error(&s, &c));
    assert_eq!(c.ops.refine_macs, 0);
    // Deterministic, and the redundant embedding agrees with the first.
    let mut checked = FixConfig::default();
    checked.self_check.redundant_embed = true;
    checked.self_check.verify_map_crc = true;
    let again = run(&s, checked);
    assert_eq!(again.report.x_m, r.x_m);
    assert_eq!(again.report.status, FixStatus::Ok);
}

#[test]
fn flat_ground_path_runs_the_same_function() {
    let s = stop(Reprojection::Lut);
    let r = run(&s, FixConfig::default()).report;
    assert!(!r.reprojection.range);
    assert!(r.ops.lut_cells > 0);
    assert_ne!(r.status, FixStatus::NoData);
}

#[test]
fn bad_input_is_an_error_or_no_data() {
    let s = stop(Reprojection::Range);
    let runner = FixRunner::shipped(FixConfig::default());
    let mut pose = s.obs.pose;
    pose.x_m = s.prior.0 as f32;
    pose.y_m = s.prior.1 as f32;
    let frames = s.obs.frames().unwrap();
    // No cameras at all: no data, at the prior.
    let none = runner
        .run(
            &s.obs.params,
            &pose,
            [None; 4],
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap()
        .report;
    assert_eq!(none.status, FixStatus::NoData);
    assert_eq!((none.x_m, none.y_m), (pose.x_m, pose.y_m));
    // One camera missing: still a fix.
    let three = runner
        .run(
            &s.obs.params,
            &pose,
            [frames[0], None, frames[2], frames[3]],
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap()
        .report;
    assert_ne!(three.status, FixStatus::NoData);
    // Black frames: no data.
    let w = s.obs.params.width_px as usize * s.obs.params.height_px as usize;
    let black = vec![0u8; w];
    let bv = orbfix::image::ImageView::new(
        &black,
        s.obs.params.width_px as usize,
        s.obs.params.height_px as usize,
    )
    .unwrap();
    let dark = runner
        .run(
            &s.obs.params,
            &pose,
            [Some(bv); 4],
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap()
        .report;
    assert_eq!(dark.status, FixStatus::NoData);
    // A NaN heading is refused.
    let mut nan = pose;
    nan.heading_deg = f32::NAN;
    let e = runner
        .run(
            &s.obs.params,
            &nan,
            frames,
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap_err();
    assert!(e.to_string().contains("reprojection"), "{e}");
    // A prior outside the map.
    let mut far = pose;
    far.x_m += 1000.0;
    let e = runner
        .run(
            &s.obs.params,
            &far,
            frames,
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap_err();
    assert!(e.to_string().contains("outside the map"), "{e}");
    // A damaged map product: caught by the CRC when checked, and by the structure always.
    let mut bad = s.product.clone();
    bad[5000] ^= 0x10;
    let mut crc = FixConfig::default();
    crc.self_check.verify_map_crc = true;
    let e = FixRunner::shipped(crc)
        .run(&s.obs.params, &pose, frames, s.obs.depths.as_ref(), &bad)
        .unwrap_err();
    assert!(e.to_string().contains("damaged"), "{e}");
    let e = runner
        .run(
            &s.obs.params,
            &pose,
            frames,
            s.obs.depths.as_ref(),
            &s.product[..s.product.len() - 7],
        )
        .unwrap_err();
    assert!(e.to_string().contains("map product"), "{e}");
    // Records made with other weights are refused.
    let mut other = orbfix::nn::model::SHIPPED_WEIGHTS.to_vec();
    let n = other.len();
    other[20] ^= 1;
    let c = orbfix::nn::weights::crc32(&other[..n - 4]);
    other[n - 4..].copy_from_slice(&c.to_le_bytes());
    if orbfix::nn::model::SiameseNet::from_bytes(&other).is_ok() {
        let e = FixRunner {
            weights: other,
            cfg: FixConfig::default(),
        }
        .run(
            &s.obs.params,
            &pose,
            frames,
            s.obs.depths.as_ref(),
            &s.product,
        )
        .unwrap_err();
        assert!(e.to_string().contains("other weights"), "{e}");
    }
    // Depth images of the wrong size.
    let small = [
        vec![0u16; 10],
        vec![0u16; 10],
        vec![0u16; 10],
        vec![0u16; 10],
    ];
    assert!(runner
        .run(&s.obs.params, &pose, frames, Some(&small), &s.product)
        .is_err());
    // The product's own header checks.
    assert!(MapProduct::parse(&s.product, CrcCheck::Verify).is_ok());
    assert_eq!(s.map.width, 480);
}

/// The relief stage: with a product that carries the world's elevation blocks it runs on the
/// depth path (every window scored over the blocks the rover saw) and the fix still finds the
/// rover; without a relief plane, with weight 0 or on flat ground it does not run, and then
/// the fix is the CNN's alone.
#[test]
fn relief_stage_runs_where_it_has_heights() {
    use orbfix_host::fix::build_map_product_relief;
    let s = stop(Reprojection::Range);
    let world = World::new(4);
    let heights = |x: f64, y: f64| world.height_m(x, y);
    let cfg = FixConfig::default();
    assert!(cfg.relief.weight > 0.0);
    let opts = MapProductOptions::for_fix(&cfg, None).unwrap();
    assert_eq!(opts.relief_block_px, opts.step_px);
    let product = build_map_product_relief(
        &s.map,
        orbfix::nn::model::SHIPPED_WEIGHTS,
        &opts,
        Some(&heights),
    )
    .unwrap();
    let p = MapProduct::parse(&product, CrcCheck::Verify).unwrap();
    let plane = p.relief().expect("a relief plane");
    assert_eq!((plane.cols(), plane.blocks()), (18 + 11, 12));
    // No heights, no relief plane: a clear error.
    assert!(
        build_map_product_relief(&s.map, orbfix::nn::model::SHIPPED_WEIGHTS, &opts, None).is_err()
    );
    let with = Stop {
        product,
        ..stop(Reprojection::Range)
    };
    let r = run(&with, cfg).report;
    assert!(r.relief_blocks >= 24, "{} blocks", r.relief_blocks);
    assert_eq!(r.ops.relief_macs, 18 * 18 * 3 * r.relief_blocks as u64);
    assert_eq!(r.status, FixStatus::Ok, "{r:?}");
    assert!(error(&with, &r) < 0.5, "fix error {} m", error(&with, &r));
    // Off: weight 0 on the same product, or a product without the plane: no relief, and
    // the same fix either way.
    let mut off = FixConfig::default();
    off.relief.weight = 0.0;
    let a = run(&with, off).report;
    let b = run(&s, FixConfig::default()).report;
    assert_eq!((a.relief_blocks, b.relief_blocks), (0, 0));
    assert_eq!(a.ops.relief_macs, 0);
    assert_eq!((a.x_m, a.y_m, a.confidence), (b.x_m, b.y_m, b.confidence));
    // Flat ground has no heights: the stage does not run.
    let flat = Stop {
        product: with.product.clone(),
        ..stop(Reprojection::Lut)
    };
    assert_eq!(run(&flat, FixConfig::default()).report.relief_blocks, 0);
}
