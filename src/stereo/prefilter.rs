//! Reduction and pre-filtering of the stereo frames, one row at a time (integer).

use super::swar::word;
use crate::image::ImageView;

/// Row `row` of `frame` reduced by `k` (1..=16, clamped; box average of `k x k` pixels,
/// rounded) into `out` (`frame.width() / k` pixels; a shorter `out` gets its first pixels, a
/// longer one keeps the rest). Rows past the reduced image (`row >= height / k`) leave
/// `out` as is. The matcher's coarser levels ([`super::scale`]) reduce by
/// `downsample * 2^level`.
pub fn downsample_row(frame: &ImageView<'_>, k: usize, row: usize, out: &mut [u8]) {
    downsample_row_by(frame, k, k, row, out);
}

/// Row `row` of `frame` reduced by `kx` across and `ky` down (each 1..=16, clamped; box
/// average of `kx x ky` pixels, rounded) into `out` (`frame.width() / kx` pixels; a shorter
/// `out` gets its first pixels, a longer one keeps the rest). Rows past the reduced image
/// leave `out` as is. [`downsample_row`] is the square case; the matcher's levels reduce by
/// `downsample * 2^level` across and `row_factor` times that down.
pub fn downsample_row_by(frame: &ImageView<'_>, kx: usize, ky: usize, row: usize, out: &mut [u8]) {
    let (k, ky) = (kx.clamp(1, 16), ky.clamp(1, 16));
    if ky != k {
        if k == 2 && ky == 4 {
            return reduce_2x4(frame, row, out);
        }
        if k % 4 == 0 && k * ky <= 256 {
            return reduce_words(frame, k, ky, row, out);
        }
        let w = frame.width().checked_div(k).unwrap_or(0);
        return reduce_rows(frame, k, ky, row, w, out);
    }
    let w = frame.width().checked_div(k).unwrap_or(0);
    let row_at = |i: usize| frame.row(row * k + i);
    match k {
        1 => {
            if let Some(src) = row_at(0) {
                for (o, &s) in out.iter_mut().zip(src).take(w) {
                    *o = s;
                }
            }
        }
        2 => {
            // The default: four output pixels from two words of each row, then one at a
            // time for the rest.
            if let (Some(a), Some(b)) = (row_at(0), row_at(1)) {
                let n4 = w.min(out.len()) / 4;
                let (head, _) = out.split_at_mut((4 * n4).min(out.len()));
                // On Armv7E-M the four-pixel steps are one assembly loop (nothing left for
                // the portable one below).
                #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
                let head: &mut [u8] = if n4 > 0 && a.len() >= 8 * n4 && b.len() >= 8 * n4 {
                    // Safety: `8 n4` bytes of `a` and `b` and `4 n4` of `head` (checked).
                    unsafe { reduce_2x2_asm(a.as_ptr(), b.as_ptr(), head.as_mut_ptr(), n4) };
                    &mut []
                } else {
                    head
                };
                for (o, (p, q)) in head
                    .chunks_exact_mut(4)
                    .zip(a.chunks_exact(8).zip(b.chunks_exact(8)))
                {
                    let (p0, p1) = (word(p), word(p.get(4..).unwrap_or(&[])));
                    let (q0, q1) = (word(q), word(q.get(4..).unwrap_or(&[])));
                    // Lanes: the sums of pixels 0..4 and 4..8 of both rows, + 2.
                    let lo = (pair_sums(p0) + pair_sums(q0) + 0x0002_0002) >> 2;
                    let hi = (pair_sums(p1) + pair_sums(q1) + 0x0002_0002) >> 2;
                    if let [o0, o1, o2, o3] = o {
                        *o0 = lo as u8;
                        *o1 = (lo >> 16) as u8;
                        *o2 = hi as u8;
                        *o3 = (hi >> 16) as u8;
                    }
                }
                for (o, (p, q)) in out
                    .iter_mut()
                    .zip(a.chunks_exact(2).zip(b.chunks_exact(2)))
                    .take(w)
                    .skip(4 * n4)
                {
                    if let ([p0, p1], [q0, q1]) = (p, q) {
                        let s = u32::from(*p0) + u32::from(*p1) + u32::from(*q0) + u32::from(*q1);
                        *o = ((s + 2) / 4) as u8;
                    }
                }
            }
        }
        3 => {
            if let (Some(a), Some(b), Some(c)) = (row_at(0), row_at(1), row_at(2)) {
                reduce([a, b, c], w, out);
            }
        }
        4 => {
            if let (Some(a), Some(b), Some(c), Some(d)) =
                (row_at(0), row_at(1), row_at(2), row_at(3))
            {
                // One output pixel from one word of each row: the byte pairs' sums in two
                // `u16` lanes (at most 4 * 510), then the two lanes.
                let blocks = a
                    .chunks_exact(4)
                    .zip(b.chunks_exact(4))
                    .zip(c.chunks_exact(4).zip(d.chunks_exact(4)));
                for (o, ((p, q), (r, s))) in out.iter_mut().zip(blocks).take(w) {
                    let t = pair_sums(word(p))
                        + pair_sums(word(q))
                        + pair_sums(word(r))
                        + pair_sums(word(s));
                    *o = (((t & 0xffff) + (t >> 16) + 8) >> 4) as u8;
                }
            }
        }
        // The second coarser level of the default rig (8 x 8): whole words of each row.
        _ if k % 4 == 0 && k * k <= 256 => reduce_words(frame, k, k, row, out),
        _ => reduce_rows(frame, k, k, row, w, out),
    }
}

