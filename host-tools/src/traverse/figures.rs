//! Figures of a drive (SVG, plotters): the path (truth, odometry alone, fused) with the fix
//! of every stop and its stated bound, and the error against distance driven.

use super::StopRecord;
use crate::fsutil::write_atomic;
use plotters::prelude::*;
use std::path::Path;

fn err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("plotting failed: {e}")
}

const TRUTH: RGBColor = RGBColor(170, 170, 170);
const ODO: RGBColor = RGBColor(214, 39, 40);
const FUSED: RGBColor = RGBColor(31, 119, 180);
const FIX_OK: RGBColor = RGBColor(44, 160, 44);
const FIX_REJ: RGBColor = RGBColor(255, 127, 14);

/// The path: truth, odometry alone and fused, with each fix (accepted: green dot in its
/// bound circle; refused: orange cross). `title` names the run.
pub fn path_svg(path: &Path, records: &[StopRecord], title: &str) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 800)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let pts = records.iter().flat_map(|r| {
            [r.truth_m, r.odometry_m, r.fused_m]
                .into_iter()
                .chain(r.fix_m)
        });
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (x, y) in pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        anyhow::ensure!(x1 >= x0, "no stops to draw");
        // Equal scales on both axes.
        let side = (x1 - x0).max(y1 - y0).max(10.0) * 1.08;
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                cx - side / 2.0..cx + side / 2.0,
                cy - side / 2.0..cy + side / 2.0,
            )
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("east (m)")
            .y_desc("north (m)")
            .draw()
            .map_err(err)?;
        let line = |f: fn(&StopRecord) -> (f64, f64)| records.iter().map(f).collect::<Vec<_>>();
        for (pts, color, width, name) in [
            (line(|r| r.truth_m), TRUTH, 6, "truth (wide, grey)"),
            (line(|r| r.odometry_m), ODO, 2, "odometry alone"),
            (line(|r| r.fused_m), FUSED, 2, "fused"),
        ] {
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(width)))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 2, color.filled())))
                .map_err(err)?;
        }
        // Pixels per metre, for the bound circles.
        let px_per_m = 800.0 / side * 0.85;
        chart
            .draw_series(records.iter().filter(|r| r.accepted).filter_map(|r| {
                let p = r.fix_m?;
                let b = r.fix_bound_m.unwrap_or(0.0);
                Some(Circle::new(
                    p,
                    ((b * px_per_m).round() as i32).max(3),
                    FIX_OK.stroke_width(1),
                ))
            }))
            .map_err(err)?
            .label("accepted fix with its bound")
            .legend(|(x, y)| Circle::new((x + 9, y), 4, FIX_OK.stroke_width(1)));
        chart
            .draw_series(
                records
                    .iter()
                    .filter(|r| !r.accepted)
                    .filter_map(|r| r.fix_m.map(|p| Cross::new(p, 5, FIX_REJ.stroke_width(2)))),
            )
            .map_err(err)?
            .label("refused fix")
            .legend(|(x, y)| Cross::new((x + 9, y), 4, FIX_REJ.stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    write_atomic(path, svg.as_bytes())
}

/// Error against distance driven (log scale): odometry alone, each fix, fused.
pub fn error_svg(path: &Path, records: &[StopRecord], title: &str) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 450)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let dmax = records.iter().map(|r| r.distance_m).fold(1.0, f64::max);
        let floor = 0.01;
        let clamp = |e: f64| e.max(floor);
        let emax = records
            .iter()
            .flat_map(|r| {
                [
                    Some(r.odometry_error_m),
                    r.fix_error_m,
                    Some(r.fused_error_m),
                ]
            })
            .flatten()
            .fold(1.0, f64::max);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..dmax * 1.02, (floor..emax * 1.5).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("distance driven (m)")
            .y_desc("position error (m, log)")
            .draw()
            .map_err(err)?;
        let odo: Vec<(f64, f64)> = records
            .iter()
            .map(|r| (r.distance_m, clamp(r.odometry_error_m)))
            .collect();
        let fused: Vec<(f64, f64)> = records
            .iter()
            .map(|r| (r.distance_m, clamp(r.fused_error_m)))
            .collect();
        for (pts, color, name) in [(odo, ODO, "odometry alone"), (fused, FUSED, "fused")] {
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 2, color.filled())))
                .map_err(err)?;
        }
        chart
            .draw_series(records.iter().filter_map(|r| {
                let e = r.fix_error_m?;
                let c = if r.accepted { FIX_OK } else { FIX_REJ };
                Some(Cross::new((r.distance_m, clamp(e)), 5, c.stroke_width(2)))
            }))
            .map_err(err)?
            .label("fix (green accepted, orange refused)")
            .legend(|(x, y)| Cross::new((x + 9, y), 4, FIX_OK.stroke_width(2)));
        for (t, name) in [(1.0, "1 m"), (5.0, "5 m")] {
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, t), (dmax * 1.02, t)],
                    BLACK.mix(0.3).stroke_width(1),
                ))
                .map_err(err)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    name,
                    (dmax * 0.005, t * 1.08),
                    ("sans-serif", 12),
                )))
                .map_err(err)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    write_atomic(path, svg.as_bytes())
}
