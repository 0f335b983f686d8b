//! The flight budget: test vectors for the firmware, the host's reference run of the same
//! core code, QEMU's report, the ELF's memory sizes, and the budget table.
//!
//! The firmware (`firmware/`) runs [`orbfix::flight_run::run`] under
//! `qemu-system-arm -machine mps2-an500 -icount shift=0` and prints a line report (format in
//! `firmware/src/main.rs`). [`parse_report`] reads it, [`elf_sizes`] reads the ELF,
//! [`host_results`] computes the same `RESULT` lines on the host, and [`Budget`] is the table
//! written to `docs/timing-budget.md` ([`Budget::markdown`]) and JSON.

pub mod vectors;

use anyhow::{bail, Context, Result};
use orbfix::flight_run::{status_code, FlightConfig, FlightOutputs, Stage};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

pub use vectors::Vectors;

/// Guest instructions per SysTick tick: QEMU `-icount shift=0` runs one instruction per
/// virtual nanosecond, and the mps2-an500 core clock feeding SysTick is 25 MHz (40 ns).
pub const INSTRUCTIONS_PER_TICK: u64 = 40;
/// Working-memory budget (stack + statics), bytes: the STACK + RAM regions of memory.x.
pub const RAM_BUDGET_BYTES: u64 = 256 * 1024;
/// Working-memory goal, bytes.
pub const RAM_GOAL_BYTES: u64 = 128 * 1024;
/// Instruction budget of the whole fix over 300 x 300 m.
pub const INSN_BUDGET: u64 = 300_000_000;
/// Instruction goal of the whole fix.
pub const INSN_GOAL: u64 = 100_000_000;

/// Address ranges of mps2-an500 as used by memory.x.
const FLASH: (u64, u64) = (0x0000_0000, 0x0040_0000);
const SRAM: (u64, u64) = (0x2000_0000, 0x2040_0000);
const PSRAM: (u64, u64) = (0x6000_0000, 0x6100_0000);

/// The `RESULT` lines (key, value) the firmware prints for `out`, in its order and format
/// (`f32` as exact bit patterns).
pub fn host_results(out: &FlightOutputs) -> Vec<(String, String)> {
    let l = &out.lut;
    let a = &out.apply;
    let f = &out.fix;
    let b = |v: f32| format!("0x{:08x}", v.to_bits());
    let st: Vec<String> = a
        .status
        .iter()
        .map(|s| status_code(*s).to_string())
        .collect();
    vec![
        (
            "lut".to_string(),
            format!(
                "{} {} {} {} {} {} {}",
                l.valid_cells,
                l.blended_cells,
                l.dropped_taps,
                l.cells_per_view[0],
                l.cells_per_view[1],
                l.cells_per_view[2],
                l.cells_per_view[3]
            ),
        ),
        (
            "apply".to_string(),
            format!("{} {} {}", st.join(" "), a.valid_cells, a.lost_cells),
        ),
        ("top_hash".to_string(), format!("0x{:08x}", out.top_hash)),
        ("mask_hash".to_string(), format!("0x{:08x}", out.mask_hash)),
        (
            "response".to_string(),
            format!("0x{:08x} {}", out.response_hash, out.response_len),
        ),
        (
            "candidates".to_string(),
            format!("0x{:08x} {}", out.candidates_hash, f.candidates),
        ),
        (
            "fix".to_string(),
            format!(
                "{} {} {} {} {} {} {}",
                b(f.x_m),
                b(f.y_m),
                b(f.score),
                b(f.confidence),
                b(f.peak_score),
                b(f.second_score),
                f.on_border as u8
            ),
        ),
        (
            "ops".to_string(),
            format!(
                "{} {} {}",
                out.ops.macs, out.ops.windows, out.ops.downsample_px
            ),
        ),
        (
            "nn".to_string(),
            format!(
                "0x{:08x} 0x{:08x} {} {} {}",
                out.embedding_hash,
                out.nn_scores_hash,
                out.nn_windows,
                out.nn_best.0,
                out.nn_best.1
            ),
        ),
        ("digest".to_string(), format!("0x{:08x}", out.digest())),
    ]
}

/// What the firmware reported.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FirmwareReport {
    /// SysTick ticks per stage, in report order.
    pub stages: Vec<(String, u64)>,
    /// SysTick ticks of the whole fix (all stages and the glue between them).
    pub total_ticks: u64,
    /// `RESULT` lines, in order.
    pub results: Vec<(String, String)>,
    /// Deepest stack use, bytes.
    pub stack_peak_bytes: u64,
    /// Size of the stack region, bytes.
    pub stack_region_bytes: u64,
    /// `END OK` seen.
    pub ok: bool,
    /// `END ERR ...` texts.
    pub errors: Vec<String>,
}

