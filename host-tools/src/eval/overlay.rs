//! Operator pictures (PNG): the reprojected overhead view, and the map with the response map
//! as a heat overlay, the truth, the prior, the fix and the top candidates (the study's
//! Figure 7, with the dense response instead of 441 squares).
//!
//! Legend: heat = coarse matcher response (transparent = mean or below, yellow = peak); white square
//! = region of rover positions searched; green cross = truth; blue plus = prior; red ring =
//! fix; orange rings = other candidates; thin yellow squares = the study's 5 best windows.

use super::{Localization, MapRegion, TopDown};
use image::{Rgb, RgbImage};

const HOLE: Rgb<u8> = Rgb([20, 30, 70]);
const RED: Rgb<u8> = Rgb([255, 40, 40]);
const ORANGE: Rgb<u8> = Rgb([255, 150, 0]);
const GREEN: Rgb<u8> = Rgb([40, 255, 80]);
const BLUE: Rgb<u8> = Rgb([60, 140, 255]);
const YELLOW: Rgb<u8> = Rgb([255, 255, 0]);
const WHITE: Rgb<u8> = Rgb([255, 255, 255]);

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// A ring of radius `r` pixels, `t` pixels thick.
pub fn ring(img: &mut RgbImage, cx: f64, cy: f64, r: f64, t: f64, c: Rgb<u8>) {
    let n = (r + t + 1.0).ceil() as i64;
    for dy in -n..=n {
        for dx in -n..=n {
            let d = ((dx * dx + dy * dy) as f64).sqrt();
            if (d - r).abs() <= t / 2.0 {
                put(img, cx as i64 + dx, cy as i64 + dy, c);
            }
        }
    }
}

/// A cross (`x` shaped when `diag`, else `+`) of half-size `h` pixels.
pub fn cross(img: &mut RgbImage, cx: f64, cy: f64, h: i64, diag: bool, c: Rgb<u8>) {
    let (x, y) = (cx as i64, cy as i64);
    for k in -h..=h {
        for w in -1..=1 {
            if diag {
                put(img, x + k + w, y + k, c);
                put(img, x + k + w, y - k, c);
            } else {
                put(img, x + k, y + w, c);
                put(img, x + w, y + k, c);
            }
        }
    }
}

/// An axis-aligned rectangle outline.
pub fn rect(img: &mut RgbImage, x0: f64, y0: f64, x1: f64, y1: f64, c: Rgb<u8>) {
    let (x0, y0, x1, y1) = (x0 as i64, y0 as i64, x1 as i64, y1 as i64);
    for x in x0..=x1 {
        put(img, x, y0, c);
        put(img, x, y1, c);
    }
    for y in y0..=y1 {
        put(img, x0, y, c);
        put(img, x1, y, c);
    }
}

/// The reprojected overhead view: gray where valid, dark blue where no camera saw the
/// ground, a red cross at the rover.
pub fn top_down_picture(top: &TopDown) -> RgbImage {
    let n = top.n as u32;
    let mut img = RgbImage::from_fn(n, n, |x, y| {
        let i = (y * n + x) as usize;
        if top.mask.get(i).copied().unwrap_or(0) == 0 {
            HOLE
        } else {
            let v = top.image.get(i).copied().unwrap_or(0);
            Rgb([v, v, v])
        }
    });
    cross(&mut img, n as f64 / 2.0, n as f64 / 2.0, 3, false, RED);
    img
}

/// Heat colour of `t` in `[0, 1]` (black-red-yellow) and its opacity.
fn heat(t: f32) -> ([f32; 3], f32) {
    let t = t.clamp(0.0, 1.0);
    let rgb = [
        (t * 2.0).min(1.0) * 255.0,
        ((t - 0.5) * 2.0).clamp(0.0, 1.0) * 255.0,
        0.0,
    ];
    (rgb, 0.7 * t.sqrt())
}

