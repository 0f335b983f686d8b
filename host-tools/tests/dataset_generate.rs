//! The dataset writer: determinism, shards, resume, reading back, bad options.

use orbfix_host::dataset::{self, combine_shards, Dataset, GenerateConfig, Preset, Shard};
use orbfix_host::world::zones::{self, Split};
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// Every file under `dir` (relative path -> bytes), skipping shard manifests.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(base: &Path, d: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(base, &p, out);
            } else {
                let rel = p.strip_prefix(base).unwrap().to_string_lossy().to_string();
                if !rel.starts_with("manifest-") {
                    out.insert(rel, std::fs::read(&p).unwrap());
                }
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// FNV-1a over names and contents: the dataset's fingerprint.
fn fingerprint(f: &BTreeMap<String, Vec<u8>>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for (k, v) in f {
        for b in k.as_bytes().iter().chain(v) {
            h ^= *b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// Asserts equal file sets, naming the differing files (not dumping bytes).
fn assert_same(a: &BTreeMap<String, Vec<u8>>, b: &BTreeMap<String, Vec<u8>>) {
    let ka: Vec<_> = a.keys().collect();
    let kb: Vec<_> = b.keys().collect();
    assert_eq!(ka, kb, "file lists differ");
    let diff: Vec<_> = a
        .iter()
        .filter(|(k, v)| b[*k] != **v)
        .map(|(k, _)| k.clone())
        .collect();
    assert!(diff.is_empty(), "files differ: {diff:?}");
}

fn smoke() -> GenerateConfig {
    let mut c = GenerateConfig::preset(Preset::Smoke, 11);
    c.range = true;
    c.point_cloud = true;
    c.sun_view_elevation = dataset::DegRange::parse("20..40").unwrap();
    c.sun_map_azimuth = dataset::DegRange::parse("90..180").unwrap();
    c
}

#[test]
fn deterministic_sharded_resumable() {
    let cfg = smoke();
    let t = tempfile::tempdir().unwrap();
    let (a, b, c) = (t.path().join("a"), t.path().join("b"), t.path().join("c"));
    let ra = dataset::generate(&cfg, &a, None, false).unwrap();
    assert_eq!((ra.rendered, ra.skipped), (6, 0));
    dataset::generate(&cfg, &b, None, false).unwrap();
    let fa = files(&a);
    // 6 locations x (4 views + 4 ranges + satellite + cloud) + manifest + dataset.json.
    assert_eq!(fa.len(), 6 * 10 + 2, "{:?}", fa.keys().collect::<Vec<_>>());
    assert_eq!(
        fingerprint(&fa),
        fingerprint(&files(&b)),
        "same seed and options must give identical bytes"
    );

    // Shards 0/3, 1/3, 2/3, then combine: the same files as one run.
    for i in 0..3 {
        let r = dataset::generate(&cfg, &c, Some(Shard { index: i, count: 3 }), false).unwrap();
        assert_eq!(r.rendered, 2);
    }
    assert!(
        Dataset::open(&c).is_err(),
        "no manifest.jsonl before combining"
    );
    assert_eq!(combine_shards(&c).unwrap(), 6);
    assert_same(&files(&c), &fa);

    // Resume: delete one view, truncate a satellite crop, leave a stale temp file.
    let ds = Dataset::open(&b).unwrap();
    std::fs::remove_file(b.join(&ds.rows[1].views[2])).unwrap();
    let sat = b.join(&ds.rows[4].satellite);
    let bytes = std::fs::read(&sat).unwrap();
    std::fs::write(&sat, &bytes[..bytes.len() / 2]).unwrap();
    let err = ds.load_satellite(&ds.rows[4]).unwrap_err();
    assert!(format!("{err:#}").contains("not a valid PNG"), "{err:#}");
    let r = dataset::generate(&cfg, &b, None, false).unwrap();
    assert_eq!((r.rendered, r.skipped), (2, 4));
    assert_eq!(fingerprint(&files(&b)), fingerprint(&fa));

    // Other options into the same folder: refused, nothing touched.
    let mut other = cfg.clone();
    other.seed = 12;
    let err = dataset::generate(&other, &b, None, false).unwrap_err();
    assert!(format!("{err:#}").contains("other options"), "{err:#}");
    assert_eq!(fingerprint(&files(&b)), fingerprint(&fa));
}

#[test]
fn manifest_rows_match_zones_and_read_back() {
    let cfg = GenerateConfig::preset(Preset::Smoke, 3);
    let t = tempfile::tempdir().unwrap();
    dataset::generate(&cfg, t.path(), None, false).unwrap();
    let ds = Dataset::open(t.path()).unwrap();
    assert_eq!(ds.rows.len(), 6);
    assert_eq!(ds.split(Split::Train).count(), 4);
    assert_eq!(ds.split(Split::Validation).count(), 1);
    assert_eq!(ds.split(Split::Test).count(), 1);
    let ids: Vec<_> = ds.rows.iter().map(|r| r.id.clone()).collect();
    let mut sorted = ids.clone();
    sorted.sort();
    assert_eq!(ids, sorted);
    for r in &ds.rows {
        let z = zones::zone(r.split).location_area();
        assert!(r.x_m > z.x_min_m && r.x_m < z.x_max_m && r.y_m > z.y_min_m && r.y_m < z.y_max_m);
        let v = ds.load_views(r).unwrap();
        assert_eq!(v[0].dimensions(), (160, 90));
        // Lunar ground: not black, not saturated, sky black at the top.
        let mean = v[0].pixels().map(|p| p[0] as f64).sum::<f64>() / (160.0 * 90.0);
        assert!(mean > 20.0 && mean < 230.0, "mean {mean}");
        assert_eq!(ds.load_satellite(r).unwrap().dimensions(), (100, 100));
        assert!(r.range.is_none());
    }
    // Rows are a pure function of (config, index).
    let world = cfg.world().unwrap();
    assert_eq!(cfg.location(&world, 5).unwrap(), ds.rows[5]);
    let text = std::fs::read_to_string(t.path().join("manifest.jsonl")).unwrap();
    for key in [
        "\"id\"",
        "\"split\"",
        "\"x_m\"",
        "\"y_m\"",
        "\"yaw_deg\"",
        "\"sun_view\"",
        "\"sun_map\"",
        "\"elevation_deg\"",
        "\"azimuth_deg\"",
        "\"views\"",
        "\"satellite\"",
    ] {
        assert!(
            text.lines().all(|l| l.contains(key)),
            "manifest lacks {key}"
        );
    }
}

#[test]
fn attitude_is_drawn_within_bounds_and_level_rows_are_unchanged() {
    let level = GenerateConfig::preset(Preset::Smoke, 9);
    let mut tilted = level.clone();
    tilted.max_attitude_deg = 5.0;
    let w = level.world().unwrap();
    let mut any = false;
    for i in 0..6 {
        let a = level.location(&w, i).unwrap();
        let b = tilted.location(&w, i).unwrap();
        assert_eq!((a.pitch_deg, a.roll_deg), (0.0, 0.0));
        assert!(b.pitch_deg.abs() <= 5.0 && b.roll_deg.abs() <= 5.0);
        any |= b.pitch_deg != 0.0;
        // The pose the dataset's views are reprojected with carries that attitude.
        let p = b.pose();
        assert_eq!(
            (p.pitch_deg, p.roll_deg, p.heading_deg),
            (b.pitch_deg as f32, b.roll_deg as f32, b.yaw_deg as f32)
        );
        assert_eq!((p.x_m, p.y_m), (b.x_m as f32, b.y_m as f32));
        // Everything else is the same draw.
        assert_eq!(
            (a.x_m, a.y_m, a.yaw_deg, a.sun_view),
            (b.x_m, b.y_m, b.yaw_deg, b.sun_view)
        );
    }
    assert!(any);
    tilted.max_attitude_deg = 45.0;
    assert!(tilted.validate().is_err());
}

#[test]
fn flat_world_has_zero_relief_same_albedo() {
    let mut cfg = GenerateConfig::preset(Preset::Smoke, 3);
    cfg.flat = true;
    let w = cfg.world().unwrap();
    let relief = orbfix_host::world::World::new(3);
    for r in 0..6 {
        let row = cfg.location(&w, r).unwrap();
        assert_eq!(row.ground_z_m, 0.0);
        assert_eq!(w.albedo(row.x_m, row.y_m), relief.albedo(row.x_m, row.y_m));
    }
}

fn orbfix(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_orbfix"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn bad_generate_options_give_clear_errors() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("d");
    let o = out.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["--preset", "huge"], "invalid value 'huge'"),
        (&["--shard", "3/2"], "0-based"),
        (&["--shard", "1/0"], "at least 1"),
        (&["--size", "0x360"], "at least 2x2"),
        (&["--size", "-640x360"], "not a positive whole number"),
        (&["--sun-elevation", "NaN"], "finite"),
        (&["--sun-elevation", "95"], "out of range"),
        (&["--sun-azimuth", "10..400"], "out of range"),
        (&["--sun-elevation", "40..20"], "empty"),
    ];
    for (args, want) in cases {
        let mut a = vec!["generate", "--out", o, "--quiet"];
        a.extend_from_slice(args);
        let (ok, err) = orbfix(&a);
        assert!(!ok, "{args:?} should fail");
        assert!(
            err.contains(want),
            "{args:?}: error should mention '{want}', got: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(
        !out.exists(),
        "a refused run must not create the output folder"
    );
    // Output under a regular file: cannot be created.
    let file = t.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    let bad = file.join("d");
    let (ok, err) = orbfix(&["generate", "--out", bad.to_str().unwrap(), "--quiet"]);
    assert!(!ok && err.contains("cannot create output folder"), "{err}");
    // Bad FOV through the render command.
    let (ok, err) = orbfix(&["render", "location", "--out", o, "--hfov", "180"]);
    assert!(!ok && err.contains("horizontal field of view"), "{err}");
}

#[test]
fn stereo_pairs_are_written_beside_the_views() {
    let mono = GenerateConfig::preset(Preset::Smoke, 5);
    let mut st = mono.clone();
    st.stereo = Some(orbfix_host::render::stereo::StereoRender {
        baseline_m: 0.3,
        right_gain: 1.02,
    });
    let t = tempfile::tempdir().unwrap();
    let (a, b, c) = (t.path().join("m"), t.path().join("s"), t.path().join("s2"));
    dataset::generate(&mono, &a, None, false).unwrap();
    dataset::generate(&st, &b, None, false).unwrap();
    dataset::generate(&st, &c, None, false).unwrap();
    assert_eq!(
        fingerprint(&files(&b)),
        fingerprint(&files(&c)),
        "deterministic"
    );
    let (dm, ds) = (Dataset::open(&a).unwrap(), Dataset::open(&b).unwrap());
    assert!(dm.rows[0].right.is_none());
    assert!(dm.load_right(&dm.rows[0]).is_err());
    for (rm, rs) in dm.rows.iter().zip(&ds.rows) {
        let paths = rs.right.as_ref().unwrap();
        assert!(paths[1].ends_with(&format!("{}_right_right.png", rs.id)));
        // The left images are the mono views; the right ones differ from them.
        let (lm, ls) = (dm.load_views(rm).unwrap(), ds.load_views(rs).unwrap());
        assert!(lm == ls);
        let r = ds.load_right(rs).unwrap();
        assert!(r
            .iter()
            .zip(&ls)
            .all(|(r, l)| r != l && r.dimensions() == l.dimensions()));
    }
}