/// Parses the firmware's semihosting output. Lines that are not part of the report (QEMU
/// messages) are ignored; a report without its header or its `END` line is an error.
pub fn parse_report(text: &str) -> Result<FirmwareReport> {
    let mut r = FirmwareReport::default();
    let mut header = false;
    let mut end = false;
    let num = |s: Option<&str>, line: &str| -> Result<u64> {
        s.context("missing number")
            .and_then(|v| v.parse::<u64>().context("not a number"))
            .with_context(|| format!("bad firmware report line {line:?}"))
    };
    for line in text.lines().map(str::trim) {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("ORBFIX-FW") => {
                if it.next() != Some("1") {
                    bail!("firmware report version is not 1 ({line:?}); rebuild the firmware and host tools from the same tree");
                }
                header = true;
            }
            Some("STAGE") => {
                let name = it.next().context("STAGE line without a name")?.to_string();
                r.stages.push((name, num(it.next(), line)?));
            }
            Some("TOTAL") => r.total_ticks = num(it.next(), line)?,
            Some("RESULT") => {
                let key = it.next().context("RESULT line without a key")?.to_string();
                let value = it.collect::<Vec<_>>().join(" ");
                r.results.push((key, value));
            }
            Some("STACK") => {
                r.stack_peak_bytes = num(it.next(), line)?;
                r.stack_region_bytes = num(it.next(), line)?;
            }
            Some("END") => {
                end = true;
                match it.next() {
                    Some("OK") => r.ok = true,
                    _ => r.errors.push(it.collect::<Vec<_>>().join(" ")),
                }
            }
            _ => {}
        }
    }
    if !header {
        bail!("no firmware report in QEMU's output (no 'ORBFIX-FW' line); output was:\n{text}");
    }
    if !end {
        bail!("the firmware report has no END line (did QEMU time out or the firmware fault?); output was:\n{text}");
    }
    Ok(r)
}

/// Memory sizes read from the firmware ELF.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ElfSizes {
    /// Bytes stored in flash: code, read-only data, the initial values of `.data`.
    pub flash_bytes: u64,
    /// Static working memory in SRAM: `.data`, `.bss`, `.uninit`.
    pub static_ram_bytes: u64,
    /// Inputs in external memory (`.psram`: frames and map), not working memory.
    pub external_input_bytes: u64,
    /// Working tables in external memory (`.xscratch`: the reprojection table).
    pub external_scratch_bytes: u64,
    /// Size of the stack region (memory.x STACK), bytes.
    pub stack_region_bytes: u64,
}

/// Reads flash, static RAM and external-memory sizes from an ELF (by load segments and
/// allocated sections, classified by the mps2-an500 address map).
pub fn elf_sizes(data: &[u8]) -> Result<ElfSizes> {
    use object::read::elf::{ElfFile32, ProgramHeader};
    use object::{Endianness, Object, ObjectSection, ObjectSymbol, SectionFlags};
    let file = ElfFile32::<Endianness>::parse(data)
        .context("the firmware file is not a valid 32-bit ELF")?;
    let e = file.endian();
    let inside = |a: u64, r: (u64, u64)| a >= r.0 && a < r.1;
    let mut s = ElfSizes::default();
    for ph in file.elf_program_headers() {
        // The load (physical) address decides where the bytes are stored.
        if ph.p_type(e) == object::elf::PT_LOAD && inside(ph.p_paddr(e) as u64, FLASH) {
            s.flash_bytes += ph.p_filesz(e) as u64;
        }
    }
    for sec in file.sections() {
        let alloc = match sec.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !alloc || sec.size() == 0 {
            continue;
        }
        if inside(sec.address(), SRAM) {
            s.static_ram_bytes += sec.size();
        } else if inside(sec.address(), PSRAM) {
            if sec.name().is_ok_and(|n| n.starts_with(".xscratch")) {
                s.external_scratch_bytes += sec.size();
            } else {
                s.external_input_bytes += sec.size();
            }
        }
    }
    let sym = |name: &str| {
        file.symbols()
            .find(|x| x.name() == Ok(name))
            .map(|x| x.address())
    };
    if let (Some(top), Some(bottom)) = (sym("_stack_start"), sym("_stack_end")) {
        s.stack_region_bytes = top.saturating_sub(bottom);
    }
    if s.flash_bytes == 0 {
        bail!("the ELF has nothing to load into flash (0x0..0x400000): is it the orbfix firmware for mps2-an500?");
    }
    Ok(s)
}

