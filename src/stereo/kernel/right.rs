//! The right image's winners: each right pixel keeps the first of its smallest costs over
//! the columns that reach it (for the left-right check).

#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::super::swar::min_u16x2;
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::slide::{INDEX_D, INDEX_E0, INDEX_STEP};

/// The right image's winners of one column: group `k`'s words at `ap` are the costs of
/// right pixels `b - 4k, b - 4k + 2` (word `2k`, indices `4k + 3`, `4k + 1`) and `b - 4k +
/// 1, b - 4k + 3` (word `2k + 1`, indices `4k + 2`, `4k`); `pe` and `pd` point at the costs
/// of pixels `b` and `b + 1` (two at a time: even pixels and odd pixels lie in separate
/// arrays), their indices lie `off` bytes further, and both move back two elements per
/// group. A pixel keeps the first of its smallest costs (its candidates come in
/// increasing index, one per column).
///
/// # Safety
/// `n >= 1`; `ap` points at `2 n` readable aligned words; for `k < n`, `pe - 2k`, `pd - 2k`
/// and both plus `off` bytes point at two writable `u16` each (any alignment of 2 bytes).
#[inline(always)]
pub(crate) unsafe fn right_groups(
    ap: *const u32,
    pe: *mut u16,
    pd: *mut u16,
    off: usize,
    n: usize,
) {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        // Safety: the caller's contract.
        unsafe { right_groups_asm(ap, pe, pd, off, n) };
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    {
        let mut jj = INDEX_E0;
        // Safety: the caller's contract; pairs are read and written as unaligned `u32`.
        unsafe {
            for k in 0..n {
                let (e, d) = (*ap.add(2 * k), *ap.add(2 * k + 1));
                for (c, a, i) in [(pe.sub(2 * k), e, jj), (pd.sub(2 * k), d, jj - INDEX_D)] {
                    let cp = c.cast::<u32>();
                    let ip = c.cast::<u8>().add(off).cast::<u32>();
                    let (m, x) = min_u16x2(cp.read_unaligned(), ip.read_unaligned(), a, i);
                    cp.write_unaligned(m);
                    ip.write_unaligned(x);
                }
                jj += INDEX_STEP;
            }
        }
    }
}

/// [`right_groups`] as one Armv7E-M loop (19 instructions per group).
///
/// # Safety
/// As [`right_groups`].
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
unsafe fn right_groups_asm(ap: *const u32, pe: *mut u16, pd: *mut u16, off: usize, n: usize) {
    // Safety: reads `2 n` aligned words at `ap`, reads and writes the pairs at `pe - 2k`,
    // `pd - 2k` and `off` bytes further (the caller's contract; single LDR/STR, which the
    // Cortex-M4/M7 allow unaligned), nothing else; no stack. `USUB16` sets the GE flags
    // that the two `SEL` after it read; the flags are not declared preserved.
    unsafe {
        core::arch::asm!(
            "movw {jj}, #3",
            "movt {jj}, #1",
            "2:",
            "ldrd {e}, {d}, [{ap}], #8",
            "ldr {c}, [{pe}]",
            "ldr {i}, [{pe}, {off}]",
            "usub16 {t}, {e}, {c}",
            "sel {c}, {c}, {e}",
            "sel {i}, {i}, {jj}",
            "str {i}, [{pe}, {off}]",
            "str {c}, [{pe}], #-4",
            "sub {e}, {jj}, #0x10001",
            "ldr {c}, [{pd}]",
            "ldr {i}, [{pd}, {off}]",
            "usub16 {t}, {d}, {c}",
            "sel {c}, {c}, {d}",
            "sel {i}, {i}, {e}",
            "str {i}, [{pd}, {off}]",
            "str {c}, [{pd}], #-4",
            "add {jj}, {jj}, #0x40004",
            "subs {n}, {n}, #1",
            "bne 2b",
            ap = inout(reg) ap => _,
            pe = inout(reg) pe => _,
            pd = inout(reg) pd => _,
            off = in(reg) off,
            n = inout(reg) n => _,
            jj = out(reg) _,
            e = out(reg) _,
            d = out(reg) _,
            c = out(reg) _,
            i = out(reg) _,
            t = out(reg) _,
            options(nostack),
        );
    }
}
