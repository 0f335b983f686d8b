//! Grid sampling: bit-identical across machines and sampling paths, grid windows equal to
//! the whole grid's pixels, pixel centres like point queries, the flat world.

use orbfix_host::world::World;

/// FNV-1a over the bits of the heights and albedos of a grid.
fn grid_digest(world: &World) -> u64 {
    let g = world.sample_grid(-40.0, 3000.0, 0.37, 64, 64);
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for v in g.height_m.iter().chain(&g.albedo) {
        for b in v.to_bits().to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
    }
    h
}

#[test]
fn the_world_is_bit_identical_across_machines() {
    // The digest of one grid of the default world. Placement uses integer hashes and exact
    // arithmetic only, so this holds on every machine; it changes only when the terrain
    // model or its defaults change (then update the digest, and say so in the commit).
    let digest = grid_digest(&World::new(2018));
    assert_eq!(digest, GOLDEN_DIGEST, "digest now {digest:#018x}");
}

const GOLDEN_DIGEST: u64 = 0xd71a_d8ad_31ed_b2f8;

/// FNV-1a over the bits of many grids: footprint-filtered ones at the renderer's mesh
/// spacings (0.1 m to 12.8 m, fine and coarse sampling paths), point grids at coarse
/// spacings, odd sizes and origins, the flat world, and filtered point queries.
fn sampler_digest() -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |v: &[f32]| {
        for x in v {
            for b in x.to_bits().to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    };
    let world = World::new(7);
    let flat = World::flat(7);
    let mut m = 0.1;
    for k in 0..8 {
        // Origins on the renderer's lattice (tile corners) and off it.
        let (ox, oy) = (64.0 * m * (3 + k) as f64, 64.0 * m * (11 - k) as f64);
        let g = world.sample_grid_filtered(ox, oy, m, 64, 64, m);
        eat(&g.height_m);
        eat(&g.albedo);
        let g = world.sample_grid_filtered(-ox - 0.37, oy + 1.9, m, 37, 23, m);
        eat(&g.height_m);
        eat(&g.albedo);
        let g = flat.sample_grid_filtered(ox + 3.3, -oy, m, 29, 31, 1.5 * m);
        eat(&g.height_m);
        eat(&g.albedo);
        let g = world.sample_grid(ox - 77.7, oy, m, 33, 17);
        eat(&g.height_m);
        eat(&g.albedo);
        m *= 2.0;
    }
    for (x, y, fp) in [
        (10.0, 20.0, 0.3),
        (-1234.5, 987.6, 2.0),
        (4000.1, 4000.2, 9.0),
    ] {
        eat(&[world.albedo_filtered(x, y, fp) as f32]);
    }
    h
}

#[test]
fn grid_windows_are_the_whole_grids_pixels() {
    // A window samples only its pixels, with the values of the whole grid (the grid's own
    // tiles, fine and coarse paths, partial tiles at the edges, point and filtered).
    let world = World::new(3);
    let flat = World::flat(3);
    for (w, ox, oy, m, nx, ny, fp) in [
        (&world, 0.0, 64.0 * 12.8, 12.8, 64, 64, 12.8),
        (&world, -77.3, 1201.9, 3.2, 45, 37, 3.2),
        (&world, 512.0, 512.0, 1.6, 64, 64, 1.6),
        (&world, 100.1, -40.0, 0.8, 29, 33, 0.8),
        (&world, 3.0, 7.0, 0.1, 40, 21, 0.1),
        (&world, 900.0, 900.0, 5.0, 23, 19, 0.0),
        (&flat, 250.0, 250.0, 6.4, 31, 17, 6.4),
    ] {
        let g = w.sample_grid_filtered(ox, oy, m, nx, ny, fp);
        for (cols, rows) in [
            (0..nx, 0..ny),
            (0..1, 0..1),
            (nx - 1..nx, ny - 1..ny),
            (3..nx.min(19), 5..ny.min(22)),
            (nx / 2..nx, 0..ny / 3),
        ] {
            let (h, a) = w.sample_grid_window(ox, oy, m, nx, ny, fp, cols.clone(), rows.clone());
            assert_eq!(h.len(), cols.len() * rows.len());
            for (k, r) in rows.clone().enumerate() {
                for (j, c) in cols.clone().enumerate() {
                    let i = r * nx + c;
                    let q = k * cols.len() + j;
                    assert_eq!(h[q].to_bits(), g.height_m[i].to_bits(), "{m} m: ({c}, {r})");
                    assert_eq!(a[q].to_bits(), g.albedo[i].to_bits(), "{m} m: ({c}, {r})");
                }
            }
        }
        let (h, _) = w.sample_grid_window(ox, oy, m, nx, ny, fp, 0..nx + 1, 0..1);
        assert!(h.is_empty(), "a window outside the grid is empty");
    }
}

