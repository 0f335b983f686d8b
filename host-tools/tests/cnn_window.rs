//! Window-first localization (the CNN path of `orbfix eval`): dense response, window
//! ranking, refinement of the best peaks and the sub-step peak find an off-grid position; the
//! float CNN matcher's dense response equals its per-window scores.

use orbfix::image::ImageView;
use orbfix::matcher::{Matcher, OpCounts};
use orbfix_host::eval::window_refine::localize_windows;
use orbfix_host::eval::{matcher_by_name, window_cell_scores, MapRegion, TopDown};
use orbfix_host::nn::float_matcher::FloatCnnMatcher;
use orbfix_host::nn::float_model::FloatNet;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A random texture with long (48 px bilinear cells) and short (5 px box) correlation.
fn texture(w: usize, h: usize, seed: u64) -> Vec<u8> {
    let mut rng = StdRng::seed_from_u64(seed);
    let cell = 48usize;
    let (gw, gh) = (w / cell + 2, h / cell + 2);
    let coarse: Vec<f32> = (0..gw * gh).map(|_| rng.random_range(0.0..1.0)).collect();
    let noise: Vec<f32> = (0..w * h).map(|_| rng.random_range(0.0..1.0)).collect();
    let r = 2usize;
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / cell as f32, y as f32 / cell as f32);
            let (cx, cy) = (fx as usize, fy as usize);
            let (ax, ay) = (fx - cx as f32, fy - cy as f32);
            let g = |c: usize, r: usize| coarse[r * gw + c];
            let c = (1.0 - ay) * ((1.0 - ax) * g(cx, cy) + ax * g(cx + 1, cy))
                + ay * ((1.0 - ax) * g(cx, cy + 1) + ax * g(cx + 1, cy + 1));
            let (mut s, mut n) = (0f32, 0f32);
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    s += noise[yy * w + xx];
                    n += 1.0;
                }
            }
            out[y * w + x] = ((0.7 * c + 0.3 * s / n) * 255.0).clamp(0.0, 255.0) as u8;
        }
    }
    out
}

#[test]
fn window_first_ncc_finds_an_off_grid_position() {
    // 400 x 400 px map at 0.25 m/px (100 m), template 200 px cut at (77, 131): neither on
    // the 50 px window grid, nor on the 16 px dense grid, nor on the 4 px refinement grid.
    let (mw, n) = (400usize, 200usize);
    let map_img = texture(mw, mw, 5);
    let geo = orbfix::geo::GeoRef::new(1000.0, 2000.0, 0.25).unwrap();
    let (c0, r0) = (77usize, 131usize);
    let mut image = vec![0u8; n * n];
    for r in 0..n {
        image[r * n..(r + 1) * n].copy_from_slice(&map_img[(r0 + r) * mw + c0..][..n]);
    }
    // Blind disc of 10 px around the centre, as the rover's cameras leave.
    let mask: Vec<u8> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f64 - 100.0, (i / n) as f64 - 100.0);
            if x.hypot(y) < 10.0 {
                0
            } else {
                255
            }
        })
        .collect();
    let top = TopDown {
        image,
        mask,
        n,
        m_per_px: 0.25,
    };
    let map = MapRegion {
        image: map_img,
        width: mw,
        height: mw,
        geo,
    };
    let mut spec = matcher_by_name("ncc").unwrap();
    spec.window_first = true;
    let loc = localize_windows(&spec, &top, &map, (1050.0, 1950.0), 50).unwrap();
    let (tx, ty) = geo.to_world((c0 + n / 2) as f32, (r0 + n / 2) as f32);
    let err = ((loc.fix.x_m - tx).powi(2) + (loc.fix.y_m - ty).powi(2)).sqrt();
    assert!(err < 0.5, "fix off by {err} m");
    assert_eq!(loc.window_scores.len(), 25);
    assert!(loc.fix.candidates.len() >= 2 && loc.fix.candidates[0].refined);
    assert!(loc.fix.confidence > 0.0 && loc.fix.confidence <= 1.0);
    assert!(!loc.fix.on_border);
    // The best window is the one nearest the truth (col 2 -> 100 px, row 3 -> 150 px).
    let best = (0..25)
        .max_by(|&a, &b| loc.window_scores[a].total_cmp(&loc.window_scores[b]))
        .unwrap();
    assert_eq!(best, 3 * 5 + 2);
    // Ranked by the best response in their cell (dense grid and refinement samples), the
    // truth's cell wins too: (77, 131) lies in the cell of window (col 2, row 3).
    assert_eq!(loc.fix.coarse_grid.step(), 16);
    assert!(!loc.fine_samples.is_empty());
    let cells = window_cell_scores(&loc);
    let best_cell = (0..25)
        .max_by(|&a, &b| cells[a].total_cmp(&cells[b]))
        .unwrap();
    assert_eq!(best_cell, 3 * 5 + 2);
}

#[test]
fn float_cnn_dense_equals_per_window_scores() {
    let dir = std::env::temp_dir().join(format!("orbfix-cnn-window-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ck = dir.join("init.safetensors");
    FloatNet::init(11).unwrap().save(&ck).unwrap();
    let m = FloatCnnMatcher::load(&ck).unwrap();
    let region = texture(300, 300, 9);
    let top = texture(200, 200, 10);
    let mask = vec![255u8; 200 * 200];
    let r = ImageView::new(&region, 300, 300).unwrap();
    let t = ImageView::new(&top, 200, 200).unwrap();
    let w = ImageView::new(&mask, 200, 200).unwrap();
    let mut out = [0f32; 9];
    let mut ops = OpCounts::default();
    let g = m.dense(&t, &w, &r, 50, &mut out, &mut ops).unwrap();
    assert_eq!((g.cols(), g.rows(), ops.windows), (3, 3, 9));
    for (i, o) in out.iter().enumerate() {
        let win = r.sub(i % 3 * 50, i / 3 * 50, 200, 200).unwrap();
        let s = m.score(&t, &w, &win, &mut OpCounts::default()).unwrap();
        assert!((s - o).abs() < 1e-4, "window {i}: {s} vs {o}");
        assert!((-1.0..=1.0001).contains(o));
    }
    // The template against itself scores ~1.
    let s = m.score(&t, &w, &t, &mut OpCounts::default()).unwrap();
    assert!(s > 0.999, "self score {s}");
    // A flat template is an error; a missing checkpoint too.
    let flat = vec![90u8; 200 * 200];
    let f = ImageView::new(&flat, 200, 200).unwrap();
    assert!(m
        .score(&f, &w, &win0(&r), &mut OpCounts::default())
        .is_err());
    assert!(FloatCnnMatcher::load(&dir.join("missing.safetensors")).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

fn win0<'a>(r: &ImageView<'a>) -> ImageView<'a> {
    r.sub(0, 0, 200, 200).unwrap()
}