/// Whether a symbol name is one of core's panic entry points (or the panic handler).
fn is_panic_symbol(name: &str) -> bool {
    // `_fail` covers core's `*_fail` / `*_failed` helpers (slice index, copy length,
    // unwrap, expect) that lead to the panic handler.
    ["panic", "_fail"].iter().any(|k| name.contains(k))
}

/// Target of a 32-bit Thumb-2 `BL` (T1) or `B.W` (T4) at `addr` made of halfwords `h1`,
/// `h2`, or `None` if they are not one.
pub fn thumb_branch_target(addr: u64, h1: u16, h2: u16) -> Option<u64> {
    let (h1, h2) = (h1 as u32, h2 as u32);
    // BL: 11110 S imm10 | 11 J1 1 J2 imm11; B.W: 11110 S imm10 | 10 J1 1 J2 imm11.
    if h1 >> 11 != 0b11110 || h2 >> 15 != 1 || (h2 >> 12) & 1 != 1 {
        return None;
    }
    let s = (h1 >> 10) & 1;
    let (j1, j2) = ((h2 >> 13) & 1, (h2 >> 11) & 1);
    let (i1, i2) = (!(j1 ^ s) & 1, !(j2 ^ s) & 1);
    let imm = (s << 24) | (i1 << 23) | (i2 << 22) | ((h1 & 0x3FF) << 12) | ((h2 & 0x7FF) << 1);
    let off = ((imm << 7) as i32) >> 7; // sign-extend 25 bits
    Some((addr as i64 + 4 + off as i64) as u64)
}

/// Call sites of panic entry points in a Thumb-2 ELF: `(caller, callee, calls)`, demangled,
/// callers that are themselves panic functions left out. Found by decoding every 32-bit
/// `BL` / `B.W` in executable sections and matching its target against panic symbols, so
/// it works on the linked firmware without a disassembler.
pub fn panic_sites(data: &[u8]) -> Result<Vec<(String, String, usize)>> {
    use object::{Object, ObjectSection, ObjectSymbol, SectionKind, SymbolKind};
    let file = object::File::parse(data).context("the firmware file is not a valid ELF")?;
    // Function symbols: (start, end, demangled name); Thumb addresses have bit 0 set.
    let mut funcs: Vec<(u64, u64, String)> = file
        .symbols()
        .filter(|s| s.kind() == SymbolKind::Text)
        .filter_map(|s| {
            let name = s.name().ok()?;
            let start = s.address() & !1;
            Some((
                start,
                start + s.size().max(2),
                format!("{:#}", rustc_demangle::demangle(name)),
            ))
        })
        .collect();
    funcs.sort();
    let panics: std::collections::HashSet<u64> = funcs
        .iter()
        .filter(|f| is_panic_symbol(&f.2))
        .map(|f| f.0)
        .collect();
    let name_at = |addr: u64| -> Option<&(u64, u64, String)> {
        let i = funcs.partition_point(|f| f.0 <= addr);
        funcs.get(i.checked_sub(1)?).filter(|f| addr < f.1)
    };
    let mut sites: BTreeMap<(String, String), usize> = BTreeMap::new();
    for sec in file.sections().filter(|s| s.kind() == SectionKind::Text) {
        let bytes = sec
            .data()
            .context("cannot read a code section of the firmware")?;
        let base = sec.address();
        let hw = |i: usize| -> Option<u32> {
            Some(u16::from_le_bytes([*bytes.get(i)?, *bytes.get(i + 1)?]) as u32)
        };
        let mut i = 0;
        while i + 4 <= bytes.len() {
            let (Some(h1), Some(h2)) = (hw(i), hw(i + 2)) else {
                break;
            };
            if let Some(target) = thumb_branch_target(base + i as u64, h1 as u16, h2 as u16) {
                if panics.contains(&target) {
                    let caller = name_at(base + i as u64)
                        .map(|f| f.2.clone())
                        .unwrap_or_else(|| "?".into());
                    if !is_panic_symbol(&caller) {
                        let callee = name_at(target)
                            .map(|f| f.2.clone())
                            .unwrap_or_else(|| "?".into());
                        *sites.entry((caller, callee)).or_default() += 1;
                    }
                }
            }
            i += 2;
        }
    }
    Ok(sites.into_iter().map(|((a, b), n)| (a, b, n)).collect())
}

