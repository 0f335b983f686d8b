//! Fault injection into the whole fix (`orbfix::fix::run`) on a stop rendered from the world:
//! bit flips in the weights, in the map product (header, pixels, window records) and in
//! every buffer of the fix's scratch, before the run and between its stages. Each injected
//! fault must be **detected** (a typed error, or the status `self-check-failed`) or
//! **harmless** (the run's output digest, `orbfix::fix::output_digest` over the report,
//! top-down image, mask, coarse response and embedding, equals the clean run's).
//!
//! How a fault gets in:
//! - weights and map product: the bytes handed to the fix are flipped (damage in storage or
//!   in transit; the fix borrows them immutably, so a flip during a run cannot be injected
//!   without undefined behaviour, see docs/reliability.md for why the redundant run covers
//!   it);
//! - scratch before the run: one bit flipped in a zeroed scratch (and one scratch full of
//!   random bytes): every buffer the fix reads it writes first, so these are harmless, with
//!   or without self-checks;
//! - scratch between stages: through the fault-injection hook `StageClock::after` (a no-op
//!   by default), called after the reprojection, the embedding and the coarse match of each
//!   run and after each run's report is made, with the live scratch.
//!
//! Printed: faults tried / detected / harmless / undetected per class
//! (`cargo test --release -p orbfix-host --test fault_injection_fix -- --nocapture`).
//! `ORBFIX_FAULTS=K` sets the flips per (buffer, injection point) (default 2).

use orbfix::fix::{self, FixConfig, FixError, FixReport, FixScratch, FixStatus, Stage, StageClock};
use orbfix::map_product::{CrcCheck, MapProduct};
use orbfix::nn::model::SHIPPED_WEIGHTS;
use orbfix_host::eval::pipeline::Reprojection;
use orbfix_host::fix::OwnedScratch;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};

mod common;
use common::{stop, Stop};

/// Owned scratch of one fix, exactly as long as `fix_buffer_sizes` says.
fn bufs_for(s: &Stop, cfg: &FixConfig) -> OwnedScratch {
    OwnedScratch::for_product(cfg, &s.product).unwrap()
}

/// The fix's buffers (the CNN's arena and input live in `work`).
const BUFFERS: [&str; 6] = [
    "top",
    "mask",
    "work",
    "response",
    "refine_floats",
    "nn_embedding",
];

/// The bytes of scratch buffer `b` (every buffer holds plain integers or floats, valid for
/// every bit pattern).
fn bytes<'s>(s: &'s mut FixScratch<'_>, b: usize) -> &'s mut [u8] {
    fn view<T>(v: &mut [T]) -> &mut [u8] {
        // Safety: only used on slices of u32, i32, f32 (no padding, every bit pattern valid);
        // the byte view covers exactly the slice.
        unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr().cast(), std::mem::size_of_val(v)) }
    }
    match b {
        0 => s.top,
        1 => s.mask,
        2 => view(s.work),
        3 => view(s.response),
        4 => view(s.refine_floats),
        _ => view(&mut s.nn_embedding[..]),
    }
}

/// A clock that flips bits of the live scratch at one injection point (the `at`-th call of
/// the hook) and records the points it saw.
#[derive(Default)]
struct Injector {
    /// (injection point, buffer, bit indices (taken modulo the buffer's bits)).
    flip: Option<(usize, usize, Vec<usize>)>,
    calls: usize,
    points: Vec<Stage>,
    fired: bool,
}

