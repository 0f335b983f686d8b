//! The two per-column loops of the band matcher's winner-take-all ([`super::band`]): the
//! window slide with the lane minima, and the right image's winners.
//!
//! Both run over the groups of four disparities of a row, two `u16` lanes per word (the
//! layout of `band::lane`). With the `armv7em-dsp` feature on Arm (Cortex-M4/M7, the flight
//! firmware) each is one assembly loop that keeps all its state in registers (`USUB16` and
//! `SEL` for the lane minima); elsewhere the portable loops below, which give the same
//! result for every input (the host tests run the matcher built on them against the scalar
//! reference, and the QEMU budget checks the firmware's output against the host's to the
//! bit).

use super::swar::min_u16x2;

/// The lane minima of a row's words with their first indices, for the words of index
/// `4k + 3 | 4k + 1` (`be`, `ie`) and of `4k + 2 | 4k` (`bd`, `id`), `k` the group (from
/// the row's first group); `u32::MAX` lanes where no cost was below `0xffff`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LaneMin {
    pub(crate) be: u32,
    pub(crate) ie: u32,
    pub(crate) bd: u32,
    pub(crate) id: u32,
}

/// Index word of group 0's `e` word (`4k + 1` high, `4k + 3` low); each group adds
/// [`INDEX_STEP`], and the `d` word's is one less in both lanes. Indices are below 2^15:
/// no lane carries.
const INDEX_E0: u32 = 0x0001_0003;
const INDEX_STEP: u32 = 0x0004_0004;
const INDEX_D: u32 = 0x0001_0001;

/// Slides the row's words one column on (`SLIDE`: adds the words at `ci`, removes those at
/// `co`, stores the sums at `ap`) and returns their lane minima with their first indices
/// (each lane sees its indices in increasing order and keeps strict improvements).
///
/// # Safety
/// `groups >= 1`; `ap` points at `2 groups` writable words, aligned; `ci` and `co` (read
/// only with `SLIDE`) at `2 groups` readable words each, aligned; none overlaps `ap`. Every
/// lane sum stays below 2^16 (the caller's bounds), so no lane carries into the other.
#[inline(always)]
pub(crate) unsafe fn slide_min<const SLIDE: bool>(
    ap: *mut u32,
    ci: *const u32,
    co: *const u32,
    groups: usize,
) -> LaneMin {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    if SLIDE {
        // Safety: the caller's contract.
        return unsafe { slide_min_asm(ap, ci, co, groups) };
    }
    let (mut be, mut ie, mut bd, mut id) = (u32::MAX, u32::MAX, u32::MAX, u32::MAX);
    let mut jj = INDEX_E0;
    // Safety: the caller's contract; every offset is below `2 groups`.
    unsafe {
        for k in 0..groups {
            let (pa, pi, po) = (ap.add(2 * k), ci.add(2 * k), co.add(2 * k));
            let (mut e, mut d) = (*pa, *pa.add(1));
            if SLIDE {
                // Exact per lane (the caller's bounds).
                e = e + *pi - *po;
                d = d + *pi.add(1) - *po.add(1);
                *pa = e;
                *pa.add(1) = d;
            }
            (be, ie) = min_u16x2(be, ie, e, jj);
            (bd, id) = min_u16x2(bd, id, d, jj - INDEX_D);
            jj += INDEX_STEP;
        }
    }
    LaneMin { be, ie, bd, id }
}