/// [`downsample_row_by`] with `kx = 2`, `ky = 4` (the default rows of a `row_factor` 2
/// rig): four output pixels from two words of each of the four rows, then one at a time.
fn reduce_2x4(frame: &ImageView<'_>, row: usize, out: &mut [u8]) {
    let w = frame.width() / 2;
    let rows = [0, 1, 2, 3].map(|i| frame.row(row * 4 + i));
    let [Some(a), Some(b), Some(c), Some(d)] = rows else {
        return;
    };
    let n4 = w.min(out.len()) / 4;
    let (head, _) = out.split_at_mut((4 * n4).min(out.len()));
    let blocks = a
        .chunks_exact(8)
        .zip(b.chunks_exact(8))
        .zip(c.chunks_exact(8).zip(d.chunks_exact(8)));
    for (o, ((p, q), (r, t))) in head.chunks_exact_mut(4).zip(blocks) {
        let half = |v: &[u8], i: usize| pair_sums(word(v.get(i..).unwrap_or(&[])));
        // Lanes: the sums of pixels 0..4 (then 4..8) of the four rows, + 4; at most
        // 8 * 255 + 4 per 16-bit lane.
        let lo = (half(p, 0) + half(q, 0) + half(r, 0) + half(t, 0) + 0x0004_0004) >> 3;
        let hi = (half(p, 4) + half(q, 4) + half(r, 4) + half(t, 4) + 0x0004_0004) >> 3;
        if let [o0, o1, o2, o3] = o {
            *o0 = lo as u8;
            *o1 = (lo >> 16) as u8;
            *o2 = hi as u8;
            *o3 = (hi >> 16) as u8;
        }
    }
    let tail = a
        .chunks_exact(2)
        .zip(b.chunks_exact(2))
        .zip(c.chunks_exact(2).zip(d.chunks_exact(2)));
    for (o, ((p, q), (r, t))) in out.iter_mut().zip(tail).take(w).skip(4 * n4) {
        let s: u32 = [p, q, r, t]
            .iter()
            .flat_map(|v| v.iter())
            .map(|&x| u32::from(x))
            .sum();
        *o = ((s + 4) / 8) as u8;
    }
}

/// Box average of `k x ky` pixels (`k` across, `ky` down, each 1..=16) of rows
/// `row ky .. row ky + ky` into the first `w` pixels of `out`.
fn reduce_rows(frame: &ImageView<'_>, k: usize, ky: usize, row: usize, w: usize, out: &mut [u8]) {
    let area = (k * ky) as u32;
    let out = match out.get_mut(..w.min(out.len())) {
        Some(o) => o,
        None => return,
    };
    if (0..ky).any(|i| frame.row(row * ky + i).is_none()) {
        return;
    }
    for (x, o) in out.iter_mut().enumerate() {
        let mut s = 0u32;
        for i in 0..ky {
            if let Some(p) = frame
                .row(row * ky + i)
                .and_then(|r| r.get(x * k..x * k + k))
            {
                s += p.iter().map(|&v| u32::from(v)).sum::<u32>();
            }
        }
        // At most 16 * 16 * 255: no overflow (`checked_div`: no panic path; area >= 1).
        *o = (s + area / 2).checked_div(area).unwrap_or(0) as u8;
    }
}

