//! The hostile command-line cases of issue 12 that are cheap to run, against the `orbfix`
//! binary: each gives a clear error (exit status 1, or 2 for a refused argument), names
//! what was wrong, prints no Rust type name and never panics; output goes only to regular
//! files. The full list with what each prints: docs/reliability.md
//! (`bash scripts/cli-cases.sh`).

use std::path::Path;
use std::process::{Command, Output, Stdio};

fn orbfix(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_orbfix"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run orbfix")
}

/// A Rust type or variant name in a message: a capitalized word with a second capital
/// inside (`BadOrigin`, `CrcMismatch`, `FrameTooSmall`), or `Some(` / `Err(`.
fn type_name(text: &str) -> Option<String> {
    for w in text.split(|c: char| !c.is_ascii_alphanumeric()) {
        let mut ch = w.chars();
        if w != "NaN"
            && ch.next().is_some_and(|c| c.is_ascii_uppercase())
            && w.chars().any(|c| c.is_ascii_lowercase())
            && ch.any(|c| c.is_ascii_uppercase())
        {
            return Some(w.to_owned());
        }
    }
    ["Some(", "Err(", "Ok("]
        .into_iter()
        .find(|p| text.contains(p))
        .map(str::to_owned)
}

/// Runs a case that must fail with a message containing every one of `needles`.
fn refused(dir: &Path, args: &[&str], code: i32, needles: &[&str]) -> String {
    let out = orbfix(dir, args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "orbfix {args:?}: {err}");
    assert!(!err.contains("panicked"), "orbfix {args:?} panicked: {err}");
    for n in needles {
        assert!(err.contains(n), "orbfix {args:?}: '{n}' not in: {err}");
    }
    assert_eq!(type_name(&err), None, "orbfix {args:?} names a type: {err}");
    err
}

