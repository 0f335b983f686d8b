//! The budget table: per-stage instructions of every stop, memory from the ELF, the fix
//! error against the truth, bit-exactness, as JSON and as docs/timing-budget.md.

use super::elf::ElfSizes;
use super::report::FirmwareReport;
use super::{INSN_BUDGET, INSN_GOAL, INSTRUCTIONS_PER_TICK, RAM_BUDGET_BYTES, RAM_GOAL_BYTES};
use orbfix::fix::{FixReport, Stage};
use serde::Serialize;
use std::collections::BTreeMap;

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

/// One stage of the budget table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageBudget {
    /// Guest instructions (SysTick ticks x 40; resolution 40 instructions).
    pub instructions: u64,
    /// Estimated milliseconds at the stated clock and CPI.
    pub ms: f64,
    /// Work items of the stage (pixels, cells, MACs), if it has a natural unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<u64>,
    /// What one work item is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// Instructions per work item.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instructions_per_unit: Option<f64>,
    /// Stage `stereo`: working-size pixels matched (four views, rows below the horizon).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pixels: Option<u64>,
    /// Stage `stereo`: instructions per pixel matched.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instructions_per_pixel: Option<f64>,
}

/// One measured stop.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StopBudget {
    /// What the stop was.
    pub description: String,
    /// Instructions of the whole fix on this stop.
    pub instructions: u64,
    /// Per-stage instructions (and units) on this stop.
    pub stages: BTreeMap<String, StageBudget>,
    /// Fix error against the truth, metres.
    pub error_m: f64,
    /// Prior error, metres.
    pub prior_error_m: f64,
    /// The fix's status and path.
    pub status: String,
    /// Which stage produced the fix.
    pub path: String,
    /// Confidence.
    pub confidence: f32,
    /// The firmware's results equal the host's.
    pub bit_exact: bool,
    /// Keys that differed.
    pub mismatches: Vec<String>,
    /// Deepest stack use, bytes.
    pub stack_peak_bytes: u64,
    /// The filter's per-stop work on this stop's fix, if measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fusion: Option<FusionBudget>,
    /// The heading search on this stop, if measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heading_search: Option<HeadingBudget>,
}

/// The fusion filter's work at one stop on the target ([`orbfix::fix::protocol::fusion_stop`]:
/// prediction over an odometry leg, the next search radius, the fix's update).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FusionBudget {
    /// Guest instructions (SysTick ticks x 40; resolution 40 instructions).
    pub instructions: u64,
    /// Estimated milliseconds at the stated clock and CPI.
    pub ms: f64,
    /// Length of the odometry leg predicted over, metres.
    pub leg_m: f64,
    /// The update folded the fix in (gain and Joseph update; else the refusal path).
    pub accepted: bool,
    /// Squared Mahalanobis distance of the fix's innovation.
    pub mahalanobis2: f64,
    /// Search radius after the update, metres.
    pub search_radius_m: f64,
    /// Every reported filter value equals the host's run of the same code.
    pub bit_exact: bool,
    /// Keys that differed.
    pub mismatches: Vec<String>,
}

