//! The window slide along a row's column sums, with the lane minima of every column
//! ([`LaneMin`]): one pass per column over the row's groups of four disparities.

use super::super::swar::min_u16x2;

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
pub(super) const INDEX_E0: u32 = 0x0001_0003;
pub(super) const INDEX_STEP: u32 = 0x0004_0004;
pub(super) const INDEX_D: u32 = 0x0001_0001;

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

/// Slides the row's words `cols` columns on without their minima (columns whose disparity
/// is not decided, `StereoParams::column_step`): for each column, adds the words at `ci`,
/// removes those at `co`, stores the sums at `ap`; the next column's words are `stride`
/// words further at `ci` and `co`.
///
/// # Safety
/// As [`slide_min`] with the slide, for each of the `cols >= 1` columns (`ci + j stride`,
/// `co + j stride` for `j < cols`); `groups >= 1`.
#[inline(always)]
pub(crate) unsafe fn slide(
    ap: *mut u32,
    ci: *const u32,
    co: *const u32,
    groups: usize,
    stride: usize,
    cols: usize,
) {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    if cols == 3 {
        // Three columns (every fourth decided) in one pass over the groups: each word of
        // `ap` loaded and stored once (22 instructions per group instead of 30).
        let (c1, c2) = (ci.wrapping_add(stride), ci.wrapping_add(2 * stride));
        let (o1, o2) = (co.wrapping_add(stride), co.wrapping_add(2 * stride));
        // Safety: reads `2 groups` aligned words at `ci + j stride` and `co + j stride` for
        // `j < 3`, reads and writes `2 groups` aligned words at `ap` (the caller's
        // contract; LDRD/STRD), nothing else; no stack; the flags are not declared
        // preserved. Each lane's sum after all three columns is the one after each column
        // in turn (the sums wrap modulo 2^32 the same way, and the caller's bounds keep
        // every intermediate lane exact).
        unsafe {
            core::arch::asm!(
                "2:",
                "ldrd r10, r11, [r0]",
                "ldrd r12, lr, [r1], #8",
                "add r10, r10, r12",
                "add r11, r11, lr",
                "ldrd r12, lr, [r4], #8",
                "sub r10, r10, r12",
                "sub r11, r11, lr",
                "ldrd r12, lr, [r2], #8",
                "add r10, r10, r12",
                "add r11, r11, lr",
                "ldrd r12, lr, [r5], #8",
                "sub r10, r10, r12",
                "sub r11, r11, lr",
                "ldrd r12, lr, [r3], #8",
                "add r10, r10, r12",
                "add r11, r11, lr",
                "ldrd r12, lr, [r8], #8",
                "sub r10, r10, r12",
                "sub r11, r11, lr",
                "strd r10, r11, [r0], #8",
                "subs r9, r9, #1",
                "bne 2b",
                inout("r0") ap => _,
                inout("r1") ci => _,
                inout("r2") c1 => _,
                inout("r3") c2 => _,
                inout("r4") co => _,
                inout("r5") o1 => _,
                inout("r8") o2 => _,
                inout("r9") groups => _,
                out("r10") _,
                out("r11") _,
                out("r12") _,
                out("lr") _,
                options(nostack),
            );
        }
        return;
    }
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        // Bytes from the end of one column's words to the next column's.
        let skip = 4 * (stride - 2 * groups);
        // Safety: reads `2 groups` aligned words at `ci + j stride` and `co + j stride`,
        // reads and writes `2 groups` aligned words at `ap` (the caller's contract;
        // LDRD/STRD), nothing else; no stack; the flags are not declared preserved.
        unsafe {
            core::arch::asm!(
                "3:",
                "mov {n}, {g}",
                "2:",
                "ldrd {e}, {d}, [{ap}]",
                "ldrd {t}, {u}, [{ci}], #8",
                "add {e}, {e}, {t}",
                "add {d}, {d}, {u}",
                "ldrd {t}, {u}, [{co}], #8",
                "sub {e}, {e}, {t}",
                "sub {d}, {d}, {u}",
                "strd {e}, {d}, [{ap}], #8",
                "subs {n}, {n}, #1",
                "bne 2b",
                "sub {ap}, {ap}, {g}, lsl #3",
                "add {ci}, {ci}, {skip}",
                "add {co}, {co}, {skip}",
                "subs {c}, {c}, #1",
                "bne 3b",
                ap = inout(reg) ap => _,
                g = in(reg) groups,
                skip = in(reg) skip,
                ci = inout(reg) ci => _,
                co = inout(reg) co => _,
                c = inout(reg) cols => _,
                n = out(reg) _,
                e = out(reg) _,
                d = out(reg) _,
                t = out(reg) _,
                u = out(reg) _,
                options(nostack),
            );
        }
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    // Safety: the caller's contract; every offset is below `(cols - 1) stride + 2 groups`.
    unsafe {
        for j in 0..cols {
            let (pi, po) = (ci.add(j * stride), co.add(j * stride));
            for k in 0..2 * groups {
                let pa = ap.add(k);
                // Exact per lane (the caller's bounds).
                *pa = *pa + *pi.add(k) - *po.add(k);
            }
        }
    }
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
