//! Reprojection benchmark: in one run and for the same output grid, the core's integer LUT
//! apply vs the f64 reference vs OpenCV's fixed-point `remap` (CV_16SC2 maps from
//! `cv2.convertMaps`, one thread, run through `host-tools/benches/remap_cv.py`; the row says
//! why if `cv2` is missing), plus the table's bytes and build time, and the core's range
//! reprojection (`reproject_range`) on the same frames with flat-ground depth images.
//!
//! Used by `orbfix bench reproject` and `cargo bench -p orbfix-host --bench reproject`.
//! Frames are the flat-ground synthetic views of [`crate::reproject::reference`] (the speed of a
//! table lookup does not depend on the picture).

use crate::reproject::reference::{
    render_flat_ground, reproject_f64, ripple_texture, stacked_source_maps,
};
use anyhow::{Context, Result};
use orbfix::camera::{Camera, CameraParams, RoverPose, View};
use orbfix::image::ImageView;
use orbfix::reproject::{
    range_scratch_bytes, range_scratch_len, reproject_range, table_len, Cell, DepthView, GridSpec,
    Lut, RangeOptions, Tap, DEFAULT_EXTRA,
};
use std::hint::black_box;
use std::time::Instant;

/// What to run.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// View size, pixels.
    pub width_px: u32,
    /// View size, pixels.
    pub height_px: u32,
    /// Grid side, cells.
    pub n: usize,
    /// Grid resolution, metres per cell.
    pub m_per_px: f32,
    /// Timed repetitions of the apply and of OpenCV's remap.
    pub reps: usize,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            width_px: 640,
            height_px: 360,
            n: 200,
            m_per_px: 0.25,
            reps: 2000,
        }
    }
}

/// Median and minimum seconds of `reps` calls of `f`.
fn time<F: FnMut()>(reps: usize, mut f: F) -> (f64, f64) {
    let mut t: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[t.len() / 2], t[0])
}

struct CvResult {
    median_s: f64,
    min_s: f64,
    version: String,
    convert_s: f64,
    map_bytes: u64,
    out: Vec<u8>,
}