/// The heading search on the target ([`orbfix::fix::run_heading_search`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeadingBudget {
    /// Headings tried.
    pub headings: u64,
    /// Step between headings, degrees.
    pub step_deg: f64,
    /// Heading sigma the search was sized for (`HeadingSearch::for_sigma`), degrees.
    pub sigma_deg: f64,
    /// Guest instructions of the whole search (SysTick ticks x 40).
    pub instructions: u64,
    /// Estimated milliseconds at the stated clock and CPI.
    pub ms: f64,
    /// Instructions per heading tried.
    pub instructions_per_heading: f64,
    /// Error of the heading estimate given to the search, degrees.
    pub estimate_error_deg: f64,
    /// Error of the heading the search reported, degrees.
    pub heading_error_deg: f64,
    /// Position error of the search's fix, metres.
    pub error_m: f64,
    /// Status of the search's fix.
    pub status: String,
    /// Every reported value (position, heading, scores, status) equals the host's run.
    pub bit_exact: bool,
    /// Keys that differed.
    pub mismatches: Vec<String>,
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
    /// Per-stage instructions and ms: the largest over the stops.
    pub stages: BTreeMap<String, StageBudget>,
    /// Stage names in run order.
    pub stage_order: Vec<String>,
    /// Instructions of the whole fix: the largest over the stops.
    pub total_instructions: u64,
    /// Estimated ms of that.
    pub total_ms: f64,
    /// Static working memory in SRAM (`.data` + `.bss` + `.uninit`), bytes.
    pub static_ram_bytes: u64,
    /// Deepest stack use over the stops, bytes.
    pub stack_peak_bytes: u64,
    /// Static RAM + stack peak, bytes.
    pub working_ram_bytes: u64,
    /// Stack region reserved by memory.x, bytes.
    pub stack_region_bytes: u64,
    /// Working-memory budget, bytes.
    pub ram_budget_bytes: u64,
    /// Flash image, bytes.
    pub flash_bytes: u64,
    /// Inputs in external memory (frames, depth, map product), bytes; not working memory.
    pub external_input_bytes: u64,
    /// Working memory placed in external memory (`.xscratch`), bytes.
    pub external_scratch_bytes: u64,
    /// Static RAM + stack peak + external scratch: all working memory, bytes.
    pub working_total_bytes: u64,
    /// Every stop's results equal the host's run of the same core on the same inputs.
    pub bit_exact: bool,
    /// Keys whose values differed, per stop (empty when bit exact).
    pub mismatches: Vec<String>,
    /// Every stop's firmware ended with `END OK`.
    pub firmware_ok: bool,
    /// No panic path remains: the firmware linked with the undefined-symbol panic handler.
    pub panic_free: bool,
    /// Where panic paths remain, when not panic free.
    pub panic_sites: Vec<String>,
    /// `"world"`: the stops are rendered from the procedural world.
    pub vectors: String,
    /// The exact configuration of the core's fix that was measured.
    pub config: String,
    /// Depth source of the stops: `stereo` (the fix's own stereo stage on rendered pairs),
    /// `truth` (the renderer's exact depth images) or `none` (flat ground).
    pub depth: String,
    /// Bytes of the work area the stereo stage uses after the range accumulator
    /// (`orbfix::fix::stereo_work_words`; 0 without stereo).
    pub stereo_work_bytes: u64,
    /// Guest instructions per SysTick tick.
    pub instructions_per_tick: u64,
    /// The filter's per-stop work: the largest over the stops that measured it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fusion: Option<FusionBudget>,
    /// The heading search: the largest over the stops that ran it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heading_search: Option<HeadingBudget>,
    /// Every stop.
    pub stops: Vec<StopBudget>,
}

/// Work units of a stage for per-unit rates.
pub fn stage_units(stage: &str, r: &FixReport) -> Option<(u64, &'static str)> {
    let s = Stage::ALL.into_iter().find(|s| s.name() == stage)?;
    let o = &r.ops;
    match s {
        Stage::LutBuild => (o.lut_cells > 0).then_some((o.lut_cells, "grid cell")),
        Stage::Stereo => (o.stereo_pixel_disparities > 0)
            .then_some((o.stereo_pixel_disparities, "pixel-disparity evaluated")),
        Stage::Reproject => Some((
            o.reproject_px,
            if r.reprojection.range {
                "frame pixel read"
            } else {
                "output pixel"
            },
        )),
        Stage::NnEmbed => Some((o.embed_macs, "MAC")),
        Stage::NnMatch => Some((o.match_elements, "embedding element")),
        Stage::Relief => (o.relief_macs > 0).then_some((o.relief_macs, "MAC")),
        Stage::Refine => Some((o.refine_macs, "MAC or downsampled pixel")),
    }
}

