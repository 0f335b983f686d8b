//! `orbfix budget`: build the flight firmware on test vectors, run it in QEMU, and write the
//! timing and memory budget (docs/timing-budget.md and a JSON file).

use anyhow::{bail, ensure, Context, Result};
use orbfix::fix::FixConfig;
use orbfix_host::budget::{self, Estimate, FusionCase, HeadingCase, Vectors};
use orbfix_host::eval::pipeline::{DepthSource, PipelineOptions};
use orbfix_host::fix::FixRunner;
use orbfix_host::traverse::TraverseOptions;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Odometry leg of the measured filter work, metres (the middle of the traverse's legs).
const FUSION_LEG_M: f64 = 40.0;
/// Where the measured filter's prediction lands from the truth, metres (east, north).
const FUSION_PRIOR_OFFSET_M: (f64, f64) = (0.5, -0.5);

/// Flight targets the budget can be measured on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// Arm Cortex-M7 (thumbv7em-none-eabihf) on QEMU's mps2-an500.
    CortexM7,
}

impl Target {
    fn name(self) -> &'static str {
        match self {
            Target::CortexM7 => "cortex-m7",
        }
    }
}

/// Build the flight firmware, run it in QEMU and write the timing and memory budget.
///
/// Steps, per stop: render a rover stop of the world's test zone (frames, depth, the map
/// product around the prior) and run the core's fix on the host; install the cross toolchain if needed (scripts/flight-toolchain.sh);
/// build firmware/ for thumbv7em-none-eabihf; run it under
/// `qemu-system-arm -machine mps2-an500 -icount shift=0`; read per-stage instruction counts,
/// the stack high-water mark and the results from its semihosting report, and flash and
/// static RAM from the ELF; write the table to --md and --json. After the fix, the firmware
/// also times the fusion filter's work at the stop (prediction over a 40 m odometry leg, the
/// search radius, the fix's update, with `orbfix traverse`'s default filter settings) and, on
/// the first --heading-stops stops, the heading search for --heading-sigma-deg around an
/// estimate --heading-offset-deg off the truth. Fails (after writing both) if any result is
/// not bit-exact with the host's.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Flight target.
    #[arg(long, value_enum, default_value_t = Target::CortexM7)]
    pub target: Target,
    /// Clock of the flight computer for the millisecond estimates, MHz.
    #[arg(long, allow_negative_numbers = true, default_value_t = 100.0)]
    pub clock_mhz: f64,
    /// Cycles per instruction assumed for the millisecond estimates.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1.0)]
    pub cpi: f64,
    /// Where to write the budget as JSON.
    #[arg(long)]
    pub json: PathBuf,
    /// Where to write the budget as Markdown [default: <repo>/docs/timing-budget.md].
    #[arg(long)]
    pub md: Option<PathBuf>,
    /// Repository root (holds firmware/ and memory.x) [default: found from the current folder].
    #[arg(long)]
    pub repo: Option<PathBuf>,
    /// Folder for the test vectors [default: <cargo target dir>/flight-vectors].
    #[arg(long)]
    pub vectors_dir: Option<PathBuf>,
    /// Environment file from scripts/flight-toolchain.sh [default: run the script].
    #[arg(long)]
    pub toolchain_env: Option<PathBuf>,
    /// World seed of the stops (the test zone's generated stops, same sun).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Stops measured (each its own firmware build and QEMU run).
    #[arg(long, default_value_t = 3)]
    pub stops: usize,
    /// Depth of the top-down image: stereo (the four stereo pairs; the fix computes depth
    /// itself, stage `stereo`), truth (the renderer's exact depth images, as an external
    /// stereo engine would give them) or none (flat ground).
    #[arg(long, value_enum, default_value_t = DepthSource::Stereo)]
    pub depth: DepthSource,
    /// Measure even if the firmware is not panic free (it is then built with its
    /// `allow-panic` feature, and the budget records `panic_free: false` and where).
    #[arg(long)]
    pub allow_panic: bool,
    #[command(flatten)]
    pub weights: orbfix_host::nn::weights_file::WeightsArg,
    /// Stops (the first ones) on which the firmware also runs the heading search (0: none;
    /// each costs the search's headings times a whole fix) [default: every stop].
    #[arg(long, default_value_t = 20, hide_default_value = true)]
    pub heading_stops: usize,
    /// Heading sigma the measured search is sized for, degrees (with `orbfix traverse`'s
    /// tolerance and step: sigma 2 gives 5 headings 2 deg apart).
    #[arg(long, default_value_t = 2.0)]
    pub heading_sigma_deg: f64,
    /// Error of the heading estimate given to the measured search, degrees.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1.5)]
    pub heading_offset_deg: f64,
    /// Give up on QEMU after this many seconds.
    #[arg(long, default_value_t = 300)]
    pub qemu_timeout_s: u64,
}

