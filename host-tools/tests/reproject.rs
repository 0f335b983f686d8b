//! Reprojection of synthetic flat-ground frames: the core's integer table against the
//! float reference, against the ground truth, across headings, with missing and bad frames.

use image::GrayImage;
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::image::ImageView;
use orbfix::reproject::{
    reproject_top_down, table_len, Cell, FrameStatus, GridSpec, Lut, ReprojectError, Tap,
    DEFAULT_EXTRA,
};
use orbfix_host::reproject::reference::{render_flat_ground, reproject_f64, ripple_texture};

struct TopDown {
    out: Vec<u8>,
    mask: Vec<u8>,
    report: orbfix::reproject::ApplyReport,
}

fn views<'a>(frames: &[Option<&'a GrayImage>; 4]) -> [Option<ImageView<'a>>; 4] {
    frames.map(|f| {
        f.map(|img| {
            ImageView::new(img.as_raw(), img.width() as usize, img.height() as usize).unwrap()
        })
    })
}

fn run_core(
    frames: &[Option<&GrayImage>; 4],
    params: &CameraParams,
    pose: &RoverPose,
    grid: &GridSpec,
) -> TopDown {
    let cells_n = table_len(grid.n);
    let mut cells = vec![Cell::EMPTY; cells_n];
    let mut extra = vec![Tap::EMPTY; DEFAULT_EXTRA];
    let mut out = vec![0u8; cells_n];
    let mut mask = vec![0u8; cells_n];
    let report = reproject_top_down(
        &views(frames),
        params,
        pose,
        grid,
        &mut cells,
        &mut extra,
        &mut out,
        &mut mask,
    )
    .unwrap();
    TopDown { out, mask, report }
}

fn all(frames: &[GrayImage; 4]) -> [Option<&GrayImage>; 4] {
    [
        Some(&frames[0]),
        Some(&frames[1]),
        Some(&frames[2]),
        Some(&frames[3]),
    ]
}

