//! One steady column of the winner-take-all in one call: the slide, the lane minima, the
//! right image's winners and the verdict (on Armv7E-M one assembly block).

#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::right::right_groups;
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::slide::slide_min;
use super::verdict::ColumnParams;
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::verdict::{decide, unique, EDGE, UNIQUE};

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