fn find_repo(given: Option<PathBuf>) -> Result<PathBuf> {
    let is_repo =
        |p: &Path| p.join("firmware/Cargo.toml").is_file() && p.join("memory.x").is_file();
    if let Some(p) = given {
        ensure!(
            is_repo(&p),
            "{} has no firmware/Cargo.toml and memory.x: pass the orbfix repository root to --repo",
            p.display()
        );
        return Ok(p);
    }
    let mut dir = std::env::current_dir().context("cannot read the current folder")?;
    loop {
        if is_repo(&dir) {
            return Ok(dir);
        }
        if !dir.pop() {
            break;
        }
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    ensure!(is_repo(&built), "cannot find the orbfix repository (firmware/ and memory.x): run from inside it or pass --repo");
    Ok(built)
}

fn toolchain_env(repo: &Path, given: Option<PathBuf>) -> Result<PathBuf> {
    if let Some(p) = given {
        ensure!(
            p.is_file(),
            "toolchain environment {} does not exist: run `bash scripts/flight-toolchain.sh`",
            p.display()
        );
        return Ok(p);
    }
    eprintln!("budget: checking the cross toolchain (scripts/flight-toolchain.sh)");
    let out = Command::new("bash")
        .arg(repo.join("scripts/flight-toolchain.sh"))
        .current_dir(repo)
        .stderr(Stdio::inherit())
        .output()
        .context("cannot run bash scripts/flight-toolchain.sh")?;
    ensure!(
        out.status.success(),
        "scripts/flight-toolchain.sh failed (its messages are above)"
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let last = text
        .lines()
        .last()
        .context("scripts/flight-toolchain.sh printed no environment file")?;
    Ok(PathBuf::from(last.trim()))
}

/// Why a firmware build failed.
enum BuildError {
    /// The link failed because a panic path remains (the no-panic check).
    PanicPath,
    /// Anything else.
    Other(anyhow::Error),
}

const PANIC_SYMBOL: &str = "orbfix_firmware_error_a_panic_path_remains";

fn build_firmware(
    repo: &Path,
    env_file: &Path,
    vectors: &Path,
    target_dir: &Path,
    allow_panic: bool,
) -> std::result::Result<PathBuf, BuildError> {
    eprintln!(
        "budget: building firmware/ for thumbv7em-none-eabihf{}",
        if allow_panic { " (allow-panic)" } else { "" }
    );
    let features = if allow_panic {
        "--features allow-panic"
    } else {
        ""
    };
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "set -e; source \"$1\"; cd firmware; cargo build --release {features} $ORBFIX_FLIGHT_CARGO_FLAGS"
        ))
        .arg("bash")
        .arg(env_file)
        .current_dir(repo)
        .env("ORBFIX_VECTORS_DIR", vectors)
        .env("CARGO_TARGET_DIR", target_dir)
        .stdout(Stdio::inherit())
        .stderr(Stdio::piped())
        .output()
        .map_err(|e| BuildError::Other(anyhow::Error::new(e).context("cannot run cargo for the firmware")))?;
    let err = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        if err.contains(PANIC_SYMBOL) {
            return Err(BuildError::PanicPath);
        }
        eprint!("{err}");
        return Err(BuildError::Other(anyhow::anyhow!(
            "building the firmware failed (cargo's messages are above)"
        )));
    }
    Ok(target_dir.join("thumbv7em-none-eabihf/release/orbfix-firmware"))
}

