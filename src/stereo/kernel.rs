//! The per-column loops of the band matcher ([`super::band`]): the column sums' update by
//! one row in and one row out and their set-up, the window slide with the lane minima, and
//! the right image's winners.
//!
//! All run over the groups of four disparities of a row, two `u16` lanes per word (the
//! layout of `band::lane`). With the `armv7em-dsp` feature on Arm (Cortex-M4/M7, the flight
//! firmware) each is one assembly loop that keeps all its state in registers (`USUB16` and
//! `SEL` for the lane minima); elsewhere the portable loops below, which give the same
//! result for every input (the host tests run the matcher built on them against the scalar
//! reference, and the QEMU budget checks the firmware's output against the host's to the
//! bit).

use super::band::lane;
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::swar::{absdiff_u8x4, split_u8x4};
use super::swar::{min2_u16x2, min_u16x2};

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

/// Column `x`'s sums of `n` groups at `pc` (two words per group) take one row in and one
/// row out: group `k`'s four right pixels of the new row are the bytes at `pn - 4k`, of
/// the old row at `po - 4k` (byte 0 the largest disparity, [`split_u8x4`]), against the
/// left pixels `a4` and `b4` (the new and the old row's, in all four bytes). The portable
/// form of [`update_columns`]' inner loop.
///
/// # Safety
/// `pc` points at `2 n` writable aligned words; `pn - 4k` and `po - 4k` (`k < n`) at four
/// readable bytes each (any alignment). Every lane stays below 2^16 and the outgoing cost
/// is part of the sum (the caller's bounds): adding first, then subtracting is exact lane
/// by lane.
#[cfg(any(test, not(all(target_arch = "arm", feature = "armv7em-dsp"))))]
#[inline(always)]
pub(crate) unsafe fn update_groups(
    pc: *mut u32,
    pn: *const u8,
    po: *const u8,
    a4: u32,
    b4: u32,
    n: usize,
) {
    // Safety: the caller's contract; bytes are read four at a time as unaligned `u32`, the
    // pointers step back with `wrapping_sub` (not read after the last group).
    unsafe {
        let (mut pc, mut pn, mut po) = (pc, pn, po);
        for _ in 0..n {
            let (en, on) = split_u8x4(absdiff_u8x4(a4, pn.cast::<u32>().read_unaligned()));
            let (eo, oo) = split_u8x4(absdiff_u8x4(b4, po.cast::<u32>().read_unaligned()));
            *pc = *pc + en - eo;
            *pc.add(1) = *pc.add(1) + on - oo;
            pc = pc.add(2);
            pn = pn.wrapping_sub(4);
            po = po.wrapping_sub(4);
        }
    }
}

/// The fast columns of one column-sum update ([`update_groups`] for each): column `x`'s
/// left pixels are the bytes at `pl + x`, `pm + x` (the new and the old row's), its right
/// pixels start at `pn + x`, `po + x`, its sums at `pc + x * stride` bytes; `cols`
/// columns, `n` groups each. The fields advance as the columns are done (the assembly
/// keeps them here between columns).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct UpdateCols {
    pub(crate) pl: *const u8,
    pub(crate) pm: *const u8,
    pub(crate) pn: *const u8,
    pub(crate) po: *const u8,
    pub(crate) pc: *mut u32,
    pub(crate) stride: usize,
    pub(crate) cols: usize,
    pub(crate) n: usize,
}