/// The map, downsized `scale` times (each picture pixel the map pixel at its centre), with
/// the coarse response of `loc` blended in: each pixel takes the response cell whose rover
/// position (window centre, `top_n / 2` pixels in) is nearest, and `tint` gives that value's
/// colour (0..255 per channel) and opacity (0..1), or `None` to leave the map as it is.
pub(crate) fn response_over_map(
    map: &MapRegion,
    loc: &Localization,
    top_n: usize,
    scale: usize,
    tint: impl Fn(f32) -> Option<([f32; 3], f32)>,
) -> RgbImage {
    let s = scale.max(1);
    let (w, h) = ((map.width / s) as u32, (map.height / s) as u32);
    let g = loc.fix.coarse_grid;
    let resp = &loc.coarse_response;
    let half = top_n as f64 / 2.0;
    RgbImage::from_fn(w, h, |x, y| {
        let (mx, my) = (
            (x as usize * s) as f64 + 0.5 * s as f64,
            (y as usize * s) as f64 + 0.5 * s as f64,
        );
        let v = map.image
            [(my as usize).min(map.height - 1) * map.width + (mx as usize).min(map.width - 1)]
            as f32;
        let mut px = [v, v, v];
        let c = ((mx - half) / g.step() as f64).round();
        let r = ((my - half) / g.step() as f64).round();
        if c >= 0.0 && r >= 0.0 && (c as usize) < g.cols() && (r as usize) < g.rows() {
            if let Some((col, a)) = tint(resp[r as usize * g.cols() + c as usize]) {
                for (p, c) in px.iter_mut().zip(col) {
                    *p = *p * (1.0 - a) + c * a;
                }
            }
        }
        Rgb(px.map(|v| v.round().clamp(0.0, 255.0) as u8))
    })
}

/// The map with the coarse response as a heat overlay and the markers of the legend.
/// `scale` downsizes the picture (1 = one pixel per map pixel).
pub fn map_picture(
    map: &MapRegion,
    loc: &Localization,
    top_n: usize,
    truth: Option<(f64, f64)>,
    prior: (f64, f64),
    scale: usize,
) -> RgbImage {
    let s = scale.max(1);
    let (lo, hi) = loc
        .coarse_response
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let span = (hi - lo).max(1e-9);
    let half = top_n as f64 / 2.0;
    let mut img = response_over_map(map, loc, top_n, s, |val| Some(heat((val - lo) / span)));
    let to_px = |x: f64, y: f64| {
        let (c, r) = map.geo.to_pixel(x as f32, y as f32);
        (c as f64 / s as f64, r as f64 / s as f64)
    };
    let sf = s as f64;
    // Searched rover positions.
    rect(
        &mut img,
        half / sf,
        half / sf,
        (map.width as f64 - half) / sf,
        (map.height as f64 - half) / sf,
        WHITE,
    );
    // The study's 5 best windows.
    let mut order: Vec<usize> = (0..loc.window_scores.len()).collect();
    order.sort_by(|&a, &b| loc.window_scores[b].total_cmp(&loc.window_scores[a]));
    let wg = loc.window_grid;
    for &i in order.iter().take(5) {
        let (c, r) = (
            (i % wg.cols() * wg.step()) as f64,
            (i / wg.cols() * wg.step()) as f64,
        );
        rect(
            &mut img,
            c / sf,
            r / sf,
            (c + top_n as f64) / sf - 1.0,
            (r + top_n as f64) / sf - 1.0,
            YELLOW,
        );
    }
    let mark = (6.0 / sf).max(3.0);
    for c in loc.fix.candidates.iter().skip(1) {
        let (x, y) = to_px(c.x_m as f64, c.y_m as f64);
        ring(&mut img, x, y, mark, 2.0, ORANGE);
    }
    let (px, py) = to_px(prior.0, prior.1);
    cross(&mut img, px, py, mark as i64 + 2, false, BLUE);
    if let Some((tx, ty)) = truth {
        let (x, y) = to_px(tx, ty);
        cross(&mut img, x, y, mark as i64 + 2, true, GREEN);
    }
    let (fx, fy) = to_px(loc.fix.x_m as f64, loc.fix.y_m as f64);
    ring(&mut img, fx, fy, mark + 2.0, 2.5, RED);
    img
}
