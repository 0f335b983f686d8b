//! Banded reprojection table ([`Lut::build_rows`]): applying the bands one after the other
//! must give the whole table's top-down image, mask and statistics bit for bit.

use orbfix::camera::{CameraParams, RoverPose};
use orbfix::image::ImageView;
use orbfix::reproject::{
    classify_frame, ApplyReport, Buffer, BuildStats, Cell, FrameStatus, GridSpec, Lut,
    ReprojectError, Tap,
};

/// Deterministic textured frames (xorshift noise smoothed along rows so bilinear weights
/// matter), one per view, `w x h` with stride `w`.
fn frames(w: usize, h: usize, seed: u32) -> Vec<Vec<u8>> {
    (0..4u32)
        .map(|v| {
            let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(v + 1) | 1;
            let mut prev = 128u32;
            (0..w * h)
                .map(|_| {
                    s ^= s << 13;
                    s ^= s >> 17;
                    s ^= s << 5;
                    prev = (prev * 3 + (s & 255)) / 4;
                    prev as u8
                })
                .collect()
        })
        .collect()
}

struct Out {
    top: Vec<u8>,
    mask: Vec<u8>,
    stats: BuildStats,
    report: ApplyReport,
}

fn whole(
    p: &CameraParams,
    pose: &RoverPose,
    g: &GridSpec,
    views: &[Option<ImageView<'_>>; 4],
) -> Out {
    let n = g.n;
    let mut cells = vec![Cell::EMPTY; n * n];
    let mut extra = vec![Tap::EMPTY; n * n];
    let lut = Lut::build(&mut cells, &mut extra, p, pose, g, p.width_px as usize).unwrap();
    let mut top = vec![7u8; n * n];
    let mut mask = vec![7u8; n * n];
    let report = lut.apply(views, &mut top, &mut mask).unwrap();
    Out {
        top,
        mask,
        stats: *lut.stats(),
        report,
    }
}

fn banded(
    p: &CameraParams,
    pose: &RoverPose,
    g: &GridSpec,
    views: &[Option<ImageView<'_>>; 4],
    band_rows: usize,
) -> Out {
    let n = g.n;
    // One band's worth of cells and taps, reused for every band.
    let mut cells = vec![Cell::EMPTY; band_rows * n];
    let mut extra = vec![Tap::EMPTY; band_rows * n];
    let mut top = vec![7u8; n * n];
    let mut mask = vec![7u8; n * n];
    let mut stats = BuildStats::default();
    let mut report: Option<ApplyReport> = None;
    // Classified once for all bands (what the flight fix does).
    let status = views.map(|f| f.as_ref().map_or(FrameStatus::Missing, classify_frame));
    let mut row = 0;
    while row < n {
        let end = (row + band_rows).min(n);
        let c = &mut cells[..(end - row) * n];
        let lut =
            Lut::build_rows(c, &mut extra, p, pose, g, p.width_px as usize, row..end).unwrap();
        assert_eq!(lut.rows(), (row, end));
        let a = lut
            .apply_with_status(
                views,
                &status,
                &mut top[row * n..end * n],
                &mut mask[row * n..end * n],
            )
            .unwrap();
        let s = lut.stats();
        stats.valid_cells += s.valid_cells;
        stats.blended_cells += s.blended_cells;
        stats.dropped_taps += s.dropped_taps;
        for (t, v) in stats.cells_per_view.iter_mut().zip(s.cells_per_view) {
            *t += v;
        }
        report = Some(match report {
            None => a,
            Some(r) => {
                assert_eq!(r.status, a.status);
                ApplyReport {
                    status: r.status,
                    valid_cells: r.valid_cells + a.valid_cells,
                    lost_cells: r.lost_cells + a.lost_cells,
                }
            }
        });
        row = end;
    }
    Out {
        top,
        mask,
        stats,
        report: report.unwrap(),
    }
}

#[test]
fn bands_equal_the_whole_table_bit_for_bit() {
    let p = CameraParams::default();
    let (w, h) = (p.width_px as usize, p.height_px as usize);
    let data = frames(w, h, 1);
    let all: Vec<ImageView<'_>> = data
        .iter()
        .map(|d| ImageView::new(d, w, h).unwrap())
        .collect();
    let dark = vec![0u8; w * h];
    let black = ImageView::new(&dark, w, h).unwrap();
    let g = GridSpec::new(200, 0.25);
    let poses = [
        RoverPose::level(10.0, -4.0, 0.0, 0.0),
        RoverPose {
            x_m: 3.0,
            y_m: 2.0,
            ground_z_m: 1.5,
            heading_deg: 37.0,
            pitch_deg: 4.0,
            roll_deg: -3.0,
        },
    ];
    for pose in &poses {
        // All four frames (the run-length fast path), one missing and one black (fallback
        // taps, lost cells).
        let sets = [
            [Some(all[0]), Some(all[1]), Some(all[2]), Some(all[3])],
            [Some(all[0]), None, Some(all[2]), Some(all[3])],
            [Some(all[0]), Some(all[1]), Some(black), Some(all[3])],
        ];
        for views in &sets {
            let want = whole(&p, pose, &g, views);
            assert!(want.stats.valid_cells > 10_000, "{:?}", want.stats);
            assert!(want.stats.blended_cells > 100, "{:?}", want.stats);
            assert_eq!(want.stats.dropped_taps, 0);
            for band_rows in [25, 7, 1, 200] {
                let got = banded(&p, pose, &g, views, band_rows);
                assert!(got.top == want.top, "top, {band_rows} rows per band");
                assert!(got.mask == want.mask, "mask, {band_rows} rows per band");
                assert_eq!(got.stats, want.stats, "{band_rows} rows per band");
                assert_eq!(got.report, want.report, "{band_rows} rows per band");
            }
        }
    }
}

#[test]
fn bad_bands_are_typed_errors() {
    let p = CameraParams::default();
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let g = GridSpec::new(20, 0.5);
    let mut cells = vec![Cell::EMPTY; 5 * 20];
    let mut extra = vec![Tap::EMPTY; 4];
    let mut build = |cells: &mut [Cell], rows: core::ops::Range<usize>| {
        Lut::build_rows(cells, &mut extra, &p, &pose, &g, 640, rows).map(|l| l.rows())
    };
    assert_eq!(build(&mut cells, 3..3), Err(ReprojectError::BadBand));
    assert_eq!(build(&mut cells, 16..21), Err(ReprojectError::BadBand));
    assert_eq!(
        build(&mut cells, 0..4),
        Err(ReprojectError::BufferSize {
            buffer: Buffer::Cells,
            needed: 80,
            got: 100
        })
    );
    assert_eq!(build(&mut cells, 15..20), Ok((15, 20)));
}

#[test]
fn given_status_leaves_views_out_and_still_checks_sizes() {
    let p = CameraParams::default();
    let (w, h) = (p.width_px as usize, p.height_px as usize);
    let data = frames(w, h, 2);
    let v: Vec<ImageView<'_>> = data
        .iter()
        .map(|d| ImageView::new(d, w, h).unwrap())
        .collect();
    let views = [Some(v[0]), Some(v[1]), Some(v[2]), Some(v[3])];
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let g = GridSpec::new(40, 0.5);
    let mut cells = vec![Cell::EMPTY; 40 * 40];
    let mut extra = vec![Tap::EMPTY; 40 * 40];
    let lut = Lut::build(&mut cells, &mut extra, &p, &pose, &g, w).unwrap();
    let (mut top, mut mask) = (vec![0u8; 1600], vec![0u8; 1600]);
    let ok = [FrameStatus::Ok; 4];
    let all = lut
        .apply_with_status(&views, &ok, &mut top, &mut mask)
        .unwrap();
    assert_eq!(all, lut.apply(&views, &mut top, &mut mask).unwrap());
    // The front view marked missing: as if its frame were None.
    let mut st = ok;
    st[0] = FrameStatus::Missing;
    let (mut t2, mut m2) = (vec![0u8; 1600], vec![0u8; 1600]);
    let got = lut
        .apply_with_status(&views, &st, &mut t2, &mut m2)
        .unwrap();
    let none = [None, Some(v[1]), Some(v[2]), Some(v[3])];
    let want = lut.apply(&none, &mut top, &mut mask).unwrap();
    assert_eq!(got, want);
    assert!(got.lost_cells > 0);
    assert!(t2 == top && m2 == mask);
    // Wrong frame size is still an error, whatever the status says.
    let small = ImageView::new(&data[0][..w * 10], w, 10).unwrap();
    let bad = [Some(small), Some(v[1]), Some(v[2]), Some(v[3])];
    assert!(matches!(
        lut.apply_with_status(&bad, &ok, &mut t2, &mut m2),
        Err(ReprojectError::FrameSize { view: 0, .. })
    ));
}

/// A depth image reduced by `k` and expanded back ([`orbfix::reproject::DepthExpander`])
/// puts every frame row of flat ground at its own distance: the expanded depth of each row
/// is the row's own flat-ground depth (to a millimetre and the Q16 rounding), where plain
/// replication is off by up to the depth change across `k` rows.
#[test]
fn expanded_reduced_depth_follows_flat_ground_row_by_row() {
    use orbfix::camera::{Camera, View};
    use orbfix::reproject::DepthExpander;
    let p = CameraParams::default();
    let pose = RoverPose::level(10.0, -4.0, 0.0, 33.0);
    let (w, h) = (p.width_px as usize, p.height_px as usize);
    for view in View::ALL {
        let cam = Camera::new(&p, &pose, view).unwrap();
        // Camera depth (mm) of flat ground at frame row `row` (fractional), centre column.
        let r = cam.world_to_cam;
        let ground_mm = |row: f32| -> Option<f32> {
            let vv = (row + 0.5 - cam.cy) / cam.focal_px;
            let uu = (0.5 * w as f32 - cam.cx) / cam.focal_px;
            let up = r[(2, 2)] + r[(1, 2)] * vv + r[(0, 2)] * uu;
            (up < -1e-3).then(|| 1000.0 * p.height_m / -up)
        };
        let ex = DepthExpander::new(&p, &pose, view).unwrap();
        for k in [2usize, 4] {
            let (mut worst, mut worst_rep) = (0f32, 0f32);
            let mut out = vec![0u16; w];
            for j in 0..h {
                let centre = ((j / k) as f32 + 0.5) * k as f32 - 0.5;
                let (Some(zc), Some(zj)) = (ground_mm(centre), ground_mm(j as f32)) else {
                    continue;
                };
                if zc > 60_000.0 || zj > 60_000.0 {
                    continue;
                }
                let src = vec![zc.round() as u16; w.div_ceil(k)];
                ex.expand_row(j, k, &src, &mut out);
                // The reduced depth is rounded to the millimetre; then the Q16 scale.
                let rel = ((out[w / 2] as f32 - zj).abs() - 1.0).max(0.0) / zj;
                worst = worst.max(rel);
                worst_rep = worst_rep.max((zc - zj).abs() / zj);
                // No data stays no data.
                let mut none = vec![7u16; w];
                ex.expand_row(j, k, &vec![0u16; w.div_ceil(k)], &mut none);
                assert!(none.iter().all(|&d| d == 0));
            }
            assert!(
                worst < 1e-4,
                "{view:?} k {k}: expanded depth off by {worst:.2e} beyond 1 mm"
            );
            assert!(
                worst_rep > 5e-3,
                "{view:?} k {k}: replication would be off by {worst_rep:.2e}"
            );
        }
    }
}

/// Far depths scaled up by [`orbfix::reproject::DepthExpander`] saturate at the largest
/// depth instead of wrapping round to a small one (which would put a far pixel next to
/// the rover): every row of every view, the largest reduced depth in, a depth at least as
/// large as the row's scale gives (or `u16::MAX`) out.
#[test]
fn expanded_far_depth_saturates_not_wraps() {
    use orbfix::camera::View;
    use orbfix::reproject::DepthExpander;
    let p = CameraParams::default();
    let pose = RoverPose::level(10.0, -4.0, 0.0, 33.0);
    let (w, h) = (p.width_px as usize, p.height_px as usize);
    let mut scaled_up = 0;
    for view in View::ALL {
        let ex = DepthExpander::new(&p, &pose, view).unwrap();
        for k in [2usize, 4] {
            let mut out = vec![0u16; w];
            for j in 0..h {
                for far in [40_000u16, u16::MAX] {
                    ex.expand_row(j, k, &vec![far; w.div_ceil(k)], &mut out);
                    // A scale is at least 1/4: a far depth never comes out near.
                    assert!(
                        out.iter().all(|&d| d >= far / 4),
                        "{view:?} k {k} row {j}: depth {far} expanded to {}",
                        out[0]
                    );
                    if far == u16::MAX && out[0] == u16::MAX {
                        scaled_up += 1;
                    }
                }
            }
        }
    }
    // Rows whose scale exceeds 1 were exercised (they saturate).
    assert!(
        scaled_up > 100,
        "only {scaled_up} rows scaled a far depth up"
    );
}