/// Runs [`update_groups`] over the columns of `u`.
///
/// # Safety
/// `u.cols >= 1`, `u.n >= 1`; for each column `x < u.cols` the contract of
/// [`update_groups`] with `pc + x * stride` (bytes, aligned words), `pn + x`, `po + x`, and
/// one readable byte at `pl + x` and `pm + x`.
#[inline(always)]
pub(crate) unsafe fn update_columns(u: &mut UpdateCols) {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        // Safety: as `update_groups` for each column (the caller's contract); reads and
        // writes the fields of `u` (`#[repr(C)]`, words at offsets 0, 4, ..., 28); no
        // stack; the flags are not declared preserved. r6 and r7 are reserved: the
        // registers are fixed so that the LDM/STM lists are in ascending order.
        unsafe {
            core::arch::asm!(
                "30:",
                "ldm r0, {{r1, r2, r3, r4, r5}}",
                "ldrb r8, [r1], #1",
                "ldrb r9, [r2], #1",
                "ldr r10, [r0, #20]",
                "add r11, r3, #1",
                "add r12, r4, #1",
                "add lr, r5, r10",
                "stm r0, {{r1, r2, r11, r12, lr}}",
                "orr r8, r8, r8, lsl #8",
                "orr r8, r8, r8, lsl #16",
                "orr r9, r9, r9, lsl #8",
                "orr r9, r9, r9, lsl #16",
                "ldr r10, [r0, #28]",
                "31:",
                "ldr r11, [r3], #-4",
                "uqsub8 lr, r8, r11",
                "uqsub8 r11, r11, r8",
                "orr r11, r11, lr",
                "ldr r12, [r4], #-4",
                "uqsub8 lr, r9, r12",
                "uqsub8 r12, r12, r9",
                "orr r12, r12, lr",
                // The new row's cost minus the old one's, per byte: both at most 126
                // (`2 prefilter_cap`), so the signed byte difference is exact, and each
                // lane takes it sign-extended (the sum stays a column cost: no lane
                // carries or borrows).
                "ssub8 r11, r11, r12",
                "ldrd r1, r2, [r5]",
                "sxtab16 r1, r1, r11",
                "sxtab16 r2, r2, r11, ror #8",
                "strd r1, r2, [r5], #8",
                "subs r10, r10, #1",
                "bne 31b",
                "ldr r10, [r0, #24]",
                "subs r10, r10, #1",
                "str r10, [r0, #24]",
                "bne 30b",
                inout("r0") u as *mut UpdateCols => _,
                out("r1") _,
                out("r2") _,
                out("r3") _,
                out("r4") _,
                out("r5") _,
                out("r8") _,
                out("r9") _,
                out("r10") _,
                out("r11") _,
                out("r12") _,
                out("lr") _,
                options(nostack),
            );
        }
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    // Safety: the caller's contract, column by column.
    unsafe {
        while u.cols > 0 {
            let a4 = u32::from(*u.pl) * 0x0101_0101;
            let b4 = u32::from(*u.pm) * 0x0101_0101;
            update_groups(u.pc, u.pn, u.po, a4, b4, u.n);
            u.pl = u.pl.add(1);
            u.pm = u.pm.add(1);
            u.pn = u.pn.wrapping_add(1);
            u.po = u.po.wrapping_add(1);
            u.pc = u.pc.cast::<u8>().wrapping_add(u.stride).cast::<u32>();
            u.cols -= 1;
        }
    }
}

/// Column `x`'s sums of `n` groups at `pc` take one row's costs: group `k`'s four right
/// pixels are the bytes at `pr - 4k`, against the left pixel `l4` (in all four bytes).
///
/// # Safety
/// `n >= 1`; `pc` points at `2 n` writable aligned words; `pr - 4k` (`k < n`) at four
/// readable bytes. Every lane stays below 2^16 (the caller's bounds).
#[inline(always)]
pub(crate) unsafe fn add_groups(pc: *mut u32, pr: *const u8, l4: u32, n: usize) {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        // Safety: reads `4 n` bytes below and at `pr` one word at a time (single LDR,
        // unaligned allowed) and reads and writes `2 n` aligned words at `pc` (the caller's
        // contract); no stack. The flags are not declared preserved.
        unsafe {
            core::arch::asm!(
                "2:",
                "ldr {t}, [{pr}], #-4",
                "uqsub8 {x}, {l4}, {t}",
                "uqsub8 {t}, {t}, {l4}",
                "orr {t}, {t}, {x}",
                "ldrd {c0}, {c1}, [{pc}]",
                "uxtab16 {c0}, {c0}, {t}",
                "uxtab16 {c1}, {c1}, {t}, ror #8",
                "strd {c0}, {c1}, [{pc}], #8",
                "subs {n}, {n}, #1",
                "bne 2b",
                pc = inout(reg) pc => _,
                pr = inout(reg) pr => _,
                n = inout(reg) n => _,
                l4 = in(reg) l4,
                t = out(reg) _,
                x = out(reg) _,
                c0 = out(reg) _,
                c1 = out(reg) _,
                options(nostack),
            );
        }
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    // Safety: the caller's contract; as in [`update_groups`].
    unsafe {
        let (mut pc, mut pr) = (pc, pr);
        for _ in 0..n {
            let (e, o) = split_u8x4(absdiff_u8x4(l4, pr.cast::<u32>().read_unaligned()));
            *pc += e;
            *pc.add(1) += o;
            pc = pc.add(2);
            pr = pr.wrapping_sub(4);
        }
    }
}

