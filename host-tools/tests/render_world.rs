//! The renderer on the built-in lunar world: shared far-terrain cache, sanity of images.

use orbfix_host::render::{self, terrain::TileCache, RenderOptions, Sun};
use orbfix_host::world::World;

fn small() -> RenderOptions {
    let mut o = RenderOptions::default();
    o.camera.width_px = 160;
    o.camera.height_px = 90;
    o
}

#[test]
fn shared_tile_cache_gives_identical_images() {
    let world = World::new(5);
    let o = small();
    let cache = TileCache::new(1 << 20);
    for (x, y, h) in [(900.0, 800.0, 10.0), (930.0, 790.0, 200.0)] {
        let pose = render::ground_pose(&world, x, y, h);
        let shared =
            render::render_views_cached(&world, &pose, Sun::default(), &o, Some(&cache)).unwrap();
        let fresh = render::render_views_with_range(&world, &pose, Sun::default(), &o).unwrap();
        assert_eq!(shared.views, fresh.views);
        assert_eq!(shared.range_m, fresh.range_m);
        for v in &fresh.views {
            // Ground in the lower half, black sky in the top row.
            let bottom: f64 = (0..160).map(|i| v.get_pixel(i, 80)[0] as f64).sum::<f64>() / 160.0;
            assert!(bottom > 30.0 && bottom < 250.0, "ground gray {bottom}");
            assert!(
                (0..160).all(|i| v.get_pixel(i, 0)[0] == 0),
                "sky must be black"
            );
        }
    }
}

#[test]
fn map_regions_and_crops_agree() {
    // A crop and a larger map region rendered separately show the same pixels where they
    // overlap (same lattice, same sun), apart from shadow edges traced on other lattices.
    let world = World::new(5);
    let o = RenderOptions::default();
    let sun = Sun::new(35.0, 200.0).unwrap();
    let (crop, g) =
        render::render_satellite_crop(&world, 1000.0, 1000.0, 80, 0.25, sun, &o).unwrap();
    let big = orbfix::geo::GeoRef::new(g.origin_x_m() - 10.0, g.origin_y_m() + 10.0, 0.25).unwrap();
    let map = render::render_ortho(&world, &big, 160, 160, sun, &o).unwrap();
    let mut same = 0;
    for r in 0..80u32 {
        for c in 0..80u32 {
            let a = crop.get_pixel(c, r)[0] as i32;
            let b = map.get_pixel(c + 40, r + 40)[0] as i32;
            if (a - b).abs() <= 1 {
                same += 1;
            }
        }
    }
    assert!(
        same >= 80 * 80 * 97 / 100,
        "only {same} of 6400 pixels agree"
    );
}

/// FNV-1a over the bits of what the rasterizer is given: every level's grid (placement,
/// heights and albedo), the node attributes (normals, lit fractions from the shadow sweep),
/// for a walk of locations with and without the shared tile cache, and the satellite crops.
/// A level's nodes deep inside the finer level (3 nodes or more: never read, left unsampled)
/// are left out, and so are normals from 2 nodes inside on (cells drawn over the finer
/// level's edge reach 2 nodes into it; their normals read one node further).
fn preparation_digest() -> u64 {
    use orbfix_host::render::{raster::NodeAttrs, shadow::ShadowField, terrain::Terrain};
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bits: &mut dyn Iterator<Item = u64>| {
        for v in bits {
            for b in v.to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    };
    let world = World::new(11);
    let mut o = RenderOptions::default();
    o.camera.width_px = 320;
    o.camera.height_px = 180;
    let focal = o.camera_params().focal_px() as f64;
    let cache = TileCache::new(1 << 22);
    let suns = [Sun::default(), Sun::new(12.0, 250.0).unwrap()];
    for i in 0..3 {
        let (x, y) = (300.0 + 97.0 * i as f64, 400.0 + 61.0 * i as f64);
        let sun = suns[i % 2];
        for c in [Some(&cache), None] {
            let t = Terrain::around_cached(&world, x, y, &o, focal, c);
            let s = ShadowField::build(&t, &sun, o.shadow_reach_m);
            let a = NodeAttrs::compute(&t, &s);
            for (k, l) in t.levels.iter().enumerate() {
                let g = &l.grid;
                eat(&mut [g.origin_x_m, g.origin_y_m, g.m_per_px]
                    .iter()
                    .map(|v| v.to_bits()));
                eat(&mut [g.nx as u64, g.ny as u64].into_iter());
                eat(&mut l.bounds.iter().map(|v| v.to_bits()));
                // How far inside the finer level's square each node lies, in nodes.
                let inside = |i: usize| {
                    let Some(f) = k.checked_sub(1).map(|j| t.levels[j].bounds) else {
                        return f64::NEG_INFINITY;
                    };
                    let (x, y) = l.node_xy(i % g.nx, i / g.nx);
                    (x - f[0]).min(f[2] - x).min(y - f[1]).min(f[3] - y) / g.m_per_px
                };
                for i in 0..g.nx * g.ny {
                    let d = inside(i);
                    if d < 3.0 {
                        eat(&mut [g.height_m[i], g.albedo[i]]
                            .iter()
                            .map(|v| v.to_bits() as u64));
                    }
                    if d < 2.0 {
                        eat(&mut a.normal[k][i].iter().map(|v| v.to_bits() as u64));
                    }
                    eat(&mut std::iter::once(a.lit[k][i].to_bits() as u64));
                }
            }
        }
        let (img, _) =
            render::render_satellite_crop_cached(&world, x, y, 64, 0.25, sun, &o, Some(&cache))
                .unwrap();
        eat(&mut img.as_raw().iter().map(|&b| b as u64));
    }
    h
}

#[test]
fn terrain_preparation_is_bit_identical() {
    // Pins the terrain levels, shadows and node attributes the rasterizer reads (and the
    // satellite crops): a speed-up of the preparation must leave them bit for bit.
    let digest = preparation_digest();
    assert_eq!(digest, PREPARATION_DIGEST, "digest now {digest:#018x}");
}

const PREPARATION_DIGEST: u64 = 0xf4ef_2995_848a_462e;
