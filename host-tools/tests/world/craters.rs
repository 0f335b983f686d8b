//! Craters: the size-frequency power law, the degradation states, the bowl, rim and ejecta
//! profile, and a fresh crater with its boulders in the world.

use orbfix_host::world::{Crater, Degradation, World, WorldConfig};

/// Least-squares slope of `ln N(>D)` against `ln D`, and `N(>D)` at the thresholds.
fn cumulative_slope(craters: &[Crater], thresholds: &[f64]) -> (f64, Vec<usize>) {
    let counts: Vec<usize> = thresholds
        .iter()
        .map(|&d| craters.iter().filter(|c| c.diameter_m >= d).count())
        .collect();
    let pts: Vec<(f64, f64)> = thresholds
        .iter()
        .zip(&counts)
        .map(|(&d, &n)| (d.ln(), (n as f64).ln()))
        .collect();
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    (sxy / sxx, counts)
}

#[test]
fn crater_sizes_follow_the_configured_power_law() {
    for (exponent, density, seed) in [(2.0, 0.08, 3u64), (2.5, 0.05, 4), (1.6, 0.08, 5)] {
        let cfg = WorldConfig {
            crater_exponent: exponent,
            crater_density_per_m2: density,
            ..WorldConfig::default()
        };
        let world = World::try_with_config(seed, cfg.clone()).expect("valid config");
        let side = 2000.0;
        let craters = world
            .craters_in(0.0, 0.0, side, side, 2.0)
            .expect("rect ok");
        let thresholds = [2.0, 4.0, 8.0, 16.0, 32.0];
        let (slope, counts) = cumulative_slope(&craters, &thresholds);
        assert!(
            (slope + exponent).abs() < 0.1,
            "exponent {exponent}: fitted cumulative slope {slope:.3}, counts {counts:?}"
        );
        // Absolute density at 2 m: N(>2) = K (2^-b - Dmax^-b) per m^2.
        let expected =
            density * (2f64.powf(-exponent) - cfg.crater_d_max_m.powf(-exponent)) * side * side;
        let got = counts[0] as f64;
        assert!(
            (got / expected - 1.0).abs() < 0.05,
            "exponent {exponent}: N(>2 m) = {got}, expected {expected:.0}"
        );
        // Every crater is within the configured diameter range and in the rectangle.
        assert!(craters.iter().all(|c| c.diameter_m >= 2.0
            && c.diameter_m < cfg.crater_d_max_m
            && (0.0..side).contains(&c.x_m)
            && (0.0..side).contains(&c.y_m)));
    }
}

#[test]
fn degradation_states_have_the_configured_fractions_and_shapes() {
    let world = World::new(11);
    let cfg = world.config().clone();
    let craters = world
        .craters_in(0.0, 0.0, 1000.0, 1000.0, 2.0)
        .expect("rect ok");
    let n = craters.len() as f64;
    assert!(n > 10_000.0);
    let frac = |s: Degradation| craters.iter().filter(|c| c.state == s).count() as f64 / n;
    assert!((frac(Degradation::Fresh) - cfg.crater_fresh_fraction).abs() < 0.02);
    assert!((frac(Degradation::Old) - cfg.crater_old_fraction).abs() < 0.02);
    assert!(frac(Degradation::Mature) > 0.3);
    for c in &craters {
        let dd = c.depth_m / c.diameter_m;
        assert!(
            dd <= cfg.crater_depth_ratio_fresh + 1e-12 && dd >= cfg.crater_depth_ratio_old - 1e-12
        );
        if c.state == Degradation::Fresh {
            assert!(dd > 0.17, "fresh crater with depth/D {dd}");
            assert!(c.freshness > 0.0);
        } else {
            assert_eq!(c.freshness, 0.0);
        }
        if c.state == Degradation::Old {
            assert!(dd < 0.12, "old crater with depth/D {dd}");
        }
    }
}