/// One stage of the budget table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageBudget {
    /// Guest instructions (SysTick ticks x 40; resolution 40 instructions).
    pub instructions: u64,
    /// Estimated milliseconds at the stated clock and CPI.
    pub ms: f64,
    /// Work items of the stage (pixels, cameras, MACs), if it has a natural unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<u64>,
    /// What one work item is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// Instructions per work item.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instructions_per_unit: Option<f64>,
}

/// The flight budget (written as JSON and as docs/timing-budget.md).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Budget {
    /// Target name (`cortex-m7`).
    pub target: String,
    /// Clock assumed for the ms estimates, MHz.
    pub clock_mhz: f64,
    /// Cycles per instruction assumed for the ms estimates.
    pub cpi: f64,
    /// Per-stage instructions and ms.
    pub stages: BTreeMap<String, StageBudget>,
    /// Stage names in run order.
    pub stage_order: Vec<String>,
    /// Instructions of the whole fix.
    pub total_instructions: u64,
    /// Estimated ms of the whole fix.
    pub total_ms: f64,
    /// Static working memory (`.data` + `.bss` + `.uninit`), bytes.
    pub static_ram_bytes: u64,
    /// Deepest stack use (stack painting), bytes.
    pub stack_peak_bytes: u64,
    /// Static RAM + stack peak, bytes.
    pub working_ram_bytes: u64,
    /// Stack region reserved by memory.x, bytes.
    pub stack_region_bytes: u64,
    /// Working-memory budget, bytes (memory.x STACK + RAM).
    pub ram_budget_bytes: u64,
    /// Flash image, bytes.
    pub flash_bytes: u64,
    /// Inputs in external memory (frames, map), bytes; not working memory.
    pub external_input_bytes: u64,
    /// The firmware's results equal the host's run of the same core on the same inputs.
    pub bit_exact: bool,
    /// Keys whose values differed (empty when bit exact).
    pub mismatches: Vec<String>,
    /// The firmware ended with `END OK`.
    pub firmware_ok: bool,
    /// No panic path remains: the firmware linked with the undefined-symbol panic handler.
    pub panic_free: bool,
    /// Where panic paths remain (`caller -> panic function (calls)`), when not panic free.
    pub panic_sites: Vec<String>,
    /// Reprojection table and other working tables placed in external memory because they
    /// do not fit the SRAM budget, bytes (counted in `working_total_bytes`).
    pub external_scratch_bytes: u64,
    /// Static RAM + stack peak + external scratch: all working memory, bytes.
    pub working_total_bytes: u64,
    /// The fix the firmware computed: east, north (metres), its distance to the true
    /// position (metres) and its confidence.
    pub fix: FixReport,
    /// What the test vectors were.
    pub vectors: String,
    /// Guest instructions per SysTick tick.
    pub instructions_per_tick: u64,
    /// `nn_match` on the dense 4 m CNN grid (3969 windows over 300 m): measured when this
    /// run's map windows were that grid, otherwise projected from the measured per-window
    /// rate. `None` when the map is smaller than a window.
    pub nn_match_dense: Option<DenseNnMatch>,
}

/// `nn_match` on the dense 4 m grid of map windows (the CNN localization's grid).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DenseNnMatch {
    /// Windows of the dense grid over this run's map.
    pub windows: u64,
    /// Grid step, metres.
    pub step_m: f64,
    /// `true`: this run scored the dense grid on the target (numbers measured); `false`:
    /// projected as `instructions_per_window` (measured on this run's windows) x `windows`.
    pub measured: bool,
    /// Windows this run scored on the target.
    pub measured_windows: u64,
    /// Instructions per window of this run's `nn_match` (measured).
    pub instructions_per_window: f64,
    /// `nn_match` instructions on the dense grid (measured or projected).
    pub instructions: u64,
    /// Estimated milliseconds of those.
    pub ms: f64,
    /// The whole fix with `nn_match` on the dense grid (measured, or this run's total with
    /// its `nn_match` replaced by the projection).
    pub whole_fix_instructions: u64,
    /// Estimated milliseconds of the whole fix with the dense grid.
    pub whole_fix_ms: f64,
}