#[test]
fn every_sampling_path_is_bit_identical() {
    // Pins the values of every grid path the renderer uses (see `sampler_digest`); a change
    // of the sampler's speed must not move it. It changes only with the terrain model.
    let digest = sampler_digest();
    assert_eq!(digest, SAMPLER_DIGEST, "digest now {digest:#018x}");
}

const SAMPLER_DIGEST: u64 = 0xada0_a785_2f46_edeb;

#[test]
fn flat_world_has_no_relief_and_the_same_albedo() {
    let (world, flat) = (World::new(5), World::flat(5));
    assert!(!flat.config().relief);
    let g = world.sample_grid(2600.0, 800.0, 0.2, 60, 50);
    let f = flat.sample_grid(2600.0, 800.0, 0.2, 60, 50);
    assert!(f.height_m.iter().all(|&h| h == 0.0));
    assert_eq!(g.albedo, f.albedo);
    assert!(g.height_m.iter().any(|&h| h != 0.0));
    for i in 0..200 {
        let (x, y) = (37.0 + 1.37 * i as f64, -11.0 + 0.71 * i as f64);
        assert_eq!(flat.height_m(x, y), 0.0);
        assert_eq!(flat.albedo(x, y), world.albedo(x, y));
        assert_eq!(flat.sample(x, y), (0.0, world.albedo(x, y)));
    }
}

#[test]
fn grid_samples_pixel_centres_like_point_queries() {
    let world = World::new(9);
    let flat = World::flat(9);
    // Fine grids (tiles gather craters and boulders), coarse ones (tiles gather craters,
    // pixels their boulders), single-pixel tiles; odd sizes leave partial tiles.
    for (ox, oy, m, nx, ny) in [
        (-13.3, 42.7, 0.31, 37, 21),
        (2903.1, 1811.9, 0.05, 41, 35),
        (120.0, 560.0, 0.2, 19, 33),
        (-400.0, 900.0, 1.7, 23, 17),
        (700.0, 1300.0, 9.0, 9, 7),
    ] {
        let g = world.sample_grid(ox, oy, m, nx, ny);
        let gf = flat.sample_grid(ox, oy, m, nx, ny);
        assert_eq!(
            (g.nx, g.ny, g.height_m.len(), g.albedo.len()),
            (nx, ny, nx * ny, nx * ny)
        );
        assert_eq!(g.pixel_centre(0, 0), (ox + 0.5 * m, oy - 0.5 * m));
        for row in 0..g.ny {
            for col in 0..g.nx {
                let (x, y) = (ox + (col as f64 + 0.5) * m, oy - (row as f64 + 0.5) * m);
                let (h, a) = world.sample(x, y);
                let i = g.index(col, row).expect("inside");
                assert_eq!(
                    g.height_m[i], h as f32,
                    "height at ({col}, {row}), {m} m/px"
                );
                assert_eq!(g.albedo[i], a as f32, "albedo at ({col}, {row}), {m} m/px");
                assert_eq!(
                    gf.albedo[i], a as f32,
                    "flat albedo at ({col}, {row}), {m} m/px"
                );
                assert_eq!(gf.height_m[i], 0.0);
                assert_eq!(world.height_m(x, y), h);
                assert_eq!(world.albedo(x, y), a);
            }
        }
        assert_eq!(g.index(nx, 0), None);
    }
    let empty = world.sample_grid(0.0, 0.0, 1.0, 0, 5);
    assert!(empty.height_m.is_empty() && empty.albedo.is_empty());
}
