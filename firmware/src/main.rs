//! orbfix example flight firmware (Cortex-M7, QEMU mps2-an500).
//!
//! Runs the core's one fix ([`orbfix::fix::run`]) once on a rover stop rendered from the
//! procedural world by the host (`orbfix budget`): four frames and their depth images (or
//! the right images of their stereo pairs: the fix then computes depth itself), the map
//! product in external memory (`.psram`), and the weights it was made with (the shipped
//! ones unless `orbfix budget --weights FILE`) in flash; then reports
//! over semihosting in the core's result protocol ([`orbfix::fix::protocol`]) and exits
//! through semihosting with status 0 (fix ran, stack within its region) or 1. When the
//! vectors ask for them, it then times the fusion filter's work at one stop of a drive
//! ([`protocol::fusion_stop`] on the fix's report) and the heading search
//! ([`fix::run_heading_search`], on the same inputs and scratch around a given heading
//! estimate) and reports them too. Under
//! `-icount shift=0` one SysTick tick is 40 instructions (see docs/flight-target.md).
//!
//! No panic path may remain: the panic handler calls a symbol that does not exist, so the
//! firmware only links when the optimizer has removed every call to it.
#![no_std]
#![no_main]
#![deny(unsafe_op_in_unsafe_fn)]
// The link-check baseline (feature no-fix) leaves the fix's imports and state unused.
#![cfg_attr(feature = "no-fix", allow(unused_imports, unused_mut, dead_code))]

mod clock;
mod report;
mod vectors {
    #![allow(dead_code)]
    include!(concat!(env!("OUT_DIR"), "/vectors.rs"));
}

use core::ptr::addr_of_mut;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::fix::{
    self, protocol, Depth, FixConfig, FixInputs, FixReport, FixScratch, HeadingSearch, Stage,
};
use orbfix::fusion::{Fusion, OdometryLeg};
use orbfix::image::ImageView;
use orbfix::nn::model::EMBED_LEN;
use orbfix::reproject::{DepthView, GridSpec};
use report::Line;

/// 4-byte alignment for word loads.
#[repr(C, align(4))]
struct Aligned<T>(T);

/// The four frames, rig order, packed (external memory: inputs).
#[link_section = ".psram.frames"]
static FRAMES: [u8; vectors::FRAMES_LEN] = *include_bytes!(concat!(env!("OUT_DIR"), "/frames.bin"));
/// Their depth images, `u16` little-endian millimetres, packed (external memory: inputs).
#[link_section = ".psram.depths"]
static DEPTHS: Aligned<[u8; vectors::DEPTHS_BYTES]> =
    Aligned(*include_bytes!(concat!(env!("OUT_DIR"), "/depths.bin")));
/// The right images of the stereo pairs, packed like the frames (external memory: inputs;
/// one frame of zeros when the vectors have no pairs).
#[link_section = ".psram.rights"]
static RIGHTS: [u8; vectors::RIGHTS_LEN] = *include_bytes!(concat!(env!("OUT_DIR"), "/rights.bin"));
/// The map product: map pixels, georeference and CNN window records (external memory:
/// inputs; 4-byte aligned so every record's embedding is).
#[link_section = ".psram.product"]
static PRODUCT: Aligned<[u8; vectors::PRODUCT_LEN]> =
    Aligned(*include_bytes!(concat!(env!("OUT_DIR"), "/product.bin")));

/// The weight file the map product was made with (`orbfix budget --weights`; default the
/// shipped weights), in flash like the core's own copy.
static WEIGHTS: [u8; vectors::WEIGHTS_LEN] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/weights.bin"));

const FRAME_LEN: usize = vectors::WIDTH * vectors::HEIGHT;

// Working memory in SRAM (.bss), sized by `fix::fix_buffer_sizes` on the host. The work
// area (the range accumulator, then the refinement's images) is in external memory
// (`.xscratch`, counted as working memory by the budget).
static mut TOP: [u8; vectors::TOP] = [0; vectors::TOP];
static mut MASK: [u8; vectors::MASK] = [0; vectors::MASK];
#[link_section = ".xscratch.work"]
static mut WORK: [u32; vectors::WORK_WORDS] = [0; vectors::WORK_WORDS];
static mut RESPONSE: [i32; vectors::RESPONSE] = [0; vectors::RESPONSE];
static mut REFINE_FLOATS: [f32; vectors::REFINE_FLOATS] = [0.0; vectors::REFINE_FLOATS];
static mut NN_EMBEDDING: [i8; EMBED_LEN] = [0; EMBED_LEN];
static mut RELIEF: [i32; vectors::RELIEF_WORDS] = [0; vectors::RELIEF_WORDS];

