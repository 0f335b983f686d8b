//! The core's integer range reprojection on rendered views: against the host `f64`
//! reference, against the flat-ground LUT on a flat world, and against the satellite crop
//! on the relief world (where it must beat the LUT).

use orbfix::camera::{CameraParams, View};
use orbfix::image::ImageView;
use orbfix::reproject::{
    range_scratch_len, reproject_range, DepthView, FrameStatus, GridSpec, RangeAccumulator,
    RangeError, RangeOptions, ReprojectError,
};
use orbfix_host::eval::pipeline::{
    make_queries, map_region, reproject_by_range, reproject_depths, reproject_views, Condition,
};
use orbfix_host::eval::TopDown;
use orbfix_host::render::{self, RenderOptions, Sun, ViewSet};
use orbfix_host::reproject::depth::{depth_images, StereoNoise};
use orbfix_host::world::World;

fn small_render() -> RenderOptions {
    RenderOptions {
        camera: CameraParams {
            width_px: 320,
            height_px: 180,
            ..CameraParams::default()
        }
        .into(),
        ..RenderOptions::default()
    }
}

fn masked_ncc(a: &[u8], b: &[u8], mask: &[u8]) -> f64 {
    let idx: Vec<usize> = (0..a.len()).filter(|&k| mask[k] != 0).collect();
    let n = idx.len() as f64;
    let ma = idx.iter().map(|&k| a[k] as f64).sum::<f64>() / n;
    let mb = idx.iter().map(|&k| b[k] as f64).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for &k in &idx {
        let (x, y) = (a[k] as f64 - ma, b[k] as f64 - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    sab / (saa * sbb).sqrt()
}

/// Mean absolute difference over cells valid in both, and that cell count.
fn mean_diff(a: &TopDown, b: &TopDown) -> (f64, usize) {
    let mut s = 0.0;
    let mut n = 0usize;
    for k in 0..a.image.len() {
        if a.mask[k] != 0 && b.mask[k] != 0 {
            s += (a.image[k] as f64 - b.image[k] as f64).abs();
            n += 1;
        }
    }
    (s / n.max(1) as f64, n)
}

fn render_at(world: &World, x: f64, y: f64, heading: f64, r: &RenderOptions) -> ViewSet {
    let pose = render::ground_pose(world, x, y, heading);
    render::render_views_with_range(world, &pose, Sun::default(), r).unwrap()
}

/// Stop `i` of the first `n` same-sun test-zone stops of `world`: its pose, its views and
/// their exact depth images.
fn stop_with_depths(
    world: &World,
    n: usize,
    i: usize,
    r: &RenderOptions,
) -> (orbfix::camera::RoverPose, ViewSet, [Vec<u16>; 4]) {
    let q = make_queries(1, n, Condition::SameSun)[i];
    let pose = render::ground_pose(world, q.x_m, q.y_m, q.heading_deg);
    let set = render_at(world, q.x_m, q.y_m, q.heading_deg, r);
    let depths = depth_images(&set, None).unwrap();
    (pose, set, depths)
}

#[test]
fn core_range_matches_f64_reference_on_relief() {
    let world = World::new(1);
    let r = small_render();
    let (pose, set, depths) = stop_with_depths(&world, 1, 0, &r);
    let grid = GridSpec::default();
    let reference = reproject_by_range(&set, &pose, &grid);
    let (core, report) = reproject_depths(&set.views, &depths, &r, &pose, &grid).unwrap();
    assert!(report.status.iter().all(|s| *s == FrameStatus::Ok));
    let (d, common) = mean_diff(&core, &reference);
    let ref_valid = reference.mask.iter().filter(|&&m| m != 0).count();
    eprintln!(
        "core vs f64 reference: mean |diff| {d:.3} gray over {common} cells (reference {ref_valid}, core {} of which {} filled)",
        report.valid_cells, report.filled_cells
    );
    assert!(d < 1.5, "mean diff {d}");
    // Nearly every reference cell is reproduced (millimetre depths move few points across
    // a cell edge), and filling adds cells without removing any.
    assert!(
        common as f64 > 0.97 * ref_valid as f64,
        "{common} of {ref_valid}"
    );
    assert!(report.valid_cells >= common);
    assert_eq!(
        report.points_used + report.points_dropped,
        report.pixels_read
    );
    assert_eq!(report.pixels_read, 4 * 320 * 180);

    // The incremental API, one view at a time, gives the same image; one view alone gives
    // a subset of the cells.
    let params = r.camera_params();
    let mut scratch = vec![0u32; range_scratch_len(grid.n)];
    let (mut out, mut mask) = (vec![0u8; grid.cells()], vec![0u8; grid.cells()]);
    let mut acc = RangeAccumulator::new(
        &params,
        &pose,
        &grid,
        &RangeOptions::default(),
        &mut scratch,
        &mut mask,
    )
    .unwrap();
    for (k, view) in View::ALL.into_iter().enumerate() {
        let f = ImageView::new(set.views[k].as_raw(), 320, 180).unwrap();
        let d = DepthView::new(&depths[k], 320, 180).unwrap();
        assert_eq!(acc.add_view(view, &f, Some(&d)).unwrap(), FrameStatus::Ok);
    }
    let rep2 = acc.finish(&mut out).unwrap();
    assert_eq!(rep2, report);
    assert_eq!(out, core.image);
    assert_eq!(mask, core.mask);
    let mut acc = RangeAccumulator::new(
        &params,
        &pose,
        &grid,
        &RangeOptions::default(),
        &mut scratch,
        &mut mask,
    )
    .unwrap();
    let f = ImageView::new(set.views[0].as_raw(), 320, 180).unwrap();
    let d = DepthView::new(&depths[0], 320, 180).unwrap();
    acc.add_view(View::Front, &f, Some(&d)).unwrap();
    let front = acc.finish(&mut out).unwrap();
    assert_eq!(front.pixels_read, 320 * 180);
    assert!(front.valid_cells > 1000 && front.valid_cells < report.valid_cells / 2);
}

#[test]
fn flat_world_range_agrees_with_lut() {
    let world = World::flat(2);
    let r = small_render();
    let q = make_queries(2, 1, Condition::SameSun)[0];
    let pose = render::ground_pose(&world, q.x_m, q.y_m, q.heading_deg);
    let set = render_at(&world, q.x_m, q.y_m, q.heading_deg, &r);
    let grid = GridSpec::default();
    let lut = reproject_views(&set.views, &r, &pose, &grid).unwrap();
    let depths = depth_images(&set, None).unwrap();
    let (range, _) = reproject_depths(&set.views, &depths, &r, &pose, &grid).unwrap();
    let (d, common) = mean_diff(&range, &lut);
    eprintln!("flat world: range vs LUT mean |diff| {d:.2} gray over {common} cells");
    assert!(common > 15_000, "{common}");
    assert!(d < 6.0, "mean diff {d}");
}

#[test]
fn relief_world_range_beats_lut_against_satellite() {
    let world = World::new(1);
    let r = small_render();
    let grid = GridSpec::default();
    let mut worse = 0;
    for q in make_queries(7, 2, Condition::SameSun) {
        let pose = render::ground_pose(&world, q.x_m, q.y_m, q.heading_deg);
        let set = render_at(&world, q.x_m, q.y_m, q.heading_deg, &r);
        let sat = map_region(&world, q.x_m, q.y_m, grid.n, 0.25, Sun::default(), &r).unwrap();
        let lut = reproject_views(&set.views, &r, &pose, &grid).unwrap();
        let noise = StereoNoise {
            k_per_m: 0.001,
            seed: 5,
        };
        let depths = depth_images(&set, Some(noise)).unwrap();
        let (range, _) = reproject_depths(&set.views, &depths, &r, &pose, &grid).unwrap();
        // Reading every s-th column near the mast (s <= 16) keeps the image close.
        let params = r.camera_params();
        let mut frames = [None; 4];
        let mut dv = [None; 4];
        for k in 0..4 {
            frames[k] = Some(ImageView::new(set.views[k].as_raw(), 320, 180).unwrap());
            dv[k] = Some(DepthView::new(&depths[k], 320, 180).unwrap());
        }
        let mut scratch = vec![0u32; range_scratch_len(grid.n)];
        let (mut out, mut mask) = (vec![0u8; grid.cells()], vec![0u8; grid.cells()]);
        let strided = RangeOptions {
            max_column_stride: 16,
            ..RangeOptions::default()
        };
        let rs = reproject_range(
            &frames,
            &dv,
            &params,
            &pose,
            &grid,
            &strided,
            &mut scratch,
            &mut out,
            &mut mask,
        )
        .unwrap();
        let n_strided = masked_ncc(&out, &sat.image, &mask);
        eprintln!(
            "query {}: strided: {} of {} pixels read, NCC vs satellite {n_strided:.3}",
            q.id,
            rs.pixels_read,
            4 * 320 * 180
        );
        assert!(rs.pixels_read < 4 * 320 * 180 * 7 / 10);
        assert!(n_strided > 0.5, "strided NCC {n_strided}");
        let n_lut = masked_ncc(&lut.image, &sat.image, &lut.mask);
        let n_range = masked_ncc(&range.image, &sat.image, &range.mask);
        eprintln!(
            "query {}: NCC vs satellite: range {n_range:.3}, LUT {n_lut:.3}",
            q.id
        );
        assert!(n_range > 0.5, "range NCC {n_range}");
        if n_range < n_lut + 0.2 {
            worse += 1;
        }
    }
    assert_eq!(worse, 0);
}

#[test]
fn bad_inputs_give_typed_errors_and_missing_views_are_reported() {
    let params = CameraParams {
        width_px: 8,
        height_px: 6,
        ..CameraParams::default()
    };
    let pose = orbfix::camera::RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let grid = GridSpec::new(32, 0.25);
    let frame = vec![128u8; 48];
    let dark = vec![0u8; 48];
    let depth = vec![3000u16; 48];
    let short = vec![3000u16; 40];
    let f = ImageView::new(&frame, 8, 6).unwrap();
    let fd = ImageView::new(&dark, 8, 6).unwrap();
    let d = DepthView::new(&depth, 8, 6).unwrap();
    let ds = DepthView::new(&short, 8, 5).unwrap();
    let mut scratch = vec![0u32; range_scratch_len(32)];
    let (mut out, mut mask) = (vec![0u8; 1024], vec![0u8; 1024]);
    let opts = RangeOptions::default();
    let e = reproject_range(
        &[Some(f), None, None, None],
        &[Some(ds), None, None, None],
        &params,
        &pose,
        &grid,
        &opts,
        &mut scratch,
        &mut out,
        &mut mask,
    );
    assert_eq!(
        e,
        Err(RangeError::DepthSize {
            view: 0,
            expected: (8, 6),
            got: (8, 5)
        })
    );
    let mut small = vec![0u32; 10];
    let e = reproject_range(
        &[Some(f), None, None, None],
        &[Some(d), None, None, None],
        &params,
        &pose,
        &grid,
        &opts,
        &mut small,
        &mut out,
        &mut mask,
    );
    assert_eq!(
        e,
        Err(RangeError::ScratchSize {
            needed: 512, // a `u16` sum per cell of the 32 x 32 grid
            got: 10
        })
    );
    let bad = RangeOptions {
        depth_scale_m: f32::NAN,
        ..opts
    };
    let e = reproject_range(
        &[Some(f), None, None, None],
        &[Some(d), None, None, None],
        &params,
        &pose,
        &grid,
        &bad,
        &mut scratch,
        &mut out,
        &mut mask,
    );
    assert_eq!(e, Err(RangeError::BadDepthScale));
    let e = reproject_range(
        &[Some(f), None, None, None],
        &[Some(d), None, None, None],
        &params,
        &pose,
        &GridSpec::new(0, 0.25),
        &opts,
        &mut scratch,
        &mut out,
        &mut mask,
    );
    assert_eq!(e, Err(RangeError::Reproject(ReprojectError::BadGridSize)));
    // 0.1 mm cells with millimetre depths: the Q32 rays would not fit i32.
    let e = reproject_range(
        &[Some(f), None, None, None],
        &[Some(d), None, None, None],
        &params,
        &pose,
        &GridSpec::new(32, 0.0001),
        &opts,
        &mut scratch,
        &mut out,
        &mut mask,
    );
    assert_eq!(e, Err(RangeError::Overflow));
    // Front usable with depth, right black, rear without depth, left missing.
    let rep = reproject_range(
        &[Some(f), Some(fd), Some(f), None],
        &[Some(d), Some(d), None, None],
        &params,
        &pose,
        &grid,
        &opts,
        &mut scratch,
        &mut out,
        &mut mask,
    )
    .unwrap();
    assert_eq!(
        rep.status,
        [
            FrameStatus::Ok,
            FrameStatus::Black,
            FrameStatus::Ok,
            FrameStatus::Missing
        ]
    );
    assert_eq!(rep.depth_missing, [false, false, true, false]);
    assert_eq!(rep.pixels_read, 48);
    // Height band and range limit: dropping points above the camera (top rows of a 3 m
    // depth wall) removes some; a 1 m range limit removes all (every point is >= 2.5 m).
    let front = [Some(f), None, None, None];
    let fdepth = [Some(d), None, None, None];
    let mut run = |g: &GridSpec, o: &RangeOptions| {
        reproject_range(
            &front,
            &fdepth,
            &params,
            &pose,
            g,
            o,
            &mut scratch,
            &mut out,
            &mut mask,
        )
        .unwrap()
    };
    let all = run(&grid, &opts);
    let low = run(
        &grid,
        &RangeOptions {
            max_height_m: 2.0,
            ..opts
        },
    );
    assert!(low.points_used > 0 && low.points_used < all.points_used);
    let near = GridSpec {
        max_range_m: 1.0,
        ..grid
    };
    assert_eq!(run(&near, &opts).points_used, 0);
    assert_eq!(
        run(
            &near,
            &RangeOptions {
                max_height_m: 2.0,
                ..opts
            }
        )
        .points_used,
        0
    );
    let far = GridSpec {
        max_range_m: 100.0,
        ..grid
    };
    assert_eq!(run(&far, &opts).points_used, all.points_used);
    let shallow = RangeOptions {
        max_depth_m: 2.9,
        ..opts
    };
    assert_eq!(run(&grid, &shallow).points_used, 0);
    // Depth 3 m straight ahead (north, 15 deg down, 90 deg HFOV): everything north of the
    // rover, within the 8 m grid, so only cells in the northern half have data.
    assert!(rep.valid_cells > 0);
    for (k, &m) in mask.iter().enumerate() {
        if m != 0 {
            assert!(k / 32 < 16, "cell {k} south of the rover");
            assert_eq!(out[k], 128);
        }
    }
}

/// The relief blocks the range reprojection accumulates ([`orbfix::reproject::relief_template`])
/// follow the world's heights: zero-mean block heights against the world's at the block
/// centres, on a stop of the relief world.
#[test]
fn relief_blocks_follow_the_world_heights() {
    use orbfix::reproject::{relief_template, relief_words, ReliefGrid};
    let world = World::new(1);
    let r = small_render();
    let (pose, set, depths) = stop_with_depths(&world, 3, 2, &r);
    let grid = GridSpec::default();
    let params = r.camera_params();
    let rg = ReliefGrid::new(grid.n, 16).unwrap();
    let mut words = vec![0i32; relief_words(&rg)];
    let mut scratch = vec![0u32; range_scratch_len(grid.n)];
    let (mut out, mut mask) = (vec![0u8; grid.cells()], vec![0u8; grid.cells()]);
    let mut acc = RangeAccumulator::new(
        &params,
        &pose,
        &grid,
        &RangeOptions::default(),
        &mut scratch,
        &mut mask,
    )
    .unwrap()
    .with_relief(rg, &mut words)
    .unwrap();
    for (k, view) in View::ALL.into_iter().enumerate() {
        let f = ImageView::new(set.views[k].as_raw(), 320, 180).unwrap();
        let d = DepthView::new(&depths[k], 320, 180).unwrap();
        acc.add_view(view, &f, Some(&d)).unwrap();
    }
    let with_relief = acc.finish(&mut out).unwrap();
    let (plain, _) = reproject_depths(&set.views, &depths, &r, &pose, &grid).unwrap();
    assert_eq!(out, plain.image, "the relief does not change the image");
    let t = relief_template(&rg, &mut words, &mask, grid.n, 300).unwrap();
    assert!(t.valid > 60, "{} of 144 blocks valid", t.valid);
    assert!(with_relief.valid_cells > 0);
    // World heights over the valid blocks (the mean of 4 x 4 samples, as the map
    // product's relief plane), zero-mean, against the template (Q7 m).
    let (nb, b, o) = (rg.blocks(), rg.block_px() as f64, rg.offset_px() as f64);
    let half = grid.n as f64 / 2.0;
    let mut pairs = Vec::new();
    for k in 0..nb * nb {
        if words[nb * nb + k] == 0 {
            continue;
        }
        let (i, j) = ((k % nb) as f64, (k / nb) as f64);
        let mut h = 0.0;
        for (si, sj) in (0..16).map(|s| ((s % 4) as f64, (s / 4) as f64)) {
            let x =
                pose.x_m as f64 + (o + (i + (si + 0.5) / 4.0) * b - half) * grid.m_per_px as f64;
            let y =
                pose.y_m as f64 - (o + (j + (sj + 0.5) / 4.0) * b - half) * grid.m_per_px as f64;
            h += world.height_m(x, y) / 16.0;
        }
        pairs.push((words[k] as f64 / 128.0, h));
    }
    let m = pairs.len() as f64;
    let (ma, mb) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / m,
        pairs.iter().map(|p| p.1).sum::<f64>() / m,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (a, b) in &pairs {
        sab += (a - ma) * (b - mb);
        saa += (a - ma) * (a - ma);
        sbb += (b - mb) * (b - mb);
    }
    let corr = sab / (saa * sbb).sqrt();
    let rms = ((saa + sbb - 2.0 * sab) / m).sqrt();
    eprintln!("relief blocks: {} valid, correlation {corr:.3} with the world, rms {rms:.3} m, spread {:.2} m", t.valid, (sbb / m).sqrt());
    assert!(corr > 0.95, "correlation {corr}");
    assert!(ma.abs() < 0.01, "zero-mean template: {ma}");
}