/// One stop's measurements.
#[allow(clippy::too_many_arguments)]
pub fn stop_budget(
    est: &Estimate,
    description: String,
    report: &FirmwareReport,
    host: &FixReport,
    mismatches: Vec<String>,
    truth: (f64, f64),
    prior: (f64, f64),
) -> StopBudget {
    let mut stages = BTreeMap::new();
    for (name, ticks) in &report.stages {
        let insn = ticks * INSTRUCTIONS_PER_TICK;
        let units = stage_units(name, host);
        stages.insert(
            name.clone(),
            StageBudget {
                instructions: insn,
                ms: est.ms(insn),
                units: units.map(|u| u.0),
                unit: units.map(|u| u.1.to_string()),
                instructions_per_unit: units.map(|u| insn as f64 / u.0.max(1) as f64),
                pixels: (name == "stereo").then_some(host.ops.stereo_px),
                instructions_per_pixel: (name == "stereo")
                    .then(|| insn as f64 / host.ops.stereo_px.max(1) as f64),
            },
        );
    }
    let d = |x: f64, y: f64| (x - truth.0).hypot(y - truth.1);
    StopBudget {
        description,
        instructions: report.total_ticks * INSTRUCTIONS_PER_TICK,
        stages,
        error_m: d(host.x_m as f64, host.y_m as f64),
        prior_error_m: d(prior.0, prior.1),
        status: host.status.name().to_string(),
        path: host.path.name().to_string(),
        confidence: host.confidence,
        bit_exact: report.ok && mismatches.is_empty(),
        mismatches,
        stack_peak_bytes: report.stack_peak_bytes,
        fusion: None,
        heading_search: None,
    }
}

/// Puts the budget together from the stops.
pub fn assemble(
    est: &Estimate,
    stops: Vec<StopBudget>,
    sizes: &ElfSizes,
    firmware_ok: bool,
    panic_sites: &[(String, String, usize)],
    config: String,
) -> Budget {
    let order: Vec<String> = Stage::ALL.iter().map(|s| s.name().to_string()).collect();
    let mut stages: BTreeMap<String, StageBudget> = BTreeMap::new();
    for s in &stops {
        for (k, v) in &s.stages {
            let e = stages.entry(k.clone()).or_insert_with(|| v.clone());
            if v.instructions > e.instructions {
                *e = v.clone();
            }
        }
    }
    let total = stops.iter().map(|s| s.instructions).max().unwrap_or(0);
    let stack = stops.iter().map(|s| s.stack_peak_bytes).max().unwrap_or(0);
    let working = sizes.static_ram_bytes + stack;
    Budget {
        target: est.target.clone(),
        clock_mhz: est.clock_mhz,
        cpi: est.cpi,
        stages,
        stage_order: order,
        total_instructions: total,
        total_ms: est.ms(total),
        static_ram_bytes: sizes.static_ram_bytes,
        stack_peak_bytes: stack,
        working_ram_bytes: working,
        stack_region_bytes: sizes.stack_region_bytes,
        ram_budget_bytes: RAM_BUDGET_BYTES,
        flash_bytes: sizes.flash_bytes,
        external_input_bytes: sizes.external_input_bytes,
        external_scratch_bytes: sizes.external_scratch_bytes,
        working_total_bytes: working + sizes.external_scratch_bytes,
        bit_exact: !stops.is_empty()
            && stops.iter().all(|s| {
                s.bit_exact
                    && s.fusion.as_ref().is_none_or(|f| f.bit_exact)
                    && s.heading_search.as_ref().is_none_or(|h| h.bit_exact)
            }),
        mismatches: stops
            .iter()
            .enumerate()
            .flat_map(|(i, s)| {
                let fusion = s.fusion.iter().flat_map(|f| &f.mismatches);
                let heading = s.heading_search.iter().flat_map(|h| &h.mismatches);
                s.mismatches
                    .iter()
                    .map(move |m| format!("stop {i}: {m}"))
                    .chain(fusion.map(move |m| format!("stop {i}: fusion {m}")))
                    .chain(heading.map(move |m| format!("stop {i}: heading search {m}")))
            })
            .collect(),
        fusion: stops
            .iter()
            .filter_map(|s| s.fusion.clone())
            .max_by_key(|f| f.instructions),
        heading_search: stops
            .iter()
            .filter_map(|s| s.heading_search.clone())
            .max_by_key(|h| h.instructions),
        firmware_ok,
        panic_free: panic_sites.is_empty(),
        panic_sites: panic_sites
            .iter()
            .map(|(a, b, n)| format!("{a} -> {b} ({n})"))
            .collect(),
        vectors: "world".to_string(),
        config,
        depth: "truth".to_string(),
        stereo_work_bytes: 0,
        instructions_per_tick: INSTRUCTIONS_PER_TICK,
        stops,
    }
}

fn kib(b: u64) -> String {
    format!("{:.1} KiB", b as f64 / 1024.0)
}

