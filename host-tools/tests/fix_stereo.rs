//! The fix with on-board stereo (`orbfix::fix::Depth::Stereo`): the core matches the
//! rover's stereo pairs itself (stage `stereo`), band by band inside the fix's work area,
//! and a pair that cannot give depth costs only that view.

use orbfix::fix::{self, Depth, FixConfig, FixInputs, FixStatus, Stage, StageClock};
use orbfix::image::ImageView;
use orbfix::map_product::{CrcCheck, MapProduct};
use orbfix::reproject::FrameStatus;
use orbfix::stereo::{Side, StereoError};
use orbfix_host::eval::pipeline::Reprojection;
use orbfix_host::fix::OwnedScratch;
use orbfix_host::fix::{FixDepth, FixOutcome, FixRunner};
use std::sync::OnceLock;

mod common;
use common::Stop;

/// The stop of [`common::stop`] with stereo pairs rendered, once for every test.
fn stop() -> &'static Stop {
    static STOP: OnceLock<Stop> = OnceLock::new();
    STOP.get_or_init(|| common::stop(Reprojection::Stereo))
}

fn pose(s: &Stop) -> orbfix::camera::RoverPose {
    let mut p = s.obs.pose;
    p.x_m = s.prior.0 as f32;
    p.y_m = s.prior.1 as f32;
    p
}

fn rights(s: &Stop) -> [Option<ImageView<'_>>; 4] {
    s.obs.right_frames().unwrap().unwrap()
}

