//! The column sums' update by one row in and one row out, and their set-up when a group
//! of four disparities enters.

#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::super::swar::{absdiff_u8x4, split_u8x4};

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
