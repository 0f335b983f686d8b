//! The near-field micro-relief (world::micro) and its texture in the ground views
//! (render::detail): a pure function of (seed, x, y), anchored to the world, shadowed away
//! from the sun, and what makes the first metres of a view textured.

use orbfix_host::render::{
    self, detail::DetailTexture, terrain::Terrain, RenderOptions, Sun, Surface,
};
use orbfix_host::world::World;

fn soil_at(w: &World, x: f64, y: f64) -> (f64, f64) {
    w.micro()
        .expect("procedural worlds have micro-relief")
        .soil(x, y, 0.01)
}

#[test]
fn soil_rows_are_the_point_values_bit_for_bit() {
    // The texture builds its soil a row at a time (vectorized); every sample must be the
    // point function's, for each level of detail (all octaves, the texture's, coarse only).
    let w = World::new(5);
    let m = w.micro().unwrap();
    let xs: Vec<f64> = (0..203).map(|c| 2000.0 + 0.031 * c as f64 + 1e-4).collect();
    let (mut h, mut g, mut tmp) = (vec![0.0; xs.len()], vec![0.0; xs.len()], Vec::new());
    for min_wl in [0.01, 0.078, 0.2] {
        for k in 0..5 {
            let y = 1500.0 - 0.3 * k as f64;
            m.soil_row(&xs, y, min_wl, &mut h, &mut g, &mut tmp);
            for (i, &x) in xs.iter().enumerate() {
                let (ph, pg) = m.soil(x, y, min_wl);
                assert_eq!(h[i].to_bits(), ph.to_bits(), "height at x {x} y {y}");
                assert_eq!(g[i].to_bits(), pg.to_bits(), "grain at x {x} y {y}");
            }
        }
    }
    assert!(
        h.iter().any(|&v| v != 0.0),
        "min_wl 0.2 leaves the coarsest octave"
    );
}

#[test]
fn micro_relief_is_a_pure_function_of_seed_and_position() {
    let a = World::new(3);
    let b = World::new(3);
    let c = World::new(4);
    let mut differs = 0;
    for k in 0..200 {
        let (x, y) = (1000.0 + 0.37 * k as f64, 1500.0 - 0.29 * k as f64);
        assert_eq!(soil_at(&a, x, y), soil_at(&b, x, y));
        if soil_at(&a, x, y) != soil_at(&c, x, y) {
            differs += 1;
        }
    }
    assert!(
        differs > 190,
        "seeds 3 and 4 agree at {} of 200 points",
        200 - differs
    );
    // Rocks and pits: the same list whichever rectangle asks, in the same order.
    let m = a.micro().unwrap();
    let mut big = Vec::new();
    m.visit_rocks([10.0, 10.0, 14.0, 14.0], 0.0, |r| big.push(*r));
    let mut small = Vec::new();
    m.visit_rocks([11.0, 11.0, 12.0, 12.0], 0.0, |r| small.push(*r));
    assert!(!small.is_empty() && big.len() > small.len());
    for r in &small {
        assert!(
            big.contains(r),
            "rock {r:?} of the small rectangle missing from the large one"
        );
    }
    // Sizes within their stated bounds, heights positive, outline inside the radius.
    for r in &big {
        assert!(r.radius_m > 0.0 && r.radius_m <= m.max_rock_radius_m());
        assert!(r.height_m > 0.0 && r.height_m <= m.max_height_m());
        let out = r.radius_m * 1.0001;
        for a in 0..16 {
            let t = a as f64 * std::f64::consts::TAU / 16.0;
            assert_eq!(
                r.height_at(r.x_m + out * t.sin(), r.y_m + out * t.cos()),
                0.0
            );
        }
        assert!(r.height_at(r.x_m, r.y_m) > 0.0);
    }
    let mut pits = 0;
    m.visit_pits([10.0, 10.0, 14.0, 14.0], |p| {
        pits += 1;
        assert!(
            p.height_at(p.x_m, p.y_m) < 0.0,
            "a pit's floor lies below the ground"
        );
        assert_eq!(p.height_at(p.x_m + p.reach_m() * 1.0001, p.y_m), 0.0);
    });
    assert!(pits > 50, "only {pits} pits in 16 m^2");
    // No micro-relief on a world without relief.
    assert!(World::flat(3).micro().is_none());
}

fn texture(w: &World, cx: f64, cy: f64, sun: Sun) -> (DetailTexture, Terrain) {
    let opts = RenderOptions::default();
    let t = Terrain::around(w, cx, cy, &opts, 320.0);
    let d = DetailTexture::build(w, w.micro().unwrap(), &t, cx, cy, 4.0, 0.03, &sun, 300.0);
    (d, t)
}

