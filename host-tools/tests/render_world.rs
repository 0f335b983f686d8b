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
