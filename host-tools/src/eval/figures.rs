//! Evaluation figures (SVG, plotters): pair score distributions per matcher (the study's
//! Figure 3), ROC curves and localization error CDFs.

use super::metrics::roc;
use anyhow::Context;
use plotters::prelude::*;
use std::path::Path;

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn finish(svg: String, path: &Path) -> anyhow::Result<()> {
    super::write_atomic(path, svg.as_bytes())
}

fn err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("plotting failed: {e}")
}

/// Histograms of matching vs non-matching pair scores of one matcher.
pub fn score_histograms(
    path: &Path,
    matcher: &str,
    pos: &[f64],
    neg: &[f64],
) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 400)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let all = pos.iter().chain(neg).copied().filter(|v| v.is_finite());
        let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        let (lo, hi) = if lo.is_finite() && hi > lo {
            (lo, hi)
        } else {
            (0.0, 1.0)
        };
        let bins = 30usize;
        let bw = (hi - lo) / bins as f64;
        let count = |v: &[f64]| {
            let mut c = vec![0usize; bins];
            for &x in v.iter().filter(|x| x.is_finite()) {
                c[(((x - lo) / bw) as usize).min(bins - 1)] += 1;
            }
            c
        };
        let (cp, cn) = (count(pos), count(neg));
        let ymax = cp.iter().chain(&cn).copied().max().unwrap_or(1).max(1) as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{matcher}: pair scores (matching vs non-matching)"),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(lo..hi, 0.0..ymax * 1.1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("score (higher = more similar)")
            .y_desc("pairs")
            .draw()
            .map_err(err)?;
        for (c, name, color) in [
            (&cp, "matching", COLORS[2]),
            (&cn, "non-matching", COLORS[3]),
        ] {
            chart
                .draw_series(c.iter().enumerate().map(|(i, &n)| {
                    let x0 = lo + i as f64 * bw;
                    Rectangle::new([(x0, 0.0), (x0 + bw, n as f64)], color.mix(0.45).filled())
                }))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 10, y + 5)], color.filled())
                });
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    finish(svg, path).with_context(|| format!("writing {}", path.display()))
}

/// ROC curves of several matchers: `(name, matching scores, non-matching scores)`.
pub fn roc_curves(path: &Path, series: &[(String, Vec<f64>, Vec<f64>)]) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (520, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("ROC: match / non-match pairs", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("false positive rate")
            .y_desc("true positive rate")
            .draw()
            .map_err(err)?;
        chart
            .draw_series(LineSeries::new(
                vec![(0.0, 0.0), (1.0, 1.0)],
                BLACK.mix(0.3),
            ))
            .map_err(err)?;
        for (k, (name, pos, neg)) in series.iter().enumerate() {
            let color = COLORS[k % COLORS.len()];
            chart
                .draw_series(LineSeries::new(roc(pos, neg), color.stroke_width(2)))
                .map_err(err)?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 15, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    finish(svg, path).with_context(|| format!("writing {}", path.display()))
}

/// Empirical CDFs of localization errors (metres) of several matchers.
pub fn error_cdfs(path: &Path, series: &[(String, Vec<f64>)]) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let xmax = series
            .iter()
            .flat_map(|s| s.1.iter().copied())
            .filter(|v| v.is_finite())
            .fold(1.0f64, f64::max)
            .min(200.0);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Localization error CDF (coarse-to-fine fix)",
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d((0.01f64..xmax * 1.05).log_scale(), 0.0..1.0)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("error, metres (log)")
            .y_desc("share of queries")
            .draw()
            .map_err(err)?;
        for (k, (name, errs)) in series.iter().enumerate() {
            let mut e: Vec<f64> = errs.iter().copied().filter(|v| v.is_finite()).collect();
            e.sort_by(f64::total_cmp);
            let n = errs.len().max(1) as f64;
            let pts: Vec<(f64, f64)> = e
                .iter()
                .enumerate()
                .flat_map(|(i, &v)| {
                    let v = v.max(0.011);
                    [(v, i as f64 / n), (v, (i + 1) as f64 / n)]
                })
                .collect();
            let color = COLORS[k % COLORS.len()];
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                .map_err(err)?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 15, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    finish(svg, path).with_context(|| format!("writing {}", path.display()))
}
