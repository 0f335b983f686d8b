//! `orbfix reproject`: one dataset location's four views to a north-up top-down image and
//! validity mask, with the flight core's integer lookup table.

use anyhow::{bail, ensure, Context, Result};
use image::GrayImage;
use orbfix::image::ImageView;
use orbfix::reproject::{
    equalize_rings, table_len, ApplyReport, BuildStats, Cell, FrameStatus, GridSpec, Lut, Tap,
    DEFAULT_EXTRA,
};
use orbfix_host::dataset::{Dataset, ManifestRow};
use orbfix_host::fsutil::write_png;
use std::path::PathBuf;
use std::time::Instant;

/// Reproject a dataset location's four ground views (flat ground at the rover's elevation)
/// into a north-up top-down image with the flight core's lookup table. By default the grid is
/// the location's satellite crop (same extent, resolution and orientation), so the two
/// compare pixel for pixel; the normalized cross-correlation with the crop is printed.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Dataset folder (written by `orbfix generate`).
    #[arg(long)]
    dataset: PathBuf,
    /// Location id (the `id` column of manifest.jsonl), e.g. 0000001.
    #[arg(long)]
    id: String,
    /// Top-down image to write (8-bit gray PNG, north-up; 0 where no data).
    #[arg(long)]
    out: PathBuf,
    /// Validity mask to write (8-bit PNG: 255 valid, 0 no data).
    #[arg(long)]
    mask_out: Option<PathBuf>,
    /// Grid side, cells (default: the satellite crop's, e.g. 200).
    #[arg(long)]
    size: Option<usize>,
    /// Grid resolution, metres per cell (default: the satellite crop's, e.g. 0.25).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f32)]
    resolution: Option<f32>,
    /// Ground distance beyond which cells are "no data", metres (default: none).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f32)]
    max_range: Option<f32>,
    /// Equalize the brightness of 1 m range rings (core `equalize_rings`) before writing:
    /// removes the oblique-view brightening with distance that the orbital view lacks.
    #[arg(long)]
    equalize: bool,
    /// Treat a view as missing (repeatable): front, right, rear or left.
    #[arg(long, value_enum)]
    drop: Vec<ViewName>,
}

/// A view by name.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum ViewName {
    Front,
    Right,
    Rear,
    Left,
}

const NAMES: [&str; 4] = ["front", "right", "rear", "left"];