fn map(dir: &Path, size_m: &str, out: &str) {
    let o = orbfix(
        dir,
        &[
            "map", "--x", "3000", "--y", "2000", "--size-m", size_m, "--out", out,
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn the_type_name_check_can_fail() {
    assert_eq!(type_name("error: BadOrigin").as_deref(), Some("BadOrigin"));
    assert_eq!(
        type_name("failed: weights(CrcMismatch { stored: 1 })").as_deref(),
        Some("CrcMismatch")
    );
    assert_eq!(type_name("reproject: Some(3)").as_deref(), Some("Some("));
    assert_eq!(type_name("elevation NaN deg"), None);
    assert_eq!(
        type_name("the weight file is corrupt: its CRC-32 is 0x1"),
        None
    );
}

#[test]
fn output_only_to_regular_files() {
    let d = tempfile::tempdir().unwrap();
    std::fs::create_dir(d.path().join("adir")).unwrap();
    let args = [
        "map", "--x", "3000", "--y", "2000", "--size-m", "50", "--out",
    ];
    refused(
        d.path(),
        &[&args[..], &["adir"]].concat(),
        1,
        &["adir", "not a regular file", "folder"],
    );
    // A device node (a private copy of /dev/full, so that a regression replaces only it).
    let dev = d.path().join("full");
    let made = Command::new("mknod")
        .arg(&dev)
        .args(["c", "1", "7"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if made {
        refused(
            d.path(),
            &[&args[..], &["full"]].concat(),
            1,
            &["not a regular file", "device"],
        );
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::metadata(&dev)
            .unwrap()
            .file_type()
            .is_char_device());
        assert!(!d.path().join("full.json").exists());
    } else {
        eprintln!(
            "mknod not permitted here: the device case is checked by scripts/cli-cases.sh as root"
        );
    }
}

#[test]
fn a_closed_stdout_ends_quietly() {
    let d = tempfile::tempdir().unwrap();
    // 71 KB of model to standard output, the reader gone after 10 bytes.
    let mut child = Command::new(env!("CARGO_BIN_EXE_orbfix"))
        .args(["export-tflite", "--out", "-"])
        .current_dir(d.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 10];
    std::io::Read::read_exact(child.stdout.as_mut().unwrap(), &mut first).unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !err.contains("panicked") && !err.contains("Broken pipe"),
        "{err}"
    );
    assert_ne!(out.status.code(), Some(101), "{err}");
}

#[test]
fn numbers_are_checked_when_given() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    refused(
        p,
        &["render", "location", "--noise", "-5", "--out", "rl"],
        2,
        &["--noise", "at least 0", "-5"],
    );
    refused(
        p,
        &["bench", "stereo", "--noise", "-5"],
        2,
        &["--noise", "at least 0"],
    );
    refused(
        p,
        &["render", "location", "--heading", "nan", "--out", "rl"],
        1,
        &["heading", "finite"],
    );
    refused(
        p,
        &["render", "location", "--hfov", "nan", "--out", "rl"],
        1,
        &["field of view"],
    );
    refused(
        p,
        &[
            "map",
            "--x",
            "0",
            "--y",
            "0",
            "--sun-elevation",
            "nan",
            "--out",
            "m.png",
        ],
        1,
        &["elevation"],
    );
    refused(
        p,
        &[
            "generate", "--preset", "smoke", "--size", "1x1", "--out", "ds",
        ],
        1,
        &["1x1", "at least"],
    );
    assert!(!p.join("ds").join("manifest.json").exists());
    // A negative coordinate is a coordinate.
    map(p, "50", "m.png");
    let o = orbfix(
        p,
        &[
            "map", "--x", "-3000", "--y", "-2000", "--size-m", "50", "--out", "n.png",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_bad_map_georeference_is_named() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    map(p, "120", "map.png");
    map(p, "50", "top.png");
    let meta = std::fs::read_to_string(p.join("map.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&meta).unwrap();
    let localize = |meta: &str| {
        vec![
            "localize",
            "--map",
            "map.png",
            "--map-meta",
            meta,
            "--top",
            "top.png",
            "--out",
            "loc",
        ]
        .into_iter()
        .map(str::to_owned)
        .collect::<Vec<_>>()
    };
    let run = |name: &str, v: &serde_json::Value, needles: &[&str]| {
        std::fs::write(p.join(name), v.to_string()).unwrap();
        let a = localize(name);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        refused(p, &a, 1, needles);
    };
    let good = v.clone();
    v["m_per_px"] = (-0.25).into();
    run("res.json", &v, &["res.json", "resolution"]);
    v = good.clone();
    v["origin_x_m"] = 1e38.into();
    run("far.json", &v, &["far.json", "origin", "10000000 m"]);
    std::fs::write(p.join("cut.json"), &meta[..meta.len() / 2]).unwrap();
    refused(
        p,
        &localize("cut.json")
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
        1,
        &["cut.json", "not a map georeference"],
    );
    refused(
        p,
        &[
            "localize",
            "--map",
            "map.png",
            "--map-meta",
            "map.json",
            "--top",
            "top.png",
            "--out",
            "loc",
            "--matcher",
            "fix",
        ],
        1,
        &["baseline"],
    );
}

#[test]
fn a_damaged_weight_file_is_refused_by_every_subcommand_that_runs_the_network() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let good = orbfix::nn::model::SHIPPED_WEIGHTS;
    let mut bad = good.to_vec();
    bad[5000] ^= 0x10;
    std::fs::write(p.join("bad.ofw"), &bad).unwrap();
    std::fs::write(p.join("cut.ofw"), &good[..1000]).unwrap();
    let cases: [&[&str]; 6] = [
        &["demo", "--stops", "1"],
        &["eval", "--seed", "2", "--queries", "1", "--json", "e.json"],
        &["embed", "--input", "x.npy", "--out", "y.npy"],
        &["export-tflite", "--out", "m.tflite"],
        &["budget", "--json", "b.json"],
        &["quantize", "--rederive-multipliers", "--out", "q.ofw"],
    ];
    for c in cases {
        refused(
            p,
            &[c, &["--weights", "bad.ofw"]].concat(),
            1,
            &["bad.ofw", "corrupt", "CRC-32"],
        );
        refused(
            p,
            &[c, &["--weights", "cut.ofw"]].concat(),
            1,
            &["cut.ofw", "truncated", "1000 bytes"],
        );
    }
    refused(
        p,
        &["demo", "--weights", "none.ofw"],
        1,
        &["cannot read the weight file none.ofw"],
    );
    for f in ["e.json", "y.npy", "m.tflite", "b.json", "q.ofw"] {
        assert!(
            !p.join(f).exists(),
            "{f} written from a damaged weight file"
        );
    }
}

#[test]
fn eval_refuses_a_tilt_limit_without_the_terrain_attitude_or_out_of_range() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let base = ["eval", "--seed", "2", "--queries", "1", "--json", "e.json"];
    refused(
        p,
        &[&base[..], &["--max-tilt", "20"]].concat(),
        1,
        &["--max-tilt", "--rover-attitude terrain"],
    );
    for bad in ["0", "95", "NaN"] {
        refused(
            p,
            &[
                &base[..],
                &["--rover-attitude", "terrain", "--max-tilt", bad],
            ]
            .concat(),
            1,
            &["--max-tilt", "(0, 90)"],
        );
    }
    assert!(!p.join("e.json").exists());
}

#[test]
fn eval_refuses_a_texture_mask_without_exact_depth_or_out_of_range() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let base = ["eval", "--seed", "2", "--queries", "1", "--json", "e.json"];
    refused(
        p,
        &[&base[..], &["--truth-min-texture", "1"]].concat(),
        1,
        &["--truth-min-texture", "--depth truth"],
    );
    for bad in ["-1", "NaN", "inf"] {
        refused(
            p,
            &[&base[..], &["--depth", "truth", "--truth-min-texture", bad]].concat(),
            2,
            &["--truth-min-texture", "at least 0"],
        );
    }
    assert!(!p.join("e.json").exists());
}

/// An eval report of `errors.len()` stops of world seed `seed` (the fields fix-report reads).
fn eval_report(seed: u64, condition: &str, errors: &[f64]) -> String {
    let stops: Vec<String> = errors
        .iter()
        .enumerate()
        .map(|(i, e)| {
            format!(
                r#"{{"id": {i}, "truth_m": [{}.5, 2000.25], "error_m": {e}, "true_cell_rank": 0,
                   "dense_s": 0.01, "status": "ok", "error_bound_m": 2.0, "path": "ncc"}}"#,
                3000 + i
            )
        })
        .collect();
    format!(
        r#"[{{"matcher": "fix", "condition": "{condition}", "seed": {seed},
              "per_query": [{}]}}]"#,
        stops.join(",")
    )
}