/// `nn_match` on the dense grid for this run (see [`DenseNnMatch`]).
fn dense_nn_match(
    est: &Estimate,
    cfg: &FlightConfig,
    v: &Vectors,
    nn_match_insn: u64,
    measured_windows: u64,
    total_insn: u64,
) -> Option<DenseNnMatch> {
    let step = orbfix::flight_run::dense_window_step(cfg.grid.m_per_px);
    let (cols, rows) =
        orbfix::flight_run::map_window_grid_step(cfg.grid.n, step, v.map_w, v.map_h)?;
    let windows = (cols * rows) as u64;
    let per_window = nn_match_insn as f64 / measured_windows.max(1) as f64;
    let measured = v.window_step_px == step && measured_windows == windows;
    let instructions = if measured {
        nn_match_insn
    } else {
        (per_window * windows as f64).round() as u64
    };
    let whole = total_insn - nn_match_insn.min(total_insn) + instructions;
    Some(DenseNnMatch {
        windows,
        step_m: step as f64 * cfg.grid.m_per_px as f64,
        measured,
        measured_windows,
        instructions_per_window: per_window,
        instructions,
        ms: est.ms(instructions),
        whole_fix_instructions: whole,
        whole_fix_ms: est.ms(whole),
    })
}

/// The fix of the budget run, for the record (the budget is about cost, not accuracy).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FixReport {
    /// Rover east, metres.
    pub x_m: f32,
    /// Rover north, metres.
    pub y_m: f32,
    /// Distance to the position the frames were rendered at, metres.
    pub error_m: f32,
    /// Distance of the prior from the true position, metres.
    pub prior_error_m: f32,
    /// Confidence, `[0, 1]`.
    pub confidence: f32,
    /// Peak on the search border (a failure).
    pub on_border: bool,
    /// CNN: best-scoring map window (row-major index over this run's window grid).
    pub nn_best_window: u32,
    /// CNN: the window nearest the true position.
    pub nn_true_window: u32,
    /// CNN: windows scored.
    pub nn_windows: u32,
}

/// Row-major index of the map window whose centre is nearest the true position.
fn true_window(cfg: &FlightConfig, v: &Vectors) -> u32 {
    let n = cfg.grid.n;
    let step = v.window_step_px;
    let Some((cols, rows)) = orbfix::flight_run::map_window_grid_step(n, step, v.map_w, v.map_h)
    else {
        return u32::MAX;
    };
    let (c, r) = v.map_geo.to_pixel(v.truth_m.0, v.truth_m.1);
    let pick = |p: f32, k: usize| {
        (((p - n as f32 / 2.0) / step as f32).round().max(0.0) as usize).min(k - 1)
    };
    (pick(r, rows) * cols + pick(c, cols)) as u32
}

/// Settings of the time estimates.
#[derive(Clone, Debug)]
pub struct Estimate {
    /// Target name.
    pub target: String,
    /// Clock, MHz.
    pub clock_mhz: f64,
    /// Cycles per instruction.
    pub cpi: f64,
}

impl Estimate {
    /// Milliseconds for `insn` instructions.
    pub fn ms(&self, insn: u64) -> f64 {
        insn as f64 * self.cpi / (self.clock_mhz * 1e3)
    }
}

/// Work units of a stage for per-unit rates: grid cells for the table, output pixels for
/// the reprojection, multiply-accumulates (as the matcher counts them) for localization.
pub fn stage_units(
    stage: &str,
    cfg: &FlightConfig,
    out: &FlightOutputs,
) -> Option<(u64, &'static str)> {
    let s = Stage::ALL.into_iter().find(|s| s.name() == stage)?;
    let cells = cfg.grid.cells() as u64;
    match s {
        Stage::LutBuild => Some((cells, "grid cell")),
        Stage::Reproject => Some((cells, "output pixel")),
        Stage::Localize => Some((out.ops.macs, "MAC")),
        Stage::NnEmbed => Some((orbfix::nn::model::embedding_macs(), "MAC")),
        Stage::NnMatch => Some((
            out.nn_windows as u64 * orbfix::nn::model::EMBED_LEN as u64,
            "embedding element",
        )),
    }
}

