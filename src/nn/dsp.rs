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

/// `SXTB16 x`: int8 lanes 0 and 2 of `x` as an int16 pair (lane 0 in the low half).
#[inline(always)]
pub(crate) fn sxtb16(x: u32) -> u32 {
    let e: u32;
    // Safety: one register-only Armv7E-M DSP instruction (`armv7em-dsp` feature only); no
    // memory, no stack, no flags.
    unsafe {
        core::arch::asm!(
            "sxtb16 {e}, {x}",
            x = in(reg) x,
            e = out(reg) e,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    e
}

/// `SXTB16 x, ROR #8`: int8 lanes 1 and 3 of `x` as an int16 pair.
#[inline(always)]
pub(crate) fn sxtb16_ror8(x: u32) -> u32 {
    let o: u32;
    // Safety: one register-only Armv7E-M DSP instruction (`armv7em-dsp` feature only); no
    // memory, no stack, no flags.
    unsafe {
        core::arch::asm!(
            "sxtb16 {o}, {x}, ror #8",
            x = in(reg) x,
            o = out(reg) o,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    o
}

/// `SXTAB16 a, x`: `a`'s two int16 lanes plus int8 lanes 0 and 2 of `x`, each lane modulo
/// `2^16`.
#[inline(always)]
pub(crate) fn sxtab16(a: u32, x: u32) -> u32 {
    let r: u32;
    // Safety: one register-only Armv7E-M DSP instruction (`armv7em-dsp` feature only); no
    // memory, no stack, no flags.
    unsafe {
        core::arch::asm!(
            "sxtab16 {r}, {a}, {x}",
            a = in(reg) a,
            x = in(reg) x,
            r = out(reg) r,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    r
}

/// `SXTAB16 a, x, ROR #8`: `a`'s two int16 lanes plus int8 lanes 1 and 3 of `x`.
#[inline(always)]
pub(crate) fn sxtab16_ror8(a: u32, x: u32) -> u32 {
    let r: u32;
    // Safety: one register-only Armv7E-M DSP instruction (`armv7em-dsp` feature only); no
    // memory, no stack, no flags.
    unsafe {
        core::arch::asm!(
            "sxtab16 {r}, {a}, {x}, ror #8",
            a = in(reg) a,
            x = in(reg) x,
            r = out(reg) r,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    r
}

/// `SMLAD acc, x, y`: `acc` plus the products of the two int16 lanes of `x` and `y`
/// (modulo `2^32`; callers bound their sums below `2^31`).
#[inline(always)]
pub(crate) fn smlad(acc: i32, x: u32, y: u32) -> i32 {
    let out: i32;
    // Safety: one register-only Armv7E-M DSP instruction (`armv7em-dsp` feature only); no
    // memory, no stack; it only sets the sticky Q bit on overflow, which nothing reads.
    unsafe {
        core::arch::asm!(
            "smlad {out}, {x}, {y}, {acc}",
            acc = in(reg) acc,
            x = in(reg) x,
            y = in(reg) y,
            out = lateout(reg) out,
            options(pure, nomem, nostack),
        );
    }
    out
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
