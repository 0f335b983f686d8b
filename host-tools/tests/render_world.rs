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

/// The cast-shadow sweep as first written (every lattice node, the whole extension towards
/// the sun, the plain level search): lit fraction at `(x, y)` of the first lattice whose
/// level square contains it.
fn plain_shadow_lit(
    t: &orbfix_host::render::terrain::Terrain,
    sun: &Sun,
    reach_m: f64,
    pts: &[(f64, f64)],
) -> Vec<f32> {
    let tan_e = sun.elevation_deg.to_radians().tan();
    let az = sun.azimuth_deg.to_radians();
    let s = (az.sin(), az.cos());
    let p = (az.cos(), -az.sin());
    let lattices: Vec<_> = t
        .levels
        .iter()
        .map(|level| {
            let b = level.bounds;
            let m = level.m();
            let (cx, cy) = (0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3]));
            let half = 0.5 * (b[2] - b[0]).hypot(b[3] - b[1]) + m;
            let (a0, b0) = (-half, -half);
            let n = (2.0 * half / m).ceil() as usize + 2;
            let mut lit = vec![1.0f32; n * n];
            let a_max = a0 + (n - 1) as f64 * m;
            for j in 0..n {
                let bj = b0 + j as f64 * m;
                let at = |a: f64| (cx + a * s.0 + bj * p.0, cy + a * s.1 + bj * p.1);
                let mut best = f64::NEG_INFINITY;
                let mut a = a_max + reach_m;
                while a > a_max {
                    let (x, y) = at(a);
                    let step = match t.height(x, y) {
                        Some((h, res)) => {
                            best = best.max(h - a * tan_e);
                            res
                        }
                        None => m.max(reach_m / 64.0),
                    };
                    a -= step.max(m);
                }
                for i in (0..n).rev() {
                    let a = a0 + i as f64 * m;
                    let (x, y) = at(a);
                    if let Some((h, _)) = t.height(x, y) {
                        let g = h - a * tan_e;
                        lit[j * n + i] = if g >= best - 1e-3 { 1.0 } else { 0.0 };
                        best = best.max(g);
                    }
                }
            }
            (b, cx, cy, m, a0, b0, n, lit)
        })
        .collect();
    pts.iter()
        .map(|&(x, y)| {
            for (b, cx, cy, m, a0, b0, n, lit) in &lattices {
                if x >= b[0] && y >= b[1] && x <= b[2] && y <= b[3] {
                    let (dx, dy) = (x - cx, y - cy);
                    let fa = ((dx * s.0 + dy * s.1) - a0) / m;
                    let fb = ((dx * p.0 + dy * p.1) - b0) / m;
                    let ia = (fa.max(0.0) as usize).min(n - 2);
                    let ib = (fb.max(0.0) as usize).min(n - 2);
                    let ta = (fa - ia as f64).clamp(0.0, 1.0) as f32;
                    let tb = (fb - ib as f64).clamp(0.0, 1.0) as f32;
                    let i = ib * n + ia;
                    let r0 = lit[i] * (1.0 - ta) + lit[i + 1] * ta;
                    let r1 = lit[i + n] * (1.0 - ta) + lit[i + n + 1] * ta;
                    return r0 * (1.0 - tb) + r1 * tb;
                }
            }
            1.0
        })
        .collect()
}

#[test]
fn shadow_sweep_matches_the_plain_sweep() {
    // The sweep skips lattice nodes no query reads and extension points that cannot raise
    // the horizon; its lit fractions must be those of the plain sweep everywhere.
    use orbfix_host::render::{shadow::ShadowField, terrain::Terrain};
    let world = World::new(4);
    let mut o = RenderOptions::default();
    o.camera.width_px = 160;
    o.camera.height_px = 90;
    o.max_range_m = 120.0;
    o.shadow_reach_m = 80.0;
    let focal = o.camera_params().focal_px() as f64;
    let t = Terrain::around(&world, 1500.0, 700.0, &o, focal);
    let b = t.levels.last().unwrap().bounds;
    // Points over every level: a spiral out to the largest square, corners and edges.
    let mut pts: Vec<(f64, f64)> = (0..4000)
        .map(|i| {
            let r = (b[2] - b[0]) * 0.5 * (i as f64 / 4000.0).sqrt();
            let th = i as f64 * 2.399_963;
            (1500.0 + r * th.cos(), 700.0 + r * th.sin())
        })
        .collect();
    for l in &t.levels {
        let [w, s, e, n] = l.bounds;
        pts.extend([
            (w, s),
            (e, n),
            (w, n),
            (e, s),
            (0.5 * (w + e), n),
            (e, 0.5 * (s + n)),
        ]);
    }
    for (el, az) in [
        (30.0, 135.0),
        (8.0, 0.0),
        (20.0, 90.0),
        (45.0, 180.0),
        (3.0, 271.3),
    ] {
        let sun = Sun::new(el, az).unwrap();
        let f = ShadowField::build(&t, &sun, o.shadow_reach_m);
        let want = plain_shadow_lit(&t, &sun, o.shadow_reach_m, &pts);
        let shadowed = want.iter().filter(|&&v| v < 1.0).count();
        assert!(shadowed > 0, "sun {el}/{az}: some shadow expected");
        for (&(x, y), &w) in pts.iter().zip(&want) {
            assert_eq!(
                f.lit(x, y).to_bits(),
                w.to_bits(),
                "sun {el}/{az} at ({x}, {y})"
            );
        }
    }
}

/// FNV-1a over the bits of what the rasterizer returns (gray levels before quantization and
/// range, metres) for left and right cameras of every view at a few locations of the
/// textured world, under two suns, at 640 x 360.
fn raster_digest() -> u64 {
    use orbfix_host::render::{
        raster::{render_view, NodeAttrs},
        shadow::ShadowField,
        stereo::right_camera,
        terrain::Terrain,
    };
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bits: &[f32]| {
        for v in bits {
            for b in v.to_bits().to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    };
    let world = World::new(3);
    let mut o = RenderOptions::default();
    o.camera.width_px = 640;
    o.camera.height_px = 360;
    let focal = o.camera_params().focal_px() as f64;
    let cache = TileCache::new(1 << 22);
    let suns = [Sun::default(), Sun::new(12.0, 250.0).unwrap()];
    for i in 0..3 {
        let (x, y) = (500.0 + 131.0 * i as f64, 700.0 - 77.0 * i as f64);
        let sun = suns[i % 2];
        let pose = render::ground_pose(&world, x, y, 37.0 * i as f64);
        let t = Terrain::around_cached(&world, x, y, &o, focal, Some(&cache));
        let s = ShadowField::build(&t, &sun, o.shadow_reach_m);
        let a = NodeAttrs::compute(&t, &s);
        let detail = render::near_field_detail(&world, &pose, &t, &sun, &o);
        assert!(detail.is_some(), "the textured world has a near field");
        for cam in render::view_cameras(&pose, &o).unwrap() {
            for c in [cam, right_camera(&cam, 0.3)] {
                let (gray, range) = render_view(&t, &a, detail.as_ref(), &c, &sun, &o);
                eat(&gray);
                eat(&range);
            }
        }
    }
    h
}

#[test]
fn raster_output_is_bit_identical() {
    // Pins the rasterizer's output (gray levels before quantization and range) of left and
    // right views: a speed-up of the rasterizer must leave every bit as it was.
    let digest = raster_digest();
    assert_eq!(digest, RASTER_DIGEST, "digest now {digest:#018x}");
}

const RASTER_DIGEST: u64 = 0x5c8b_761f_10f1_3099;