fn depths() -> Option<&'static [u16]> {
    // Safety: `u16` is valid for every bit pattern; `align_to` only yields the aligned
    // middle (the buffer is 4-byte aligned, so the prefix is empty), and the target is
    // little-endian like the file.
    let (pre, d, _) = unsafe { DEPTHS.0.align_to::<u16>() };
    pre.is_empty().then_some(d)
}

fn inputs() -> Option<FixInputs<'static>> {
    let params = CameraParams {
        width_px: vectors::WIDTH as u32,
        height_px: vectors::HEIGHT as u32,
        hfov_deg: vectors::HFOV_DEG,
        height_m: vectors::CAM_HEIGHT_M,
        tilt_deg: vectors::TILT_DEG,
    };
    let pose = RoverPose {
        x_m: vectors::POSE[0],
        y_m: vectors::POSE[1],
        ground_z_m: vectors::POSE[2],
        heading_deg: vectors::POSE[3],
        pitch_deg: vectors::POSE[4],
        roll_deg: vectors::POSE[5],
    };
    let frame = |i: usize| {
        let data = FRAMES.get(i * FRAME_LEN..(i + 1) * FRAME_LEN)?;
        ImageView::new(data, vectors::WIDTH, vectors::HEIGHT).ok()
    };
    let d = depths()?;
    let depth = |i: usize| {
        let data = d.get(i * FRAME_LEN..(i + 1) * FRAME_LEN)?;
        DepthView::new(data, vectors::WIDTH, vectors::HEIGHT).ok()
    };
    Some(FixInputs {
        params,
        pose,
        frames: [frame(0), frame(1), frame(2), frame(3)],
        depth: if vectors::HAS_STEREO {
            let right = |i: usize| {
                let data = RIGHTS.get(i * FRAME_LEN..(i + 1) * FRAME_LEN)?;
                ImageView::new(data, vectors::WIDTH, vectors::HEIGHT).ok()
            };
            Depth::Stereo([right(0), right(1), right(2), right(3)])
        } else if vectors::HAS_DEPTH {
            Depth::Images([depth(0), depth(1), depth(2), depth(3)])
        } else {
            Depth::Flat
        },
        map_product: &PRODUCT.0,
        weights: &WEIGHTS,
    })
}

#[entry]
fn main() -> ! {
    Line::new()
        .str(protocol::HEADER)
        .str(" ")
        .u64(protocol::VERSION as u64)
        .send();
    let mut cfg = FixConfig {
        grid: GridSpec::new(vectors::GRID_N, vectors::GRID_M_PER_PX),
        ..FixConfig::default()
    };
    cfg.stereo.matcher.baseline_m = vectors::STEREO_BASELINE_M;
    // Safety: `main` runs once and is the only code that touches these statics (the
    // SysTick and HardFault handlers do not), so these are the only references to them.
    let mut scratch = unsafe {
        FixScratch {
            top: &mut *addr_of_mut!(TOP),
            mask: &mut *addr_of_mut!(MASK),
            work: &mut *addr_of_mut!(WORK),
            response: &mut *addr_of_mut!(RESPONSE),
            refine_floats: &mut *addr_of_mut!(REFINE_FLOATS),
            nn_embedding: &mut *addr_of_mut!(NN_EMBEDDING),
            relief: &mut *addr_of_mut!(RELIEF),
        }
    };
    let mut clock = clock::StageTicks::start();
    let t0 = clock.now();
    #[cfg(not(feature = "no-fix"))]
    let result = match inputs() {
        Some(inp) => {
            fix::run(&inp, &cfg, &mut scratch, &mut clock).map_err(|e| report::fix_error(&e))
        }
        None => Err("bad test vectors (sizes)"),
    };
    #[cfg(feature = "no-fix")]
    let result: Result<orbfix::fix::FixReport, &str> = {
        let _ = (&mut scratch, &cfg, inputs().is_some());
        Err("built without the fix (feature no-fix: link-check baseline)")
    };
    let total = clock.now().wrapping_sub(t0);
    #[cfg(feature = "panic-probe")]
    {
        // Proof that the no-panic link check bites: an index the optimizer cannot prove.
        let i = (total % 7) as usize;
        Line::new()
            .u64(FRAMES[FRAMES.len() / 2 + i * FRAMES.len()] as u64)
            .send();
    }

    for stage in Stage::ALL {
        Line::new()
            .str(protocol::STAGE)
            .str(" ")
            .str(stage.name())
            .str(" ")
            .u64(clock.ticks(stage))
            .send();
    }
    Line::new().str(protocol::TOTAL).str(" ").u64(total).send();

    let mut ok = true;
    match &result {
        Ok(r) => report::results(r, fix::output_digest(r, &scratch, cfg.grid.n)),
        Err(what) => {
            ok = false;
            Line::new().str(protocol::END).str(" ERR ").str(what).send();
        }
    }
    #[cfg(not(feature = "no-fix"))]
    if let Ok(r) = &result {
        if vectors::FUSION && !fusion_entry(r, &clock) {
            ok = false;
        }
        if vectors::HEADING_STEPS > 0 && !heading_entry(&cfg, &mut scratch, &mut clock) {
            ok = false;
        }
    }

    let (peak, size) = clock::stack_peak();
    Line::new()
        .str(protocol::STACK)
        .str(" ")
        .u64(peak as u64)
        .str(" ")
        .u64(size as u64)
        .send();
    if peak >= size {
        ok = false;
        Line::new()
            .str(protocol::END)
            .str(" ERR stack overflow")
            .send();
    }
    if ok {
        Line::new().str(protocol::END).str(" OK").send();
    }
    report::exit(ok)
}

