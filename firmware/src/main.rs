//! orbfix example flight firmware (Cortex-M7, QEMU mps2-an500).
//!
//! Runs the whole fix of the `orbfix` core ([`orbfix::flight_run::run`]) once on test
//! vectors made by the host (`orbfix budget`), which sit in external memory (`.psram`),
//! then reports over semihosting, one record per line:
//!
//! ```text
//! ORBFIX-FW 1
//! STAGE <name> <systick ticks>
//! TOTAL <systick ticks>
//! RESULT <key> <value>
//! STACK <peak bytes> <stack bytes>
//! END OK | END ERR <what>
//! ```
//!
//! and exits through semihosting with status 0 (fix ran, stack within its region) or 1.
//! Under `-icount shift=0` one SysTick tick is 40 instructions (see docs/flight-target.md).
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
use orbfix::flight_run::{self, FlightConfig, FlightInputs, Scratch, Stage};
use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::localize::LocalizeConfig;
use orbfix::nn::input::INPUT_LEN;
use orbfix::nn::model::{Arena, EMBED_LEN};
use orbfix::reproject::{table_len, GridSpec};
use report::Line;

/// The four frames, dataset order, packed (external memory: inputs).
#[link_section = ".psram.frames"]
static FRAMES: [u8; vectors::FRAMES_LEN] = *include_bytes!(concat!(env!("OUT_DIR"), "/frames.bin"));
/// CNN records of the map windows (embedding and its sums, `orbfix::nn::window_cosine`
/// layout), made on the ground with the map (external memory: inputs). 4-byte aligned so
/// every record's embedding is too (records are a multiple of 4 bytes).
#[link_section = ".psram.mapwin"]
static MAP_WINDOWS: Aligned<[u8; vectors::MAP_WINDOWS_LEN]> = Aligned(*include_bytes!(concat!(
    env!("OUT_DIR"),
    "/map_windows.bin"
)));
/// The orbital map region (external memory: inputs).
#[link_section = ".psram.map"]
static MAP: [u8; vectors::MAP_LEN] = *include_bytes!(concat!(env!("OUT_DIR"), "/map.bin"));

const FRAME_LEN: usize = vectors::WIDTH * vectors::HEIGHT;
const CELLS: usize = table_len(vectors::GRID_N);

// Working memory in SRAM (.bss): top-down image, mask and the localizer's scratch. The
// reprojection table has no buffer of its own: the core builds and applies it in bands of
// `flight_run::LUT_BAND_ROWS` grid rows inside LOC_FLOATS (cells) and LOC_BYTES (overlap
// taps) before the localizer uses them.
static mut TOP: [u8; CELLS] = [0; CELLS];
static mut MASK: [u8; CELLS] = [0; CELLS];
static mut LOC_BYTES: [u8; vectors::LOC_BYTES] = [0; vectors::LOC_BYTES];
static mut LOC_FLOATS: [f32; vectors::LOC_FLOATS] = [0.0; vectors::LOC_FLOATS];
static mut NN_ARENA: Arena = Arena::new();
static mut NN_INPUT: [i8; INPUT_LEN] = [0; INPUT_LEN];
static mut NN_EMBEDDING: [i8; EMBED_LEN] = [0; EMBED_LEN];

/// 4-byte alignment for word loads.
#[repr(C, align(4))]
struct Aligned<T>(T);

fn inputs() -> Option<FlightInputs<'static>> {
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
    Some(FlightInputs {
        params,
        pose,
        frames: [frame(0)?, frame(1)?, frame(2)?, frame(3)?],
        map: ImageView::new(&MAP, vectors::MAP_W, vectors::MAP_H).ok()?,
        map_geo: GeoRef::new(
            vectors::MAP_GEO[0],
            vectors::MAP_GEO[1],
            vectors::MAP_GEO[2],
        )
        .ok()?,
        map_windows: &MAP_WINDOWS.0,
    })
}

#[entry]
fn main() -> ! {
    Line::new().str("ORBFIX-FW 1").send();
    let cfg = FlightConfig {
        grid: GridSpec::new(vectors::GRID_N, vectors::GRID_M_PER_PX),
        localize: LocalizeConfig::default(),
    };
    // Safety: `main` runs once and is the only code that touches these statics (the
    // SysTick and HardFault handlers do not), so these are the only references to them.
    let mut scratch = unsafe {
        Scratch {
            top: &mut *addr_of_mut!(TOP),
            mask: &mut *addr_of_mut!(MASK),
            loc_bytes: &mut *addr_of_mut!(LOC_BYTES),
            loc_floats: &mut *addr_of_mut!(LOC_FLOATS),
            nn_arena: &mut *addr_of_mut!(NN_ARENA),
            nn_input: &mut *addr_of_mut!(NN_INPUT),
            nn_embedding: &mut *addr_of_mut!(NN_EMBEDDING),
        }
    };
    let mut clock = clock::StageTicks::start();
    let t0 = clock.now();
    #[cfg(not(feature = "no-fix"))]
    let result = match inputs() {
        Some(inp) => flight_run::run(&inp, &cfg, &mut scratch, &mut clock)
            .map_err(|e| report::flight_error(&e)),
        None => Err("bad test vectors (sizes or georeference)"),
    };
    #[cfg(feature = "no-fix")]
    let result: Result<orbfix::flight_run::FlightOutputs, &str> = {
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
            .str("STAGE ")
            .str(stage.name())
            .str(" ")
            .u64(clock.ticks(stage))
            .send();
    }
    Line::new().str("TOTAL ").u64(total).send();

    let mut ok = true;
    match &result {
        Ok(out) => report::outputs(out),
        Err(what) => {
            ok = false;
            Line::new().str("END ERR ").str(what).send();
        }
    }

    let (peak, size) = clock::stack_peak();
    Line::new()
        .str("STACK ")
        .u64(peak as u64)
        .str(" ")
        .u64(size as u64)
        .send();
    if peak >= size {
        ok = false;
        Line::new().str("END ERR stack overflow").send();
    }
    if ok {
        Line::new().str("END OK").send();
    }
    report::exit(ok)
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
