//! Geometry, shadows and errors of the renderer, on test surfaces with known features.

use image::GrayImage;
use nalgebra::Vector3;
use orbfix::camera::{Camera, CameraError, RoverPose, View};
use orbfix::geo::GeoRef;
use orbfix_host::render::{
    self, render_ortho, render_views_with_range, Photometry, RenderError, RenderOptions, Sun,
    Surface,
};

/// A plane at height `z` with albedo 0.1 and a bright disc (albedo 1) of radius `r` at `(mx, my)`.
struct Marker {
    z: f64,
    mx: f64,
    my: f64,
    r: f64,
}

impl Surface for Marker {
    fn height_m(&self, _x: f64, _y: f64) -> f64 {
        self.z
    }
    fn albedo(&self, x: f64, y: f64) -> f64 {
        if (x - self.mx).hypot(y - self.my) <= self.r {
            1.0
        } else {
            0.1
        }
    }
}

/// Flat ground at 0 with a 4 m high round mesa of radius 1.5 m at `(cx, cy)`.
struct Mesa {
    cx: f64,
    cy: f64,
}

impl Surface for Mesa {
    fn height_m(&self, x: f64, y: f64) -> f64 {
        let d = (x - self.cx).hypot(y - self.cy);
        // Steep smooth edge between 1.5 and 2 m.
        4.0 * (1.0 - ((d - 1.5) / 0.5).clamp(0.0, 1.0))
    }
    fn albedo(&self, _x: f64, _y: f64) -> f64 {
        0.12
    }
}

fn opts() -> RenderOptions {
    RenderOptions {
        photometry: Photometry::Lambert,
        ..Default::default()
    }
}

/// Centroid `(u, v)` (pixel-centre coordinates) and count of pixels brighter than `thr`.
fn bright_centroid(img: &GrayImage, thr: u8) -> (f64, f64, usize) {
    let (mut su, mut sv, mut n) = (0.0, 0.0, 0usize);
    for (x, y, p) in img.enumerate_pixels() {
        if p[0] > thr {
            su += x as f64 + 0.5;
            sv += y as f64 + 0.5;
            n += 1;
        }
    }
    (su / n.max(1) as f64, sv / n.max(1) as f64, n)
}