#[test]
fn crater_profile_has_bowl_rim_and_ejecta() {
    let fresh = Crater {
        x_m: 0.0,
        y_m: 0.0,
        diameter_m: 20.0,
        depth_m: 4.0,
        rim_m: 0.8,
        smoothing_m: 0.05 * 4.8,
        degradation: 0.0,
        state: Degradation::Fresh,
        freshness: 1.0,
        ejecta_extent_radii: 2.5,
        id: 42,
    };
    let r = 10.0;
    let h = |rho: f64| fresh.height_at((rho * r) * (rho * r));
    assert!((h(0.0) + 4.0).abs() < 1e-9, "floor {}", h(0.0));
    // The rim crest is raised, within the smoothing of the configured rim height.
    let crest = (0..200)
        .map(|i| h(0.8 + 0.002 * i as f64))
        .fold(f64::MIN, f64::max);
    assert!(crest > 0.7 && crest <= 0.8, "crest {crest}");
    // Bowl rises monotonically to the rim; the ejecta decays monotonically to zero.
    for i in 0..90 {
        let rho = i as f64 * 0.01;
        assert!(h(rho + 0.01) >= h(rho));
    }
    for i in 0..140 {
        let rho = 1.1 + i as f64 * 0.01;
        assert!(h(rho + 0.01) <= h(rho) && h(rho) >= 0.0);
    }
    assert!(h(1.5) > 0.1 && h(1.5) < 0.3, "ejecta at 1.5 R: {}", h(1.5));
    assert_eq!(h(2.5), 0.0);
    assert_eq!(h(3.0), 0.0);
    // A degraded crater of the same size is shallower with a lower, rounder rim.
    let old = Crater {
        depth_m: 1.0,
        rim_m: 0.1,
        smoothing_m: 0.6 * 1.1,
        degradation: 0.9,
        state: Degradation::Old,
        freshness: 0.0,
        ..fresh
    };
    let ho = |rho: f64| old.height_at((rho * r) * (rho * r));
    assert!(ho(0.0) > h(0.0) + 2.0);
    assert!(ho(1.0) < h(1.0));
    // Only the fresh one brightens its surroundings.
    assert!(fresh.albedo_at(3.0, 0.0, 9.0, 0.08) > 0.0);
    assert_eq!(old.albedo_at(3.0, 0.0, 9.0, 0.08), 0.0);
    assert_eq!(fresh.albedo_at(30.0, 0.0, 900.0, 0.08), 0.0);
}

#[test]
fn a_fresh_crater_in_the_world_is_a_bowl_with_boulders_around_it() {
    // Few, large craters, no noise: one crater stands out clearly.
    let cfg = WorldConfig {
        noise_amplitude_m: 0.0,
        crater_density_per_m2: 0.01,
        crater_d_min_m: 20.0,
        crater_d_max_m: 40.0,
        crater_fresh_fraction: 0.5,
        crater_old_fraction: 0.2,
        ..WorldConfig::default()
    };
    let world = World::try_with_config(21, cfg.clone()).expect("valid config");
    let smooth = World::try_with_config(
        21,
        WorldConfig {
            rock_density_per_m2: 0.0,
            ..cfg
        },
    )
    .expect("valid config");
    let all = world
        .craters_in(-500.0, -500.0, 500.0, 500.0, 0.0)
        .expect("rect ok");
    // A fresh crater with no other crater's blanket reaching its rim.
    let c = all
        .iter()
        .find(|c| {
            c.state == Degradation::Fresh
                && c.freshness > 0.5
                && all.iter().all(|o| {
                    std::ptr::eq(*c, o)
                        || (o.x_m - c.x_m).hypot(o.y_m - c.y_m)
                            > 1.2 * c.radius_m() + 2.5 * o.radius_m()
                })
        })
        .expect("an isolated fresh crater");
    let r = c.radius_m();
    let floor = smooth.height_m(c.x_m, c.y_m);
    assert!(
        (floor + c.depth_m).abs() < 0.05 * c.depth_m,
        "floor {floor}, depth {}",
        c.depth_m
    );
    let rim = smooth.height_m(c.x_m + r, c.y_m);
    assert!(rim > 0.5 * c.rim_m, "rim {rim} vs {}", c.rim_m);
    // Boulders: share of points raised by rocks, on the crater's inner slopes vs far away.
    let covered = |x0: f64, y0: f64, side: f64| {
        let g = world.sample_grid(x0, y0, 0.1, (side / 0.1) as usize, (side / 0.1) as usize);
        let s = smooth.sample_grid(x0, y0, 0.1, g.nx, g.ny);
        let n = g
            .height_m
            .iter()
            .zip(&s.height_m)
            .filter(|(a, b)| a > b)
            .count();
        n as f64 / g.height_m.len() as f64
    };
    let near = covered(c.x_m - 0.6 * r, c.y_m + 0.6 * r, 1.2 * r);
    // Background: a square no crater reaches.
    let far = (0..400)
        .map(|i| {
            (
                -480.0 + 24.0 * (i % 40) as f64,
                -480.0 + 24.0 * (i / 40) as f64,
            )
        })
        .find(|&(x, y)| {
            all.iter()
                .all(|o| (o.x_m - x - 10.0).hypot(o.y_m - y + 10.0) > 2.5 * o.radius_m() + 15.0)
        })
        .map(|(x, y)| covered(x, y, 20.0))
        .expect("a crater-free square");
    assert!(
        near > 3.0 * far && near > 0.02,
        "rock cover near {near:.4}, far {far:.4}"
    );
}