/// [`column`]'s verdict: the winner lies on its range's edge, or its window reaches
/// outside the right image.
pub(crate) const EDGE: u32 = u32::MAX;
/// [`column`]'s verdict: another lane's minimum, more than one index from the winner, is
/// below the uniqueness threshold.
pub(crate) const UNIQUE: u32 = u32::MAX - 1;

/// A row's settings for [`column`] (and the column's own `lim`), in the order the assembly
/// reads them.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct ColumnParams {
    /// Groups of the row (>= 1).
    pub(crate) n: u32,
    /// Bytes from a right pixel's cost to its index.
    pub(crate) off: u32,
    /// The row's range, indices from its first group.
    pub(crate) lo: u32,
    pub(crate) hi: u32,
    /// The largest index whose window lies inside the right image: `x - r - d0` (may be
    /// negative).
    pub(crate) lim: i32,
    /// `99 - uniqueness_pct` and `100 - uniqueness_pct` (>= 50).
    pub(crate) um1: u32,
    pub(crate) den: u32,
    /// The gap the runner-up needs, cost units.
    pub(crate) gap: u32,
}

/// The winner of a column's lane minima and the first uniqueness test: [`EDGE`] when the
/// winner (the first minimum: smallest cost, then smallest index) lies on the range's edge
/// (`j <= lo`, `j >= hi`) or past `lim`; [`UNIQUE`] when another lane's minimum more than
/// one index from it is below the threshold `t` ([`threshold`]); else the winner as `cost
/// << 16 | index`, for the exact runner-up.
#[inline(always)]
pub(crate) fn decide(m: &LaneMin, p: &ColumnParams) -> u32 {
    let keys = [
        (m.be << 16) | (m.ie & 0xffff),
        (m.be & 0xffff_0000) | (m.ie >> 16),
        (m.bd << 16) | (m.id & 0xffff),
        (m.bd & 0xffff_0000) | (m.id >> 16),
    ];
    let key = keys.iter().fold(u32::MAX, |a, &k| a.min(k));
    let (best, j) = (key >> 16, key & 0xffff);
    if j <= p.lo || j >= p.hi || j as i32 > p.lim {
        return EDGE;
    }
    let t = threshold(best, p);
    // A lane's index i is at or next to j when i - (j - 1) is 0, 1 or 2 (j >= 1).
    let jm1 = j - 1;
    if keys
        .iter()
        .any(|&k| (k & 0xffff).wrapping_sub(jm1) > 2 && (k >> 16) < t)
    {
        return UNIQUE;
    }
    key
}

/// The runner-up cost below which the winner `best` is not unique: `s (100 - u) < 100
/// best` or `s < best + gap`, i.e. `s` below the larger of `ceil(100 best / (100 - u))` and
/// `best + gap`, and never a biased lane's (`0x8000` or more).
#[inline(always)]
pub(crate) fn threshold(best: u32, p: &ColumnParams) -> u32 {
    ((100 * best + p.um1).checked_div(p.den))
        .unwrap_or(0)
        .max(best + p.gap)
        .min(0x8000)
}