#[test]
fn marker_lands_where_the_camera_model_predicts_in_views_and_satellite() {
    let (x, y, heading) = (100.0f64, 200.0f64, 30.0f64);
    let (s, c) = heading.to_radians().sin_cos();
    // 6 m ahead, 1 m to the right.
    let mx = x + 6.0 * s + 1.0 * c;
    let my = y + 6.0 * c - 1.0 * s;
    let surf = Marker {
        z: 5.0,
        mx,
        my,
        r: 0.6,
    };
    let o = opts();
    let sun = Sun::new(90.0, 0.0).unwrap();
    let mut pose = render::ground_pose_on(&surf, x, y, heading);
    assert_eq!(pose.ground_z_m, 5.0);
    pose.pitch_deg = 5.0;
    pose.roll_deg = -4.0;
    // The views shade each pixel from the albedo interpolated between the mesh's nodes, so
    // the disc's edge is where the albedo is halfway between the ground's and the disc's:
    // an exposure that does not saturate the disc, and that gray level as the threshold.
    let ov = RenderOptions { exposure: 0.9, ..o };
    let set = render_views_with_range(&surf, &pose, sun, &ov).unwrap();
    let cam = Camera::new(&o.camera_params(), &pose, View::Front).unwrap();
    let (pu, pv) = cam
        .project(Vector3::new(mx as f32, my as f32, 5.0))
        .unwrap();
    let n_cam = cam.world_to_cam.row(2).transpose();
    let up = [0.0, 0.0, 1.0];
    let view = [-n_cam.x as f64, -n_cam.y as f64, -n_cam.z as f64];
    let mid = ov.gray(ov.radiance(0.55, up, sun.direction(), view, 1.0));
    let (u, v, n) = bright_centroid(&set.views[0], mid.round() as u8);
    assert!(n > 50, "marker too small in the front view: {n} px");
    assert!(
        (u - pu as f64).abs() < 1.0 && (v - pv as f64).abs() < 1.0,
        "front view: marker at ({u:.2}, {v:.2}), camera model says ({pu:.2}, {pv:.2})"
    );
    // Not in the rear view.
    assert_eq!(bright_centroid(&set.views[2], mid.round() as u8).2, 0);
    // Range at the predicted pixel is the distance from the optical centre.
    let w = o.camera.width_px as usize;
    let k = pv as usize * w + pu as usize;
    let want = (Vector3::new(mx as f32, my as f32, 5.0) - cam.centre).norm();
    let got = set.range_m[0][k];
    assert!(
        (got - want).abs() < 0.02 * want,
        "range {got} m, expected {want} m"
    );
    // The sky (top row of a 15 deg down tilted view on a plane) is black with range 0.
    assert_eq!(set.views[0].get_pixel(320, 0)[0], 0);
    assert_eq!(set.range_m[0][320], 0.0);

    // Satellite crop centred on the rover: marker at the georeference's pixel.
    let (sat, geo) = render::render_satellite_crop(&surf, x, y, 200, 0.25, sun, &o).unwrap();
    let (pc, pr) = geo.to_pixel(mx as f32, my as f32);
    let (sc, sr, sn) = bright_centroid(&sat, 240);
    assert!(
        sn > 10,
        "satellite marker too small: {sn} px, max {:?}, at pred {:?}",
        sat.pixels().map(|p| p[0]).max(),
        sat.get_pixel(pc as u32, pr as u32)
    );
    assert!(
        (sc - pc as f64).abs() < 0.3 && (sr - pr as f64).abs() < 0.3,
        "satellite: marker at ({sc:.2}, {sr:.2}), georeference says ({pc:.2}, {pr:.2})"
    );
    // Box-filtered (2 x 2 samples per pixel): same place, to a tenth of a pixel.
    let o2 = RenderOptions {
        ortho_supersample: 2,
        ..o
    };
    let (sat2, _) = render::render_satellite_crop(&surf, x, y, 200, 0.25, sun, &o2).unwrap();
    let (sc2, sr2, _) = bright_centroid(&sat2, 200);
    assert!(
        (sc2 - pc as f64).abs() < 0.3 && (sr2 - pr as f64).abs() < 0.3,
        "supersampled satellite: marker at ({sc2:.2}, {sr2:.2}), georeference says ({pc:.2}, {pr:.2})"
    );
}

#[test]
fn point_cloud_lies_on_the_plane() {
    let surf = Marker {
        z: 2.0,
        mx: 1e6,
        my: 0.0,
        r: 0.1,
    };
    let o = RenderOptions {
        camera: orbfix::camera::CameraParams {
            width_px: 160,
            height_px: 90,
            ..Default::default()
        }
        .into(),
        ..opts()
    };
    let pose = render::ground_pose_on(&surf, 10.0, 10.0, 0.0);
    let set = render_views_with_range(&surf, &pose, Sun::default(), &o).unwrap();
    let pts = render::ply::points_from_range(&set.cameras[1], &set.range_m[1], &set.views[1], 3);
    assert!(pts.len() > 500);
    // Near points (within 30 m) lie on z = 2 to within centimetres.
    let near: Vec<_> = pts
        .iter()
        .filter(|p| (p.x - 10.0).hypot(p.y - 10.0) < 30.0)
        .collect();
    assert!(near.len() > 100);
    for p in near {
        assert!((p.z - 2.0).abs() < 0.05, "point {p:?} off the plane");
    }
    let bytes = render::ply::ply_bytes(&pts);
    assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
}

fn ortho_at(img: &GrayImage, geo: &GeoRef, x: f64, y: f64) -> u8 {
    let (c, r) = geo.to_pixel(x as f32, y as f32);
    img.get_pixel(c as u32, r as u32)[0]
}

