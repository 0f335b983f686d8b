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

/// One pass of the 2 pixel x 2 channel kernel of `nn::mat_mult` over four field values:
/// the four column words at `*col` (two `LDRD`: `x0`, `x1` even lanes, then odd), one weight
/// word at each of `*wa` and `*wb` (`LDR`, any alignment), four `SXTB16` and eight `SMLAD`
/// into `acc = [a0, a1, b0, b1]` (channel `a` pixels 0 and 1, channel `b` pixels 0 and 1);
/// advances `col` by four words and `wa`, `wb` by four bytes. Sums modulo `2^32` (the
/// caller bounds them below `2^31`).
///
/// # Safety
/// `*col` must point to four readable, 4-byte aligned `u32`, and `*wa`, `*wb` to four
/// readable bytes each.
#[inline(always)]
pub(crate) unsafe fn mac_2x2(
    acc: &mut [i32; 4],
    col: &mut *const u32,
    wa: &mut *const i8,
    wb: &mut *const i8,
) {
    let [mut a0, mut a1, mut b0, mut b1] = *acc;
    // Safety: the caller guarantees the 16 column bytes (word aligned, as `LDRD` needs) and
    // both weight words are readable; the Cortex-M7 allows the weights' unaligned `LDR`.
    // Only reads memory, no stack; `SMLAD` may set the sticky Q bit, which nothing reads.
    unsafe {
        core::arch::asm!(
            "ldrd {x0}, {x1}, [{c}], #8",
            "ldr {w}, [{pa}], #4",
            "sxtb16 {t}, {w}",
            "smlad {a0}, {x0}, {t}, {a0}",
            "smlad {a1}, {x1}, {t}, {a1}",
            "sxtb16 {w}, {w}, ror #8",
            "ldr {v}, [{pb}], #4",
            "sxtb16 {t}, {v}",
            "smlad {b0}, {x0}, {t}, {b0}",
            "smlad {b1}, {x1}, {t}, {b1}",
            "sxtb16 {v}, {v}, ror #8",
            "ldrd {x0}, {x1}, [{c}], #8",
            "smlad {a0}, {x0}, {w}, {a0}",
            "smlad {a1}, {x1}, {w}, {a1}",
            "smlad {b0}, {x0}, {v}, {b0}",
            "smlad {b1}, {x1}, {v}, {b1}",
            a0 = inout(reg) a0,
            a1 = inout(reg) a1,
            b0 = inout(reg) b0,
            b1 = inout(reg) b1,
            c = inout(reg) *col,
            pa = inout(reg) *wa,
            pb = inout(reg) *wb,
            x0 = out(reg) _,
            x1 = out(reg) _,
            w = out(reg) _,
            v = out(reg) _,
            t = out(reg) _,
            options(readonly, nostack),
        );
    }
    *acc = [a0, a1, b0, b1];
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