/// The smallest cost of the row's words outside indices `j - 1 ..= j + 1` (relative to
/// the row's first group, `1 <= j`, `j + 1 < 4 groups`), and the costs of `j - 1` (low) and
/// `j + 1` (high); a smallest cost of `0x8000` or more means none. The three lanes are set
/// to `0xffff` (above every cost) in their words for the scan, and their words restored
/// after it.
#[inline(always)]
pub(crate) fn runner_up(ap: &mut [u32], j: usize) -> (u32, u32) {
    let ((i0, s0), (i1, s1), (i2, s2)) = (lane(j - 1), lane(j), lane(j + 1));
    let (Some(&w0), Some(&w2)) = (ap.get(i0), ap.get(i2)) else {
        return (0, 0);
    };
    let costs = ((w0 >> s0) & 0xffff) | (((w2 >> s2) & 0xffff) << 16);
    // Words may coincide: each is masked after the one before it, and restored in the
    // reverse order, so the first saved value (the original) is the last written.
    let mut saved = [0u32; 3];
    for ((i, sh), o) in [(i0, s0), (i1, s1), (i2, s2)].into_iter().zip(&mut saved) {
        if let Some(v) = ap.get_mut(i) {
            *o = *v;
            *v |= 0xffff << sh;
        }
    }
    let m = ap.iter().fold(u32::MAX, |m, &v| min2_u16x2(m, v));
    for (i, o) in [i2, i1, i0].into_iter().zip(saved.into_iter().rev()) {
        if let Some(v) = ap.get_mut(i) {
            *v = o;
        }
    }
    ((m & 0xffff).min(m >> 16), costs)
}

/// The exact uniqueness test of a winner `key` (`cost << 16 | index`) that passed
/// [`decide`]: [`UNIQUE`] when the runner-up more than one index away ([`runner_up`]) is
/// below the threshold ([`threshold`]), else `key` with the costs of its two neighbours
/// (index - 1 low, index + 1 high).
#[inline(never)]
pub(crate) fn unique(ap: &mut [u32], key: u32, p: &ColumnParams) -> (u32, u32) {
    let (best, j) = (key >> 16, (key & 0xffff) as usize);
    if j == 0 {
        return (UNIQUE, 0);
    }
    let (run, costs) = runner_up(ap, j);
    if run < threshold(best, p) {
        (UNIQUE, 0)
    } else {
        (key, costs)
    }
}

/// One column of a row whose groups' right pixels all lie inside the image: the window
/// slide and its lane minima ([`slide_min`]), the right image's winners
/// ([`right_groups`], `pe`, `pd`, `p.off`), then [`decide`] and, for a winner that passes
/// it, [`unique`]: the verdict ([`EDGE`], [`UNIQUE`] or the winner) and the winner's
/// neighbours' costs.
///
/// # Safety
/// As [`slide_min`] with the slide and [`right_groups`], with `p.n` groups.
#[inline(always)]
pub(crate) unsafe fn column(
    ap: *mut u32,
    ci: *const u32,
    co: *const u32,
    pe: *mut u16,
    pd: *mut u16,
    p: &ColumnParams,
) -> (u32, u32) {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        // Safety: the caller's contract.
        unsafe { column_asm(ap, ci, co, pe, pd, p) }
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    {
        let n = p.n as usize;
        // Safety: the caller's contract.
        let m = unsafe { slide_min::<true>(ap, ci, co, n) };
        // Safety: the caller's contract.
        unsafe { right_groups(ap, pe, pd, p.off as usize, n) };
        match decide(&m, p) {
            key @ (EDGE | UNIQUE) => (key, 0),
            // Safety: `ap` points at `2 n` words that nothing else refers to during the
            // call (the caller's contract).
            key => unique(
                unsafe { core::slice::from_raw_parts_mut(ap, 2 * n) },
                key,
                p,
            ),
        }
    }
}