/// [`downsample_row_by`] with `kx` a multiple of 4 (`kx ky <= 256`: the coarser levels of
/// a `row_factor` 2 rig, 4 x 8 and 8 x 16): each output pixel sums whole words of each row
/// in two `u16` lanes (at most `kx ky / 2 * 255`), 32 output pixels at a time.
fn reduce_words(frame: &ImageView<'_>, kx: usize, ky: usize, row: usize, out: &mut [u8]) {
    const CHUNK: usize = 32;
    let w = frame.width().checked_div(kx).unwrap_or(0).min(out.len());
    if (0..ky).any(|i| frame.row(row * ky + i).is_none()) {
        return;
    }
    let area = (kx * ky) as u32;
    let words = kx / 4;
    let mut x0 = 0;
    while x0 < w {
        let n = CHUNK.min(w - x0);
        let mut acc = [0u32; CHUNK];
        for i in 0..ky {
            let Some(r) = frame.row(row * ky + i) else {
                return;
            };
            let src = r.get(x0 * kx..(x0 + n) * kx).unwrap_or(&[]);
            // The two coarser levels' widths unrolled; any other multiple of 4 word by word.
            match kx {
                4 => {
                    for (a, c) in acc.iter_mut().zip(src.chunks_exact(4)) {
                        *a += pair_sums(word(c));
                    }
                }
                8 => {
                    for (a, c) in acc.iter_mut().zip(src.chunks_exact(8)) {
                        let (lo, hi) = c.split_at(4);
                        *a += pair_sums(word(lo)) + pair_sums(word(hi));
                    }
                }
                _ => {
                    for (a, px) in acc.iter_mut().zip(src.chunks_exact(kx)) {
                        for c in px.chunks_exact(4).take(words) {
                            *a += pair_sums(word(c));
                        }
                    }
                }
            }
        }
        for (o, &a) in out.iter_mut().skip(x0).zip(acc.iter()).take(n) {
            let s = (a & 0xffff) + (a >> 16);
            *o = (s + area / 2).checked_div(area).unwrap_or(0) as u8;
        }
        x0 += n;
    }
}

/// The 2 x 2 reduction's four pixels a step ([`downsample_row_by`]) as one Armv7E-M loop:
/// the byte pairs of a word of each row summed in two `u16` lanes (`UXTB16`, `UXTAB16`),
/// plus 2, shifted down by 2 (a lane's sum is at most 1,022: the low lane's byte 0 and the
/// high lane's byte 2 then hold the two pixels, the bits the high lane shifted into the
/// low one lie above byte 1), and the four bytes packed (`UXTB16`, `ORR`, `PKHBT`).
///
/// # Safety
/// `n >= 1`; `8 n` bytes readable at `pa` and `pb`, `4 n` writable at `po`.
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
unsafe fn reduce_2x2_asm(pa: *const u8, pb: *const u8, po: *mut u8, n: usize) {
    // Safety: reads `8 n` bytes at `pa` and `pb` and writes `4 n` at `po` (the caller's
    // contract; single LDR/STR, which the Cortex-M4/M7 allow unaligned); no stack. The
    // flags are not declared preserved. 0x00020002 is a Thumb-2 modified immediate.
    unsafe {
        core::arch::asm!(
            "2:",
            "ldr {t}, [{pa}], #4",
            "uxtb16 {lo}, {t}",
            "uxtab16 {lo}, {lo}, {t}, ror #8",
            "ldr {t}, [{pb}], #4",
            "uxtab16 {lo}, {lo}, {t}",
            "uxtab16 {lo}, {lo}, {t}, ror #8",
            "ldr {t}, [{pa}], #4",
            "uxtb16 {hi}, {t}",
            "uxtab16 {hi}, {hi}, {t}, ror #8",
            "ldr {t}, [{pb}], #4",
            "uxtab16 {hi}, {hi}, {t}",
            "uxtab16 {hi}, {hi}, {t}, ror #8",
            "add {lo}, {lo}, #0x20002",
            "add {hi}, {hi}, #0x20002",
            "lsr {lo}, {lo}, #2",
            "lsr {hi}, {hi}, #2",
            "uxtb16 {lo}, {lo}",
            "uxtb16 {hi}, {hi}",
            "orr {lo}, {lo}, {lo}, lsr #8",
            "orr {hi}, {hi}, {hi}, lsr #8",
            "pkhbt {lo}, {lo}, {hi}, lsl #16",
            "str {lo}, [{po}], #4",
            "subs {n}, {n}, #1",
            "bne 2b",
            pa = inout(reg) pa => _,
            pb = inout(reg) pb => _,
            po = inout(reg) po => _,
            n = inout(reg) n => _,
            t = out(reg) _,
            lo = out(reg) _,
            hi = out(reg) _,
            options(nostack),
        );
    }
}