/// Normalized cross-correlation of `a` and `b` over cells where `mask` is 255.
fn masked_ncc(a: &[u8], b: &[u8], mask: &[u8]) -> Option<f64> {
    let (mut n, mut sa, mut sb) = (0f64, 0f64, 0f64);
    for ((&x, &y), &m) in a.iter().zip(b).zip(mask) {
        if m == 255 {
            n += 1.0;
            sa += x as f64;
            sb += y as f64;
        }
    }
    if n < 2.0 {
        return None;
    }
    let (ma, mb) = (sa / n, sb / n);
    let (mut sab, mut saa, mut sbb) = (0f64, 0f64, 0f64);
    for ((&x, &y), &m) in a.iter().zip(b).zip(mask) {
        if m == 255 {
            let (dx, dy) = (x as f64 - ma, y as f64 - mb);
            sab += dx * dy;
            saa += dx * dx;
            sbb += dy * dy;
        }
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// A dataset location's flat-ground top-down image on a grid, made with the flight core's
/// lookup table ([`top_down`]).
pub struct TopDown {
    /// Grid side, cells.
    pub n: usize,
    /// `n * n` gray levels, north-up, 0 where no data.
    pub image: Vec<u8>,
    /// `n * n`, 255 valid, 0 no data.
    pub mask: Vec<u8>,
    /// What the table application did.
    pub report: ApplyReport,
    /// What the table build produced.
    pub stats: BuildStats,
    /// Bytes of the lookup table.
    pub table_bytes: usize,
    /// Time of the table build.
    pub build_time: std::time::Duration,
    /// Time of the table application.
    pub apply_time: std::time::Duration,
}

/// Reprojects the four views of dataset location `row` onto `grid` (flat ground at the
/// rover's elevation, flight core's lookup table); views listed in `dropped` (0 front,
/// 1 right, 2 rear, 3 left) are treated as missing.
pub fn top_down(
    ds: &Dataset,
    row: &ManifestRow,
    grid: &GridSpec,
    dropped: &[usize],
) -> Result<TopDown> {
    let n = grid.n;
    let params = ds.info.config.render.camera_params();
    // The attitude the views were rendered with (a `--max-attitude` dataset).
    let pose = row.pose();
    let views: [GrayImage; 4] = ds
        .load_views(row)
        .with_context(|| format!("loading the views of {}", row.id))?;
    let (w, h) = (params.width_px as usize, params.height_px as usize);
    let mut frames: [Option<ImageView<'_>>; 4] = [None; 4];
    for (k, (f, img)) in frames.iter_mut().zip(views.iter()).enumerate() {
        let dropped = dropped.contains(&k);
        if !dropped {
            *f = Some(
                ImageView::new(img.as_raw(), w, h)
                    .map_err(|e| anyhow::anyhow!("{} view of {}: {e}", NAMES[k], row.id))?,
            );
        }
    }

    let cells_n = table_len(n);
    let mut cells = vec![Cell::EMPTY; cells_n];
    let mut extra = vec![Tap::EMPTY; DEFAULT_EXTRA.max(cells_n / 8)];
    let t0 = Instant::now();
    let lut = Lut::build(&mut cells, &mut extra, &params, &pose, grid, w)
        .map_err(|e| anyhow::anyhow!("building the lookup table: {e}"))?;
    let t_build = t0.elapsed();
    let mut out = vec![0u8; cells_n];
    let mut mask = vec![0u8; cells_n];
    let t1 = Instant::now();
    let report = lut
        .apply(&frames, &mut out, &mut mask)
        .map_err(|e| anyhow::anyhow!("reprojecting: {e}"))?;
    let t_apply = t1.elapsed();
    Ok(TopDown {
        n,
        image: out,
        mask,
        report,
        stats: *lut.stats(),
        table_bytes: lut.bytes(),
        build_time: t_build,
        apply_time: t_apply,
    })
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let ds = Dataset::open(&args.dataset)
        .with_context(|| format!("opening dataset {}", args.dataset.display()))?;
    let Some(row) = ds.rows.iter().find(|r| r.id == args.id) else {
        let first: Vec<_> = ds.rows.iter().take(3).map(|r| r.id.as_str()).collect();
        bail!(
            "no location '{}' in {} ({} locations, e.g. {})",
            args.id,
            args.dataset.display(),
            ds.rows.len(),
            first.join(", ")
        );
    };
    let crop_n = ds.info.config.satellite_px as usize;
    let crop_res = ds.info.config.satellite_m_per_px as f32;
    let n = args.size.unwrap_or(crop_n);
    let res = args.resolution.unwrap_or(crop_res);
    ensure!(
        n > 0 && n <= 4096,
        "--size {n} must be between 1 and 4096 cells"
    );
    ensure!(
        res.is_finite() && res > 0.0,
        "--resolution {res} must be a positive number of metres per cell"
    );
    let mut grid = GridSpec::new(n, res);
    if let Some(r) = args.max_range {
        ensure!(
            r.is_finite() && r > 0.0,
            "--max-range {r} must be a positive number of metres"
        );
        grid.max_range_m = r;
    }
    let dropped: Vec<usize> = args.drop.iter().map(|d| *d as usize).collect();
    let td = top_down(&ds, row, &grid, &dropped)?;
    let (n, mut out, mask, report) = (td.n, td.image, td.mask, td.report);
    let (t_build, t_apply) = (td.build_time, td.apply_time);
    let cells_n = table_len(n);
    let ring_cells = ((1.0 / res).round() as u32).max(1);
    let out_raw = out.clone();
    let mut equalized = out.clone();
    equalize_rings(&mut equalized, &mask, n, ring_cells);
    if args.equalize {
        out.clone_from(&equalized);
    }

    let top = GrayImage::from_raw(n as u32, n as u32, out.clone())
        .context("internal: top-down buffer size")?;
    write_png(&args.out, &top).with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(mp) = &args.mask_out {
        let m = GrayImage::from_raw(n as u32, n as u32, mask.clone())
            .context("internal: mask buffer size")?;
        write_png(mp, &m).with_context(|| format!("writing {}", mp.display()))?;
    }

    println!(
        "{}: {n} x {n} cells at {res} m, heading {:.1} deg; {} valid ({:.1} %), {} feathered",
        row.id,
        row.yaw_deg,
        report.valid_cells,
        100.0 * report.valid_cells as f64 / cells_n as f64,
        td.stats.blended_cells
    );
    println!(
        "table {} B ({:.2} B/cell), build {:.2} ms, apply {:.3} ms (debug builds are slower; `orbfix bench reproject` for speed)",
        td.table_bytes,
        td.table_bytes as f64 / cells_n as f64,
        t_build.as_secs_f64() * 1e3,
        t_apply.as_secs_f64() * 1e3
    );
    for (k, st) in report.status.iter().enumerate() {
        if *st != FrameStatus::Ok {
            println!(
                "warning: {} view not used ({st}); {} cells lost to no data",
                NAMES[k], report.lost_cells
            );
        }
    }
    if n == crop_n && (res - crop_res).abs() < 1e-6 {
        let sat = ds
            .load_satellite(row)
            .with_context(|| format!("loading the satellite crop of {}", row.id))?;
        let fmt = |c: Option<f64>| c.map_or("undefined".to_string(), |c| format!("{c:.4}"));
        println!(
            "NCC with the satellite crop over valid cells: {} raw, {} with 1 m range rings equalized",
            fmt(masked_ncc(&out_raw, sat.as_raw(), &mask)),
            fmt(masked_ncc(&equalized, sat.as_raw(), &mask))
        );
    }
    Ok(())
}
