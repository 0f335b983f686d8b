//! Tests of the flight budget's host side: report parsing, result comparison, ELF reading,
//! Thumb branch decoding and the synthetic test vectors with the host's reference run.

use orbfix::flight_run::FlightConfig;
use orbfix::localize::LocalizeConfig;
use orbfix::reproject::GridSpec;
use orbfix_host::budget::{self, ElfSizes, Estimate, Vectors};

/// A small configuration so the tests stay fast: 80 x 80 cells of 0.25 m (20 m).
fn small_cfg() -> FlightConfig {
    FlightConfig {
        grid: GridSpec::new(80, 0.25),
        localize: LocalizeConfig::default(),
    }
}

fn small_vectors(seed: u64) -> Vectors {
    Vectors::synthetic(seed, 160, 90, 60.0, 0.25, 80).unwrap()
}

fn report_text(results: &[(String, String)]) -> String {
    let mut t = String::from("qemu noise\nORBFIX-FW 1\nSTAGE lut_build 100\nSTAGE reproject 50\n");
    t += "STAGE localize 1000\nSTAGE nn_embed 20\nSTAGE nn_match 30\nTOTAL 1200\n";
    for (k, v) in results {
        t += &format!("RESULT {k} {v}\n");
    }
    t += "STACK 3000 32768\nEND OK\n";
    t
}

#[test]
fn parses_a_report_and_rejects_broken_ones() {
    let r = budget::parse_report(&report_text(&[("digest".into(), "0x12345678".into())])).unwrap();
    assert_eq!(r.stages.len(), 5);
    assert_eq!(r.stages[2], ("localize".to_string(), 1000));
    assert_eq!(r.total_ticks, 1200);
    assert_eq!(r.stack_peak_bytes, 3000);
    assert_eq!(r.stack_region_bytes, 32768);
    assert!(r.ok);
    assert_eq!(
        r.results,
        vec![("digest".to_string(), "0x12345678".to_string())]
    );
    // Truncated (QEMU stopped): no END line.
    assert!(budget::parse_report("ORBFIX-FW 1\nSTAGE a 1\n").is_err());
    // Not a report at all.
    assert!(budget::parse_report("hello\n").is_err());
    // Other version, garbage numbers.
    assert!(budget::parse_report("ORBFIX-FW 2\nEND OK\n").is_err());
    assert!(budget::parse_report("ORBFIX-FW 1\nSTAGE a x\nEND OK\n").is_err());
    // A failure report parses and says so.
    let f = budget::parse_report("ORBFIX-FW 1\nEND ERR hard fault\n").unwrap();
    assert!(!f.ok);
    assert_eq!(f.errors, vec!["hard fault".to_string()]);
}

#[test]
fn host_run_is_deterministic_localizes_and_compares_bit_exactly() {
    let cfg = small_cfg();
    let v = small_vectors(3);
    let a = v.host_run(&cfg).unwrap();
    let b = small_vectors(3).host_run(&cfg).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.digest(), b.digest());
    // The frames are rendered over the map a few metres from the prior: the fix finds it.
    let err = (a.fix.x_m - v.truth_m.0).hypot(a.fix.y_m - v.truth_m.1);
    let prior = (v.pose.x_m - v.truth_m.0).hypot(v.pose.y_m - v.truth_m.1);
    assert!(
        err < 0.5 && prior > 1.0,
        "fix error {err} m, prior off by {prior} m"
    );
    // Another seed gives other results.
    assert_ne!(
        small_vectors(4).host_run(&cfg).unwrap().digest(),
        a.digest()
    );

    let expected = budget::host_results(&a);
    let est = Estimate {
        target: "cortex-m7".into(),
        clock_mhz: 100.0,
        cpi: 1.0,
    };
    let sizes = ElfSizes {
        flash_bytes: 1000,
        static_ram_bytes: 2000,
        external_input_bytes: 3000,
        external_scratch_bytes: 4000,
        stack_region_bytes: 32768,
    };
    let report = budget::parse_report(&report_text(&expected)).unwrap();
    let ok = budget::assemble(&est, &report, &sizes, &cfg, &a, &v, &[]);
    assert!(ok.bit_exact && ok.panic_free, "{:?}", ok.mismatches);
    assert_eq!(ok.total_instructions, 1200 * budget::INSTRUCTIONS_PER_TICK);
    assert_eq!(ok.stages["localize"].instructions, 40_000);
    assert!((ok.stages["localize"].ms - 0.4).abs() < 1e-9);
    assert_eq!(ok.working_ram_bytes, 2000 + 3000);
    assert_eq!(ok.working_total_bytes, 2000 + 3000 + 4000);
    let md = ok.markdown("orbfix budget --json x.json");
    assert!(md.contains("| localize | 40,000 |") && md.contains("bit_exact: true"));
    // nn_match on the dense 4 m grid, projected from the measured rate: the 60 m map has
    // 9 x 9 study windows (80 px every 20 px) and 11 x 11 dense ones (every 16 px).
    assert_eq!(a.nn_windows, 81);
    let d = ok.nn_match_dense.as_ref().unwrap();
    assert!(!d.measured);
    assert_eq!((d.windows, d.measured_windows, d.step_m), (121, 81, 4.0));
    assert_eq!(d.instructions, 1793); // 1200 instructions / 81 windows x 121, rounded
    assert_eq!(d.whole_fix_instructions, 48_000 - 1200 + 1793);
    assert!(md.contains("dense 4 m grid, **projected**") && md.contains("| 1,793 |"));

    // One flipped bit in the fix makes it not bit exact, and says where.
    let mut bad = expected.clone();
    let fix = bad.iter_mut().find(|(k, _)| k == "fix").unwrap();
    let x = u32::from_str_radix(&fix.1[2..10], 16).unwrap() ^ 1;
    fix.1 = format!("0x{x:08x}{}", &fix.1[10..]);
    let report = budget::parse_report(&report_text(&bad)).unwrap();
    let nb = budget::assemble(&est, &report, &sizes, &cfg, &a, &v, &[]);
    assert!(!nb.bit_exact);
    assert_eq!(nb.mismatches, vec!["fix".to_string()]);
    // A missing result is a mismatch too.
    let report = budget::parse_report(&report_text(&expected[1..])).unwrap();
    assert!(!budget::assemble(&est, &report, &sizes, &cfg, &a, &v, &[]).bit_exact);
}

