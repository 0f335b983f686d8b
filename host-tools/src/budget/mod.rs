//! The flight budget: world-rendered test vectors for the firmware ([`vectors`]), the host's
//! run of the same core code, QEMU's report ([`report`]), the ELF's memory sizes and panic
//! sites ([`elf`]), and the budget table ([`table`]).
//!
//! The firmware (`firmware/`) runs [`orbfix::fix::run`] under
//! `qemu-system-arm -machine mps2-an500 -icount shift=0` and prints its report in the core's
//! result protocol ([`orbfix::fix::protocol`]).

pub mod elf;
pub mod report;
pub mod table;
pub mod vectors;

pub use elf::{elf_sizes, panic_sites, thumb_branch_target, ElfSizes};
pub use report::{
    expected_fusion, expected_heading, expected_results, keyed_mismatches, mismatches,
    parse_report, ExtraReport, FirmwareReport,
};
pub use table::{
    assemble, stop_budget, Budget, Estimate, FusionBudget, HeadingBudget, StageBudget, StopBudget,
};
pub use vectors::{FusionCase, HeadingCase, Vectors};

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
