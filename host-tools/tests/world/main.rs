//! Tests of the procedural lunar world: zones, determinism, robustness to bad input here;
//! craters, rocks, grid sampling, the filtered albedo and the world's cost in the modules.

mod albedo;
mod cost;
mod craters;
mod rocks;
mod sampling;

use orbfix_host::world::zones::{self, Split, Zone, MAP_HALF_EXTENT_M, WORLD_SIZE_M};
use orbfix_host::world::{World, WorldConfig, WorldError};

#[test]
fn zones_are_disjoint_and_maps_stay_inside() {
    assert_eq!(zones::ALL.len(), 3);
    for (i, s) in Split::ALL.into_iter().enumerate() {
        let z = zones::zone(s);
        assert_eq!(z, zones::ALL[i]);
        assert_eq!(z.name, s.name());
        assert_eq!(s.name().parse::<Split>(), Ok(s));
        assert!(!z.is_empty());
        assert!(z.x_min_m >= 0.0 && z.y_min_m >= 0.0);
        assert!(z.x_max_m <= WORLD_SIZE_M && z.y_max_m <= WORLD_SIZE_M);
        // Locations at least a map half-extent inside: every map region lies in the zone.
        let loc = z.location_area();
        assert!(!loc.is_empty(), "{} has no room for a 300 m map", z.name);
        assert_eq!(loc.inset(-MAP_HALF_EXTENT_M), z);
        let (cx, cy) = z.centre();
        assert_eq!(zones::split_at(cx, cy), Some(s));
    }
    // The study's sizes: 2 x 2 km training, 1 x 1 km validation and test.
    assert_eq!(
        (zones::TRAIN.width_m(), zones::TRAIN.height_m()),
        (2000.0, 2000.0)
    );
    for z in [zones::VALIDATION, zones::TEST] {
        assert_eq!((z.width_m(), z.height_m()), (1000.0, 1000.0));
    }
    for a in 0..3 {
        for b in 0..3 {
            if a == b {
                continue;
            }
            let (za, zb) = (zones::ALL[a], zones::ALL[b]);
            assert!(!za.overlaps(&zb), "{} overlaps {}", za.name, zb.name);
            // A map region (a location area grown by the half extent) of one split never
            // reaches into another zone.
            let grown = za.location_area().inset(-MAP_HALF_EXTENT_M);
            assert!(!grown.overlaps(&zb));
            assert!(
                za.gap_m(&zb) >= 500.0,
                "{} and {} closer than 500 m",
                za.name,
                zb.name
            );
        }
    }
    // Points in the gaps belong to no split; a sanity check of `overlaps` itself.
    assert_eq!(zones::split_at(2250.0, 500.0), None);
    assert_eq!(zones::split_at(3000.0, 1250.0), None);
    let a = Zone {
        name: "a",
        x_min_m: 0.0,
        y_min_m: 0.0,
        x_max_m: 10.0,
        y_max_m: 10.0,
    };
    let b = Zone {
        name: "b",
        x_min_m: 9.0,
        y_min_m: 9.0,
        x_max_m: 20.0,
        y_max_m: 20.0,
    };
    assert!(a.overlaps(&b));
    assert!("nope".parse::<Split>().is_err());
}

#[test]
fn same_seed_same_world_other_seed_other_world() {
    let (a, b, c) = (World::new(7), World::new(7), World::new(8));
    let ga = a.sample_grid(1234.5, 987.0, 0.25, 48, 40);
    let gb = b.sample_grid(1234.5, 987.0, 0.25, 48, 40);
    let gc = c.sample_grid(1234.5, 987.0, 0.25, 48, 40);
    assert_eq!(ga, gb);
    assert_eq!(ga, a.clone().sample_grid(1234.5, 987.0, 0.25, 48, 40));
    let differ = ga
        .height_m
        .iter()
        .zip(&gc.height_m)
        .filter(|(p, q)| p != q)
        .count();
    assert!(
        differ > ga.height_m.len() * 9 / 10,
        "only {differ} heights differ"
    );
    let differ = ga
        .albedo
        .iter()
        .zip(&gc.albedo)
        .filter(|(p, q)| p != q)
        .count();
    assert!(
        differ > ga.albedo.len() * 9 / 10,
        "only {differ} albedos differ"
    );
    assert_eq!(a.seed(), 7);
    let ca = a.craters_in(0.0, 0.0, 200.0, 200.0, 1.0).expect("rect ok");
    let cc = c.craters_in(0.0, 0.0, 200.0, 200.0, 1.0).expect("rect ok");
    assert_eq!(
        ca,
        b.craters_in(0.0, 0.0, 200.0, 200.0, 1.0).expect("rect ok")
    );
    assert_ne!(ca, cc);
}