impl StageClock for Injector {
    fn begin(&mut self, _stage: Stage) {}
    fn end(&mut self, _stage: Stage) {}
    fn after(&mut self, stage: Stage, scratch: &mut FixScratch<'_>) {
        if let Some((at, b, bits)) = &self.flip {
            if *at == self.calls {
                let v = bytes(scratch, *b);
                for &bit in bits {
                    let bit = bit % (v.len() * 8);
                    v[bit / 8] ^= 1 << (bit % 8);
                }
                self.fired = true;
            }
        }
        self.calls += 1;
        self.points.push(stage);
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Outcome {
    Error(FixError),
    Report(FixStatus, u32),
    Panic,
}

fn run_fix(
    s: &Stop,
    cfg: &FixConfig,
    weights: &[u8],
    product: &[u8],
    bufs: &mut OwnedScratch,
    clock: &mut Injector,
) -> Outcome {
    let mut pose = s.obs.pose;
    pose.x_m = s.prior.0 as f32;
    pose.y_m = s.prior.1 as f32;
    let frames = s.obs.frames().unwrap();
    let mut dviews = [None; 4];
    if let Some(ds) = &s.obs.depths {
        let (w, h) = (
            s.obs.params.width_px as usize,
            s.obs.params.height_px as usize,
        );
        for (dv, d) in dviews.iter_mut().zip(ds) {
            *dv = Some(orbfix::reproject::DepthView::new(d, w, h).unwrap());
        }
    }
    let inputs = fix::FixInputs {
        params: s.obs.params,
        pose,
        frames,
        depth: match &s.obs.depths {
            Some(_) => fix::Depth::Images(dviews),
            None => fix::Depth::Flat,
        },
        map_product: product,
        weights,
    };
    let mut scratch = bufs.scratch();
    let r: Result<Result<FixReport, FixError>, _> = catch_unwind(AssertUnwindSafe(|| {
        fix::run(&inputs, cfg, &mut scratch, clock)
    }));
    match r {
        Err(_) => Outcome::Panic,
        Ok(Err(e)) => Outcome::Error(e),
        Ok(Ok(report)) => Outcome::Report(
            report.status,
            fix::output_digest(&report, &scratch, cfg.grid.n),
        ),
    }
}

#[derive(Default)]
struct Tally {
    tried: usize,
    detected: usize,
    harmless: usize,
    undetected: Vec<String>,
    how: BTreeMap<String, usize>,
}

impl Tally {
    fn add(&mut self, clean: &Outcome, got: &Outcome, what: impl FnOnce() -> String) {
        self.tried += 1;
        match got {
            Outcome::Error(e) => {
                self.detected += 1;
                // Grouped by the message up to its details (CRCs, sizes).
                let m = e.to_string();
                let key = m
                    .split(['(', ':'])
                    .next()
                    .unwrap_or_default()
                    .trim()
                    .to_owned();
                *self.how.entry(format!("error: {key}")).or_default() += 1;
            }
            Outcome::Report(FixStatus::SelfCheckFailed, _) => {
                self.detected += 1;
                *self.how.entry("self-check-failed".into()).or_default() += 1;
            }
            g if g == clean => self.harmless += 1,
            g => self.undetected.push(format!("{} -> {g:?}", what())),
        }
    }

    fn print(&self, class: &str) {
        println!(
            "{class}: {} faults, {} detected, {} harmless, {} undetected",
            self.tried,
            self.detected,
            self.harmless,
            self.undetected.len()
        );
        for (how, n) in &self.how {
            println!("    {n:5} {how}");
        }
        for u in self.undetected.iter().take(10) {
            println!("    undetected: {u}");
        }
    }
}

fn per_point() -> usize {
    std::env::var("ORBFIX_FAULTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2)
}

/// The flight self-check: both CRCs and the redundant whole run.
fn flight_cfg() -> FixConfig {
    let mut cfg = FixConfig::default();
    cfg.self_check.verify_map_crc = true;
    cfg.self_check.redundant_run = true;
    cfg
}

/// Flips in the weights and in the map product handed to the fix.
#[test]
fn flips_in_weights_and_map_product_are_detected() {
    let s = stop(Reprojection::Range);
    let cfg = flight_cfg();
    let mut bufs = bufs_for(&s, &cfg);
    let clean = run_fix(
        &s,
        &cfg,
        SHIPPED_WEIGHTS,
        &s.product,
        &mut bufs,
        &mut Injector::default(),
    );
    assert!(
        matches!(clean, Outcome::Report(FixStatus::Ok, _)),
        "{clean:?}"
    );
    let mut rng = StdRng::seed_from_u64(12);
    let k = per_point();

    // Weights: every bit of the header, random bits elsewhere (every bit of the file is
    // covered by tests/fault_injection.rs against the parser alone).
    let mut w = SHIPPED_WEIGHTS.to_vec();
    let nbits = w.len() * 8;
    let bits: Vec<usize> = (0..16 * 8)
        .chain((0..16 * k).map(|_| rng.random_range(0..nbits)))
        .chain(nbits - 32..nbits)
        .collect();
    let mut t = Tally::default();
    for &bit in &bits {
        w[bit / 8] ^= 1 << (bit % 8);
        let got = run_fix(
            &s,
            &cfg,
            &w,
            &s.product,
            &mut bufs,
            &mut Injector::default(),
        );
        t.add(&clean, &got, || format!("weights bit {bit}"));
        w[bit / 8] ^= 1 << (bit % 8);
    }
    t.print("weights");
    assert!(t.undetected.is_empty());
    assert_eq!(t.detected, t.tried, "every weight flip is refused");

    // Map product: header, pixels, window records, CRC trailer.
    let meta = *MapProduct::parse(&s.product, CrcCheck::Skip)
        .unwrap()
        .meta();
    let pixels = 64..64 + meta.width * meta.height;
    let records = pixels.end.next_multiple_of(4)..s.product.len() - 4;
    let mut p = s.product.clone();
    let mut map_bits: Vec<(&str, usize)> = Vec::new();
    map_bits.extend((0..64 * 8).step_by(3).map(|b| ("header", b)));
    for (name, r) in [("pixels", &pixels), ("records", &records)] {
        map_bits.extend((0..32 * k).map(|_| (name, rng.random_range(r.start * 8..r.end * 8))));
    }
    map_bits.extend((p.len() * 8 - 32..p.len() * 8).map(|b| ("crc", b)));
    let mut t = Tally::default();
    for &(name, bit) in &map_bits {
        p[bit / 8] ^= 1 << (bit % 8);
        let got = run_fix(
            &s,
            &cfg,
            SHIPPED_WEIGHTS,
            &p,
            &mut bufs,
            &mut Injector::default(),
        );
        t.add(&clean, &got, || format!("map product {name} bit {bit}"));
        p[bit / 8] ^= 1 << (bit % 8);
    }
    t.print("map product (verify_map_crc)");
    assert!(t.undetected.is_empty());
    assert_eq!(t.detected, t.tried, "every map product flip is refused");

    // Without verify_map_crc (the default, for a product checked once when loaded), a
    // flipped pixel or record goes unnoticed: why the flight configuration verifies it.
    let mut unchecked = FixConfig::default();
    unchecked.self_check.redundant_run = true;
    let clean_u = run_fix(
        &s,
        &unchecked,
        SHIPPED_WEIGHTS,
        &s.product,
        &mut bufs,
        &mut Injector::default(),
    );
    let mut t = Tally::default();
    for &(name, bit) in map_bits
        .iter()
        .filter(|(n, _)| *n == "records" || *n == "pixels")
    {
        p[bit / 8] ^= 1 << (bit % 8);
        let got = run_fix(
            &s,
            &unchecked,
            SHIPPED_WEIGHTS,
            &p,
            &mut bufs,
            &mut Injector::default(),
        );
        t.add(&clean_u, &got, || format!("map product {name} bit {bit}"));
        p[bit / 8] ^= 1 << (bit % 8);
    }
    t.print("map pixels and records without verify_map_crc (not the flight configuration)");
    assert!(
        !t.undetected.is_empty(),
        "without the map CRC some record or pixel flips must change the fix unnoticed (else this test cannot see a fault)"
    );
}

/// Flips in the scratch before the run: harmless, because the fix writes every buffer it
/// reads before reading it (without any self-check, on both reprojection paths).
#[test]
fn flips_in_scratch_before_the_run_are_harmless() {
    let k = per_point();
    let mut rng = StdRng::seed_from_u64(13);
    for path in [Reprojection::Range, Reprojection::Lut] {
        let s = stop(path);
        let cfg = FixConfig::default();
        let mut bufs = bufs_for(&s, &cfg);
        let clean = run_fix(
            &s,
            &cfg,
            SHIPPED_WEIGHTS,
            &s.product,
            &mut bufs,
            &mut Injector::default(),
        );
        assert!(matches!(clean, Outcome::Report(_, _)), "{clean:?}");
        let mut t = Tally::default();
        for (b, buf) in BUFFERS.iter().enumerate() {
            for _ in 0..8 * k {
                let mut bufs = bufs_for(&s, &cfg);
                let v = bytes(&mut bufs.scratch(), b).len() * 8;
                let bit = rng.random_range(0..v);
                bytes(&mut bufs.scratch(), b)[bit / 8] ^= 1 << (bit % 8);
                let got = run_fix(
                    &s,
                    &cfg,
                    SHIPPED_WEIGHTS,
                    &s.product,
                    &mut bufs,
                    &mut Injector::default(),
                );
                t.add(&clean, &got, || format!("{buf} bit {bit} before the run"));
            }
        }
        // And a scratch full of random bytes.
        let mut bufs = bufs_for(&s, &cfg);
        for b in 0..BUFFERS.len() {
            rng.fill(bytes(&mut bufs.scratch(), b));
        }
        // Random bit patterns may be NaN floats: still plain data.
        let got = run_fix(
            &s,
            &cfg,
            SHIPPED_WEIGHTS,
            &s.product,
            &mut bufs,
            &mut Injector::default(),
        );
        t.add(&clean, &got, || "a scratch of random bytes".into());
        t.print(&format!(
            "scratch before the run ({path:?} path, no self-check)"
        ));
        assert!(t.undetected.is_empty());
        assert_eq!(t.harmless, t.tried);
    }
}

/// Flips in the scratch between stages, through the `StageClock::after` hook: with the
/// flight self-check every one is detected or harmless. With only the redundant embedding,
/// flips in the top-down image or mask after the reprojection, in the embedding after the
/// embedding stage and in the response after the match go unnoticed (counted, not
/// asserted): why the flight configuration runs the whole fix twice.
#[test]
fn flips_in_scratch_between_stages_are_detected_or_harmless() {
    let k = per_point();
    let s = stop(Reprojection::Range);
    let mut rng = StdRng::seed_from_u64(14);
    let embed_only = {
        let mut c = FixConfig::default();
        c.self_check.verify_map_crc = true;
        c.self_check.redundant_embed = true;
        c
    };
    for (name, cfg, must_hold) in [
        (
            "flight self-check (verify_map_crc, redundant_run)",
            flight_cfg(),
            true,
        ),
        ("redundant_embed only", embed_only, false),
    ] {
        let mut bufs = bufs_for(&s, &cfg);
        let mut probe = Injector::default();
        let clean = run_fix(&s, &cfg, SHIPPED_WEIGHTS, &s.product, &mut bufs, &mut probe);
        assert!(
            matches!(clean, Outcome::Report(FixStatus::Ok, _)),
            "{clean:?}"
        );
        let points = probe.points.clone();
        let per_run = points.len() / if cfg.self_check.redundant_run { 2 } else { 1 };
        assert_eq!(
            &points[..per_run],
            &[
                Stage::Reproject,
                Stage::NnEmbed,
                Stage::NnMatch,
                Stage::Refine
            ]
        );
        let mut t = Tally::default();
        let mut missed: BTreeMap<String, usize> = BTreeMap::new();
        for (at, stage) in points.iter().enumerate() {
            for (b, buf) in BUFFERS.iter().enumerate() {
                for _ in 0..k {
                    let len = bytes(&mut bufs.scratch(), b).len() * 8;
                    let bits: Vec<usize> = vec![rng.random_range(0..len)];
                    let mut clock = Injector {
                        flip: Some((at, b, bits.clone())),
                        ..Injector::default()
                    };
                    let got = run_fix(&s, &cfg, SHIPPED_WEIGHTS, &s.product, &mut bufs, &mut clock);
                    assert!(clock.fired);
                    let before = t.undetected.len();
                    t.add(&clean, &got, || {
                        format!(
                            "{buf} bit {} after {} of run {}",
                            bits[0],
                            stage.name(),
                            at / per_run + 1
                        )
                    });
                    if t.undetected.len() > before {
                        *missed
                            .entry(format!("{buf} after {}", stage.name()))
                            .or_default() += 1;
                    }
                }
            }
        }
        t.print(&format!("scratch between stages, {name}"));
        for (m, n) in &missed {
            println!("    missed: {n} x {m}");
        }
        if must_hold {
            assert!(t.undetected.is_empty(), "undetected: {:?}", t.undetected);
        } else {
            assert!(
                missed.keys().any(|m| m.starts_with("top after reproject")),
                "a flip in the top-down image after the reprojection escapes the redundant embedding"
            );
        }
    }
}
