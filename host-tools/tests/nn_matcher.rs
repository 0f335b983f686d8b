//! The int8 CNN behind the `Matcher` trait: dense agrees with per-window scores, scores are
//! cosines, bad input is a typed error.

use orbfix::image::ImageView;
use orbfix::matcher::{MatchError, Matcher, OpCounts};
use orbfix::nn::matcher::CnnMatcher;
use orbfix::nn::model::embedding_macs;
use orbfix_host::nn::data::{render_ortho, rover_proxy, RoverAug, Sun, TEST_ZONE};
use orbfix_host::world::World;
use rand::rngs::StdRng;
use rand::SeedableRng;

#[test]
fn cnn_matcher_dense_matches_score_and_rejects_bad_input() {
    let m = CnnMatcher::shipped().expect("shipped weights");
    let world = World::new(1);
    let (x, y) = TEST_ZONE.centre();
    let sun = Sun {
        elevation_deg: 30.0,
        azimuth_deg: 135.0,
    };
    let aug = RoverAug {
        heading_deg: 0.0,
        missing_view: None,
        gain: 1.0,
        offset: 0.0,
        noise: 1.0,
    };
    let (top, mask) = rover_proxy(&world, x, y, sun, &aug, &mut StdRng::seed_from_u64(1));
    // 75 m x 75 m region at 0.25 m/px, windows every 12.5 m: 3 x 3, truth in the middle.
    let region = render_ortho(&world, x, y, 300, 0.25, sun);
    let t = ImageView::new(&top, 200, 200).unwrap();
    let w = ImageView::new(&mask, 200, 200).unwrap();
    let r = ImageView::new(&region, 300, 300).unwrap();
    let mut ops = OpCounts::default();
    let mut out = [0f32; 9];
    let g = m.dense(&t, &w, &r, 50, &mut out, &mut ops).unwrap();
    assert_eq!((g.cols(), g.rows()), (3, 3));
    assert_eq!(ops.windows, 9);
    assert_eq!(ops.macs, 10 * embedding_macs() + 9 * 2048);
    assert!(out.iter().all(|s| (-1.0..=1.0).contains(s)));
    let mut ops2 = OpCounts::default();
    let s4 = m
        .score(&t, &w, &r.sub(50, 50, 200, 200).unwrap(), &mut ops2)
        .unwrap();
    assert_eq!(s4, out[4]);
    // A featureless template is an error; a mask of the wrong size too.
    let flat = vec![90u8; 200 * 200];
    let f = ImageView::new(&flat, 200, 200).unwrap();
    assert_eq!(
        m.score(&f, &w, &r, &mut ops2),
        Err(MatchError::FeaturelessTemplate)
    );
    let small = ImageView::new(&mask[..100 * 100], 100, 100).unwrap();
    assert_eq!(
        m.score(&t, &small, &r, &mut ops2),
        Err(MatchError::MaskSizeMismatch)
    );
    let none = vec![0u8; 200 * 200];
    let n = ImageView::new(&none, 200, 200).unwrap();
    assert_eq!(
        m.score(&t, &n, &r, &mut ops2),
        Err(MatchError::NoValidPixels)
    );
}