#[test]
fn shadows_fall_away_from_the_sun_in_orbit_and_ground_views() {
    let mesa = Mesa { cx: 50.0, cy: 50.0 };
    let o = opts();
    let geo = GeoRef::centred(50.0, 50.0, 300, 300, 0.1).unwrap();
    for az in [90.0, 0.0, 225.0] {
        let sun = Sun::new(30.0, az).unwrap();
        let img = render_ortho(&mesa, &geo, 300, 300, sun, &o).unwrap();
        let (s, c) = f64::to_radians(az).sin_cos();
        // 4 m tall, sun 30 deg up: shadow about 6.9 m long behind the mesa's edge at 2 m.
        let behind = ortho_at(&img, &geo, 50.0 - 4.5 * s, 50.0 - 4.5 * c);
        let front = ortho_at(&img, &geo, 50.0 + 4.5 * s, 50.0 + 4.5 * c);
        let beyond = ortho_at(&img, &geo, 50.0 - 10.0 * s, 50.0 - 10.0 * c);
        assert!(
            (behind as i32) < front as i32 - 40,
            "sun az {az}: behind {behind} should be much darker than in front {front}"
        );
        assert!(
            (beyond as i32 - front as i32).abs() <= 2,
            "sun az {az}: beyond the shadow {beyond} vs {front}"
        );
    }
    // Ground view: a rover south of the mesa looking north sees the shadow (sun from the
    // east) on the mesa's west side, left of the mesa in the image.
    let sun = Sun::new(30.0, 90.0).unwrap();
    let pose = render::ground_pose_on(&mesa, 50.0, 35.0, 0.0);
    let set = render_views_with_range(&mesa, &pose, sun, &o).unwrap();
    let cam = set.cameras[0];
    let px = |x: f64, y: f64| {
        let (u, v) = cam.project(Vector3::new(x as f32, y as f32, 0.0)).unwrap();
        set.views[0].get_pixel(u as u32, v as u32)[0]
    };
    let west = px(45.5, 49.0);
    let east = px(54.5, 49.0);
    assert!(
        (west as i32) < east as i32 - 40,
        "ground view: west {west} vs east {east}"
    );
}

#[test]
fn bad_options_give_clear_errors() {
    for (e, a) in [
        (f64::NAN, 0.0),
        (91.0, 0.0),
        (-1.0, 0.0),
        (30.0, 360.0),
        (30.0, f64::NAN),
        (30.0, -10.0),
    ] {
        let err = Sun::new(e, a).unwrap_err();
        assert!(matches!(err, RenderError::Sun(_)), "{e} {a}: {err}");
        assert!(err.to_string().contains("deg"));
    }
    let surf = Marker {
        z: 0.0,
        mx: 0.0,
        my: 0.0,
        r: 1.0,
    };
    let pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
    let mut o = opts();
    o.camera.hfov_deg = 180.0;
    let err = render::render_views(&surf, &pose, Sun::default(), &o).unwrap_err();
    assert_eq!(err, RenderError::Camera(CameraError::FovOutOfRange));
    assert!(
        err.to_string().contains("horizontal field of view"),
        "{err}"
    );
    let mut o = opts();
    o.camera.width_px = 0;
    assert!(render::render_views(&surf, &pose, Sun::default(), &o).is_err());
    let mut bad_pose = pose;
    bad_pose.heading_deg = f32::NAN;
    assert!(render::render_views(&surf, &bad_pose, Sun::default(), &opts()).is_err());
    let geo = GeoRef::new(0.0, 0.0, 0.25).unwrap();
    assert!(render_ortho(&surf, &geo, 0, 10, Sun::default(), &opts()).is_err());
    let mut o = opts();
    o.noise_sigma = f64::NAN;
    assert!(matches!(o.validate(), Err(RenderError::Option(_))));
}

#[test]
fn noise_is_seeded_and_deterministic() {
    let surf = Marker {
        z: 0.0,
        mx: 0.0,
        my: 5.0,
        r: 0.3,
    };
    let geo = GeoRef::centred(0.0, 0.0, 64, 64, 0.25).unwrap();
    let mut o = opts();
    let clean = render_ortho(&surf, &geo, 64, 64, Sun::default(), &o).unwrap();
    o.noise_sigma = 4.0;
    o.noise_seed = 7;
    let a = render_ortho(&surf, &geo, 64, 64, Sun::default(), &o).unwrap();
    let b = render_ortho(&surf, &geo, 64, 64, Sun::default(), &o).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, clean);
    o.noise_seed = 8;
    assert_ne!(
        render_ortho(&surf, &geo, 64, 64, Sun::default(), &o).unwrap(),
        a
    );
}

#[test]
fn gray_table_matches_the_exact_mapping() {
    let o = RenderOptions::default();
    let g = render::GrayMap::new(o.gamma);
    let mut worst = 0.0f64;
    for k in 0..=20000 {
        let r = k as f64 / 16000.0 - 0.1; // includes < 0 and > 1
        worst = worst.max((g.gray(r) as f64 - o.gray(r)).abs());
    }
    assert!(worst < 0.05, "table off by {worst} gray levels");
}