/// The filter's work at one stop ([`protocol::fusion_stop`]) on the fix's report, from the
/// start, leg and settings in the vectors; reports its ticks and results. `false` (after an
/// `END ERR` line) if the filter refused.
#[cfg(not(feature = "no-fix"))]
fn fusion_entry(fix_report: &FixReport, clock: &clock::StageTicks) -> bool {
    use core::hint::black_box;
    let cfg = protocol::fusion_config_from_words(&vectors::FUSION_CFG);
    let Ok(mut filter) = Fusion::new(cfg, vectors::FUSION_START[0], vectors::FUSION_START[1])
    else {
        Line::new()
            .str(protocol::END)
            .str(" ERR fusion settings refused")
            .send();
        return false;
    };
    let leg = OdometryLeg {
        distance_m: vectors::FUSION_LEG[0],
        heading_deg: vectors::FUSION_LEG[1],
    };
    let t0 = clock.now();
    // The barriers keep the filter's work between the two clock readings.
    let stop = protocol::fusion_stop(
        black_box(&mut filter),
        black_box(&leg),
        black_box(fix_report),
    );
    black_box(&stop);
    let ticks = clock.now().wrapping_sub(t0);
    let Ok(stop) = stop else {
        Line::new()
            .str(protocol::END)
            .str(" ERR fusion failed")
            .send();
        return false;
    };
    Line::new().str(protocol::FUSION).str(" ").u64(ticks).send();
    report::keyed(
        protocol::FUSION_RESULT,
        &protocol::FUSION_KEYS,
        &protocol::fusion_values(&filter, &stop),
    );
    true
}

/// The heading search on the stop's inputs around the vectors' heading estimate, with the
/// fix's scratch (no memory of its own beyond the stack); reports its ticks and results.
#[cfg(not(feature = "no-fix"))]
fn heading_entry(
    cfg: &FixConfig,
    scratch: &mut FixScratch<'_>,
    clock: &mut clock::StageTicks,
) -> bool {
    let (Ok(search), Some(mut inp)) = (
        HeadingSearch::new(vectors::HEADING_STEPS, vectors::HEADING_STEP_DEG),
        inputs(),
    ) else {
        Line::new()
            .str(protocol::END)
            .str(" ERR bad heading-search vectors")
            .send();
        return false;
    };
    inp.pose.heading_deg = vectors::HEADING_ESTIMATE_DEG;
    let t0 = clock.now();
    let found = fix::run_heading_search(&inp, cfg, &search, scratch, clock);
    let ticks = clock.now().wrapping_sub(t0);
    match found {
        Ok(h) => {
            Line::new()
                .str(protocol::HEADING)
                .str(" ")
                .u64(search.count() as u64)
                .str(" ")
                .u64(ticks)
                .send();
            let digest = fix::output_digest(&h.report, scratch, cfg.grid.n);
            report::keyed(
                protocol::HEADING_RESULT,
                &protocol::HEADING_KEYS,
                &protocol::heading_values(&h, digest),
            );
            true
        }
        Err(e) => {
            Line::new()
                .str(protocol::END)
                .str(" ERR heading search: ")
                .str(report::fix_error(&e))
                .send();
            false
        }
    }
}

#[exception]
fn SysTick() {
    clock::on_wrap();
}

// Safety: cortex-m-rt requires the HardFault handler to be `unsafe fn`; it only reports
// over semihosting and exits, touching no shared state.
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    Line::new().str("END ERR hard fault").send();
    report::exit(false)
}

#[cfg(not(feature = "allow-panic"))]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    extern "Rust" {
        // Deliberately never defined: if any panic path survives optimization, the link
        // fails with this name (see docs/flight-target.md, "No panics on the target").
        #[link_name = "orbfix_firmware_error_a_panic_path_remains_see_docs_flight_target_md"]
        fn a_panic_path_remains() -> !;
    }
    // Safety: this call is never linked into a working binary; the symbol does not exist.
    unsafe { a_panic_path_remains() }
}

#[cfg(feature = "allow-panic")]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    Line::new().str("END ERR panic").send();
    report::exit(false)
}
