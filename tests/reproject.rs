//! Core reprojection: typed errors, table layout and sizes, frame classification.

use orbfix::camera::{CameraError, CameraParams, RoverPose};
use orbfix::image::ImageView;
use orbfix::reproject::{
    classify_frame, table_bytes, table_len, Buffer, Cell, DefaultLutStorage, FrameStatus, GridSpec,
    Lut, LutStorage, ReprojectError, Tap, DEFAULT_EXTRA,
};

fn build_err(
    params: CameraParams,
    pose: RoverPose,
    grid: GridSpec,
    cells: usize,
    stride: usize,
) -> ReprojectError {
    let mut c = vec![Cell::EMPTY; cells];
    let mut e = vec![Tap::EMPTY; 16];
    Lut::build(&mut c, &mut e, &params, &pose, &grid, stride).unwrap_err()
}

#[test]
fn sizes_are_fixed_and_stated() {
    assert_eq!(core::mem::size_of::<Cell>(), 8);
    assert_eq!(core::mem::size_of::<Tap>(), 8);
    assert_eq!(table_len(200), 40_000);
    assert_eq!(table_bytes(200), 320_000);
    assert_eq!(DefaultLutStorage::bytes(), 320_000 + 8 * DEFAULT_EXTRA);
    assert_eq!(LutStorage::<16, 4>::bytes(), 160);
}

#[test]
fn rejects_bad_parameters_with_typed_errors() {
    let p = CameraParams::default();
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let g = GridSpec::new(8, 0.5);
    let bad = |f: fn(&mut CameraParams)| {
        let mut q = p;
        f(&mut q);
        build_err(q, pose, g, 64, 640)
    };
    assert_eq!(
        bad(|q| q.tilt_deg = f32::NAN),
        ReprojectError::Camera(CameraError::TiltOutOfRange)
    );
    assert_eq!(
        bad(|q| q.tilt_deg = 95.0),
        ReprojectError::Camera(CameraError::TiltOutOfRange)
    );
    assert_eq!(
        bad(|q| q.hfov_deg = 0.0),
        ReprojectError::Camera(CameraError::FovOutOfRange)
    );
    assert_eq!(
        bad(|q| q.hfov_deg = f32::NAN),
        ReprojectError::Camera(CameraError::FovOutOfRange)
    );
    assert_eq!(
        bad(|q| q.height_m = 0.0),
        ReprojectError::Camera(CameraError::HeightOutOfRange)
    );
    assert_eq!(
        bad(|q| q.width_px = 0),
        ReprojectError::Camera(CameraError::ZeroImageSize)
    );
    let mut nan_pose = pose;
    nan_pose.heading_deg = f32::NAN;
    assert_eq!(
        build_err(p, nan_pose, g, 64, 640),
        ReprojectError::Camera(CameraError::NonFinitePose)
    );
    assert_eq!(
        build_err(p, pose, GridSpec::new(0, 0.5), 0, 640),
        ReprojectError::BadGridSize
    );
    assert_eq!(
        build_err(p, pose, GridSpec::new(8, 0.0), 64, 640),
        ReprojectError::BadResolution
    );
    assert_eq!(
        build_err(p, pose, GridSpec::new(8, f32::NAN), 64, 640),
        ReprojectError::BadResolution
    );
    let mut g2 = g;
    g2.max_range_m = f32::NAN;
    assert_eq!(build_err(p, pose, g2, 64, 640), ReprojectError::BadMaxRange);
    assert_eq!(
        build_err(p, pose, g, 63, 640),
        ReprojectError::BufferSize {
            buffer: Buffer::Cells,
            needed: 64,
            got: 63
        }
    );
    assert_eq!(
        build_err(p, pose, g, 64, 639),
        ReprojectError::FrameTooSmall
    );
    let mut huge = p;
    huge.width_px = 1 << 16;
    huge.height_px = 1 << 15;
    assert_eq!(
        build_err(huge, pose, g, 64, 1 << 16),
        ReprojectError::FrameTooLarge
    );
}