fn ncc(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

#[test]
fn integer_table_matches_float_reference() {
    let params = CameraParams::default();
    let mut pose = RoverPose::level(3.0, -2.0, 1.5, 30.0);
    pose.pitch_deg = 2.0;
    pose.roll_deg = -1.5;
    let frames = render_flat_ground(&params, &pose, ripple_texture).unwrap();
    let grid = GridSpec::default();
    let core = run_core(&all(&frames), &params, &pose, &grid);
    assert!(core.report.all_ok());
    let r = reproject_f64(
        &all(&frames),
        &params,
        &pose,
        grid.n,
        grid.m_per_px as f64,
        f64::INFINITY,
    )
    .unwrap();
    let (mut sum, mut max, mut both, mut disagree) = (0.0f64, 0.0f64, 0usize, 0usize);
    for k in 0..table_len(grid.n) {
        let vi = core.mask[k] == 255;
        if vi != r.valid[k] {
            disagree += 1;
        }
        if vi && r.valid[k] {
            let d = (core.out[k] as f64 - r.value[k]).abs();
            sum += d;
            max = max.max(d);
            both += 1;
        }
    }
    let mean = sum / both as f64;
    eprintln!("int vs f64: {both} cells, mean |d| {mean:.3}, max {max:.3}, validity disagreements {disagree}");
    // Most of the grid is seen (the gaps are the mast's blind disc and far diagonal wedges).
    assert!(both > table_len(grid.n) * 3 / 4, "only {both} valid cells");
    assert!(
        disagree < table_len(grid.n) / 1000,
        "{disagree} cells disagree on validity"
    );
    assert!(mean <= 1.0, "mean abs difference {mean}");
    assert!(max <= 3.0, "max abs difference {max}");
}

#[test]
fn top_down_matches_ground_truth_texture() {
    let params = CameraParams::default();
    let pose = RoverPose::level(-7.0, 11.0, 0.0, 123.0);
    let frames = render_flat_ground(&params, &pose, ripple_texture).unwrap();
    let grid = GridSpec::default();
    let core = run_core(&all(&frames), &params, &pose, &grid);
    let n = grid.n;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for row in 0..n {
        for col in 0..n {
            if core.mask[row * n + col] == 255 {
                let x = pose.x_m as f64 + (col as f64 + 0.5 - 0.5 * n as f64) * 0.25;
                let y = pose.y_m as f64 + (0.5 * n as f64 - row as f64 - 0.5) * 0.25;
                a.push(core.out[row * n + col] as f64);
                b.push(ripple_texture(x, y));
            }
        }
    }
    let c = ncc(&a, &b);
    eprintln!("NCC vs ground truth over {} cells: {c:.4}", a.len());
    assert!(c >= 0.9, "NCC {c}");
    // A wrong orientation (east-west flip) must score far lower: the test can fail.
    let mut flipped = Vec::new();
    for row in 0..n {
        for col in 0..n {
            if core.mask[row * n + col] == 255 {
                let x = pose.x_m as f64 - (col as f64 + 0.5 - 0.5 * n as f64) * 0.25;
                let y = pose.y_m as f64 + (0.5 * n as f64 - row as f64 - 0.5) * 0.25;
                flipped.push(ripple_texture(x, y));
            }
        }
    }
    assert!(ncc(&a, &flipped) < 0.5);
}

#[test]
fn heading_does_not_change_the_north_up_image() {
    let params = CameraParams::default();
    let grid = GridSpec::default();
    let p0 = RoverPose::level(5.0, 5.0, 0.0, 0.0);
    let p1 = RoverPose::level(5.0, 5.0, 0.0, 37.0);
    let f0 = render_flat_ground(&params, &p0, ripple_texture).unwrap();
    let f1 = render_flat_ground(&params, &p1, ripple_texture).unwrap();
    let a = run_core(&all(&f0), &params, &p0, &grid);
    let b = run_core(&all(&f1), &params, &p1, &grid);
    let (mut sum, mut cnt) = (0.0, 0usize);
    let (mut xa, mut xb) = (Vec::new(), Vec::new());
    for k in 0..table_len(grid.n) {
        if a.mask[k] == 255 && b.mask[k] == 255 {
            sum += (a.out[k] as f64 - b.out[k] as f64).abs();
            cnt += 1;
            xa.push(a.out[k] as f64);
            xb.push(b.out[k] as f64);
        }
    }
    let mean = sum / cnt as f64;
    let c = ncc(&xa, &xb);
    eprintln!("heading 0 vs 37: {cnt} common cells, mean |d| {mean:.3}, NCC {c:.4}");
    assert!(cnt > table_len(grid.n) * 2 / 3);
    assert!(mean < 4.0, "mean abs difference {mean}");
    assert!(c > 0.97, "NCC {c}");
    // Reprojecting the rotated frames with the wrong heading must not agree.
    let wrong = run_core(&all(&f1), &params, &p0, &grid);
    let (mut xw, mut xr) = (Vec::new(), Vec::new());
    for k in 0..table_len(grid.n) {
        if a.mask[k] == 255 && wrong.mask[k] == 255 {
            xw.push(wrong.out[k] as f64);
            xr.push(a.out[k] as f64);
        }
    }
    assert!(ncc(&xw, &xr) < 0.6);
}

#[test]
fn missing_black_and_saturated_views_become_no_data() {
    let params = CameraParams::default();
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let frames = render_flat_ground(&params, &pose, ripple_texture).unwrap();
    let grid = GridSpec::default();
    let full = run_core(&all(&frames), &params, &pose, &grid);
    let n = grid.n;
    // Due east of the rover at 10 m: only the right view (heading 0) sees it.
    let east = (n / 2) * n + n / 2 + 40;
    let north = (n / 2 - 40) * n + n / 2;
    assert_eq!(full.mask[east], 255);
    let black = GrayImage::from_pixel(params.width_px, params.height_px, image::Luma([3]));
    let white = GrayImage::from_pixel(params.width_px, params.height_px, image::Luma([255]));
    for (right, expect) in [
        (None, FrameStatus::Missing),
        (Some(&black), FrameStatus::Black),
        (Some(&white), FrameStatus::Saturated),
    ] {
        let fr = [Some(&frames[0]), right, Some(&frames[2]), Some(&frames[3])];
        let t = run_core(&fr, &params, &pose, &grid);
        assert_eq!(t.report.status[1], expect);
        assert!(!t.report.all_ok());
        assert_eq!(
            t.mask[east], 0,
            "{expect:?}: right-only cell must be no data"
        );
        assert_eq!(t.out[east], 0);
        assert_eq!(t.mask[north], 255);
        assert_eq!(t.out[north], full.out[north]);
        assert!(t.report.lost_cells > 1000);
        assert_eq!(
            t.report.valid_cells + t.report.lost_cells,
            full.report.valid_cells
        );
        // Nothing from the bad frame leaks in: every valid cell is close to the full output.
        for k in 0..table_len(n) {
            if t.mask[k] == 255 {
                assert!(
                    (t.out[k] as i32 - full.out[k] as i32).abs() <= 40,
                    "cell {k}"
                );
            }
        }
    }
    let none: [Option<&GrayImage>; 4] = [None; 4];
    let t = run_core(&none, &params, &pose, &grid);
    assert_eq!(t.report.valid_cells, 0);
    assert!(t.mask.iter().all(|&m| m == 0));
}

#[test]
fn table_build_rejects_bad_inputs() {
    let params = CameraParams::default();
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let grid = GridSpec::new(64, 0.5);
    let mut cells = vec![Cell::EMPTY; 64 * 64];
    let mut extra = vec![Tap::EMPTY; 512];
    let lut = Lut::build(&mut cells, &mut extra, &params, &pose, &grid, 640).unwrap();
    let small = GrayImage::new(320, 180);
    let good = GrayImage::from_pixel(640, 360, image::Luma([100]));
    let fr = views(&[Some(&good), Some(&small), None, None]);
    let mut out = vec![0u8; 64 * 64];
    let mut mask = vec![0u8; 64 * 64];
    assert_eq!(
        lut.apply(&fr, &mut out, &mut mask),
        Err(ReprojectError::FrameSize {
            view: 1,
            expected: (640, 360),
            got: (320, 180)
        })
    );
    let fr = views(&[Some(&good), None, None, None]);
    assert!(matches!(
        lut.apply(&fr, &mut out[..10], &mut mask),
        Err(ReprojectError::BufferSize { .. })
    ));
    let r = lut.apply(&fr, &mut out, &mut mask).unwrap();
    assert_eq!(r.status[0], FrameStatus::Ok);
    assert!(r.valid_cells > 0);
    // Uniform frame in: uniform out wherever valid (weights sum to exactly 1).
    assert!(out
        .iter()
        .zip(&mask)
        .all(|(&o, &m)| (m == 255 && o == 100) || (m == 0 && o == 0)));
}
