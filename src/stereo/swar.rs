//! Four `u8` lanes in one `u32` for the column costs of [`super::band`]: per-byte absolute
//! differences and their split into two pairs of `u16` lanes.
//!
//! With the `armv7em-dsp` feature on Arm (Cortex-M4/M7, the flight firmware) the absolute
//! differences are two `UQSUB8` and one `ORR`; elsewhere a portable loop over the four
//! bytes gives the same value for every input (the host tests run the matcher built on
//! these against a plain scalar reference, and the QEMU budget checks the firmware's
//! output against the host's to the bit).
//!
//! The lane sums themselves need no DSP instruction: the callers bound every `u16` lane
//! below `2^16` and never let a lane go below 0, so a plain `u32` add or subtract of two
//! lane pairs carries and borrows nothing from one lane into the other.

/// Per-byte `|a - b|` of the four `u8` lanes of `a` and `b`.
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
pub(crate) fn absdiff_u8x4(a: u32, b: u32) -> u32 {
    let out: u32;
    // Safety: register-only Armv7E-M DSP instructions (compiled only with the
    // `armv7em-dsp` feature on Arm, for Cortex-M4/M7); no memory, no stack. `UQSUB8`
    // writes no flags (the GE bits are only set by the non-saturating SIMD forms, and
    // nothing here reads them).
    unsafe {
        core::arch::asm!(
            "uqsub8 {t}, {a}, {b}",
            "uqsub8 {o}, {b}, {a}",
            "orr {o}, {o}, {t}",
            a = in(reg) a,
            b = in(reg) b,
            t = out(reg) _,
            o = out(reg) out,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    out
}

/// Per-byte `|a - b|` of the four `u8` lanes of `a` and `b` (portable form).
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
#[inline(always)]
pub(crate) fn absdiff_u8x4(a: u32, b: u32) -> u32 {
    let (a, b) = (a.to_le_bytes(), b.to_le_bytes());
    u32::from_le_bytes([
        a[0].abs_diff(b[0]),
        a[1].abs_diff(b[1]),
        a[2].abs_diff(b[2]),
        a[3].abs_diff(b[3]),
    ])
}

/// Bytes 0 and 2 of `d` as the low and high `u16` lanes of the first word, bytes 1 and 3 as
/// those of the second (`UXTB16 d` and `UXTB16 d, ROR #8` on Armv7E-M).
#[inline(always)]
pub(crate) fn split_u8x4(d: u32) -> (u32, u32) {
    (d & 0x00ff_00ff, (d >> 8) & 0x00ff_00ff)
}

/// The first four bytes of a chunk as a little-endian word (byte 0 in the low lane); 0 for
/// a shorter chunk. One (unaligned) word load where the target allows it.
#[inline(always)]
pub(crate) fn word(c: &[u8]) -> u32 {
    if c.len() < 4 {
        return 0;
    }
    // Safety: `c` has at least four bytes; the read is unaligned and copies them.
    u32::from_le(unsafe { c.as_ptr().cast::<u32>().read_unaligned() })
}

/// Lane-wise minimum of two `u16` pairs with their indices: where `a`'s lane is strictly
/// below `best`'s, that lane of `a` and of `a_idx`, else that of `best` and `best_idx`
/// (`USUB16` then two `SEL` on the GE flags on Armv7E-M).
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
pub(crate) fn min_u16x2(best: u32, best_idx: u32, a: u32, a_idx: u32) -> (u32, u32) {
    let (m, i): (u32, u32);
    // Safety: register-only Armv7E-M DSP instructions (compiled only with the
    // `armv7em-dsp` feature on Arm, for Cortex-M4/M7); no memory, no stack. `USUB16` sets
    // the GE flags (lane `a >= best`), which the two `SEL` in the same block read; the
    // flags are not declared preserved.
    unsafe {
        core::arch::asm!(
            "usub16 {t}, {a}, {b}",
            "sel {m}, {b}, {a}",
            "sel {i}, {bi}, {ai}",
            a = in(reg) a,
            b = in(reg) best,
            ai = in(reg) a_idx,
            bi = in(reg) best_idx,
            t = out(reg) _,
            m = out(reg) m,
            i = out(reg) i,
            options(pure, nomem, nostack),
        );
    }
    (m, i)
}

/// Lane-wise minimum of two `u16` pairs with their indices (portable form of the
/// Armv7E-M `USUB16` + `SEL` version): where `a`'s lane is strictly below `best`'s, that
/// lane of `a` and of `a_idx`, else that of `best` and `best_idx`.
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
#[inline(always)]
pub(crate) fn min_u16x2(best: u32, best_idx: u32, a: u32, a_idx: u32) -> (u32, u32) {
    let lo = if (a & 0xffff) < (best & 0xffff) {
        0x0000_ffff
    } else {
        0
    };
    let hi = if (a >> 16) < (best >> 16) {
        0xffff_0000
    } else {
        0
    };
    let take = lo | hi;
    (
        (a & take) | (best & !take),
        (a_idx & take) | (best_idx & !take),
    )
}

/// Lane-wise minimum of two `u16` pairs (`USUB16` then `SEL` on Armv7E-M).
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
pub(crate) fn min2_u16x2(a: u32, b: u32) -> u32 {
    let m: u32;
    // Safety: register-only Armv7E-M DSP instructions (compiled only with the
    // `armv7em-dsp` feature on Arm, for Cortex-M4/M7); no memory, no stack. `USUB16` sets
    // the GE flags (lane `a >= b`), which the `SEL` in the same block reads; the flags are
    // not declared preserved.
    unsafe {
        core::arch::asm!(
            "usub16 {t}, {a}, {b}",
            "sel {m}, {b}, {a}",
            a = in(reg) a,
            b = in(reg) b,
            t = out(reg) _,
            m = out(reg) m,
            options(pure, nomem, nostack),
        );
    }
    m
}

/// Lane-wise minimum of two `u16` pairs (portable form of the Armv7E-M version).
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
#[inline(always)]
pub(crate) fn min2_u16x2(a: u32, b: u32) -> u32 {
    let lo = (a & 0xffff).min(b & 0xffff);
    let hi = (a >> 16).min(b >> 16);
    lo | hi << 16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_are_per_byte() {
        let a = u32::from_le_bytes([0, 255, 17, 200]);
        let b = u32::from_le_bytes([255, 0, 20, 200]);
        assert_eq!(absdiff_u8x4(a, b).to_le_bytes(), [255, 255, 3, 0]);
        assert_eq!(
            split_u8x4(u32::from_le_bytes([1, 2, 3, 4])),
            (1 | 3 << 16, 2 | 4 << 16)
        );
        assert_eq!(word(&[1, 2, 3, 4, 5]), 0x0403_0201);
        assert_eq!(word(&[1, 2]), 0);
        // Strictly below takes the lane; equal keeps the old one.
        let (m, i) = min_u16x2(5 | 7 << 16, 1 | 2 << 16, 4 | 7 << 16, 8 | 9 << 16);
        assert_eq!((m, i), (4 | 7 << 16, 8 | 2 << 16));
        let (m, i) = min_u16x2(5 | 7 << 16, 1 | 2 << 16, 6 | 3 << 16, 8 | 9 << 16);
        assert_eq!((m, i), (5 | 3 << 16, 1 | 9 << 16));
        assert_eq!(min2_u16x2(5 | 7 << 16, 4 | 9 << 16), 4 | 7 << 16);
        assert_eq!(min2_u16x2(u32::MAX, 3 | 65535 << 16), 3 | 65535 << 16);
    }
}