#[test]
fn the_texture_is_anchored_to_the_world_and_shadowed_away_from_the_sun() {
    let w = World::new(5);
    let sun = Sun::new(20.0, 90.0).unwrap();
    // Two rover positions 1.3 m apart: the texels they share are the same ground.
    let (a, _) = texture(&w, 2000.0, 2000.0, sun);
    let (b, _) = texture(&w, 2001.3, 1999.4, sun);
    let (mut same, mut lit_same, mut n) = (0, 0, 0);
    for k in 0..400 {
        let (x, y) = (2000.2 + 0.0065 * k as f64, 1999.0 + 0.007 * k as f64);
        let (sa, sb) = (
            a.sample(x, y, 0.001).unwrap(),
            b.sample(x, y, 0.001).unwrap(),
        );
        n += 1;
        if (sa.texel.gx - sb.texel.gx).abs() < 1e-4
            && (sa.texel.gy - sb.texel.gy).abs() < 1e-4
            && (sa.texel.albedo_mul - sb.texel.albedo_mul).abs() < 1e-4
        {
            same += 1;
        }
        if (sa.texel.lit - sb.texel.lit).abs() < 0.5 {
            lit_same += 1;
        }
    }
    assert_eq!(same, n, "slopes and albedo of shared texels differ");
    assert!(
        lit_same * 100 >= n * 97,
        "cast shadows agree at {lit_same} of {n} points"
    );

    // A lower sun casts more shadow on the same ground; a sun in the east shadows the west
    // flanks of the pits' rims, so the lit texels lean towards the sun.
    let lit_share = |elev: f64| {
        let (d, _) = texture(&w, 2000.0, 2000.0, Sun::new(elev, 90.0).unwrap());
        let mut lit = 0.0;
        let mut m = 0.0;
        for i in 0..120 {
            for j in 0..120 {
                let (x, y) = (1998.2 + 0.03 * i as f64, 1998.2 + 0.03 * j as f64);
                lit += d.sample(x, y, 0.001).unwrap().texel.lit as f64;
                m += 1.0;
            }
        }
        lit / m
    };
    let (low, high) = (lit_share(8.0), lit_share(60.0));
    assert!(
        low < high - 0.02 && high > 0.97,
        "lit share {low:.3} at 8 deg, {high:.3} at 60 deg"
    );
    // Slopes towards the sun are lit, slopes away from it in shadow more often.
    let (d, _) = texture(&w, 2000.0, 2000.0, Sun::new(8.0, 90.0).unwrap());
    let (mut toward, mut away) = ((0.0, 0.0), (0.0, 0.0));
    for i in 0..200 {
        for j in 0..200 {
            let (x, y) = (1997.0 + 0.03 * i as f64, 1997.0 + 0.03 * j as f64);
            let t = d.sample(x, y, 0.001).unwrap().texel;
            // Ground rising to the east (gx > 0) faces west, away from an eastern sun.
            if t.gx > 0.2 {
                away = (away.0 + t.lit as f64, away.1 + 1.0);
            } else if t.gx < -0.2 {
                toward = (toward.0 + t.lit as f64, toward.1 + 1.0);
            }
        }
    }
    let (lt, la) = (toward.0 / toward.1, away.0 / away.1);
    assert!(
        lt > la + 0.1,
        "lit share facing the sun {lt:.3}, facing away {la:.3}"
    );
}

/// Mean absolute difference between horizontal neighbours over the bottom `rows` rows.
fn near_texture(img: &image::GrayImage, rows: u32) -> f64 {
    let (w, h) = img.dimensions();
    let (mut s, mut n) = (0.0, 0.0);
    for y in h - rows..h {
        for x in 1..w {
            s += (img.get_pixel(x, y)[0] as f64 - img.get_pixel(x - 1, y)[0] as f64).abs();
            n += 1.0;
        }
    }
    s / n
}

#[test]
fn the_near_field_is_textured_and_the_geometry_is_unchanged() {
    let w = World::new(2);
    let pose = render::ground_pose(&w, 2900.0, 2000.0, 40.0);
    let sun = Sun::new(25.0, 200.0).unwrap();
    let with = RenderOptions::default();
    let without = RenderOptions {
        detail_range_m: 0.0,
        ..with
    };
    let a = render::render_views_with_range(&w, &pose, sun, &with).unwrap();
    let b = render::render_views_with_range(&w, &pose, sun, &without).unwrap();
    for k in 0..4 {
        // The micro-relief is drawn as texture: the range images do not move.
        assert_eq!(a.range_m[k], b.range_m[k], "view {k}: range changed");
        let (ta, tb) = (
            near_texture(&a.views[k], 120),
            near_texture(&b.views[k], 120),
        );
        assert!(
            ta > 1.5 * tb && ta > 1.0,
            "view {k}: neighbour difference {ta:.2} with the micro-relief, {tb:.2} without"
        );
    }
    // Deterministic.
    let again = render::render_views_with_range(&w, &pose, sun, &with).unwrap();
    assert_eq!(a.views, again.views);
    // A bad option is refused with its name.
    let bad = RenderOptions {
        detail_cell_m: 0.0001,
        ..with
    };
    let e = render::render_views(&w, &pose, sun, &bad).unwrap_err();
    assert!(e.to_string().contains("detail_cell_m"), "{e}");
    let _ = w.micro().map(|_| Surface::micro(&w));
}
