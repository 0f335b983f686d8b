//! Instruction counting with SysTick, and the stack high-water mark.
//!
//! SysTick runs from the core clock with the largest reload (2^24 ticks per wrap); its
//! interrupt counts wraps, so readings are 64-bit tick counts. Under QEMU's
//! `-icount shift=0` the mps2-an500 core clock makes one tick 40 guest instructions.

use core::ptr::{addr_of, read_volatile, write_volatile};
use core::sync::atomic::{AtomicU32, Ordering};
use orbfix::fix::{Stage, StageClock};

const SYST_CSR: *mut u32 = 0xE000_E010 as *mut u32;
const SYST_RVR: *mut u32 = 0xE000_E014 as *mut u32;
const SYST_CVR: *mut u32 = 0xE000_E018 as *mut u32;
const RELOAD: u32 = 0x00FF_FFFF;

static WRAPS: AtomicU32 = AtomicU32::new(0);

/// Called by the SysTick exception: one more wrap of the 24-bit counter.
pub fn on_wrap() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// Ticks since [`StageTicks::start`], and the ticks spent in each stage.
pub struct StageTicks {
    began: [u64; Stage::ALL.len()],
    spent: [u64; Stage::ALL.len()],
}

impl StageTicks {
    /// Starts SysTick (core clock, interrupt on wrap) from zero.
    pub fn start() -> Self {
        // Safety: SYST_* are the architecturally defined SysTick registers of every
        // ARMv7-M core; nothing else in this program touches them.
        unsafe {
            write_volatile(SYST_CSR, 0);
            write_volatile(SYST_RVR, RELOAD);
            write_volatile(SYST_CVR, 0);
            // CLKSOURCE = core clock, TICKINT, ENABLE.
            write_volatile(SYST_CSR, 0b111);
        }
        Self {
            began: [0; Stage::ALL.len()],
            spent: [0; Stage::ALL.len()],
        }
    }

    /// Ticks since start.
    pub fn now(&self) -> u64 {
        loop {
            let w1 = WRAPS.load(Ordering::Relaxed);
            // Safety: SYST_CVR is the SysTick current-value register (always mapped on
            // ARMv7-M); reading it has no side effect (COUNTFLAG lives in CSR).
            let cur = unsafe { read_volatile(SYST_CVR) } & RELOAD;
            let w2 = WRAPS.load(Ordering::Relaxed);
            if w1 == w2 {
                return ((w1 as u64) << 24) + (RELOAD - cur) as u64;
            }
        }
    }

    /// Ticks spent in `stage` (0 if it did not run).
    pub fn ticks(&self, stage: Stage) -> u64 {
        self.spent.get(stage as usize).copied().unwrap_or(0)
    }
}

impl StageClock for StageTicks {
    fn begin(&mut self, stage: Stage) {
        let t = self.now();
        if let Some(b) = self.began.get_mut(stage as usize) {
            *b = t;
        }
    }

    fn end(&mut self, stage: Stage) {
        let t = self.now();
        let i = stage as usize;
        if let (Some(b), Some(s)) = (self.began.get(i), self.spent.get_mut(i)) {
            // A stage may run in several spans (the table stages run band by band).
            *s = s.wrapping_add(t.wrapping_sub(*b));
        }
    }
}

extern "C" {
    // From memory.x: the stack occupies [_stack_end, _stack_start); cortex-m-rt's
    // `paint-stack` fills it with 0xCCCC_CCCC before main.
    static _stack_start: u32;
    static _stack_end: u32;
}
const PAINT: u32 = 0xCCCC_CCCC;

/// `(peak, size)`: the deepest stack use so far and the stack region's size, bytes.
/// `peak == size` means the stack overflowed its region.
pub fn stack_peak() -> (usize, usize) {
    let top = addr_of!(_stack_start) as usize;
    let bottom = addr_of!(_stack_end) as usize;
    let size = top.saturating_sub(bottom);
    let mut p = bottom;
    while p < top {
        // Safety: [bottom, top) is the stack region from memory.x, mapped SRAM, 4-aligned;
        // words below the current stack pointer are not in use by anything else.
        let v = unsafe { read_volatile(p as *const u32) };
        if v != PAINT {
            break;
        }
        p += 4;
    }
    (top - p, size)
}
