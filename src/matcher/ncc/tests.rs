//! Tests of the masked NCC: gain, offset and hole invariance, flat inputs, and the dense
//! paths equal to the per-window scores to the bit.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::*;

#[test]
fn ncc_is_gain_and_offset_invariant_and_ignores_holes() {
    let t = [10u8, 50, 30, 90, 70, 20, 0, 0, 0];
    let mut m = [0u8; 9];
    for i in 0..9 {
        m[i] = 40 + t[i] / 2;
    }
    m[6] = 255; // under a hole: must not matter
    let w = [255u8, 255, 255, 255, 255, 255, 0, 0, 0];
    let (tv, mv, wv) = (
        ImageView::new(&t, 3, 3).unwrap(),
        ImageView::new(&m, 3, 3).unwrap(),
        ImageView::new(&w, 3, 3).unwrap(),
    );
    let mut ops = OpCounts::default();
    let s = Ncc::default().score(&tv, &wv, &mv, &mut ops).unwrap();
    assert!(s > 0.999, "{s}");
    // Inverted map: anti-correlated.
    let inv: [u8; 9] = core::array::from_fn(|i| 255 - m[i]);
    let iv = ImageView::new(&inv, 3, 3).unwrap();
    let s = Ncc::default().score(&tv, &wv, &iv, &mut ops).unwrap();
    assert!(s < -0.999, "{s}");
}

#[test]
fn general_dense_path_with_holes_equals_per_window_scores_to_the_bit() {
    let mut seed = 777u32;
    let mut rnd = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 24) as u8
    };
    // 40 x 30 = 1200 px: beyond the fast path, so the general path runs.
    let (tw, th, rw, rh) = (40usize, 30usize, 52usize, 37usize);
    let t: [u8; 1200] = core::array::from_fn(|_| rnd());
    // A top-down-like weight: a hole disc in the middle, no data outside a disc, partial
    // weights at the edges, and a row of many short runs.
    let w: [u8; 1200] = core::array::from_fn(|i| {
        let (x, y) = ((i % tw) as i32 - 20, (i / tw) as i32 - 15);
        let d2 = x * x + y * y;
        if y == 3 {
            return if x % 3 == 0 { 0 } else { 200 };
        }
        match d2 {
            0..=12 => 0,
            13..=20 => 90,
            21..=300 => 255,
            _ => 0,
        }
    });
    let m: [u8; 52 * 37] = core::array::from_fn(|_| rnd());
    let (tv, wv, mv) = (
        ImageView::new(&t, tw, th).unwrap(),
        ImageView::new(&w, tw, th).unwrap(),
        ImageView::new(&m, rw, rh).unwrap(),
    );
    let mut out = [0f32; 13 * 8];
    let mut ops = OpCounts::default();
    let g = Ncc::default()
        .dense(&tv, &wv, &mv, 1, &mut out, &mut ops)
        .unwrap();
    assert_eq!((g.cols, g.rows), (13, 8));
    for r in 0..g.rows {
        for c in 0..g.cols {
            let win = mv.sub(c, r, tw, th).unwrap();
            let mut o = OpCounts::default();
            let s = Ncc::default().score(&tv, &wv, &win, &mut o).unwrap();
            assert_eq!(out[r * g.cols + c].to_bits(), s.to_bits(), "({c}, {r})");
        }
    }
}

#[test]
fn fast_dense_path_equals_per_window_scores_to_the_bit() {
    let mut seed = 12345u32;
    let mut rnd = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 24) as u8
    };
    let (tw, th, rw, rh) = (9usize, 7usize, 40usize, 30usize);
    let t: [u8; 63] = core::array::from_fn(|_| rnd());
    // Mostly one weight, a hole disc and a few partial weights (like a coarse mask).
    let w: [u8; 63] = core::array::from_fn(|i| match i % 11 {
        0 => 0,
        3 => 77,
        _ => 255,
    });
    let m: [u8; 1200] = core::array::from_fn(|_| rnd());
    let (tv, wv, mv) = (
        ImageView::new(&t, tw, th).unwrap(),
        ImageView::new(&w, tw, th).unwrap(),
        ImageView::new(&m, rw, rh).unwrap(),
    );
    for step in [1usize, 2, 3, 7, 10] {
        let mut out = [0f32; 1200];
        let mut ops = OpCounts::default();
        let g = Ncc::default()
            .dense(&tv, &wv, &mv, step, &mut out, &mut ops)
            .unwrap();
        assert!(
            ops.macs < 3 * (tw * th * g.len()) as u64,
            "fast path not taken"
        );
        for r in 0..g.rows {
            for c in 0..g.cols {
                let win = mv.sub(c * step, r * step, tw, th).unwrap();
                let mut o = OpCounts::default();
                let s = Ncc::default().score(&tv, &wv, &win, &mut o).unwrap();
                assert_eq!(s.to_bits(), out[r * g.cols + c].to_bits(), "{step} {c} {r}");
            }
        }
    }
}

#[test]
fn general_dense_path_equals_per_window_scores_to_the_bit() {
    let mut seed = 777u32;
    let mut rnd = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 24) as u8
    };
    // 33 x 33 = 1089 px > FAST_MAX_PX, random weights: the general path.
    let (tw, th, rw, rh) = (33usize, 33usize, 40usize, 37usize);
    let t: [u8; 1089] = core::array::from_fn(|_| rnd());
    let w: [u8; 1089] = core::array::from_fn(|_| rnd());
    let m: [u8; 1480] = core::array::from_fn(|_| rnd());
    let (tv, wv, mv) = (
        ImageView::new(&t, tw, th).unwrap(),
        ImageView::new(&w, tw, th).unwrap(),
        ImageView::new(&m, rw, rh).unwrap(),
    );
    for step in [1usize, 2, 3] {
        let mut out = [0f32; 64];
        let mut ops = OpCounts::default();
        let g = Ncc::default()
            .dense(&tv, &wv, &mv, step, &mut out, &mut ops)
            .unwrap();
        assert_eq!(ops.macs, 3 * (tw * th * g.len()) as u64);
        for r in 0..g.rows {
            for c in 0..g.cols {
                let win = mv.sub(c * step, r * step, tw, th).unwrap();
                let mut o = OpCounts::default();
                let s = Ncc::default().score(&tv, &wv, &win, &mut o).unwrap();
                assert_eq!(s.to_bits(), out[r * g.cols + c].to_bits(), "{step} {c} {r}");
            }
        }
    }
}

#[test]
fn ncc_flat_inputs() {
    let t = [7u8; 4];
    let m = [1u8, 2, 3, 4];
    let w = [1u8; 4];
    let (tv, mv, wv) = (
        ImageView::new(&t, 2, 2).unwrap(),
        ImageView::new(&m, 2, 2).unwrap(),
        ImageView::new(&w, 2, 2).unwrap(),
    );
    let mut ops = OpCounts::default();
    assert_eq!(
        Ncc::default().score(&tv, &wv, &mv, &mut ops),
        Err(MatchError::FeaturelessTemplate)
    );
    // Flat map window scores 0.
    let s = Ncc::default().score(&mv, &wv, &tv, &mut ops).unwrap();
    assert_eq!(s, 0.0);
    let z = [0u8; 4];
    let zv = ImageView::new(&z, 2, 2).unwrap();
    assert_eq!(
        Ncc::default().score(&mv, &zv, &tv, &mut ops),
        Err(MatchError::NoValidPixels)
    );
}