/// `n` with thousands separators.
pub fn thousands(n: u64) -> String {
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

fn verdict(v: u64, budget: u64, goal: u64) -> &'static str {
    if v <= goal {
        "within the goal"
    } else if v <= budget {
        "within the budget, over the goal"
    } else {
        "OVER BUDGET"
    }
}

impl Budget {
    /// The section on the fusion filter and the heading search (nothing when neither ran).
    fn markdown_drive(&self, m: &mut String) {
        if self.fusion.is_none() && self.heading_search.is_none() {
            return;
        }
        m.push_str("## A stop of a drive: fusion filter and heading search\n\n");
        m.push_str("| what | stop | instructions | ms | detail | bit-exact |\n");
        m.push_str("|---|---:|---:|---:|---|---|\n");
        for (i, s) in self.stops.iter().enumerate() {
            if let Some(f) = &s.fusion {
                m.push_str(&format!(
                    "| fusion filter (predict over {:.0} m, search radius, update) | {i} | {} | {:.4} | {}, squared Mahalanobis {:.3}, next radius {:.1} m | {} |\n",
                    f.leg_m,
                    thousands(f.instructions),
                    f.ms,
                    if f.accepted { "fix accepted" } else { "fix refused" },
                    f.mahalanobis2,
                    f.search_radius_m,
                    f.bit_exact
                ));
            }
        }
        for (i, s) in self.stops.iter().enumerate() {
            if let Some(h) = &s.heading_search {
                m.push_str(&format!(
                    "| heading search ({} headings, step {} deg, sigma {} deg) | {i} | {} | {:.1} | {} per heading ({:.2} x this stop's fix); estimate {:+.2} deg off, found {:+.2} deg off; fix {:.3} m off, {} | {} |\n",
                    h.headings,
                    h.step_deg,
                    h.sigma_deg,
                    thousands(h.instructions),
                    h.ms,
                    thousands(h.instructions_per_heading.round() as u64),
                    h.instructions_per_heading / s.instructions.max(1) as f64,
                    h.estimate_error_deg,
                    h.heading_error_deg,
                    h.error_m,
                    h.status,
                    h.bit_exact
                ));
            }
        }
        m.push('\n');
        m.push_str(
            "Measured in the same firmware run, after the fix: the filter's work at one stop of \
             a drive as `orbfix traverse` does it (`orbfix::fix::protocol::fusion_stop`: the \
             prediction over the odometry leg, the search radius, the update of the stop's fix; \
             the traverse's default filter settings, the filter placed so that its prediction \
             lands 0.7 m from the truth, as a dead-reckoned prior does), and the heading search \
             `orbfix::fix::run_heading_search` on the same inputs and the fix's own scratch (no \
             static memory of its own; its stack is in the stack peak below), around a heading \
             estimate off by the stated amount. Both report their results in the result \
             protocol and are compared with the host's run of the same code.\n\n",
        );
    }