/// [`slide_min`] with the slide, as one Armv7E-M loop (20 instructions per group).
///
/// # Safety
/// As [`slide_min`].
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
unsafe fn slide_min_asm(ap: *mut u32, ci: *const u32, co: *const u32, groups: usize) -> LaneMin {
    let (be, ie, bd, id): (u32, u32, u32, u32);
    // Safety: reads `2 groups` words at `ci` and `co`, reads and writes `2 groups` words at
    // `ap` (the caller's contract; LDRD/STRD on aligned words), nothing else; no stack.
    // `USUB16` sets the GE flags that the two `SEL` after it read; the flags are not
    // declared preserved. The immediates 0x00010001 and 0x00040004 are Thumb-2 modified
    // immediates.
    unsafe {
        core::arch::asm!(
            "mvn {be}, #0",
            "mvn {ie}, #0",
            "mvn {bd}, #0",
            "mvn {id}, #0",
            "movw {jj}, #3",
            "movt {jj}, #1",
            "2:",
            "ldrd {e}, {d}, [{ap}]",
            "ldr {t}, [{ci}], #4",
            "add {e}, {e}, {t}",
            "ldr {t}, [{ci}], #4",
            "add {d}, {d}, {t}",
            "ldr {t}, [{co}], #4",
            "sub {e}, {e}, {t}",
            "ldr {t}, [{co}], #4",
            "sub {d}, {d}, {t}",
            "strd {e}, {d}, [{ap}], #8",
            "usub16 {t}, {e}, {be}",
            "sel {be}, {be}, {e}",
            "sel {ie}, {ie}, {jj}",
            "sub {e}, {jj}, #0x10001",
            "usub16 {t}, {d}, {bd}",
            "sel {bd}, {bd}, {d}",
            "sel {id}, {id}, {e}",
            "add {jj}, {jj}, #0x40004",
            "subs {n}, {n}, #1",
            "bne 2b",
            ap = inout(reg) ap => _,
            ci = inout(reg) ci => _,
            co = inout(reg) co => _,
            n = inout(reg) groups => _,
            be = out(reg) be,
            ie = out(reg) ie,
            bd = out(reg) bd,
            id = out(reg) id,
            jj = out(reg) _,
            e = out(reg) _,
            d = out(reg) _,
            t = out(reg) _,
            options(nostack),
        );
    }
    LaneMin { be, ie, bd, id }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lane_minima_keep_the_first_smallest_of_each_lane() {
        // Three groups; lane costs chosen with ties across groups.
        let mut ap = [
            10u32 | 5 << 16,
            7 | 9 << 16,
            3 | 5 << 16,
            7 | 2 << 16,
            3 | 6 << 16,
            1 | 2 << 16,
        ];
        let z = [0u32; 6];
        // Safety: three groups of two words each, no overlap.
        let m = unsafe { slide_min::<true>(ap.as_mut_ptr(), z.as_ptr(), z.as_ptr(), 3) };
        // e words: low lane indices 3, 7, 11 (costs 10, 3, 3): 3 at 7; high 1, 5, 9 (5, 5,
        // 6): 5 at 1. d words: low 2, 6, 10 (7, 7, 1): 1 at 10; high 0, 4, 8 (9, 2, 2): 2 at 4.
        assert_eq!(
            m,
            LaneMin {
                be: 3 | 5 << 16,
                ie: 7 | 1 << 16,
                bd: 1 | 2 << 16,
                id: 10 | 4 << 16
            }
        );
        // The slide adds `ci` and removes `co` lane by lane.
        let ci = [1u32 | 1 << 16; 6];
        let co = [1u32; 6];
        let before = ap;
        // Safety: as above.
        unsafe { slide_min::<true>(ap.as_mut_ptr(), ci.as_ptr(), co.as_ptr(), 3) };
        for (a, b) in ap.iter().zip(before) {
            assert_eq!(*a, b + (1 << 16));
        }
    }

    #[test]
    fn right_winners_take_strict_improvements() {
        // Pixels 0..8: even costs, odd costs, then their indices (16 bytes further).
        let mut rb = [0xffffu16; 16];
        let ap = [5u32 | 6 << 16, 7 | 8 << 16];
        // b = 4: e -> pixels 4 (low, index 3) and 6 (high, index 1), d -> 5 (index 2), 7
        // (index 0).
        let off = 16;
        // Safety: pixel 4 is even entry 2, pixel 5 odd entry 2 (two elements each, inside).
        unsafe {
            let p = rb.as_mut_ptr();
            right_groups(ap.as_ptr(), p.add(2), p.add(4 + 2), off, 1);
        }
        assert_eq!(&rb[2..4], &[5, 6]);
        assert_eq!(&rb[6..8], &[7, 8]);
        assert_eq!(&rb[8 + 2..8 + 4], &[3, 1]);
        assert_eq!(&rb[8 + 6..8 + 8], &[2, 0]);
        // An equal cost does not replace; a smaller one does.
        let ap2 = [5u32 | 1 << 16, 9 | 8 << 16];
        // Safety: as above.
        unsafe {
            let p = rb.as_mut_ptr();
            right_groups(ap2.as_ptr(), p.add(2), p.add(4 + 2), off, 1);
        }
        assert_eq!(&rb[2..4], &[5, 1]);
        assert_eq!(&rb[8 + 2..8 + 4], &[3, 1]);
        assert_eq!(&rb[6..8], &[7, 8]);
    }
}