/// Puts the budget together and compares results with the host's.
pub fn assemble(
    est: &Estimate,
    report: &FirmwareReport,
    sizes: &ElfSizes,
    cfg: &FlightConfig,
    host: &FlightOutputs,
    v: &Vectors,
    panic_sites: &[(String, String, usize)],
) -> Budget {
    let expected = host_results(host);
    let mut stages = BTreeMap::new();
    let mut order = Vec::new();
    for (name, ticks) in &report.stages {
        let insn = ticks * INSTRUCTIONS_PER_TICK;
        let units = stage_units(name, cfg, host);
        stages.insert(
            name.clone(),
            StageBudget {
                instructions: insn,
                ms: est.ms(insn),
                units: units.map(|u| u.0),
                unit: units.map(|u| u.1.to_string()),
                instructions_per_unit: units.map(|u| insn as f64 / u.0.max(1) as f64),
            },
        );
        order.push(name.clone());
    }
    let mut mismatches = Vec::new();
    for (k, want) in &expected {
        let got = report
            .results
            .iter()
            .find(|(rk, _)| rk == k)
            .map(|(_, v)| v);
        if got != Some(want) {
            mismatches.push(k.clone());
        }
    }
    for (k, _) in &report.results {
        if !expected.iter().any(|(ek, _)| ek == k) {
            mismatches.push(k.clone());
        }
    }
    let total = report.total_ticks * INSTRUCTIONS_PER_TICK;
    let stack_region = if sizes.stack_region_bytes > 0 {
        sizes.stack_region_bytes
    } else {
        report.stack_region_bytes
    };
    let nn_match_dense = stages
        .get(Stage::NnMatch.name())
        .and_then(|s| dense_nn_match(est, cfg, v, s.instructions, host.nn_windows as u64, total));
    Budget {
        target: est.target.clone(),
        clock_mhz: est.clock_mhz,
        cpi: est.cpi,
        stages,
        stage_order: order,
        total_instructions: total,
        total_ms: est.ms(total),
        static_ram_bytes: sizes.static_ram_bytes,
        stack_peak_bytes: report.stack_peak_bytes,
        working_ram_bytes: sizes.static_ram_bytes + report.stack_peak_bytes,
        stack_region_bytes: stack_region,
        ram_budget_bytes: RAM_BUDGET_BYTES,
        flash_bytes: sizes.flash_bytes,
        external_input_bytes: sizes.external_input_bytes,
        external_scratch_bytes: sizes.external_scratch_bytes,
        working_total_bytes: sizes.static_ram_bytes
            + report.stack_peak_bytes
            + sizes.external_scratch_bytes,
        panic_free: panic_sites.is_empty(),
        panic_sites: panic_sites
            .iter()
            .map(|(a, b, n)| format!("{a} -> {b} ({n})"))
            .collect(),
        fix: {
            let d = |x: f32, y: f32| (x - v.truth_m.0).hypot(y - v.truth_m.1);
            FixReport {
                x_m: host.fix.x_m,
                y_m: host.fix.y_m,
                error_m: d(host.fix.x_m, host.fix.y_m),
                prior_error_m: d(v.pose.x_m, v.pose.y_m),
                confidence: host.fix.confidence,
                on_border: host.fix.on_border,
                nn_best_window: host.nn_best.0,
                nn_true_window: true_window(cfg, v),
                nn_windows: host.nn_windows,
            }
        },
        bit_exact: report.ok && mismatches.is_empty() && !expected.is_empty(),
        mismatches,
        firmware_ok: report.ok,
        vectors: v.describe(),
        instructions_per_tick: INSTRUCTIONS_PER_TICK,
        nn_match_dense,
    }
}

fn kib(b: u64) -> String {
    format!("{:.1} KiB", b as f64 / 1024.0)
}

fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

