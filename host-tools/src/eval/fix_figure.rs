//! The operator's picture of one fix (SVG): the orbital map with the coarse CNN response as
//! a heat map and its colour scale, the searched region, the prior, the truth, the fix with
//! its stated error bound, the other candidates, axes in metres and a legend.

use super::overlay::response_over_map;
use super::{Localization, MapRegion};
use anyhow::Context;
use base64::Engine;
use image::RgbImage;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;

/// Share of the response (the highest scores) drawn in colour; the rest shows the map.
const HEAT_TOP_SHARE: f32 = 0.10;

fn viridis(t: f32) -> RGBColor {
    ViridisRGB::get_color_normalized(t.clamp(0.0, 1.0), 0.0, 1.0)
}

/// The map raster (downsized by `scale`) with the top of the response blended in.
fn heat_raster(
    map: &MapRegion,
    loc: &Localization,
    top_n: usize,
    scale: usize,
) -> (RgbImage, f32, f32) {
    let resp = &loc.coarse_response;
    let mut sorted: Vec<f32> = resp.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_by(f32::total_cmp);
    let hi = sorted.last().copied().unwrap_or(1.0);
    let lo = sorted
        .get(((1.0 - HEAT_TOP_SHARE) * sorted.len() as f32) as usize)
        .copied()
        .unwrap_or(0.0);
    let span = (hi - lo).max(1e-6);
    let img = response_over_map(map, loc, top_n, scale, |val| {
        (val >= lo).then(|| {
            let t = (val - lo) / span;
            let col = viridis(t);
            ([col.0 as f32, col.1 as f32, col.2 as f32], 0.2 + 0.6 * t)
        })
    });
    (img, lo, hi)
}

/// Everything the picture marks.
pub struct FixMarks {
    /// True position, metres (when known).
    pub truth: Option<(f64, f64)>,
    /// Prior, metres.
    pub prior: (f64, f64),
    /// Stated error bound of the fix, metres.
    pub bound_m: f64,
    /// Title.
    pub title: String,
}

fn circle_path(cx: f64, cy: f64, r: f64) -> Vec<(f64, f64)> {
    (0..=72)
        .map(|i| {
            let a = i as f64 / 72.0 * std::f64::consts::TAU;
            (cx + r * a.cos(), cy + r * a.sin())
        })
        .collect()
}

/// The SVG text of the picture.
pub fn fix_svg(
    map: &MapRegion,
    loc: &Localization,
    top_n: usize,
    marks: &FixMarks,
) -> anyhow::Result<String> {
    let scale = 2;
    let (raster, lo, hi) = heat_raster(map, loc, top_n, scale);
    let mut png = Vec::new();
    image::DynamicImage::ImageRgb8(raster.clone())
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .context("encoding the map raster")?;
    let m = map.geo.m_per_px() as f64;
    let x0 = map.geo.origin_x_m() as f64;
    let y1 = map.geo.origin_y_m() as f64;
    let x1 = x0 + map.width as f64 * m;
    let y0 = y1 - map.height as f64 * m;
    let (pw, ph) = (raster.width(), raster.height());
    let (w, h) = (pw + 300, ph + 110);
    let mut svg = String::new();
    let plot_area;
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let (main, side) = root.split_horizontally(pw + 80);
        let mut chart = ChartBuilder::on(&main)
            .caption(&marks.title, ("sans-serif", 16))
            .margin_top(10)
            .margin_left(5)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("east (m)")
            .y_desc("north (m)")
            .draw()?;
        plot_area = chart.plotting_area().get_pixel_range();
        let half = top_n as f64 / 2.0 * m;
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![
                    (x0 + half, y0 + half),
                    (x1 - half, y0 + half),
                    (x1 - half, y1 - half),
                    (x0 + half, y1 - half),
                    (x0 + half, y0 + half),
                ],
                WHITE.stroke_width(1),
            )))?
            .label("rover positions searched")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], WHITE.stroke_width(2)));
        let (px, py) = marks.prior;
        chart
            .draw_series(std::iter::once(Cross::new(
                (px, py),
                6,
                RGBColor(60, 140, 255).stroke_width(2),
            )))?
            .label("prior")
            .legend(|(x, y)| Cross::new((x + 8, y), 5, RGBColor(60, 140, 255).stroke_width(2)));
        let others: Vec<(f64, f64)> = loc
            .fix
            .candidates
            .iter()
            .map(|c| (c.x_m as f64, c.y_m as f64))
            .filter(|&(x, y)| (x - loc.fix.x_m as f64).hypot(y - loc.fix.y_m as f64) > 1.0)
            .collect();
        chart
            .draw_series(
                others
                    .iter()
                    .map(|&p| Circle::new(p, 6, RGBColor(255, 150, 0).stroke_width(2))),
            )?
            .label("other candidates")
            .legend(|(x, y)| Circle::new((x + 8, y), 5, RGBColor(255, 150, 0).stroke_width(2)));
        if let Some((tx, ty)) = marks.truth {
            chart
                .draw_series(std::iter::once(Cross::new(
                    (tx, ty),
                    7,
                    RGBColor(40, 220, 80).stroke_width(3),
                )))?
                .label("truth")
                .legend(|(x, y)| Cross::new((x + 8, y), 5, RGBColor(40, 220, 80).stroke_width(3)));
        }
        let (fx, fy) = (loc.fix.x_m as f64, loc.fix.y_m as f64);
        chart
            .draw_series(std::iter::once(Circle::new((fx, fy), 4, RED.filled())))?
            .label("fix")
            .legend(|(x, y)| Circle::new((x + 8, y), 4, RED.filled()));
        if marks.bound_m.is_finite() {
            // At least 3 px so a sub-metre bound stays visible.
            let r = marks.bound_m.max(3.0 * m * scale as f64);
            chart
                .draw_series(std::iter::once(PathElement::new(
                    circle_path(fx, fy, r),
                    RED.stroke_width(2),
                )))?
                .label(format!("error bound ({:.2} m)", marks.bound_m))
                .legend(|(x, y)| Circle::new((x + 8, y), 6, RED.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 13))
            .draw()?;
        // Colour scale of the response.
        let mut bar = ChartBuilder::on(&side)
            .margin_top(40)
            .margin_bottom(50)
            .margin_left(20)
            .margin_right(60)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..1.0, lo as f64..hi as f64)?;
        bar.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_desc("CNN cosine (top 10 % of windows)")
            .draw()?;
        let steps = 64;
        bar.draw_series((0..steps).map(|i| {
            let a = lo as f64 + (hi - lo) as f64 * i as f64 / steps as f64;
            let b = lo as f64 + (hi - lo) as f64 * (i + 1) as f64 / steps as f64;
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                viridis(i as f32 / steps as f32).filled(),
            )
        }))?;
        root.present()?;
    }
    // The raster under the marks: an <image> right after the background.
    let b64 = base64::engine::general_purpose::STANDARD.encode(&png);
    let (xr, yr) = plot_area;
    let (ax0, ax1, ay0, ay1) = (xr.start, xr.end, yr.start, yr.end);
    let img = format!(
        "<image x=\"{ax0}\" y=\"{ay0}\" width=\"{}\" height=\"{}\" preserveAspectRatio=\"none\" href=\"data:image/png;base64,{b64}\"/>\n",
        ax1 - ax0,
        ay1 - ay0
    );
    let at = svg
        .find("<rect")
        .and_then(|i| svg[i..].find("/>").map(|j| i + j + 2))
        .context("unexpected SVG from plotters (no background)")?;
    svg.insert_str(at, &format!("\n{img}"));
    Ok(svg)
}