#[test]
fn writes_vectors_the_firmware_can_include() {
    let dir = std::env::temp_dir().join(format!("orbfix-vectors-{}", std::process::id()));
    let cfg = small_cfg();
    let v = small_vectors(5);
    v.write(&dir, &cfg).unwrap();
    let src = std::fs::read_to_string(dir.join("vectors.rs")).unwrap();
    assert!(src.contains("pub const WIDTH: usize = 160;"));
    assert!(src.contains("pub const GRID_N: usize = 80;"));
    assert!(src.contains(&format!(
        "f32::from_bits(0x{:08x})",
        v.pose.heading_deg.to_bits()
    )));
    assert_eq!(std::fs::read(dir.join("frames.bin")).unwrap(), v.frames);
    assert_eq!(std::fs::read(dir.join("map.bin")).unwrap().len(), 240 * 240);
    let records = 81 * orbfix::nn::window_cosine::WINDOW_RECORD_BYTES;
    assert_eq!(
        std::fs::read(dir.join("map_windows.bin")).unwrap(),
        v.map_windows
    );
    assert_eq!(v.map_windows.len(), records);
    assert!(src.contains(&format!("pub const MAP_WINDOWS_LEN: usize = {records};")));
    std::fs::remove_dir_all(&dir).unwrap();
    // Bad sizes are errors, not panics.
    assert!(Vectors::synthetic(1, 0, 90, 60.0, 0.25, 80).is_err());
    assert!(Vectors::synthetic(1, 160, 90, f32::NAN, 0.25, 80).is_err());
    assert!(Vectors::synthetic(1, 160, 90, 60.0, 0.0, 80).is_err());
    assert!(Vectors::synthetic_with_step(1, 160, 90, 60.0, 0.25, 80, 0).is_err());
}

#[test]
fn elf_reader_rejects_non_elf_and_decodes_thumb_branches() {
    assert!(budget::elf_sizes(b"not an elf").is_err());
    assert!(budget::elf_sizes(&[]).is_err());
    assert!(budget::panic_sites(b"\x7fELF truncated").is_err());
    // bl 0xc3c4 at 0xc210 (forward), as the linker encodes it.
    assert_eq!(
        budget::thumb_branch_target(0xc210, 0xf000, 0xf8d8),
        Some(0xc3c4)
    );
    // Round trips of an encoder over forward and backward offsets, BL and B.W.
    for (addr, target) in [
        (0x1000u64, 0x0u64),
        (0x8000, 0x3_fffe),
        (0x20_0000, 0x1_0000),
    ] {
        let off = target as i64 - (addr as i64 + 4);
        let imm = (off as u32) & 0x1FF_FFFF;
        let s = (imm >> 24) & 1;
        let (i1, i2) = ((imm >> 23) & 1, (imm >> 22) & 1);
        let (j1, j2) = ((!i1 ^ s) & 1, (!i2 ^ s) & 1);
        let h1 = (0b11110 << 11) | (s << 10) | ((imm >> 12) & 0x3FF);
        for link in [1u32, 0] {
            let h2 = (1 << 15)
                | (link << 14)
                | (j1 << 13)
                | (1 << 12)
                | (j2 << 11)
                | ((imm >> 1) & 0x7FF);
            assert_eq!(
                budget::thumb_branch_target(addr, h1 as u16, h2 as u16),
                Some(target),
                "addr {addr:#x} target {target:#x} link {link}"
            );
        }
    }
    // A 16-bit instruction pair is not a branch.
    assert_eq!(budget::thumb_branch_target(0, 0x4770, 0xbf00), None);
}

#[test]
fn dense_grid_vectors_score_every_dense_window_and_count_as_measured() {
    let cfg = small_cfg();
    let step = orbfix::flight_run::dense_window_step(0.25);
    let v = Vectors::synthetic_with_step(3, 160, 90, 60.0, 0.25, 80, step).unwrap();
    assert_eq!(v.window_step_px, 16);
    let out = v.host_run(&cfg).unwrap();
    assert_eq!(out.nn_windows, 121);
    assert!(v.describe().contains("121 CNN map windows every 4 m"));
    // Same frames and map as the study-grid vectors of the seed: only the CNN part differs.
    let study = small_vectors(3).host_run(&cfg).unwrap();
    assert_eq!(
        (out.fix, out.embedding_hash),
        (study.fix, study.embedding_hash)
    );
    assert_ne!(out.nn_scores_hash, study.nn_scores_hash);
    let est = Estimate {
        target: "cortex-m7".into(),
        clock_mhz: 100.0,
        cpi: 1.0,
    };
    let report = budget::parse_report(&report_text(&budget::host_results(&out))).unwrap();
    let b = budget::assemble(&est, &report, &ElfSizes::default(), &cfg, &out, &v, &[]);
    let d = b.nn_match_dense.unwrap();
    assert!(d.measured && b.bit_exact);
    assert_eq!((d.windows, d.instructions), (121, 1200));
    assert_eq!(d.whole_fix_instructions, b.total_instructions);
}