fn run_stereo(
    s: &Stop,
    cfg: FixConfig,
    rights: [Option<ImageView<'_>>; 4],
) -> anyhow::Result<FixOutcome> {
    FixRunner::shipped(cfg).run_with(
        &s.obs.params,
        &pose(s),
        s.obs.frames().unwrap(),
        FixDepth::Stereo(rights),
        &s.product,
    )
}

fn error(s: &Stop, r: &orbfix::fix::FixReport) -> f64 {
    (r.x_m as f64 - s.truth.0).hypot(r.y_m as f64 - s.truth.1)
}

#[test]
fn stereo_fix_finds_the_rover_and_equals_the_same_depth_given_as_images() {
    let s = stop();
    let out = run_stereo(s, FixConfig::default(), rights(s)).unwrap();
    let r = &out.report;
    assert_eq!(
        r.reprojection.stereo,
        Some([None; 4]),
        "every pair gave depth"
    );
    assert!(r.reprojection.range);
    // 834,856 with the defaults of 2026-12-07 (1.09 M before).
    assert!(r.ops.stereo_pixel_disparities > 700_000, "{:?}", r.ops);
    assert!(r.ops.stereo_depth_px > 10_000, "{:?}", r.ops);
    assert!(r.ops.stereo_px >= r.ops.stereo_depth_px);
    assert_eq!(r.status, FixStatus::Ok, "{r:?}");
    let e = error(s, r);
    assert!(e < 1.0, "stereo-depth fix {e:.2} m off");
    // The same core matcher's depth, computed outside the fix and given as images: the
    // same top-down image and the same position (banding and on-the-fly placement change
    // nothing). The fix's stereo path gives the black sky no depth
    // (`RangeOptions::sky_below_gray`); depth images are placed as given, so the sky is cut
    // from them here.
    let sky = FixConfig::default().range.sky_below_gray;
    assert!(sky > 0);
    let mut depths = s.obs.depths.clone().unwrap();
    let mut cut = 0;
    for (d, f) in depths.iter_mut().zip(&s.obs.views) {
        for (z, &g) in d.iter_mut().zip(f.as_raw()) {
            if g < sky && *z > 0 {
                *z = 0;
                cut += 1;
            }
        }
    }
    assert!(cut > 0, "the matcher gave some of the sky depth");
    let img = FixRunner::shipped(FixConfig::default())
        .run_with(
            &s.obs.params,
            &pose(s),
            s.obs.frames().unwrap(),
            FixDepth::Images(&depths),
            &s.product,
        )
        .unwrap();
    assert_eq!(img.top, out.top);
    assert_eq!(img.mask, out.mask);
    assert_eq!((img.report.x_m, img.report.y_m), (r.x_m, r.y_m));
    assert_eq!(img.report.reprojection.stereo, None);
    assert_eq!(img.report.ops.stereo_pixel_disparities, 0);
    // Truth depth on the same stop, for scale.
    let truth = s.obs.truth_depths.as_ref().unwrap();
    let t = FixRunner::shipped(FixConfig::default())
        .run(
            &s.obs.params,
            &pose(s),
            s.obs.frames().unwrap(),
            Some(truth),
            &s.product,
        )
        .unwrap();
    assert!(error(s, &t.report) < 1.0);
    assert_ne!(t.top, out.top, "stereo depth is not the truth");
}

#[test]
fn bands_of_any_height_give_the_same_fix() {
    let s = stop();
    let a = run_stereo(s, FixConfig::default(), rights(s)).unwrap();
    let mut cfg = FixConfig::default();
    cfg.stereo.band_rows = 7;
    let b = run_stereo(s, cfg, rights(s)).unwrap();
    assert_eq!(a.top, b.top);
    assert_eq!(a.mask, b.mask);
    assert_eq!((a.report.x_m, a.report.y_m), (b.report.x_m, b.report.y_m));
    assert_eq!(a.report.ops.stereo_px, b.report.ops.stereo_px);
    assert_eq!(a.report.ops.stereo_depth_px, b.report.ops.stereo_depth_px);
    // Each view's bands are one stream: smaller bands repeat no set-up rows and match no
    // row twice, so the work is the same.
    assert_eq!(
        b.report.ops.stereo_cost_updates,
        a.report.ops.stereo_cost_updates
    );
    assert_eq!(
        b.report.ops.stereo_pixel_disparities,
        a.report.ops.stereo_pixel_disparities
    );
    // Smaller bands need a smaller work area.
    let meta = *MapProduct::parse(&s.product, CrcCheck::Skip)
        .unwrap()
        .meta();
    let big = fix::fix_buffer_sizes(&FixConfig::default(), &meta).unwrap();
    assert!(
        fix::stereo_work_words(&cfg.stereo) < fix::stereo_work_words(&FixConfig::default().stereo)
    );
    // The accumulator (a `u16` sum per cell) and the stereo scratch coexist.
    assert!(
        big.work_words
            >= orbfix::reproject::range_scratch_len(200)
                + fix::stereo_work_words(&FixConfig::default().stereo)
    );
    assert_eq!(orbfix::reproject::range_scratch_len(200), 200 * 200 / 2);
}

#[test]
fn a_bad_pair_costs_only_its_view() {
    let s = stop();
    let good = run_stereo(s, FixConfig::default(), rights(s)).unwrap();
    let (w, h) = (
        s.obs.params.width_px as usize,
        s.obs.params.height_px as usize,
    );
    let black = vec![0u8; w * h];
    let white = vec![255u8; w * h];
    let small = vec![128u8; (w - 2) * h];
    let mut r = rights(s);
    r[0] = Some(ImageView::new(&small, w - 2, h).unwrap());
    r[1] = None;
    r[2] = Some(ImageView::new(&black, w, h).unwrap());
    let out = run_stereo(s, FixConfig::default(), r).unwrap();
    let st = out.report.reprojection.stereo.unwrap();
    assert_eq!(
        st[0],
        Some(StereoError::PairSize {
            left: (w, h),
            right: (w - 2, h)
        })
    );
    assert_eq!(st[1], Some(StereoError::MissingRight));
    assert_eq!(
        st[2],
        Some(StereoError::Frame {
            side: Side::Right,
            status: FrameStatus::Black
        })
    );
    assert_eq!(st[3], None, "the good pair still gives depth");
    assert!(out.report.reprojection.valid_cells > 0);
    assert!(out.report.reprojection.valid_cells < good.report.reprojection.valid_cells / 2);
    // A saturated right image, and a black left frame (no stereo run at all for it).
    let mut r = rights(s);
    r[3] = Some(ImageView::new(&white, w, h).unwrap());
    let mut frames = s.obs.frames().unwrap();
    frames[0] = Some(ImageView::new(&black, w, h).unwrap());
    let out = FixRunner::shipped(FixConfig::default())
        .run_with(
            &s.obs.params,
            &pose(s),
            frames,
            FixDepth::Stereo(r),
            &s.product,
        )
        .unwrap();
    let st = out.report.reprojection.stereo.unwrap();
    assert_eq!(
        st[3],
        Some(StereoError::Frame {
            side: Side::Right,
            status: FrameStatus::Saturated
        })
    );
    assert_eq!(out.report.reprojection.status[0], FrameStatus::Black);
    assert_eq!(st[0], None);
    assert_eq!((st[1], st[2]), (None, None));
    // No right image at all: no depth anywhere, a "no data" report at the prior.
    let out = run_stereo(s, FixConfig::default(), [None; 4]).unwrap();
    assert_eq!(out.report.status, FixStatus::NoData);
    assert_eq!(out.report.reprojection.valid_cells, 0);
    assert_eq!(
        out.report.reprojection.stereo,
        Some([Some(StereoError::MissingRight); 4])
    );
}

#[test]
fn a_baseline_of_zero_or_nan_is_a_clear_error() {
    let s = stop();
    for b in [0.0f32, f32::NAN, -0.3, f32::INFINITY] {
        let mut cfg = FixConfig::default();
        cfg.stereo.matcher.baseline_m = b;
        let e = run_stereo(s, cfg, rights(s)).unwrap_err().to_string();
        assert!(
            e.contains("baseline") && !e.contains("StereoError"),
            "{b}: {e}"
        );
    }
    // A rig that needs more disparities than the scratch was sized for.
    let mut cfg = FixConfig::default();
    cfg.stereo.max_disparities = 5;
    let e = run_stereo(s, cfg, rights(s)).unwrap_err().to_string();
    assert!(e.contains("stereo.max_disparities"), "{e}");
    cfg.stereo.max_disparities = 0;
    let meta = *MapProduct::parse(&s.product, CrcCheck::Skip)
        .unwrap()
        .meta();
    assert!(fix::fix_buffer_sizes(&cfg, &meta).is_err());
}

/// Counts the spans of each stage.
#[derive(Default)]
struct Spans {
    begun: [u32; Stage::ALL.len()],
    ended: [u32; Stage::ALL.len()],
}

impl StageClock for Spans {
    fn begin(&mut self, s: Stage) {
        self.begun[s as usize] += 1;
    }
    fn end(&mut self, s: Stage) {
        self.ended[s as usize] += 1;
    }
}

#[test]
fn the_stage_clock_sees_the_stereo_stage_band_by_band() {
    let s = stop();
    let cfg = FixConfig::default();
    let mut bufs = OwnedScratch::for_product(&cfg, &s.product).unwrap();
    let mut scratch = bufs.scratch();
    let inputs = FixInputs {
        params: s.obs.params,
        pose: pose(s),
        frames: s.obs.frames().unwrap(),
        depth: Depth::Stereo(rights(s)),
        map_product: &s.product,
        weights: orbfix::nn::model::SHIPPED_WEIGHTS,
    };
    let mut clock = Spans::default();
    let r = fix::run(&inputs, &cfg, &mut scratch, &mut clock).unwrap();
    assert_eq!(r.status, FixStatus::Ok);
    assert_eq!(clock.begun, clock.ended);
    let st = clock.begun[Stage::Stereo as usize];
    // Rig set-up, then 4 views x (the view's stream, the bands: 180 rows from row 0, the
    // horizon rows searched from the image's top, 30 rows a band: 6 bands).
    assert_eq!(st, 1 + 4 * (1 + 6), "{:?}", clock.begun);
    assert!(clock.begun[Stage::Reproject as usize] >= 4 * 5 + 2);
    assert_eq!(clock.begun[Stage::LutBuild as usize], 0);
    // A too-short work area is refused, not overrun.
    scratch.work = &mut [];
    assert!(fix::run(&inputs, &cfg, &mut scratch, &mut Spans::default()).is_err());
}

#[test]
fn a_view_whose_ranges_outgrow_the_scratch_loses_only_its_depth() {
    let s = stop();
    // The scratch sized for the level rover's widest row and one group of four
    // disparities more (rolled 15 degrees, the side views' ranges grow by one group).
    let mut cfg = FixConfig::default();
    let level = orbfix::stereo::StereoRig::new(&s.obs.params, &cfg.stereo.matcher).unwrap();
    cfg.stereo.max_disparities = level.buffer_sizes().max_disparities + 4;
    let fits = run_stereo(s, cfg, rights(s)).unwrap();
    assert_eq!(fits.report.reprojection.stereo, Some([None; 4]));
    // Rolled 15 degrees, the front and rear views see the ground slant across their rows:
    // wider ranges than the scratch holds, so those two views lose their depth (a typed
    // error) and the side views keep theirs.
    let mut p = pose(s);
    p.roll_deg = 15.0;
    let out = FixRunner::shipped(cfg)
        .run_with(
            &s.obs.params,
            &p,
            s.obs.frames().unwrap(),
            FixDepth::Stereo(rights(s)),
            &s.product,
        )
        .unwrap();
    let st = out.report.reprojection.stereo.unwrap();
    for v in [0, 2] {
        assert!(
            matches!(st[v], Some(StereoError::BufferSize { needed, got, .. }) if needed > got),
            "view {v}: {:?}",
            st[v]
        );
    }
    assert_eq!((st[1], st[3]), (None, None));
    assert!(out.report.reprojection.valid_cells > 0);
}
