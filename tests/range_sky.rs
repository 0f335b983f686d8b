//! The range stage's sky rule ([`RangeOptions::sky_below_gray`]): frame pixels darker than
//! the threshold get no depth in [`RangeAccumulator::add_rows`], the on-board stereo's path.

use orbfix::camera::{CameraParams, RoverPose, View};
use orbfix::image::ImageView;
use orbfix::reproject::{
    range_scratch_len, DepthBand, GridSpec, RangeAccumulator, RangeOptions, RangeReport,
};

/// Places the front view of a flat-ground depth image (millimetres, `factor` times
/// smaller) with `frame`, returning the top-down image, its mask and the report.
fn place_front(
    frame: &[u8],
    depth: &[u16],
    factor: usize,
    sky: u8,
) -> (Vec<u8>, Vec<u8>, RangeReport) {
    let (cam, pose) = (
        CameraParams::default(),
        RoverPose::level(0.0, 0.0, 0.0, 0.0),
    );
    let grid = GridSpec::new(200, 0.25);
    let opts = RangeOptions {
        sky_below_gray: sky,
        ..RangeOptions::default()
    };
    let mut scratch = vec![0u32; range_scratch_len(grid.n)];
    let mut mask = vec![0u8; grid.cells()];
    let mut acc =
        RangeAccumulator::new(&cam, &pose, &grid, &opts, &mut scratch, &mut mask).unwrap();
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    let view = ImageView::new(frame, w, h).unwrap();
    let band = DepthBand {
        data: depth,
        width: w / factor,
        first_row: 0,
        factor,
    };
    let mut row_buf = vec![0u16; w];
    acc.add_rows(View::Front, &view, 0..h, &band, &mut row_buf)
        .unwrap();
    let mut out = vec![0u8; grid.cells()];
    let rep = acc.finish(&mut out).unwrap();
    (out, mask, rep)
}

#[test]
fn dark_pixels_get_no_depth_when_the_sky_rule_is_on() {
    let cam = CameraParams::default();
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    let (f, t) = (cam.focal_px(), cam.tilt_deg.to_radians());
    // Flat ground 2 m down at `factor` times less resolution.
    let flat = |factor: usize| -> Vec<u16> {
        let (wr, hr) = (w / factor, h / factor);
        let mut d = vec![0u16; wr * hr];
        for (j, row) in d.chunks_mut(wr).enumerate() {
            let yn = ((j * factor) as f32 + 0.5 * factor as f32 - 0.5 * h as f32) / f;
            let s = libm::sinf(t) + yn * libm::cosf(t);
            if s > 0.0 {
                row.fill((1000.0 * cam.height_m / s).min(60_000.0) as u16);
            }
        }
        d
    };
    // Lit ground, and a black band (the sky's gray, 0..=7) over its left third; 8 and
    // above (the deepest shadow is about 29) stays.
    let mut frame = vec![100u8; w * h];
    for row in frame.chunks_mut(w) {
        for (x, g) in row.iter_mut().enumerate().take(w / 3) {
            *g = (x % 10) as u8;
        }
    }
    let depth = flat(1);
    let (on, on_mask, on_rep) = place_front(&frame, &depth, 1, 8);
    // The same as depth images without depth where the frame is darker than 8.
    let mut cut = depth.clone();
    for (d, &g) in cut.iter_mut().zip(&frame) {
        if g < 8 {
            *d = 0;
        }
    }
    let (by_hand, by_hand_mask, by_hand_rep) = place_front(&frame, &cut, 1, 0);
    assert_eq!(on, by_hand);
    assert_eq!(on_mask, by_hand_mask);
    assert_eq!(on_rep.points_used, by_hand_rep.points_used);
    // Off: every pixel with depth is placed, the dark ones too.
    let (_, _, off_rep) = place_front(&frame, &depth, 1, 0);
    assert!(off_rep.points_used > on_rep.points_used + on_rep.points_used / 4);
    // The on-board stereo's path (depth at half resolution, expanded per row): the
    // same pixels go.
    let half = flat(2);
    let (_, _, on2) = place_front(&frame, &half, 2, 8);
    let (_, _, off2) = place_front(&frame, &half, 2, 0);
    assert!(off2.points_used > on2.points_used + on2.points_used / 4);
    assert!(on2.valid_cells < off2.valid_cells);
}