/// Runs the ELF in QEMU; returns (exit code, stdout).
fn run_qemu(elf: &Path, timeout: Duration) -> Result<(Option<i32>, String)> {
    eprintln!(
        "budget: running {} in qemu-system-arm (mps2-an500, -icount shift=0)",
        elf.display()
    );
    let mut child = Command::new("qemu-system-arm")
        .args(["-cpu", "cortex-m7", "-machine", "mps2-an500", "-nographic"])
        .args(["-semihosting-config", "enable=on,target=native", "-icount", "shift=0"])
        .args(["-monitor", "none", "-serial", "none", "-kernel"])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("cannot start qemu-system-arm: install it (`apt-get install qemu-system-arm`, or run scripts/flight-toolchain.sh as root)")?;
    // Semihosting console output arrives on QEMU's stderr; keep stdout too.
    let mut stdout = child.stdout.take().context("no stdout from QEMU")?;
    let mut stderr = child.stderr.take().context("no stderr from QEMU")?;
    let out_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s + &out_reader.join().unwrap_or_default()
    });
    let start = Instant::now();
    let code = loop {
        if let Some(st) = child.try_wait().context("waiting for QEMU")? {
            break st.code();
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            let text = reader.join().unwrap_or_default();
            bail!(
                "QEMU ran longer than {} s and was stopped; output so far:\n{text}",
                timeout.as_secs()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let text = reader.join().unwrap_or_default();
    Ok((code, text))
}

/// Runs `orbfix budget`.
pub fn run(args: Args) -> Result<()> {
    ensure!(
        args.clock_mhz.is_finite() && args.clock_mhz > 0.0,
        "--clock-mhz must be a positive number, got {}",
        args.clock_mhz
    );
    ensure!(
        args.cpi.is_finite() && args.cpi > 0.0,
        "--cpi must be a positive number, got {}",
        args.cpi
    );
    let weights = args.weights.bytes()?;
    let repo = find_repo(args.repo.clone())?;
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo.join("target"));
    let vectors_dir = args
        .vectors_dir
        .clone()
        .unwrap_or_else(|| target_dir.join("flight-vectors"));

    ensure!(
        (1..=20).contains(&args.stops),
        "--stops must be 1..=20, got {}",
        args.stops
    );
    let opts = PipelineOptions {
        reprojection: args.depth.reprojection(),
        ..PipelineOptions::default()
    };
    let mut cfg = FixConfig::default();
    // The firmware sets the baseline from the vectors; everything else is the default.
    cfg.stereo.matcher.baseline_m = opts.stereo_params().baseline_m;
    let runner = FixRunner { weights, cfg };
    ensure!(
        args.heading_offset_deg.is_finite() && args.heading_offset_deg.abs() <= 20.0,
        "--heading-offset-deg must be within +-20 degrees, got {}",
        args.heading_offset_deg
    );
    let drive = TraverseOptions::default();
    let heading_search = if args.heading_stops > 0 {
        Some(drive.heading_search(args.heading_sigma_deg)?.with_context(|| {
            format!(
                "--heading-sigma-deg {} needs no heading search (at most the traverse's tolerance, {} deg): pass a larger sigma or --heading-stops 0",
                args.heading_sigma_deg, drive.heading_tolerance_deg
            )
        })?)
    } else {
        None
    };
    let env_file = toolchain_env(&repo, args.toolchain_env.clone())?;
    let est = Estimate {
        target: args.target.name().to_string(),
        clock_mhz: args.clock_mhz,
        cpi: args.cpi,
    };
    let mut stops = Vec::new();
    let mut all_ok = true;
    let mut panic_free = true;
    let mut sites = Vec::new();
    let mut sizes = budget::ElfSizes::default();
    for i in 0..args.stops {
        eprintln!(
            "budget: stop {i}: rendering from world seed {} (test zone)",
            args.seed
        );
        let mut v = Vectors::world_stop(args.seed, i, &opts, &runner.weights)?;
        let true_heading = v.pose.heading_deg;
        v.fusion = Some(FusionCase::before_stop(
            drive.fusion_config(),
            v.truth_m,
            FUSION_PRIOR_OFFSET_M,
            FUSION_LEG_M,
            true_heading as f64,
        ));
        if i < args.heading_stops {
            v.heading = heading_search.map(|search| HeadingCase {
                search,
                estimate_deg: (true_heading as f64 + args.heading_offset_deg) as f32,
            });
        }
        let host = v.host_run(&runner)?;
        let host_fusion = v
            .fusion
            .as_ref()
            .map(|c| c.host_run(&host.report))
            .transpose()?;
        if v.heading.is_some() {
            eprintln!("budget: stop {i}: heading search on the host");
        }
        let host_heading = v.host_heading_search(&runner)?;
        v.write(&vectors_dir, &cfg)?;
        eprintln!("budget: stop {i}: {}", v.source);
        let (elf, free) = match build_firmware(&repo, &env_file, &vectors_dir, &target_dir, false) {
            Ok(elf) => (elf, true),
            Err(BuildError::Other(e)) => return Err(e),
            Err(BuildError::PanicPath) => {
                eprintln!(
                    "budget: the firmware does NOT link: a panic path remains in the code it                      runs (no-panic check, docs/flight-target.md); rebuilding with allow-panic                      to find where"
                );
                match build_firmware(&repo, &env_file, &vectors_dir, &target_dir, true) {
                    Ok(elf) => (elf, false),
                    Err(BuildError::PanicPath) => {
                        bail!("the allow-panic build still refers to the panic symbol")
                    }
                    Err(BuildError::Other(e)) => return Err(e),
                }
            }
        };
        let elf_bytes = std::fs::read(&elf)
            .with_context(|| format!("cannot read the firmware {}", elf.display()))?;
        if !free {
            panic_free = false;
            sites = budget::panic_sites(&elf_bytes)?;
            eprintln!("budget: panic paths (caller -> panic function (call sites)):");
            for (a, b, n) in &sites {
                eprintln!("  {a} -> {b} ({n})");
            }
            if !args.allow_panic {
                bail!(
                    "the firmware is not panic free ({} call sites above); fix them, or pass                      --allow-panic to measure anyway (the budget then records panic_free: false)",
                    sites.iter().map(|s| s.2).sum::<usize>()
                );
            }
        }
        sizes = budget::elf_sizes(&elf_bytes)?;
        let (code, text) = run_qemu(&elf, Duration::from_secs(args.qemu_timeout_s))?;
        let report = budget::parse_report(&text)?;
        if !report.ok {
            eprintln!(
                "budget: stop {i}: the firmware reported failure ({:?}; QEMU exit code {code:?})",
                report.errors
            );
            all_ok = false;
        }
        let expected = budget::expected_results(&host.report, host.digest);
        let mism = budget::mismatches(&report, &expected);
        let mut stop = budget::stop_budget(
            &est,
            v.source.clone(),
            &report,
            &host.report,
            mism,
            v.truth_m,
            (v.pose.x_m as f64, v.pose.y_m as f64),
        );
        eprintln!(
            "budget: stop {i}: {} instructions, fix error {:.3} m ({}, {}), bit_exact {}",
            stop.instructions, stop.error_m, stop.status, stop.path, stop.bit_exact
        );
        if let (Some(case), Some((filter, fs))) = (&v.fusion, &host_fusion) {
            let got = report.fusion.clone().unwrap_or_default();
            let mism = budget::keyed_mismatches(&got.results, &budget::expected_fusion(filter, fs));
            let insn = got.ticks * budget::INSTRUCTIONS_PER_TICK;
            let f = budget::FusionBudget {
                instructions: insn,
                ms: est.ms(insn),
                leg_m: case.leg.distance_m as f64,
                accepted: fs.outcome.accepted(),
                mahalanobis2: fs.outcome.mahalanobis2 as f64,
                search_radius_m: filter.search_radius_m() as f64,
                bit_exact: report.ok && report.fusion.is_some() && mism.is_empty(),
                mismatches: mism,
            };
            eprintln!(
                "budget: stop {i}: fusion filter {} instructions ({}), bit_exact {}",
                f.instructions,
                if f.accepted { "accepted" } else { "refused" },
                f.bit_exact
            );
            stop.fusion = Some(f);
        }
        if let (Some(case), Some((hf, digest))) = (&v.heading, &host_heading) {
            let got = report.heading.clone().unwrap_or_default();
            let mism =
                budget::keyed_mismatches(&got.results, &budget::expected_heading(hf, *digest));
            let insn = got.ticks * budget::INSTRUCTIONS_PER_TICK;
            let herr = |h: f64| (h - true_heading as f64 + 540.0).rem_euclid(360.0) - 180.0;
            let h = budget::HeadingBudget {
                headings: case.search.count() as u64,
                step_deg: case.search.step_deg() as f64,
                sigma_deg: args.heading_sigma_deg,
                instructions: insn,
                ms: est.ms(insn),
                instructions_per_heading: insn as f64 / case.search.count() as f64,
                estimate_error_deg: herr(case.estimate_deg as f64),
                heading_error_deg: herr(hf.heading_deg as f64),
                error_m: (hf.report.x_m as f64 - v.truth_m.0)
                    .hypot(hf.report.y_m as f64 - v.truth_m.1),
                status: hf.report.status.name().to_string(),
                bit_exact: report.ok
                    && report
                        .heading
                        .as_ref()
                        .is_some_and(|r| r.headings == case.search.count() as u64)
                    && mism.is_empty(),
                mismatches: mism,
            };
            eprintln!(
                "budget: stop {i}: heading search ({} headings) {} instructions, heading {:+.2} deg off (estimate {:+.2}), bit_exact {}",
                h.headings, h.instructions, h.heading_error_deg, h.estimate_error_deg, h.bit_exact
            );
            stop.heading_search = Some(h);
        }
        stops.push(stop);
    }
    let mut b = budget::assemble(&est, stops, &sizes, all_ok, &sites, format!("{cfg:?}"));
    b.depth = args.depth.name().to_string();
    if args.depth == DepthSource::Stereo {
        b.stereo_work_bytes = 4 * orbfix::fix::stereo_work_words(&cfg.stereo) as u64;
    }
    if !panic_free && b.panic_sites.is_empty() {
        // The link failed on the panic symbol but no call site was decoded: still not free.
        b.panic_free = false;
        b.panic_sites.push("(call sites not decoded)".to_string());
    }

    let command = format!(
        "orbfix budget --target {} --clock-mhz {} --cpi {} --seed {} --stops {} --depth {}{} --json {}{}{}",
        est.target,
        args.clock_mhz,
        args.cpi,
        args.seed,
        args.stops,
        args.depth.name(),
        if args.heading_stops >= args.stops && args.heading_sigma_deg == 2.0 && args.heading_offset_deg == 1.5 {
            String::new()
        } else {
            format!(
                " --heading-stops {} --heading-sigma-deg {} --heading-offset-deg {}",
                args.heading_stops, args.heading_sigma_deg, args.heading_offset_deg
            )
        },
        args.json.display(),
        // Quoted so the page's command writes this page, not the default one.
        args.md
            .as_ref()
            .map(|m| format!(" --md {}", m.display()))
            .unwrap_or_default(),
        if args.allow_panic {
            " --allow-panic"
        } else {
            ""
        }
    );
    let md = args
        .md
        .clone()
        .unwrap_or_else(|| repo.join("docs/timing-budget.md"));
    orbfix_host::fsutil::write_atomic(&md, b.markdown(&command).as_bytes())?;
    let json = serde_json::to_string_pretty(&b).context("cannot serialize the budget")?;
    orbfix_host::fsutil::write_atomic(&args.json, json.as_bytes())?;
    eprintln!("budget: wrote {} and {}", md.display(), args.json.display());
    println!(
        "total {} instructions ({:.2} ms at {} MHz, CPI {}), working RAM {} B (static {} + stack {}), flash {} B, bit_exact {}",
        b.total_instructions, b.total_ms, b.clock_mhz, b.cpi, b.working_ram_bytes, b.static_ram_bytes,
        b.stack_peak_bytes, b.flash_bytes, b.bit_exact
    );
    if !b.firmware_ok {
        bail!("the firmware reported failure on at least one stop (messages above)");
    }
    if !b.bit_exact {
        bail!(
            "the firmware's results differ from the host's for: {:?}",
            b.mismatches
        );
    }
    Ok(())
}
