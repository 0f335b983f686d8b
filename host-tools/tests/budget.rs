//! Tests of the flight budget's host side: world-rendered test vectors with the host's run of
//! the one fix, report parsing in the core's result protocol, result comparison, the budget
//! table, ELF reading and Thumb branch decoding.

use orbfix::fix::FixStatus;
use orbfix::fix::{protocol, FixConfig, HeadingSearch, Stage};
use orbfix::fusion::Fusion;
use orbfix::reproject::GridSpec;
use orbfix_host::budget::{self, ElfSizes, Estimate, FusionCase, HeadingCase, Vectors};
use orbfix_host::eval::pipeline::PipelineOptions;
use orbfix_host::fix::FixRunner;
use orbfix_host::render::RenderOptions;
use orbfix_host::traverse::TraverseOptions;

/// A small stop so the tests stay fast: 160 x 90 frames, an 80-cell top-down grid (20 m) and
/// a 60 m map (11 x 11 CNN windows).
fn small() -> (PipelineOptions, FixRunner) {
    let mut render = RenderOptions::default();
    render.camera.width_px = 160;
    render.camera.height_px = 90;
    let opts = PipelineOptions {
        render,
        grid: GridSpec::new(80, 0.25),
        map_px: 240,
        ..PipelineOptions::default()
    };
    let cfg = FixConfig {
        grid: opts.grid,
        ..FixConfig::default()
    };
    (opts, FixRunner::shipped(cfg))
}

fn report_text(results: &[(String, String)]) -> String {
    let mut t = format!("qemu noise\n{} {}\n", protocol::HEADER, protocol::VERSION);
    for (i, s) in Stage::ALL.iter().enumerate() {
        t += &format!("STAGE {} {}\n", s.name(), 100 * (i + 1));
    }
    t += "TOTAL 1600\n";
    for (k, v) in results {
        t += &format!("RESULT {k} {v}\n");
    }
    t += "STACK 3000 32768\nEND OK\n";
    t
}

#[test]
fn parses_a_report_and_rejects_broken_ones() {
    let r = budget::parse_report(&report_text(&[("digest".into(), "0x12345678".into())])).unwrap();
    assert_eq!(r.stages.len(), Stage::ALL.len());
    assert_eq!(r.stages[3], ("nn_embed".to_string(), 400));
    assert_eq!(r.total_ticks, 1600);
    assert_eq!(r.stack_peak_bytes, 3000);
    assert_eq!(r.stack_region_bytes, 32768);
    assert!(r.ok);
    assert_eq!(
        r.results,
        vec![("digest".to_string(), "0x12345678".to_string())]
    );
    // Truncated (QEMU stopped): no END line.
    let v = protocol::VERSION;
    assert!(budget::parse_report(&format!("ORBFIX-FW {v}\nSTAGE a 1\n")).is_err());
    // Not a report at all.
    assert!(budget::parse_report("hello\n").is_err());
    // Other version, garbage numbers.
    assert!(budget::parse_report("ORBFIX-FW 1\nEND OK\n").is_err());
    assert!(budget::parse_report(&format!("ORBFIX-FW {v}\nSTAGE a x\nEND OK\n")).is_err());
    // The previous protocol version is refused.
    assert!(budget::parse_report(&format!("ORBFIX-FW {}\nEND OK\n", v - 1)).is_err());
    // A result of the filter before its FUSION line is refused.
    assert!(budget::parse_report(&format!(
        "ORBFIX-FW {v}\nFUSION-RESULT x_m 0x00000000\nEND OK\n"
    ))
    .is_err());
    // A failure report parses and says so.
    let f = budget::parse_report(&format!("ORBFIX-FW {v}\nEND ERR hard fault\n")).unwrap();
    assert!(!f.ok);
    assert_eq!(f.errors, vec!["hard fault".to_string()]);
}