impl Budget {
    /// The budget as the Markdown page docs/timing-budget.md.
    pub fn markdown(&self, command: &str) -> String {
        let mut m = String::new();
        m.push_str("# Flight timing and memory budget\n\n");
        m.push_str("Generated by `orbfix budget`; do not edit by hand. Regenerate with:\n\n");
        m.push_str(&format!("    {command}\n\n"));
        m.push_str(&format!(
            "Target: **{}** (QEMU `mps2-an500`, `-icount shift=0`). Estimates at **{} MHz** and \
             a CPI of **{}** cycles per instruction (QEMU counts instructions, not cycles; see \
             docs/flight-target.md). Test vectors: {}.\n\n",
            self.target, self.clock_mhz, self.cpi, self.vectors
        ));
        m.push_str("## Time\n\n");
        m.push_str("| stage | instructions | ms | work | instructions / unit |\n");
        m.push_str("|---|---:|---:|---|---:|\n");
        for name in &self.stage_order {
            if let Some(s) = self.stages.get(name) {
                let (work, per) = match (&s.units, &s.unit, s.instructions_per_unit) {
                    (Some(u), Some(unit), Some(p)) => {
                        (format!("{} x {unit}", thousands(*u)), format!("{p:.2}"))
                    }
                    _ => (String::new(), String::new()),
                };
                m.push_str(&format!(
                    "| {name} | {} | {:.3} | {work} | {per} |\n",
                    thousands(s.instructions),
                    s.ms
                ));
            }
        }
        m.push_str(&format!(
            "| **whole fix** | **{}** | **{:.3}** | | |\n\n",
            thousands(self.total_instructions),
            self.total_ms
        ));
        let verdict = |v: u64, budget: u64, goal: u64| {
            if v <= goal {
                "within the goal"
            } else if v <= budget {
                "within the budget, over the goal"
            } else {
                "OVER BUDGET"
            }
        };
        m.push_str(&format!(
            "Whole fix: {} instructions against a budget of {} (goal {}): {}. Stage counts come \
             from SysTick at {} instructions per tick, so each is exact to +-{} instructions.\n\n",
            thousands(self.total_instructions),
            thousands(INSN_BUDGET),
            thousands(INSN_GOAL),
            verdict(self.total_instructions, INSN_BUDGET, INSN_GOAL),
            self.instructions_per_tick,
            self.instructions_per_tick
        ));
        if let Some(d) = &self.nn_match_dense {
            m.push_str(&format!(
                "### CNN matching on the dense {} m grid\n\n",
                d.step_m
            ));
            m.push_str("| | windows | instructions | ms | instructions / window |\n");
            m.push_str("|---|---:|---:|---:|---:|\n");
            if d.measured {
                m.push_str(&format!(
                    "| `nn_match`, dense {} m grid (**measured** above) | {} | {} | {:.3} | {:.1} |\n",
                    d.step_m,
                    thousands(d.windows),
                    thousands(d.instructions),
                    d.ms,
                    d.instructions_per_window
                ));
            } else if let Some(s) = self.stages.get("nn_match") {
                m.push_str(&format!(
                    "| `nn_match` as measured above | {} | {} | {:.3} | {:.1} |\n",
                    thousands(d.measured_windows),
                    thousands(s.instructions),
                    s.ms,
                    d.instructions_per_window
                ));
            }
            if !d.measured {
                m.push_str(&format!(
                    "| `nn_match`, dense {} m grid, **projected** (measured rate x {} windows) | {} | {} | {:.3} | {:.1} |\n",
                    d.step_m,
                    thousands(d.windows),
                    thousands(d.windows),
                    thousands(d.instructions),
                    d.ms,
                    d.instructions_per_window
                ));
            }
            m.push_str(&format!(
                "| **whole fix** with `nn_match` on the dense grid ({}) | | **{}** | **{:.3}** | |\n\n",
                if d.measured { "measured" } else { "projected" },
                thousands(d.whole_fix_instructions),
                d.whole_fix_ms
            ));
            m.push_str(&format!(
                "The CNN localization scores map windows every {} m ({} windows over this map) \
                 and ranks the study's windows by the best score in their cell. {}\n\n",
                d.step_m,
                thousands(d.windows),
                if d.measured {
                    "This run's firmware scored that grid itself (`orbfix budget --cnn-grid \
                     dense`, the default)."
                } else {
                    "This run's firmware scored the study's grid; the dense line is the measured \
                     instructions per window times the dense grid's windows (the per-window work \
                     does not depend on the window count; `orbfix budget --cnn-grid dense`, \
                     the default, measures it on the target)."
                }
            ));
        }
        m.push_str(
            "Per-unit rates: `lut_build` per top-down grid cell, `reproject` per output pixel, \
             `localize` per MAC as the matcher counts them (NCC correlation sums, downsampling \
             included in the instructions). For scale, int8 network kernels on a Cortex-M7 \
             (STM32H743, public figures) take about 4 cycles per MAC with CMSIS-NN and 2.2 with \
             TinyEngine.\n\n",
        );
        m.push_str("## Memory\n\n");
        m.push_str("| what | bytes | |\n|---|---:|---|\n");
        m.push_str(&format!(
            "| static RAM (.data + .bss + .uninit) | {} | {} |\n",
            thousands(self.static_ram_bytes),
            kib(self.static_ram_bytes)
        ));
        m.push_str(&format!(
            "| stack peak (painted, of a {} region) | {} | {} |\n",
            kib(self.stack_region_bytes),
            thousands(self.stack_peak_bytes),
            kib(self.stack_peak_bytes)
        ));
        m.push_str(&format!(
            "| **working RAM** (static + stack peak) | **{}** | **{}**: {} (budget {}, goal {}) |\n",
            thousands(self.working_ram_bytes),
            kib(self.working_ram_bytes),
            verdict(self.working_ram_bytes, RAM_BUDGET_BYTES, RAM_GOAL_BYTES),
            kib(RAM_BUDGET_BYTES),
            kib(RAM_GOAL_BYTES)
        ));
        m.push_str(&format!(
            "| external scratch (`.xscratch`, PSRAM) | {} | {}{} |\n",
            thousands(self.external_scratch_bytes),
            kib(self.external_scratch_bytes),
            if self.external_scratch_bytes == 0 {
                ": none, all working memory is in SRAM"
            } else {
                ": working memory outside the SRAM budget"
            }
        ));
        m.push_str(&format!(
            "| **all working memory** (SRAM + external scratch) | **{}** | **{}**: {} |\n",
            thousands(self.working_total_bytes),
            kib(self.working_total_bytes),
            verdict(self.working_total_bytes, RAM_BUDGET_BYTES, RAM_GOAL_BYTES)
        ));
        m.push_str(&format!(
            "| flash (code + constants + .data image) | {} | {} |\n",
            thousands(self.flash_bytes),
            kib(self.flash_bytes)
        ));
        m.push_str(&format!(
            "| external inputs (frames, map, CNN map-window records; PSRAM) | {} | {}, not working memory |\n\n",
            thousands(self.external_input_bytes),
            kib(self.external_input_bytes)
        ));
        m.push_str(
            "No heap: the firmware has no allocator. The link fails if static RAM does not fit \
             in memory.x's RAM region (budget minus the stack region). The reprojection table \
             (8 bytes per grid cell plus overlap taps) is built and applied in bands of grid \
             rows (`flight_run::LUT_BAND_ROWS`) inside the localizer's scratch, which the \
             localizer only needs afterwards, so it adds nothing to static RAM. Anything placed \
             in `.xscratch` (external memory) would be working memory all the same and is \
             counted in the total.\n\n",
        );
        m.push_str("## No panics\n\n");
        if self.panic_free {
            m.push_str(
                "`panic_free: true`: the firmware links with a panic handler that calls an \
                 undefined symbol, so no panic path remains in anything it runs.\n\n",
            );
        } else {
            m.push_str(
                "`panic_free: false`: the firmware does **not** link with the no-panic panic \
                 handler; these numbers come from the `allow-panic` build (same code, a panic \
                 handler that reports and exits). Panic call sites in the linked firmware \
                 (caller -> panic function (sites)):\n\n",
            );
            for s in &self.panic_sites {
                m.push_str(&format!("- `{s}`\n"));
            }
            m.push('\n');
        }
        m.push_str("## Fix of this run\n\n");
        m.push_str(&format!(
            "Fix at ({:.3}, {:.3}) m, {:.3} m from the true position (prior {:.3} m off), \
             confidence {:.3}{}.\n\n",
            self.fix.x_m,
            self.fix.y_m,
            self.fix.error_m,
            self.fix.prior_error_m,
            self.fix.confidence,
            if self.fix.on_border {
                ", peak ON THE BORDER (failure)"
            } else {
                ""
            }
        ));
        m.push_str(&format!(
            "CNN window ranking: best window {} of {}, window nearest the truth {}. \
             These synthetic value-noise vectors are for measuring cost; this ranking is not \
             a measurement of the network's accuracy.\n\n",
            self.fix.nn_best_window, self.fix.nn_windows, self.fix.nn_true_window
        ));
        m.push_str("## Bit-exactness\n\n");
        if self.bit_exact {
            m.push_str(
                "`bit_exact: true`: every result the firmware reported (table statistics, \
                 top-down image and mask hashes, coarse response hash, candidates, fix and \
                 scores as `f32` bit patterns, operation counts, digest) equals the host's run \
                 of the same core code on the same inputs.\n",
            );
        } else {
            m.push_str(&format!(
                "`bit_exact: false`: firmware ok = {}, mismatching results: {:?}.\n",
                self.firmware_ok, self.mismatches
            ));
        }
        m
    }
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create folder {}", dir.display()))?;
    let name = path.file_name().context("output path has no file name")?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("cannot move {} to {}", tmp.display(), path.display()))?;
    Ok(())
}
