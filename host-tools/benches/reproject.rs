//! Reprojection benchmark: in one run and for the same 200 x 200 output, the core's
//! integer LUT apply vs the f64 reference vs OpenCV's fixed-point `remap` (CV_16SC2 maps,
//! one thread, through `benches/remap_cv.py`; the column says so if `cv2` is missing);
//! plus the table's bytes and build time.
//!
//! Run: `cargo bench -p orbfix-host --bench reproject` (env `ORBFIX_BENCH_REPS` sets the
//! apply repetitions, default 2000; `ORBFIX_PYTHON` the interpreter, default `python3`).

use anyhow::{Context, Result};
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::image::ImageView;
use orbfix::reproject::{table_len, Cell, GridSpec, Lut, Tap, DEFAULT_EXTRA};
use orbfix_host::reproject_ref::{
    render_flat_ground, reproject_f64, ripple_texture, stacked_source_maps,
};
use std::hint::black_box;
use std::time::Instant;

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

fn main() -> Result<()> {
    let reps: usize = std::env::var("ORBFIX_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let params = CameraParams::default();
    let pose = RoverPose::level(3.0, -2.0, 0.0, 30.0);
    let grid = GridSpec::default();
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
    let mut extra = vec![Tap::EMPTY; DEFAULT_EXTRA];
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
    .map_err(|e| anyhow::anyhow!("table build failed: {e:?}"))?;
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
    Ok(())
}