/// Sums of the byte pairs of `v` in two `u16` lanes: bytes 0 + 1 low, 2 + 3 high.
#[inline(always)]
fn pair_sums(v: u32) -> u32 {
    (v & 0x00ff_00ff) + ((v >> 8) & 0x00ff_00ff)
}

/// Box average of `K x K` pixels of the `K` source rows (rounded) into the first `w`
/// pixels of `out` (each row holds at least `w K` pixels: `w` = frame width / `K`).
#[inline(always)]
fn reduce<const K: usize>(rows: [&[u8]; K], w: usize, out: &mut [u8]) {
    let area = (K * K) as u32;
    let mut blocks = rows.map(|r| r.chunks_exact(K));
    for o in out.iter_mut().take(w) {
        let mut s = 0u32;
        for it in blocks.iter_mut() {
            if let Some(c) = it.next() {
                s += c.iter().map(|&p| u32::from(p)).sum::<u32>();
            }
        }
        // K is a constant: the division is a multiply and a shift.
        *o = ((s + area / 2) / area) as u8;
    }
}

/// Horizontal Sobel of the middle row of three (`above`, `mid`, `below`, equal lengths),
/// clipped to `±cap` and offset by `cap` (0..=2 cap) into `out`; the first and last columns
/// reuse their inner neighbour (replicated border).
pub fn prefilter(above: &[u8], mid: &[u8], below: &[u8], cap: u8, out: &mut [u8]) {
    let w = mid.len().min(above.len()).min(below.len()).min(out.len());
    if w == 0 {
        return;
    }
    let cap = i32::from(cap);
    let at = |r: &[u8], i: usize| r.get(i).map_or(0, |&p| i32::from(p));
    let edge = |x: usize| {
        let xl = x.saturating_sub(1);
        let xr = (x + 1).min(w - 1);
        let g = at(above, xr) - at(above, xl) + 2 * (at(mid, xr) - at(mid, xl)) + at(below, xr)
            - at(below, xl);
        (g.clamp(-cap, cap) + cap) as u8
    };
    if let Some(o) = out.first_mut() {
        *o = edge(0);
    }
    // Interior columns x = 1 .. w - 1 (w >= 3): with the column sums
    // `v(x) = above(x) + 2 mid(x) + below(x)` the Sobel is `v(x + 1) - v(x - 1)`.
    if w >= 3 {
        let v = |i: usize| -> i32 {
            match (above.get(i), mid.get(i), below.get(i)) {
                (Some(&a), Some(&m), Some(&b)) => i32::from(a) + 2 * i32::from(m) + i32::from(b),
                _ => 0,
            }
        };
        let (v0, v1) = (v(0), v(1));
        // Safety: `w` is at most every row's length (above), so columns `2 .. w` of the
        // three rows and `1 .. w - 1` of `out` exist.
        unsafe {
            sobel_interior(
                above.as_ptr().add(2),
                mid.as_ptr().add(2),
                below.as_ptr().add(2),
                out.as_mut_ptr().add(1),
                w - 2,
                v0,
                v1,
                cap,
            );
        }
    }
    if w >= 2 {
        if let Some(o) = out.get_mut(w - 1) {
            *o = edge(w - 1);
        }
    }
}