#[test]
fn world_stop_runs_the_fix_deterministically_and_compares_bit_exactly() {
    let (opts, runner) = small();
    let v = Vectors::world_stop(2, 0, &opts, &runner.weights).unwrap();
    assert!(v.depths.is_some(), "the range path has depth images");
    let a = v.host_run(&runner).unwrap();
    let b = Vectors::world_stop(2, 0, &opts, &runner.weights)
        .unwrap()
        .host_run(&runner)
        .unwrap();
    assert_eq!(a.digest, b.digest, "same stop, same digest");
    assert_ne!(
        Vectors::world_stop(2, 1, &opts, &runner.weights)
            .unwrap()
            .host_run(&runner)
            .unwrap()
            .digest,
        a.digest,
        "another stop, another digest"
    );

    let expected = budget::expected_results(&a.report, a.digest);
    assert_eq!(expected.len(), protocol::RESULTS);
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
    let stop = |report: &budget::FirmwareReport| {
        budget::stop_budget(
            &est,
            v.source.clone(),
            report,
            &a.report,
            budget::mismatches(report, &expected),
            v.truth_m,
            (v.pose.x_m as f64, v.pose.y_m as f64),
        )
    };
    let ok = budget::assemble(&est, vec![stop(&report)], &sizes, true, &[], "cfg".into());
    assert!(ok.bit_exact && ok.panic_free, "{:?}", ok.mismatches);
    assert_eq!(ok.vectors, "world");
    assert_eq!(ok.total_instructions, 1600 * budget::INSTRUCTIONS_PER_TICK);
    assert_eq!(ok.stages["nn_embed"].instructions, 16_000);
    assert_eq!(ok.stages["nn_embed"].unit.as_deref(), Some("MAC"));
    assert!((ok.stages["nn_embed"].ms - 0.16).abs() < 1e-9);
    assert_eq!(ok.working_ram_bytes, 2000 + 3000);
    assert_eq!(ok.working_total_bytes, 2000 + 3000 + 4000);
    assert!(ok.stops[0].error_m.is_finite());
    let md = ok.markdown("orbfix budget --json x.json");
    assert!(
        md.contains("| nn_embed | 16,000 |") && md.contains("bit_exact: true"),
        "{md}"
    );

    // One flipped bit in the position makes it not bit exact, and says where.
    let mut bad = expected.clone();
    let x = bad.iter_mut().find(|(k, _)| k == "x_m").unwrap();
    let v0 = u32::from_str_radix(&x.1[2..], 16).unwrap() ^ 1;
    x.1 = format!("0x{v0:08x}");
    let nb = budget::assemble(
        &est,
        vec![stop(&budget::parse_report(&report_text(&bad)).unwrap())],
        &sizes,
        true,
        &[],
        "cfg".into(),
    );
    assert!(!nb.bit_exact);
    assert_eq!(nb.mismatches, vec!["stop 0: x_m".to_string()]);
    // A missing result is a mismatch too.
    let short = budget::parse_report(&report_text(&expected[1..])).unwrap();
    assert!(!budget::assemble(&est, vec![stop(&short)], &sizes, true, &[], "c".into()).bit_exact);
}