#[test]
fn stride_and_range_are_honoured() {
    let p = CameraParams::default();
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let mut g = GridSpec::new(40, 1.0);
    g.max_range_m = 10.0;
    let mut cells = vec![Cell::EMPTY; 1600];
    let mut extra = vec![Tap::EMPTY; 64];
    let lut = Lut::build(&mut cells, &mut extra, &p, &pose, &g, 700).unwrap();
    assert_eq!(lut.frame_stride(), 700);
    // Cells beyond 10 m (corners of a 40 m grid) are no data; the ring at ~6 m has data.
    assert!(!lut.cells()[0].is_valid());
    assert!(lut.cells()[20 * 40 + 26].is_valid());
    let s = lut.stats();
    assert!(s.valid_cells < 1600 && s.valid_cells > 200);
    assert_eq!(s.cells_per_view.iter().sum::<usize>(), s.valid_cells);
    // Each view takes about a quarter of the disc.
    for c in s.cells_per_view {
        assert!(
            c * 5 > s.valid_cells && c * 3 < s.valid_cells,
            "{:?}",
            s.cells_per_view
        );
    }
    let buf = vec![50u8; 700 * 360];
    let tight = vec![50u8; 640 * 360];
    let strided = ImageView::with_stride(&buf, 640, 360, 700).unwrap();
    let packed = ImageView::new(&tight, 640, 360).unwrap();
    let mut out = vec![0u8; 1600];
    let mut mask = vec![0u8; 1600];
    assert_eq!(
        lut.apply(&[Some(packed), None, None, None], &mut out, &mut mask),
        Err(ReprojectError::FrameStride {
            view: 0,
            expected: 700,
            got: 640
        })
    );
    let r = lut.apply(&[Some(strided); 4], &mut out, &mut mask).unwrap();
    assert_eq!(r.valid_cells, s.valid_cells);
    assert!(out
        .iter()
        .zip(&mask)
        .all(|(&o, &m)| o == if m == 255 { 50 } else { 0 }));
}

#[test]
fn full_secondary_table_drops_feathering_not_data() {
    let p = CameraParams::default();
    let pose = RoverPose::level(0.0, 0.0, 0.0, 10.0);
    let g = GridSpec::new(100, 0.5);
    let mut c1 = vec![Cell::EMPTY; 10_000];
    let mut e1 = vec![Tap::EMPTY; 2_000];
    let full = Lut::build(&mut c1, &mut e1, &p, &pose, &g, 640).unwrap();
    let mut c2 = vec![Cell::EMPTY; 10_000];
    let mut e2: Vec<Tap> = Vec::new();
    let none = Lut::build(&mut c2, &mut e2, &p, &pose, &g, 640).unwrap();
    assert!(full.stats().blended_cells > 0);
    assert_eq!(full.stats().dropped_taps, 0);
    assert_eq!(none.stats().blended_cells, 0);
    assert_eq!(none.stats().dropped_taps, full.stats().blended_cells);
    assert_eq!(none.stats().valid_cells, full.stats().valid_cells);
    assert_eq!(full.bytes(), 8 * 10_000 + 8 * full.stats().blended_cells);
}

#[test]
fn classifies_black_saturated_and_normal_frames() {
    let w = 200;
    let h = 100;
    let mut img = vec![0u8; w * h];
    assert_eq!(
        classify_frame(&ImageView::new(&img, w, h).unwrap()),
        FrameStatus::Black
    );
    img.iter_mut().for_each(|p| *p = 252);
    assert_eq!(
        classify_frame(&ImageView::new(&img, w, h).unwrap()),
        FrameStatus::Saturated
    );
    // A dark sky over the top quarter and lit ground below is a normal frame.
    for (i, p) in img.iter_mut().enumerate() {
        *p = if i / w < h / 4 { 0 } else { 90 + (i % 7) as u8 };
    }
    assert_eq!(
        classify_frame(&ImageView::new(&img, w, h).unwrap()),
        FrameStatus::Ok
    );
}

#[test]
fn compile_time_storage_builds_a_table() {
    let mut s: Box<LutStorage<{ 32 * 32 }, 64>> = Box::new(LutStorage::new());
    let p = CameraParams::default();
    let pose = RoverPose::level(1.0, 2.0, 3.0, 45.0);
    let LutStorage { cells, extra } = &mut *s;
    let lut = Lut::build(cells, extra, &p, &pose, &GridSpec::new(32, 1.0), 640).unwrap();
    assert!(lut.stats().valid_cells > 500);
}
