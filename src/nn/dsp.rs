//! Armv7E-M DSP instructions (`SXTB16`, `SMLAD`) for the int8 kernels, with the
//! `armv7em-dsp` feature on Arm only (Cortex-M4/M7); elsewhere the kernels' portable loops
//! run, and the QEMU budget checks the two agree to the bit.
//!
//! Both instructions work on two int16 lanes of a 32-bit register: `SXTB16` sign-extends
//! bytes 0 and 2 (or, rotated by 8, bytes 1 and 3) into them, `SMLAD` adds both lane
//! products to an accumulator. Callers bound their sums below `2^31` (SMLAD would set the
//! sticky Q flag on overflow, which nothing reads).

/// `(SXTB16 x, SXTB16 (x ROR 8))`: int8 lanes 0, 2 and 1, 3 of `x` as int16 pairs.
#[inline(always)]
pub(crate) fn sxtb16_pair(x: u32) -> (u32, u32) {
    let (e, o): (u32, u32);
    // Safety: register-only Armv7E-M DSP instructions (this module only exists with the
    // `armv7em-dsp` feature, for Cortex-M4/M7 targets); no memory, no stack, no flags.
    unsafe {
        core::arch::asm!(
            "sxtb16 {e}, {x}",
            "sxtb16 {o}, {x}, ror #8",
            x = in(reg) x,
            e = out(reg) e,
            o = out(reg) o,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    (e, o)
}

/// `acc + x . y` over four int8 lanes of `y`, with `x` given as int16 pairs `xe` (lanes 0,
/// 2) and `xo` (lanes 1, 3), as [`sxtb16_pair`] splits them: `SXTB16` and `SMLAD` twice.
#[inline(always)]
pub(crate) fn smlad_pair(acc: i32, xe: u32, xo: u32, y: u32) -> i32 {
    let out: i32;
    // Safety: register-only Armv7E-M DSP instructions (`armv7em-dsp` feature only); no
    // memory, no stack; SMLAD only sets the sticky Q bit on overflow, which the callers'
    // bounds rule out and nothing reads.
    unsafe {
        core::arch::asm!(
            "sxtb16 {t}, {y}",
            "smlad {acc}, {xe}, {t}, {acc}",
            "sxtb16 {t}, {y}, ror #8",
            "smlad {acc}, {xo}, {t}, {acc}",
            acc = inout(reg) acc => out,
            xe = in(reg) xe,
            xo = in(reg) xo,
            y = in(reg) y,
            t = out(reg) _,
            options(pure, nomem, nostack),
        );
    }
    out
}