#[test]
fn every_patch_has_features_and_lunar_relief() {
    let world = World::new(1);
    let mut state = 0x1234_5678u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for z in zones::ALL {
        let loc = z.location_area();
        for _ in 0..10 {
            let x = loc.x_min_m + next() * loc.width_m();
            let y = loc.y_min_m + next() * loc.height_m();
            // Craters of 2..50 m with centres in the 50 x 50 m patch around the location.
            let n = world
                .craters_in(x - 25.0, y - 25.0, x + 25.0, y + 25.0, 2.0)
                .expect("rect ok")
                .iter()
                .filter(|c| c.diameter_m <= 50.0)
                .count();
            assert!(
                n >= 10,
                "only {n} craters of 2..50 m in the patch at ({x:.0}, {y:.0})"
            );
            // Relief over the 300 m map region: rolling metres, not flat, not alpine.
            let g = world.sample_grid(x - 150.0, y + 150.0, 5.0, 60, 60);
            let mean = g.height_m.iter().map(|&h| f64::from(h)).sum::<f64>() / 3600.0;
            let sd = (g
                .height_m
                .iter()
                .map(|&h| (f64::from(h) - mean).powi(2))
                .sum::<f64>()
                / 3600.0)
                .sqrt();
            assert!(
                (0.3..25.0).contains(&sd),
                "height sd {sd:.2} m at ({x:.0}, {y:.0})"
            );
            assert!(g.albedo.iter().all(|&a| (0.03..0.4).contains(&a)));
        }
    }
}

#[test]
fn bad_input_gives_errors_not_panics() {
    let world = World::new(1);
    for (x, y) in [
        (f64::NAN, 0.0),
        (0.0, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NAN),
    ] {
        assert_eq!(world.height_m(x, y), 0.0);
        assert_eq!(world.albedo(x, y), world.config().albedo_mean);
    }
    // Far away but finite: still a terrain.
    assert!(world.height_m(1e9, -1e9).is_finite());
    assert!(world.try_sample_grid(f64::NAN, 0.0, 1.0, 4, 4).is_err());
    assert!(world.try_sample_grid(0.0, 0.0, 0.0, 4, 4).is_err());
    assert!(world.try_sample_grid(0.0, 0.0, -1.0, 4, 4).is_err());
    assert!(world.try_sample_grid(0.0, 0.0, 1.0, 0, 4).is_err());
    assert!(world.try_sample_grid(0.0, 0.0, 1.0, usize::MAX, 2).is_err());
    assert!(world.try_sample_grid(0.0, 0.0, 1.0, 4, 4).is_ok());
    let huge = world.sample_grid(0.0, 0.0, 1.0, usize::MAX, 3);
    assert_eq!((huge.nx, huge.ny, huge.height_m.len()), (0, 0, 0));
    let nan_grid = world.sample_grid(f64::NAN, 0.0, 1.0, 3, 3);
    assert!(nan_grid.height_m.iter().all(|&h| h == 0.0));
    assert!(world.craters_in(0.0, 0.0, 1e7, 1e7, 1.0).is_err());
    assert!(world.craters_in(10.0, 0.0, 0.0, 10.0, 1.0).is_err());
    assert!(world.rocks_in(0.0, 0.0, f64::NAN, 1.0).is_err());
    for bad in [
        WorldConfig {
            crater_exponent: f64::NAN,
            ..WorldConfig::default()
        },
        WorldConfig {
            crater_d_max_m: 0.5,
            ..WorldConfig::default()
        },
        WorldConfig {
            crater_fresh_fraction: 0.8,
            crater_old_fraction: 0.5,
            ..WorldConfig::default()
        },
        WorldConfig {
            noise_octaves: 40,
            ..WorldConfig::default()
        },
        WorldConfig {
            crater_density_per_m2: 10.0,
            ..WorldConfig::default()
        },
        WorldConfig {
            albedo_mean: -0.1,
            ..WorldConfig::default()
        },
    ] {
        let err = World::try_with_config(1, bad.clone()).expect_err("invalid config");
        assert!(matches!(err, WorldError::BadConfig { .. }));
        assert!(err.to_string().contains("out of range"), "{err}");
        // The infallible constructor falls back to the defaults.
        assert_eq!(World::with_config(1, bad).config(), &WorldConfig::default());
    }
    assert!(WorldConfig::default().validate().is_ok());
}

#[test]
fn world_is_clone_send_sync() {
    fn check<T: Clone + Send + Sync + 'static>() {}
    check::<World>();
    check::<orbfix_host::world::HeightGrid>();
}