/// The interior of [`prefilter`]: `n` outputs at `po`, output `i` the clipped `v(i + 2) -
/// v(i)` with `v(0) = v0`, `v(1) = v1` and `v(i + 2)` from the bytes at `pa + i`, `pm + i`,
/// `pb + i` (`a + 2 m + b`), offset by `cap`.
///
/// # Safety
/// `n` bytes readable at `pa`, `pm`, `pb` and writable at `po`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn sobel_interior(
    pa: *const u8,
    pm: *const u8,
    pb: *const u8,
    po: *mut u8,
    n: usize,
    v0: i32,
    v1: i32,
    cap: i32,
) {
    let (mut pa, mut pm, mut pb, mut po) = (pa, pm, pb, po);
    let (mut v0, mut v1) = (v0, v1);
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    let left = n;
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    let left = n % 4;
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    if n >= 4 {
        let blocks = n / 4;
        let capw = (cap as u32) * 0x0001_0001;
        // `v` of the last block's last even and odd column (`v(i)`, `v(i + 1)` for the
        // next output `i`), low and high half.
        let mut last = (v0 as u32) | ((v1 as u32) << 16);
        // Safety: reads `4 blocks` bytes at `pa`, `pm`, `pb` and writes as many at `po`
        // (the caller's contract; single LDR/STR, which the Cortex-M4/M7 allow unaligned),
        // advancing each pointer; no stack. The flags are not declared preserved.
        //
        // Four outputs a step, in 16-bit lanes: `ve` = v of the even bytes of the block
        // (columns j, j + 2), `vo` of the odd ones (j + 1, j + 3), each `a + 2 m + b` <=
        // 1,020; outputs j - 2 and j (lanes of `u`) are `ve` minus (`last` low, `ve` low),
        // outputs j - 1 and j + 1 (lanes of `t`) `vo` minus (`last` high, `vo` low), both
        // within +-1,020; each is clipped to 0..=2 cap as `max(g + cap, 0)` (`USAT16`)
        // then the minimum with 2 cap (`USUB16`, `SEL`), and the byte order j - 2, j - 1,
        // j, j + 1 is `u | t << 8` (every lane below 256).
        unsafe {
            core::arch::asm!(
                "2:",
                "ldr r10, [r1], #4",
                "uxtb16 r11, r10",
                "uxtb16 r12, r10, ror #8",
                "lsl r11, r11, #1",
                "lsl r12, r12, #1",
                "ldr r10, [r0], #4",
                "uxtab16 r11, r11, r10",
                "uxtab16 r12, r12, r10, ror #8",
                "ldr r10, [r2], #4",
                "uxtab16 r11, r11, r10",
                "uxtab16 r12, r12, r10, ror #8",
                "ror r10, r12, #16",
                "pkhtb r10, r10, r5, asr #16",
                "ssub16 r10, r12, r10",
                "ror lr, r11, #16",
                "pkhbt lr, r5, lr",
                "ssub16 lr, r11, lr",
                "pkhtb r5, r12, r11, asr #16",
                "sadd16 r10, r10, r8",
                "usat16 r10, #15, r10",
                "usub16 r11, r10, r9",
                "sel r10, r9, r10",
                "sadd16 lr, lr, r8",
                "usat16 lr, #15, lr",
                "usub16 r11, lr, r9",
                "sel lr, r9, lr",
                "orr lr, lr, r10, lsl #8",
                "str lr, [r3], #4",
                "subs r4, r4, #1",
                "bne 2b",
                inout("r0") pa,
                inout("r1") pm,
                inout("r2") pb,
                inout("r3") po,
                inout("r4") blocks => _,
                inout("r5") last,
                in("r8") capw,
                in("r9") 2 * capw,
                out("r10") _,
                out("r11") _,
                out("r12") _,
                out("lr") _,
                options(nostack),
            );
        }
        (v0, v1) = ((last & 0xffff) as i32, (last >> 16) as i32);
    }
    // Safety: the caller's contract; one element per step for the `left` outputs.
    unsafe {
        for _ in 0..left {
            let v2 = i32::from(*pa) + 2 * i32::from(*pm) + i32::from(*pb);
            *po = ((v2 - v0).max(-cap).min(cap) + cap) as u8;
            (v0, v1) = (v1, v2);
            pa = pa.add(1);
            pm = pm.add(1);
            pb = pb.add(1);
            po = po.add(1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_blocks() {
        let mut buf = [0u8; 16];
        for (i, b) in buf.iter_mut().enumerate() {
            *b = (i * 10) as u8;
        }
        let img = ImageView::new(&buf, 4, 4).unwrap();
        let mut out = [0u8; 2];
        downsample_row(&img, 2, 0, &mut out);
        // (0 + 10 + 40 + 50) / 4 = 25, (20 + 30 + 60 + 70) / 4 = 45.
        assert_eq!(out, [25, 45]);
        downsample_row(&img, 2, 1, &mut out);
        assert_eq!(out, [105, 125]);
        let mut one = [0u8; 4];
        downsample_row(&img, 1, 3, &mut one);
        assert_eq!(one, [120, 130, 140, 150]);
    }

    #[test]
    fn sobel_is_clipped_and_offset() {
        let row = [10u8, 10, 20, 40, 40];
        let mut out = [0u8; 5];
        prefilter(&row, &row, &row, 31, &mut out);
        // x = 1: 4 * (20 - 10) = 40 -> clipped 31 -> 62; x = 0: 4 * (10 - 10) = 0 -> 31.
        assert_eq!(out, [31, 62, 62, 62, 31]);
        let flat = [7u8; 5];
        prefilter(&flat, &flat, &flat, 5, &mut out);
        assert_eq!(out, [5; 5]);
    }
    // The plain per-pixel forms these replaced, kept as references.
    fn downsample_row_ref(frame: &ImageView<'_>, k: usize, row: usize, out: &mut [u8]) {
        downsample_row_by_ref(frame, k, k, row, out);
    }

    fn downsample_row_by_ref(
        frame: &ImageView<'_>,
        k: usize,
        ky: usize,
        row: usize,
        out: &mut [u8],
    ) {
        let (k, ky) = (k.clamp(1, 16), ky.clamp(1, 16));
        let w = frame.width().checked_div(k).unwrap_or(0);
        let area = (k * ky) as u32;
        if (0..ky).any(|i| frame.row(row * ky + i).is_none()) {
            return;
        }
        for (i, o) in out.iter_mut().enumerate().take(w) {
            let mut s = 0u32;
            for r in (0..ky).filter_map(|j| frame.row(row * ky + j)) {
                if let Some(b) = r.get(i * k..i * k + k) {
                    s += b.iter().map(|&p| u32::from(p)).sum::<u32>();
                }
            }
            *o = (s + area / 2).checked_div(area).unwrap_or(0) as u8;
        }
    }

    /// Horizontal Sobel of the middle row of three (`above`, `mid`, `below`, equal lengths),
    /// clipped to `±cap` and offset by `cap` (0..=2 cap) into `out`; the first and last columns
    /// reuse their inner neighbour (replicated border).
    fn prefilter_ref(above: &[u8], mid: &[u8], below: &[u8], cap: u8, out: &mut [u8]) {
        let w = mid.len().min(above.len()).min(below.len()).min(out.len());
        if w == 0 {
            return;
        }
        let cap = i32::from(cap);
        let at = |r: &[u8], i: usize| r.get(i).map_or(0, |&p| i32::from(p));
        for (x, o) in out.iter_mut().enumerate().take(w) {
            let xl = x.saturating_sub(1);
            let xr = (x + 1).min(w - 1);
            let g = at(above, xr) - at(above, xl) + 2 * (at(mid, xr) - at(mid, xl)) + at(below, xr)
                - at(below, xl);
            *o = (g.clamp(-cap, cap) + cap) as u8;
        }
    }

    #[test]
    fn equal_to_the_per_pixel_references_on_random_rows() {
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 24) as u8
        };
        let mut img = [0u8; 37 * 33];
        for w in [1usize, 2, 3, 4, 5, 8, 13, 37] {
            let h = 33;
            for p in img.iter_mut() {
                *p = next();
            }
            let view = ImageView::new(&img[..w * h], w, h).unwrap();
            for k in 1..=16 {
                for row in 0..=h / k {
                    let (mut a, mut b) = ([3u8; 40], [3u8; 40]);
                    downsample_row(&view, k, row, &mut a);
                    downsample_row_ref(&view, k, row, &mut b);
                    assert_eq!(a, b, "w {w} k {k} row {row}");
                }
            }
            // Rows reduced more than columns (a `row_factor` 2 rig: 2 x 4, 4 x 8, 8 x 16).
            for (k, ky) in [(1, 2), (2, 4), (4, 8), (8, 16), (3, 5)] {
                for row in 0..=h / ky {
                    let (mut a, mut b) = ([3u8; 40], [3u8; 40]);
                    downsample_row_by(&view, k, ky, row, &mut a);
                    downsample_row_by_ref(&view, k, ky, row, &mut b);
                    assert_eq!(a, b, "w {w} k {k} x {ky} row {row}");
                }
            }
            for cap in [1u8, 31, 63] {
                let (r0, r1, r2) = (&img[..w], &img[w..2 * w], &img[2 * w..3 * w]);
                let (mut a, mut b) = ([5u8; 40], [5u8; 40]);
                prefilter(r0, r1, r2, cap, &mut a[..w]);
                prefilter_ref(r0, r1, r2, cap, &mut b[..w]);
                assert_eq!(a, b, "w {w} cap {cap}");
            }
        }
    }
}
