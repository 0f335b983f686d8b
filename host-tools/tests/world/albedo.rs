//! The footprint-filtered albedo: the box average of the fine albedo.

use orbfix_host::world::{Degradation, World};

/// Box average of a fine point-sampled grid's albedo over `k x k` blocks.
fn block_mean(g: &orbfix_host::world::HeightGrid, k: usize) -> Vec<f64> {
    let (nx, ny) = (g.nx / k, g.ny / k);
    let mut out = vec![0.0; nx * ny];
    for r in 0..ny * k {
        for c in 0..nx * k {
            out[(r / k) * nx + c / k] += g.albedo[r * g.nx + c] as f64;
        }
    }
    out.iter().map(|s| s / (k * k) as f64).collect()
}

fn rms(a: &[f64], b: &[f32]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(x, &y)| (x - y as f64).powi(2))
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

#[test]
fn footprint_filtered_albedo_is_the_box_average_of_the_fine_albedo() {
    let world = World::new(3);
    // A fresh crater with its own boulders, and the ground around it.
    let c = world
        .craters_in(500.0, 500.0, 1500.0, 1500.0, 8.0)
        .unwrap()
        .into_iter()
        .find(|c| c.state == Degradation::Fresh && c.diameter_m < 30.0)
        .expect("a fresh crater of 8-30 m");
    let side = 3.0 * c.diameter_m;
    let (ox, oy) = (c.x_m - 0.5 * side, c.y_m + 0.5 * side);
    for (coarse, k) in [(0.4, 16usize), (1.6, 64)] {
        let fine_m = coarse / k as f64;
        let n = (side / coarse) as usize;
        let fine = world.sample_grid(ox, oy, fine_m, n * k, n * k);
        let truth = block_mean(&fine, k);
        let point = world.sample_grid(ox, oy, coarse, n, n);
        let filt = world.sample_grid_filtered(ox, oy, coarse, n, n, coarse);
        // Heights stay point samples, except that boulders taken by their mean (up to 1.6 m
        // wide at 1.6 m: bumps of at most 0.64 m, rarely two overlapping) are left out.
        if coarse < 1.0 {
            assert_eq!(filt.height_m, point.height_m);
        } else {
            let dh = filt
                .height_m
                .iter()
                .zip(&point.height_m)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(dh > 0.0 && dh < 0.7, "{coarse} m: height change {dh}");
        }
        let (e_point, e_filt) = (rms(&truth, &point.albedo), rms(&truth, &filt.albedo));
        let mean = |v: &[f32]| v.iter().map(|&a| a as f64).sum::<f64>() / v.len() as f64;
        let m_truth = truth.iter().sum::<f64>() / truth.len() as f64;
        eprintln!(
            "{coarse} m: RMS vs box average: point {e_point:.5}, filtered {e_filt:.5}; mean {m_truth:.5} / {:.5} / {:.5}",
            mean(&point.albedo),
            mean(&filt.albedo)
        );
        assert!(e_filt < 0.6 * e_point, "{coarse} m: {e_filt} vs {e_point}");
        // Area-preserving: the filtered mean is the true mean (boulders smaller than the
        // footprint enter by their expected value at 1.6 m, so only statistically).
        let tol = if coarse < 1.0 { 0.001 } else { 0.004 };
        assert!(
            (mean(&filt.albedo) - m_truth).abs() < tol,
            "{coarse} m mean"
        );
    }
    // Footprint 0 is the point sampler; the point query agrees with the grid.
    let g0 = world.sample_grid_filtered(ox, oy, 0.3, 20, 20, 0.0);
    assert_eq!(g0, world.sample_grid(ox, oy, 0.3, 20, 20));
    let gf = world.sample_grid_filtered(ox, oy, 0.3, 20, 20, 0.3);
    for (col, row) in [(0, 0), (7, 3), (19, 19)] {
        let (x, y) = gf.pixel_centre(col, row);
        let i = gf.index(col, row).unwrap();
        assert_eq!(world.albedo_filtered(x, y, 0.3) as f32, gf.albedo[i]);
    }
    assert_eq!(
        world.albedo_filtered(f64::NAN, 0.0, 0.3),
        world.config().albedo_mean
    );
}