/// [`column`] as one Armv7E-M block: the slide loop, the four lane keys and their minimum,
/// the right winners' loop, then the edge and uniqueness tests and, for a winner that
/// passes them, the exact runner-up ([`runner_up`]: the three lanes at and next to the
/// winner set to `0xffff` for one scan of the words, then restored), in registers (values
/// live across a loop go to the stack with one PUSH and come back with one POP).
///
/// # Safety
/// As [`column`].
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
unsafe fn column_asm(
    ap: *mut u32,
    ci: *const u32,
    co: *const u32,
    pe: *mut u16,
    pd: *mut u16,
    p: &ColumnParams,
) -> (u32, u32) {
    let (res, costs): (u32, u32);
    // Safety: reads `2 n` aligned words at `ci` and `co`, reads and writes `2 n` aligned
    // words at `ap` (three of their halfwords written and restored by the exact runner-up:
    // the lanes of indices `j - 1 ..= j + 1 < 4 n`, little-endian) and the right winners' pairs at `pe`, `pd` (and `off` bytes further),
    // reads `p` (the caller's contract); pushes and pops 3 and 5 registers on the stack
    // (balanced). `USUB16` sets the GE flags the `SEL` after it read; no flags are
    // preserved. The registers are fixed (r6 and r7 are reserved) so that the register
    // lists of PUSH and POP are in ascending order. Thumb-2 modified immediates: 0x00010001,
    // 0x00040004, 0x8000.
    unsafe {
        core::arch::asm!(
            "ldr r8, [r5]",
            "push {{r3, r4, r5}}",
            // Slide and lane minima: be r3, ie r4, bd r5, id r9, jj r10.
            "mvn r3, #0",
            "mvn r4, #0",
            "mvn r5, #0",
            "mvn r9, #0",
            "movw r10, #3",
            "movt r10, #1",
            "21:",
            "ldrd r11, r12, [r0]",
            "ldr lr, [r1], #4",
            "add r11, r11, lr",
            "ldr lr, [r1], #4",
            "add r12, r12, lr",
            "ldr lr, [r2], #4",
            "sub r11, r11, lr",
            "ldr lr, [r2], #4",
            "sub r12, r12, lr",
            "strd r11, r12, [r0], #8",
            "usub16 lr, r11, r3",
            "sel r3, r3, r11",
            "sel r4, r4, r10",
            "sub r11, r10, #0x10001",
            "usub16 lr, r12, r5",
            "sel r5, r5, r12",
            "sel r9, r9, r11",
            "add r10, r10, #0x40004",
            "subs r8, r8, #1",
            "bne 21b",
            // The four keys (cost << 16 | index) and the smallest, r11.
            "pkhbt r1, r4, r3, lsl #16",
            "pkhtb r2, r3, r4, asr #16",
            "pkhbt r8, r9, r5, lsl #16",
            "pkhtb r10, r5, r9, asr #16",
            "mov r11, r1",
            "cmp r11, r2",
            "it hi",
            "movhi r11, r2",
            "cmp r11, r8",
            "it hi",
            "movhi r11, r8",
            "cmp r11, r10",
            "it hi",
            "movhi r11, r10",
            "pop {{r3, r4, r5}}",
            "push {{r1, r2, r8, r10, r11}}",
            // Right winners: pe r3, pd r4, off r9, jj r10, from the row's first word.
            "ldr r8, [r5]",
            "ldr r9, [r5, #4]",
            "sub r0, r0, r8, lsl #3",
            "movw r10, #3",
            "movt r10, #1",
            "22:",
            "ldrd r11, r12, [r0], #8",
            "ldr r1, [r3]",
            "ldr r2, [r3, r9]",
            "usub16 lr, r11, r1",
            "sel r1, r1, r11",
            "sel r2, r2, r10",
            "str r2, [r3, r9]",
            "str r1, [r3], #-4",
            "sub r11, r10, #0x10001",
            "ldr r1, [r4]",
            "ldr r2, [r4, r9]",
            "usub16 lr, r12, r1",
            "sel r1, r1, r12",
            "sel r2, r2, r11",
            "str r2, [r4, r9]",
            "str r1, [r4], #-4",
            "add r10, r10, #0x40004",
            "subs r8, r8, #1",
            "bne 22b",
            "pop {{r1, r2, r8, r10, r11}}",
            // Edge: j r12 <= lo, >= hi, or > lim (signed).
            "uxth r12, r11",
            "ldr r9, [r5, #8]",
            "cmp r12, r9",
            "bls 28f",
            "ldr r9, [r5, #12]",
            "cmp r12, r9",
            "bhs 28f",
            "ldr r9, [r5, #16]",
            "cmp r12, r9",
            "bgt 28f",
            // Threshold r9 = min(max(ceil(100 best / den), best + gap), 0x8000).
            "lsr lr, r11, #16",
            "mov r9, #100",
            "mul r9, r9, lr",
            "ldr r3, [r5, #20]",
            "add r9, r9, r3",
            "ldr r3, [r5, #24]",
            "udiv r9, r9, r3",
            "ldr r3, [r5, #28]",
            "add r3, r3, lr",
            "cmp r9, r3",
            "it lo",
            "movlo r9, r3",
            "cmp r9, #0x8000",
            "it hi",
            "movhi r9, #0x8000",
            // A key more than one index from j (index - (j - 1) > 2) below the threshold.
            "sub r12, r12, #1",
            "uxth r3, r1",
            "sub r3, r3, r12",
            "cmp r3, #2",
            "bls 23f",
            "cmp r9, r1, lsr #16",
            "bhi 29f",
            "23:",
            "uxth r3, r2",
            "sub r3, r3, r12",
            "cmp r3, #2",
            "bls 24f",
            "cmp r9, r2, lsr #16",
            "bhi 29f",
            "24:",
            "uxth r3, r8",
            "sub r3, r3, r12",
            "cmp r3, #2",
            "bls 25f",
            "cmp r9, r8, lsr #16",
            "bhi 29f",
            "25:",
            "uxth r3, r10",
            "sub r3, r3, r12",
            "cmp r3, #2",
            "bls 26f",
            "cmp r9, r10, lsr #16",
            "bhi 29f",
            // The exact runner-up: the halfword of index k lies at byte `8 (k >> 2) + 6 -
            // 4 (k & 1) - (k & 2)` of the row's words (`band::lane`): j - 1 at r1, j at r2,
            // j + 1 at r10 (each minus 6).
            "26:",
            "ldr r8, [r5]",
            "sub r0, r0, r8, lsl #3",
            "lsr r1, r12, #2",
            "add r1, r0, r1, lsl #3",
            "and r3, r12, #1",
            "sub r1, r1, r3, lsl #2",
            "and r3, r12, #2",
            "sub r1, r1, r3",
            "add r4, r12, #1",
            "lsr r2, r4, #2",
            "add r2, r0, r2, lsl #3",
            "and r3, r4, #1",
            "sub r2, r2, r3, lsl #2",
            "and r3, r4, #2",
            "sub r2, r2, r3",
            "add r4, r12, #2",
            "lsr r10, r4, #2",
            "add r10, r0, r10, lsl #3",
            "and r3, r4, #1",
            "sub r10, r10, r3, lsl #2",
            "and r3, r4, #2",
            "sub r10, r10, r3",
            // The neighbours' costs, r3 (j - 1 low, j + 1 high); the three lanes masked.
            "ldrh r3, [r1, #6]",
            "ldrh r4, [r10, #6]",
            "pkhbt r3, r3, r4, lsl #16",
            "movw r4, #0xffff",
            "strh r4, [r1, #6]",
            "strh r4, [r2, #6]",
            "strh r4, [r10, #6]",
            // The smallest lane of all `2 n` words, r4, two words a step.
            "mvn r4, #0",
            "27:",
            "ldrd lr, r12, [r0], #8",
            "usub16 r5, lr, r4",
            "sel r4, r4, lr",
            "usub16 r5, r12, r4",
            "sel r4, r4, r12",
            "subs r8, r8, #1",
            "bne 27b",
            // Restored: j + 1, j (the winner's cost), j - 1.
            "lsr lr, r3, #16",
            "strh lr, [r10, #6]",
            "lsr lr, r11, #16",
            "strh lr, [r2, #6]",
            "strh r3, [r1, #6]",
            "uxth lr, r4",
            "cmp lr, r4, lsr #16",
            "it hi",
            "lsrhi lr, r4, #16",
            "mov r1, r3",
            "cmp lr, r9",
            "blo 29f",
            "b 30f",
            "28:",
            "mvn r11, #0",
            "b 30f",
            "29:",
            "mvn r11, #1",
            "30:",
            inout("r0") ap => _,
            inout("r1") ci => costs,
            inout("r2") co => _,
            inout("r3") pe => _,
            inout("r4") pd => _,
            inout("r5") p as *const ColumnParams => _,
            out("r8") _,
            out("r9") _,
            out("r10") _,
            out("r11") res,
            out("r12") _,
            out("lr") _,
        );
    }
    (res, costs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runner_up_skips_the_winner_and_its_neighbours_and_restores_the_words() {
        // Four groups of pseudo-random lane costs; every winner index in range.
        let mut seed = 0x2545_f491u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % 2000
        };
        for _ in 0..50 {
            let ap0: [u32; 8] = core::array::from_fn(|_| next() | (next() << 16));
            let cost = |j: usize| {
                let (i, s) = lane(j);
                (ap0[i] >> s) & 0xffff
            };
            for j in 1..15 {
                let mut ap = ap0;
                let (run, costs) = runner_up(&mut ap, j);
                let want = (0..16)
                    .filter(|&i: &usize| i.abs_diff(j) > 1)
                    .map(cost)
                    .min()
                    .unwrap_or(u32::MAX);
                assert_eq!(run, want, "index {j}");
                assert_eq!(costs, cost(j - 1) | (cost(j + 1) << 16), "index {j}");
                assert_eq!(ap, ap0, "index {j}: words restored");
            }
        }
    }

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

    #[test]
    fn column_sums_take_a_row_in_and_a_row_out() {
        // Two groups; right bytes of the new row 10..18, of the old row 20..28.
        let new: [u8; 8] = [1, 2, 3, 4, 5, 6, 7, 8];
        let old: [u8; 8] = [9, 9, 9, 9, 0, 0, 0, 0];
        let mut cs = [100u32 | 100 << 16; 4];
        let (a4, b4) = (5u32 * 0x0101_0101, 3u32 * 0x0101_0101);
        // Safety: group 0 reads bytes 4..8, group 1 bytes 0..4; four words.
        unsafe {
            update_groups(
                cs.as_mut_ptr(),
                new.as_ptr().add(4),
                old.as_ptr().add(4),
                a4,
                b4,
                2,
            );
        }
        // Group 0: new |5 - (5, 6, 7, 8)| = (0, 1, 2, 3), old |3 - 0| = 3: word 0 takes
        // bytes 0 and 2 (+0 -3, +2 -3), word 1 bytes 1 and 3 (+1 -3, +3 -3).
        assert_eq!(cs[0], 97 | 99 << 16);
        assert_eq!(cs[1], 98 | 100 << 16);
        // Group 1: new |5 - (1, 2, 3, 4)| = (4, 3, 2, 1), old |3 - 9| = 6.
        assert_eq!(cs[2], 98 | 96 << 16);
        assert_eq!(cs[3], 97 | 95 << 16);
        let mut z = [0u32; 4];
        // Safety: as above.
        unsafe { add_groups(z.as_mut_ptr(), new.as_ptr().add(4), a4, 2) };
        assert_eq!(z, [2 << 16, 1 | 3 << 16, 4 | 2 << 16, 3 | 1 << 16]);
    }
}