#[test]
fn fix_report_pools_folders_and_pairs_the_same_stops() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    for f in ["a", "b", "ta", "tb", "other"] {
        std::fs::create_dir(p.join(f)).unwrap();
    }
    let w = |f: &str, s: &str| std::fs::write(p.join(f), s).unwrap();
    // Stereo-like reports of two sets and truth-like ones of the same stops.
    w(
        "a/s2.json",
        &eval_report(2, "cross-sun", &[0.2, 9.0, 0.4, 3.0]),
    );
    w(
        "b/s10.json",
        &eval_report(10, "cross-sun", &[0.1, 0.3, 40.0, 0.2]),
    );
    w(
        "ta/s2.json",
        &eval_report(2, "cross-sun", &[0.1, 0.2, 0.3, 0.4]),
    );
    w(
        "tb/s10.json",
        &eval_report(10, "cross-sun", &[0.1, 0.3, 0.3, 7.0]),
    );
    let o = orbfix(
        p,
        &[
            "fix-report",
            "--dir",
            "a",
            "--dir",
            "b",
            "--against",
            "ta",
            "--against",
            "tb",
            "--out",
            "r.md",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(p.join("r.md")).unwrap();
    // Pooled: 8 stops, 5 within 1 m, 6 within 5 m; seeds of both folders.
    assert!(
        md.contains("| fix | cross-sun | 2, 10 | 8 | 0.625 ["),
        "{md}"
    );
    assert!(md.contains("| 0.750 ["), "{md}");
    // Paired: within 1 m 5/8 here, 7/8 there (here only: seed 10 stop 3; there only: seed 2
    // stops 1 and 3, seed 10 stop 2); within 5 m 6/8 against 7/8 (here only: seed 10 stop 3;
    // there only: seed 2 stop 1, seed 10 stop 2).
    assert!(
        md.contains("| fix | cross-sun | 8 | 0.625 / 0.875 | -0.250 ["),
        "{md}"
    );
    assert!(md.contains("| 1 / 3 | 0.750 / 0.875 | -0.125 ["), "{md}");
    assert!(md.contains("| 1 / 2 |"), "{md}");
    // Reports of other stops under the same numbers are refused, the page kept.
    w(
        "other/s2.json",
        &eval_report(2, "cross-sun", &[0.1; 4]).replace("2000.25", "9.0"),
    );
    refused(
        p,
        &[
            "fix-report",
            "--dir",
            "a",
            "--against",
            "other",
            "--out",
            "r.md",
        ],
        1,
        &["same stops"],
    );
    refused(
        p,
        &[
            "fix-report",
            "--dir",
            "a",
            "--against",
            "b",
            "--out",
            "r.md",
        ],
        1,
        &["no stop of these reports has a partner"],
    );
    assert_eq!(std::fs::read_to_string(p.join("r.md")).unwrap(), md);
}