fn run_opencv(
    frames: &[image::GrayImage; 4],
    params: &CameraParams,
    pose: &RoverPose,
    grid: &GridSpec,
    reps: usize,
) -> Result<std::result::Result<CvResult, String>> {
    let dir = std::env::temp_dir().join(format!("orbfix-bench-reproject-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let stacked: Vec<u8> = frames
        .iter()
        .flat_map(|f| f.as_raw().iter().copied())
        .collect();
    let (mx, my) = stacked_source_maps(params, pose, grid.n, grid.m_per_px as f64);
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    std::fs::write(dir.join("frames.u8"), &stacked)?;
    std::fs::write(dir.join("mapx.f32"), f32s(&mx))?;
    std::fs::write(dir.join("mapy.f32"), f32s(&my))?;
    let meta = serde_json::json!({
        "w": params.width_px, "h4": 4 * params.height_px, "n": grid.n, "reps": reps
    });
    std::fs::write(dir.join("meta.json"), meta.to_string())?;
    let py = std::env::var("ORBFIX_PYTHON").unwrap_or_else(|_| "python3".into());
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/remap_cv.py");
    let res = std::process::Command::new(&py)
        .arg(script)
        .arg(&dir)
        .output();
    let result = match res {
        Err(e) => Err(format!("could not run {py} ({e})")),
        Ok(o) => {
            let text = String::from_utf8_lossy(&o.stdout);
            match serde_json::from_str::<serde_json::Value>(text.trim()) {
                Err(_) => Err(format!(
                    "{py} {script} failed: {}",
                    String::from_utf8_lossy(&o.stderr).trim()
                )),
                Ok(v) if v.get("error").is_some() => Err(v["error"].to_string()),
                Ok(v) => Ok(CvResult {
                    median_s: v["median_s"].as_f64().unwrap_or(f64::NAN),
                    min_s: v["min_s"].as_f64().unwrap_or(f64::NAN),
                    version: v["version"].as_str().unwrap_or("?").to_string(),
                    convert_s: v["convert_s"].as_f64().unwrap_or(f64::NAN),
                    map_bytes: v["map_bytes"].as_u64().unwrap_or(0),
                    out: std::fs::read(dir.join("out_cv.u8")).unwrap_or_default(),
                }),
            }
        }
    };
    let _ = std::fs::remove_dir_all(&dir);
    Ok(result)
}

/// Runs the benchmark and prints its table to stdout.
pub fn run(opts: &BenchOptions) -> Result<()> {
    anyhow::ensure!(opts.reps > 0, "repetitions must be at least 1");
    let reps = opts.reps;
    let params = CameraParams {
        width_px: opts.width_px,
        height_px: opts.height_px,
        ..CameraParams::default()
    };
    params
        .validate()
        .map_err(|e| anyhow::anyhow!("bad view size {}x{}: {e}", opts.width_px, opts.height_px))?;
    let pose = RoverPose::level(3.0, -2.0, 0.0, 30.0);
    let grid = GridSpec::new(opts.n, opts.m_per_px);
    grid.validate().map_err(|e| {
        anyhow::anyhow!(
            "bad grid {} x {} at {} m: {e}",
            opts.n,
            opts.n,
            opts.m_per_px
        )
    })?;
    let n_cells = table_len(grid.n);
    let frames = render_flat_ground(&params, &pose, ripple_texture)?;
    let views: [Option<ImageView<'_>>; 4] = [0, 1, 2, 3].map(|k| {
        ImageView::new(
            frames[k].as_raw(),
            params.width_px as usize,
            params.height_px as usize,
        )
        .ok()
    });

    // Table build (per stop).
    let mut cells = vec![Cell::EMPTY; n_cells];
    let mut extra = vec![Tap::EMPTY; DEFAULT_EXTRA.max(n_cells / 8)];
    let (build_med, build_min) = time(50, || {
        let lut = Lut::build(
            &mut cells,
            &mut extra,
            &params,
            &pose,
            &grid,
            params.width_px as usize,
        );
        black_box(lut.map(|l| l.stats().valid_cells).ok());
    });
    let lut = Lut::build(
        &mut cells,
        &mut extra,
        &params,
        &pose,
        &grid,
        params.width_px as usize,
    )
    .map_err(|e| anyhow::anyhow!("table build failed: {e}"))?;
    let stats = *lut.stats();

    // Apply (per frame set).
    let mut out = vec![0u8; n_cells];
    let mut mask = vec![0u8; n_cells];
    let (apply_med, apply_min) = time(reps, || {
        let r = lut.apply(black_box(&views), &mut out, &mut mask);
        black_box(r.ok());
    });

    // f64 reference.
    let fr = [
        Some(&frames[0]),
        Some(&frames[1]),
        Some(&frames[2]),
        Some(&frames[3]),
    ];
    let (ref_med, ref_min) = time(5, || {
        black_box(
            reproject_f64(
                &fr,
                &params,
                &pose,
                grid.n,
                grid.m_per_px as f64,
                f64::INFINITY,
            )
            .ok(),
        );
    });

    let cv = run_opencv(&frames, &params, &pose, &grid, reps)?;

    let mpx = |s: f64| n_cells as f64 / s / 1e6;
    println!(
        "reprojection: 4 views {}x{} -> {}x{} cells at {} m/cell ({} valid, {} feathered)",
        params.width_px,
        params.height_px,
        grid.n,
        grid.n,
        grid.m_per_px,
        stats.valid_cells,
        stats.blended_cells
    );
    println!(
        "table: {} B ({} cells x 8 B + {} taps x 8 B) = {:.2} B/cell; build median {:.3} ms (min {:.3} ms)",
        lut.bytes(),
        n_cells,
        stats.blended_cells,
        lut.bytes() as f64 / n_cells as f64,
        build_med * 1e3,
        build_min * 1e3
    );
    println!(
        "{:<36} {:>12} {:>12} {:>12} {:>12}",
        "method (one thread)", "median us", "min us", "Mpx/s", "vs OpenCV"
    );
    let cv_med = cv.as_ref().ok().map(|c| c.median_s);
    let row = |name: &str, med: f64, min: f64| {
        let ratio = cv_med
            .map(|c| format!("{:.2}x", c / med))
            .unwrap_or_else(|| "n/a".into());
        println!(
            "{:<36} {:>12.1} {:>12.1} {:>12.1} {:>12}",
            name,
            med * 1e6,
            min * 1e6,
            mpx(med),
            ratio
        );
    };
    row("orbfix LUT apply (int, feathered)", apply_med, apply_min);
    row("f64 reference (bilinear, feathered)", ref_med, ref_min);
    match &cv {
        Ok(c) => {
            row(
                &format!("OpenCV {} remap CV_16SC2", c.version),
                c.median_s,
                c.min_s,
            );
            println!(
                "OpenCV map: {} B, convertMaps {:.3} ms (float maps from the f64 model, not timed)",
                c.map_bytes,
                c.convert_s * 1e3
            );
            if c.out.len() == n_cells {
                let (mut s, mut mx, mut cnt) = (0u64, 0u8, 0u64);
                for k in 0..n_cells {
                    if mask[k] == 255 {
                        let d = out[k].abs_diff(c.out[k]);
                        s += d as u64;
                        mx = mx.max(d);
                        cnt += 1;
                    }
                }
                println!(
                    "orbfix vs OpenCV output over valid cells: mean |d| {:.3}, max {} (OpenCV does not feather)",
                    s as f64 / cnt.max(1) as f64,
                    mx
                );
            }
        }
        Err(why) => println!("{:<36} {:>12}   ({why})", "OpenCV remap CV_16SC2", "n/a"),
    }
    bench_range(&frames, &params, &pose, &grid, reps, apply_med)
}

/// Millimetre depth images of the flat ground `z = pose.ground_z_m` seen by the four views
/// (0 above the horizon or beyond 65.535 m).
pub fn flat_ground_depths(params: &CameraParams, pose: &RoverPose) -> Result<[Vec<u16>; 4]> {
    let mut out: [Vec<u16>; 4] = Default::default();
    for (o, view) in out.iter_mut().zip(View::ALL) {
        let cam = Camera::new(params, pose, view)
            .map_err(|e| anyhow::anyhow!("camera of {view:?}: {e}"))?;
        let (w, h) = (params.width_px as usize, params.height_px as usize);
        let rt = cam.world_to_cam.transpose();
        *o = (0..w * h)
            .map(|i| {
                let xn = ((i % w) as f32 + 0.5 - cam.cx) / cam.focal_px;
                let yn = ((i / w) as f32 + 0.5 - cam.cy) / cam.focal_px;
                // Un-normalized ray (camera z = 1): depth = t where the ray meets the ground.
                let d = rt * nalgebra::Vector3::new(xn, yn, 1.0);
                if d.z >= -1e-6 {
                    return 0;
                }
                let depth_mm = (params.height_m / -d.z * 1000.0).round();
                if (1.0..=u16::MAX as f32).contains(&depth_mm) {
                    depth_mm as u16
                } else {
                    0
                }
            })
            .collect();
    }
    Ok(out)
}

/// Times the core's range reprojection on the same frames with flat-ground depths and
/// prints pixels/s and the ratio to the LUT apply.
fn bench_range(
    frames: &[image::GrayImage; 4],
    params: &CameraParams,
    pose: &RoverPose,
    grid: &GridSpec,
    reps: usize,
    lut_apply_s: f64,
) -> Result<()> {
    let depths = flat_ground_depths(params, pose)?;
    let (w, h) = (params.width_px as usize, params.height_px as usize);
    let mut views: [Option<ImageView<'_>>; 4] = [None; 4];
    let mut dviews: [Option<DepthView<'_>>; 4] = [None; 4];
    for ((v, dv), (f, d)) in views
        .iter_mut()
        .zip(dviews.iter_mut())
        .zip(frames.iter().zip(&depths))
    {
        *v = Some(ImageView::new(f.as_raw(), w, h).map_err(|e| anyhow::anyhow!("{e}"))?);
        *dv = Some(DepthView::new(d, w, h).map_err(|e| anyhow::anyhow!("{e}"))?);
    }
    let n_cells = grid.cells();
    let mut scratch = vec![0u32; range_scratch_len(grid.n)];
    let mut out = vec![0u8; n_cells];
    let mut mask = vec![0u8; n_cells];
    let opts = RangeOptions::default();
    let mut report = None;
    let (med, min) = time(reps.div_ceil(10).max(5), || {
        let r = reproject_range(
            black_box(&views),
            &dviews,
            params,
            pose,
            grid,
            &opts,
            &mut scratch,
            &mut out,
            &mut mask,
        );
        report = r.ok();
    });
    let r = report.context("range reprojection failed")?;
    println!(
        "range path: {} pixels read, {} placed, {} cells visited, {} valid ({} filled); scratch {} B",
        r.pixels_read,
        r.points_used,
        r.cells_visited,
        r.valid_cells,
        r.filled_cells,
        range_scratch_bytes(grid.n)
    );
    println!(
        "{:<36} {:>12.1} {:>12.1} {:>12.1} {:>12}",
        "orbfix range reproject (int, depth)",
        med * 1e6,
        min * 1e6,
        r.pixels_read as f64 / med / 1e6,
        format!("{:.2}x LUT", lut_apply_s / med)
    );
    // Column stride up to 16 (every pixel read stays within half a cell on flat ground).
    let full = out.clone();
    let strided = RangeOptions {
        max_column_stride: 16,
        ..opts
    };
    let mut report = None;
    let (med2, min2) = time(reps.div_ceil(10).max(5), || {
        let r = reproject_range(
            black_box(&views),
            &dviews,
            params,
            pose,
            grid,
            &strided,
            &mut scratch,
            &mut out,
            &mut mask,
        );
        report = r.ok();
    });
    let r2 = report.context("range reprojection (strided) failed")?;
    let (mut s, mut c) = (0u64, 0u64);
    for (k, (&a, &b)) in full.iter().zip(&out).enumerate() {
        if mask[k] == 255 && a != 0 {
            s += u64::from(a.abs_diff(b));
            c += 1;
        }
    }
    println!(
        "{:<36} {:>12.1} {:>12.1} {:>12.1} {:>12}",
        "  same, max column stride 16",
        med2 * 1e6,
        min2 * 1e6,
        r.pixels_read as f64 / med2 / 1e6,
        format!("{:.2}x LUT", lut_apply_s / med2)
    );
    println!(
        "  strided: {} pixels read, {} placed, {} valid ({} filled); vs every pixel: mean |d| {:.2} gray over {} cells",
        r2.pixels_read,
        r2.points_used,
        r2.valid_cells,
        r2.filled_cells,
        s as f64 / c.max(1) as f64,
        c
    );
    println!(
        "(range rows: Mpx/s counts the frames' pixels; the ratio is LUT apply time / range time)"
    );
    Ok(())
}