#[test]
fn writes_vectors_the_firmware_can_include() {
    let dir = std::env::temp_dir().join(format!("orbfix-vectors-{}", std::process::id()));
    let (opts, runner) = small();
    let v = Vectors::world_stop(3, 0, &opts, &runner.weights).unwrap();
    v.write(&dir, &runner.cfg).unwrap();
    let src = std::fs::read_to_string(dir.join("vectors.rs")).unwrap();
    assert!(src.contains("pub const WIDTH: usize = 160;"));
    assert!(src.contains("pub const GRID_N: usize = 80;"));
    assert!(src.contains("pub const HAS_DEPTH: bool = true;"));
    assert!(src.contains(&format!(
        "f32::from_bits(0x{:08x})",
        v.pose.heading_deg.to_bits()
    )));
    assert_eq!(std::fs::read(dir.join("frames.bin")).unwrap(), v.frames);
    assert_eq!(std::fs::read(dir.join("product.bin")).unwrap(), v.product);
    // The weights the product was made with, which the firmware's fix runs.
    assert_eq!(
        std::fs::read(dir.join("weights.bin")).unwrap(),
        runner.weights
    );
    assert!(src.contains(&format!(
        "pub const WEIGHTS_LEN: usize = {};",
        runner.weights.len()
    )));
    assert_eq!(
        std::fs::read(dir.join("depths.bin")).unwrap().len(),
        4 * 2 * 160 * 90
    );
    assert!(src.contains(&format!(
        "pub const PRODUCT_LEN: usize = {};",
        v.product.len()
    )));
    std::fs::remove_dir_all(&dir).unwrap();
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

/// Appends the filter's and the heading search's lines to a report text (before `STACK`).
fn with_extras(
    text: &str,
    fusion: &[(String, String)],
    headings: usize,
    heading: &[(String, String)],
) -> String {
    let mut extra = "FUSION 22\n".to_string();
    for (k, v) in fusion {
        extra += &format!("{} {k} {v}\n", protocol::FUSION_RESULT);
    }
    extra += &format!("HEADING {headings} 5000\n");
    for (k, v) in heading {
        extra += &format!("{} {k} {v}\n", protocol::HEADING_RESULT);
    }
    text.replace("STACK ", &(extra + "STACK "))
}

#[test]
fn fusion_and_heading_search_entries_are_the_traverse_s_work_and_compare_bit_exactly() {
    let (opts, runner) = small();
    let drive = TraverseOptions::default();
    let mut v = Vectors::world_stop(2, 0, &opts, &runner.weights).unwrap();
    let h0 = v.pose.heading_deg;
    let case = FusionCase::before_stop(
        drive.fusion_config(),
        v.truth_m,
        (0.5, -0.5),
        40.0,
        h0 as f64,
    );
    let search = drive.heading_search(2.0).unwrap().unwrap();
    assert_eq!(
        search,
        HeadingSearch::for_sigma(2.0, 1.0, 2.0).unwrap().unwrap()
    );
    assert_eq!(search.count(), 5);
    v.fusion = Some(case);
    v.heading = Some(HeadingCase {
        search,
        estimate_deg: h0 + 1.5,
    });
    let fix = v.host_run(&runner).unwrap();

    // The budget's filter work is the traverse's: predict, radius, update, in that order; on
    // the small stop's own fix and on an ok fix at the truth (the accepting branch).
    let mut at_truth = fix.report.clone();
    at_truth.status = FixStatus::Ok;
    at_truth.x_m = v.truth_m.0 as f32;
    at_truth.y_m = v.truth_m.1 as f32;
    at_truth.error_bound_m = 0.5;
    let traverse_way = |r: &orbfix::fix::FixReport| {
        let mut t = Fusion::new(drive.fusion_config(), case.start_m.0, case.start_m.1).unwrap();
        t.predict(&case.leg).unwrap();
        let radius = t.search_radius_m();
        let outcome = t.update(r).unwrap();
        (t, radius, outcome)
    };
    for r in [&fix.report, &at_truth] {
        let (filter, stop) = case.host_run(r).unwrap();
        let (t, radius, outcome) = traverse_way(r);
        assert_eq!(filter, t);
        assert_eq!(stop.search_radius_m.to_bits(), radius.to_bits());
        assert_eq!(stop.outcome, outcome);
        assert_eq!(outcome.accepted(), r.status == FixStatus::Ok, "{outcome:?}");
    }
    let (filter, stop) = case.host_run(&at_truth).unwrap();
    let p = filter.position();
    assert!((p.0 as f64 - v.truth_m.0).hypot(p.1 as f64 - v.truth_m.1) < 0.7);

    // The heading search the budget checks is the traverse's (same core call, same pose).
    let (hf, digest) = v.host_heading_search(&runner).unwrap().unwrap();
    let mut pose = v.pose;
    pose.heading_deg = h0 + 1.5;
    let frames = (0..4).map(|i| {
        let n = v.frame_pixels();
        orbfix::image::ImageView::new(&v.frames[i * n..(i + 1) * n], 160, 90).ok()
    });
    let frames: [_; 4] = frames.collect::<Vec<_>>().try_into().unwrap();
    let (ht, out) = runner
        .run_heading_search(
            &v.params,
            &pose,
            frames,
            v.depths.as_ref(),
            &v.product,
            &search,
        )
        .unwrap();
    assert_eq!(hf, ht);
    assert_eq!(hf.tried, 5);
    assert_eq!(digest, out.digest);
    // The reported heading is the best try's, moved by less than half a step.
    assert!([-4.0, -2.0, 0.0, 2.0, 4.0].contains(&hf.best_offset_deg));
    assert!(
        (hf.heading_deg - (h0 + 1.5 + hf.best_offset_deg)).abs() <= 1.0 + 1e-4,
        "{} vs {h0} + 1.5 + {}",
        hf.heading_deg,
        hf.best_offset_deg
    );

    // A firmware report with both entries parses; equal values are bit exact.
    let fx = budget::expected_fusion(&filter, &stop);
    let hx = budget::expected_heading(&hf, digest);
    assert_eq!(fx.len(), protocol::FUSION_RESULTS);
    assert_eq!(hx.len(), protocol::HEADING_RESULTS);
    let expected = budget::expected_results(&fix.report, fix.digest);
    let text = with_extras(&report_text(&expected), &fx, 5, &hx);
    let r = budget::parse_report(&text).unwrap();
    let (rf, rh) = (r.fusion.clone().unwrap(), r.heading.clone().unwrap());
    assert_eq!((rf.ticks, rh.headings, rh.ticks), (22, 5, 5000));
    assert!(budget::keyed_mismatches(&rf.results, &fx).is_empty());
    assert!(budget::keyed_mismatches(&rh.results, &hx).is_empty());
    assert!(
        budget::mismatches(&r, &expected).is_empty(),
        "the fix's lines are unchanged"
    );

    // One flipped bit of the searched heading is found and named.
    let mut bad = hx.clone();
    let e = bad.iter_mut().find(|(k, _)| k == "heading_deg").unwrap();
    let b0 = u32::from_str_radix(&e.1[2..], 16).unwrap() ^ 1;
    e.1 = format!("0x{b0:08x}");
    let rb = budget::parse_report(&with_extras(&report_text(&expected), &fx, 5, &bad)).unwrap();
    assert_eq!(
        budget::keyed_mismatches(&rb.heading.unwrap().results, &hx),
        vec!["heading_deg".to_string()]
    );

    // The budget table: both entries per stop and overall; a heading mismatch is not bit exact.
    let est = Estimate {
        target: "cortex-m7".into(),
        clock_mhz: 100.0,
        cpi: 1.0,
    };
    let mut sb = budget::stop_budget(
        &est,
        "stop".into(),
        &r,
        &fix.report,
        vec![],
        v.truth_m,
        (v.pose.x_m as f64, v.pose.y_m as f64),
    );
    sb.fusion = Some(budget::FusionBudget {
        instructions: 880,
        ms: est.ms(880),
        leg_m: 40.0,
        accepted: true,
        mahalanobis2: stop.outcome.mahalanobis2 as f64,
        search_radius_m: 25.0,
        bit_exact: true,
        mismatches: vec![],
    });
    let heading_entry = |bit_exact: bool| budget::HeadingBudget {
        headings: 5,
        step_deg: 2.0,
        sigma_deg: 2.0,
        instructions: 200_000,
        ms: est.ms(200_000),
        instructions_per_heading: 40_000.0,
        estimate_error_deg: 1.5,
        heading_error_deg: 0.2,
        error_m: 0.1,
        status: "ok".into(),
        bit_exact,
        mismatches: if bit_exact {
            vec![]
        } else {
            vec!["heading_deg".into()]
        },
    };
    sb.heading_search = Some(heading_entry(true));
    let sizes = ElfSizes::default();
    let b = budget::assemble(&est, vec![sb.clone()], &sizes, true, &[], "c".into());
    assert!(b.bit_exact, "{:?}", b.mismatches);
    assert_eq!(b.fusion.as_ref().map(|f| f.instructions), Some(880));
    assert_eq!(b.heading_search.as_ref().map(|h| h.headings), Some(5));
    let md = b.markdown("orbfix budget --json x.json");
    assert!(
        md.contains("## A stop of a drive") && md.contains("| 880 |"),
        "{md}"
    );
    let json = serde_json::to_value(&b).unwrap();
    assert_eq!(json["heading_search"]["headings"], 5);
    assert_eq!(json["fusion"]["instructions"], 880);
    sb.heading_search = Some(heading_entry(false));
    let nb = budget::assemble(&est, vec![sb], &sizes, true, &[], "c".into());
    assert!(!nb.bit_exact);
    assert_eq!(
        nb.mismatches,
        vec!["stop 0: heading search heading_deg".to_string()]
    );

    // The vectors carry both cases for the firmware.
    let dir = std::env::temp_dir().join(format!("orbfix-vectors-drive-{}", std::process::id()));
    v.write(&dir, &runner.cfg).unwrap();
    let src = std::fs::read_to_string(dir.join("vectors.rs")).unwrap();
    assert!(src.contains("pub const FUSION: bool = true;"), "{src}");
    assert!(src.contains("pub const HEADING_STEPS: usize = 2;"), "{src}");
    assert!(src.contains(&format!(
        "pub const FUSION_CFG: [u32; 12] = {:?};",
        protocol::fusion_config_words(&drive.fusion_config())
    )));
    assert_eq!(
        protocol::fusion_config_from_words(&protocol::fusion_config_words(&drive.fusion_config())),
        drive.fusion_config()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