    /// The budget as the Markdown page docs/timing-budget.md.
    pub fn markdown(&self, command: &str) -> String {
        let mut m = String::new();
        m.push_str("# Flight timing and memory budget\n\n");
        m.push_str("Generated by `orbfix budget`; do not edit by hand. Regenerate with:\n\n");
        m.push_str(&format!("    {command}\n\n"));
        m.push_str(&format!(
            "Target: **{}** (QEMU `mps2-an500`, `-icount shift=0`). Estimates at **{} MHz** and \
             a CPI of **{}** cycles per instruction (QEMU counts instructions, not cycles; see \
             docs/flight-target.md). The firmware runs the core's one fix, `orbfix::fix::run`, \
             the same function `orbfix eval` and `orbfix demo` run, on {} stops rendered from \
             the procedural world's test zone (relief, the eval's renderer, {}); the host runs \
             the same code on the same inputs for the bit-exactness check. Configuration: \
             `{}`.\n\n",
            self.target,
            self.clock_mhz,
            self.cpi,
            self.stops.len(),
            match self.depth.as_str() {
                "stereo" => "the four stereo pairs, from which the fix computes depth itself in its `stereo` stage",
                "none" => "no depth: flat ground",
                _ => "truth depth images as an external stereo engine would give them",
            },
            self.config
        ));
        m.push_str("## Time (largest over the stops)\n\n");
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
        if let Some(s) = self.stages.get("stereo").filter(|s| s.instructions > 0) {
            m.push_str(&format!(
                "Stereo stage (four views, its largest stop): {} instructions, {:.2} per \
                 working-size pixel matched ({} pixels) and {:.2} per pixel-disparity evaluated \
                 (target: at most 40,000,000 for the four views: {}). Its scratch, {} bytes, \
                 lies in the work area after the range accumulator.\n\n",
                thousands(s.instructions),
                s.instructions_per_pixel.unwrap_or(0.0),
                thousands(s.pixels.unwrap_or(0)),
                s.instructions_per_unit.unwrap_or(0.0),
                if s.instructions <= 40_000_000 {
                    "within"
                } else {
                    "OVER"
                },
                thousands(self.stereo_work_bytes),
            ));
        }
        m.push_str(&format!(
            "Whole fix: {} instructions against a budget of {} (goal {}): {}. Stage counts come \
             from SysTick at {} instructions per tick, so each is exact to +-{} instructions. \
             For scale, int8 network kernels on a Cortex-M7 (STM32H743, public figures) take \
             about 4 cycles per MAC with CMSIS-NN and 2.2 with TinyEngine.\n\n",
            thousands(self.total_instructions),
            thousands(INSN_BUDGET),
            thousands(INSN_GOAL),
            verdict(self.total_instructions, INSN_BUDGET, INSN_GOAL),
            self.instructions_per_tick,
            self.instructions_per_tick
        ));
        m.push_str("## Stops\n\n");
        m.push_str("| stop | instructions | fix error | prior error | status | path | confidence | bit-exact |\n");
        m.push_str("|---|---:|---:|---:|---|---|---:|---|\n");
        for (i, s) in self.stops.iter().enumerate() {
            m.push_str(&format!(
                "| {i} | {} | {:.3} m | {:.1} m | {} | {} | {:.3} | {} |\n",
                thousands(s.instructions),
                s.error_m,
                s.prior_error_m,
                s.status,
                s.path,
                s.confidence,
                s.bit_exact
            ));
        }
        m.push('\n');
        for (i, s) in self.stops.iter().enumerate() {
            m.push_str(&format!("- stop {i}: {}\n", s.description));
        }
        m.push('\n');
        self.markdown_drive(&mut m);
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
            "| external scratch (`.xscratch`, PSRAM: the work area) | {} | {} |\n",
            thousands(self.external_scratch_bytes),
            kib(self.external_scratch_bytes),
        ));
        if self.stereo_work_bytes > 0 {
            m.push_str(&format!(
                "| of which the stereo stage (matcher scratch, one depth band, one row) | {} | {} |\n",
                thousands(self.stereo_work_bytes),
                kib(self.stereo_work_bytes),
            ));
        }
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
            "| external inputs (frames, depth images, map product; PSRAM) | {} | {}, not working memory |\n\n",
            thousands(self.external_input_bytes),
            kib(self.external_input_bytes)
        ));
        m.push_str(
            "No heap: the firmware has no allocator; every buffer's size comes from \
             `orbfix::fix::fix_buffer_sizes`. The work area is shared by the stages in turn: \
             the range reprojection's accumulator (a `u16` gray sum per top-down cell; the \
             sample counts live in the mask) with the stereo stage's scratch, then the CNN's \
             arena and input, then the refinement's images. It is placed in external memory \
             and counted as working memory all the same.\n\n",
        );
        m.push_str("## No panics\n\n");
        if self.panic_free {
            m.push_str(
                "`panic_free: true`: the firmware links with a panic handler that calls an \
                 undefined symbol, so no panic path remains in anything it runs.\n\n",
            );
        } else {
            m.push_str("`panic_free: false`: panic call sites in the linked firmware:\n\n");
            for s in &self.panic_sites {
                m.push_str(&format!("- `{s}`\n"));
            }
            m.push('\n');
        }
        m.push_str("## Bit-exactness\n\n");
        if self.bit_exact {
            m.push_str(
                "`bit_exact: true`: on every stop, every result the firmware reported (position \
                 and scores as `f32` bit patterns, status, path, windows, and a digest of the \
                 top-down image, mask, coarse response, embedding, candidates and operation \
                 counts; `orbfix::fix::protocol`) equals the host's run of the same code on the \
                 same inputs.\n",
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
