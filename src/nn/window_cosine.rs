//! The flight path's cosine scoring of the rover's embedding against the stored embeddings
//! of the map windows: bit for bit the Q15 result of [`cosine_q15`], at a fraction of its
//! cost.
//!
//! [`cosine_q15`] shifts both int8 embeddings by the zero point and recomputes both norms
//! for every pair, in 64-bit accumulators (about 18 instructions per embedding element on
//! the Cortex-M7). Here the work is split by what it depends on:
//!
//! - **map side, on the ground** ([`write_window_record`]): each window's embedding is
//!   stored with the sum and the sum of squares of its raw int8 values, a [`WindowRecord`]
//!   of [`WINDOW_RECORD_BYTES`] bytes (layout below);
//! - **rover side, once per fix** ([`TemplateStats::new`]): the same two sums of the
//!   rover's embedding, and its zero-point-shifted norm;
//! - **per window** ([`cosine_q15_windows`], [`WINDOWS_PER_PASS`] windows per pass over
//!   the rover's embedding): only the raw int8 dot product `sum a_i * b_i` (i32
//!   accumulator; with the `armv7em-dsp` feature on Arm, SXTB16 + SMLAD on 32-bit words,
//!   otherwise a plain loop), then the zero-point terms, the map norm and the Q15 quotient
//!   from the sums (about 2 instructions per element on the Cortex-M7, docs/flight-target.md).
//!
//! With `n` elements and zero point `zp` the identities are exact integer algebra:
//!
//! ```text
//! sum (a - zp)(b - zp) = sum a b - zp (sum a + sum b) + n zp^2
//! sum (b - zp)^2       = sum b^2 - 2 zp sum b + n zp^2
//! ```
//!
//! and the quotient is formed as [`cosine_q15`] forms it (`(dot << 15) / isqrt(na * nb)`,
//! truncating, clamped to `[-32768, 32768]`, 0 for a zero norm) from the same floor square
//! root ([`isqrt_u64_bits`], one result bit per step, equals
//! [`super::input::isqrt_u64`]'s Newton iteration for every input) and the same quotient
//! ([`q15_quotient`], bit search instead of a 64-bit division), so the score is identical
//! for every pair of embeddings and every zero point. The records do not depend on the
//! zero point.
//!
//! # Window record layout ([`WINDOW_RECORD_BYTES`] = 2056 bytes, a multiple of 4)
//!
//! | offset | bytes | field |
//! |---:|---:|---|
//! | 0 | 4 | `sum_sq`: `u32` little-endian, `sum b_i^2` of the raw int8 values (at most 2048 x 128^2 = 33,554,432) |
//! | 4 | 4 | `sum`: `i32` little-endian, `sum b_i` (within +-262,144) |
//! | 8 | 2048 | the embedding, int8 as two's-complement bytes, NHWC 8 x 8 x 32 |
//!
//! Records are stored back to back, row-major over the window grid; a 4-byte aligned start
//! keeps every embedding 4-byte aligned for word loads.

use super::model::EMBED_LEN;
use super::NnError;

#[cfg(doc)]
use super::model::cosine_q15;

/// Bytes of a record's header (`sum_sq`, `sum`).
pub const WINDOW_HEADER_BYTES: usize = 8;
/// Bytes of one window record: header and the int8 embedding.
pub const WINDOW_RECORD_BYTES: usize = WINDOW_HEADER_BYTES + EMBED_LEN;

/// Bytes of `windows` records (`get_buffer_size`-style).
pub const fn window_records_bytes(windows: usize) -> usize {
    windows * WINDOW_RECORD_BYTES
}

/// Sum and sum of squares of raw int8 values (units: int8 steps, squared for `sum_sq`).
/// For [`EMBED_LEN`] values `|sum| <= 262,144` and `sum_sq <= 33,554,432`.
fn sums(v: &[i8; EMBED_LEN]) -> (i32, u32) {
    let (mut s, mut q) = (0i32, 0u32);
    for &x in v.iter() {
        let x = x as i32;
        s += x;
        // x^2 <= 16384, 2048 of them <= 2^25: no overflow.
        q += (x * x) as u32;
    }
    (s, q)
}

/// Writes the record of one map window's embedding `emb` into `out` (at least
/// [`WINDOW_RECORD_BYTES`] bytes; the first [`WINDOW_RECORD_BYTES`] are written).
/// Done on the ground, once per map.
pub fn write_window_record(emb: &[i8; EMBED_LEN], out: &mut [u8]) -> Result<(), NnError> {
    let out = out
        .get_mut(..WINDOW_RECORD_BYTES)
        .ok_or(NnError::BufferSize)?;
    let (s, q) = sums(emb);
    let (head, body) = out.split_at_mut(WINDOW_HEADER_BYTES);
    let (hq, hs) = head.split_at_mut(4);
    hq.copy_from_slice(&q.to_le_bytes());
    hs.copy_from_slice(&s.to_le_bytes());
    for (d, &v) in body.iter_mut().zip(emb.iter()) {
        *d = v as u8;
    }
    Ok(())
}

/// One stored map window: a borrowed [`WINDOW_RECORD_BYTES`]-byte record (layout in the
/// module docs).
#[derive(Clone, Copy, Debug)]
pub struct WindowRecord<'a> {
    sum_sq: u32,
    sum: i32,
    emb: &'a [u8; EMBED_LEN],
}

/// Zero embedding bytes of [`WindowRecord::EMPTY`].
static ZERO_EMBEDDING: [u8; EMBED_LEN] = [0; EMBED_LEN];

impl WindowRecord<'static> {
    /// The record of an all-zero embedding (sums 0): a placeholder to fill arrays of
    /// records with before parsing into them.
    pub const EMPTY: Self = Self {
        sum_sq: 0,
        sum: 0,
        emb: &ZERO_EMBEDDING,
    };
}

impl<'a> WindowRecord<'a> {
    /// Reads a record from the first [`WINDOW_RECORD_BYTES`] bytes of `bytes`
    /// ([`NnError::BufferSize`] if shorter).
    pub fn parse(bytes: &'a [u8]) -> Result<Self, NnError> {
        let (Some(q), Some(s), Some(e)) = (
            bytes.get(0..4),
            bytes.get(4..8),
            bytes.get(WINDOW_HEADER_BYTES..WINDOW_RECORD_BYTES),
        ) else {
            return Err(NnError::BufferSize);
        };
        let word = |b: &[u8]| {
            let mut w = [0u8; 4];
            w.copy_from_slice(b);
            w
        };
        let emb: &[u8; EMBED_LEN] = e.try_into().map_err(|_| NnError::BufferSize)?;
        Ok(Self {
            sum_sq: u32::from_le_bytes(word(q)),
            sum: i32::from_le_bytes(word(s)),
            emb,
        })
    }

    /// The embedding, int8 as two's-complement bytes.
    pub fn embedding_bytes(&self) -> &'a [u8; EMBED_LEN] {
        self.emb
    }

    /// `sum b_i^2` of the raw int8 values.
    pub fn sum_sq(&self) -> u32 {
        self.sum_sq
    }

    /// `sum b_i` of the raw int8 values.
    pub fn sum(&self) -> i32 {
        self.sum
    }
}

/// `n * zp^2 - 2 zp s + q` for `n` values with sum `s` and sum of squares `q`: the squared
/// norm of the zero-point-shifted values (exact in i64 for any `s`, `q` and an int8 `zp`:
/// |terms| <= 2^32, 2^40, 2^25).
fn shifted_norm(q: u32, s: i32, zp: i64) -> i64 {
    q as i64 - 2 * zp * s as i64 + EMBED_LEN as i64 * zp * zp
}

/// The rover's embedding prepared once per fix: its raw sum, its zero point and its
/// zero-point-shifted squared norm `sum (a - zp)^2`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TemplateStats {
    sum: i32,
    zp: i64,
    norm_sq: u64,
}

impl TemplateStats {
    /// Statistics of embedding `a` with zero point `zp` (the network's output zero point,
    /// an int8 value: every product and sum below then stays far inside `i64`).
    pub fn new(a: &[i8; EMBED_LEN], zp: i8) -> Self {
        let (s, q) = sums(a);
        let zp = zp as i64;
        Self {
            sum: s,
            zp,
            norm_sq: u64::try_from(shifted_norm(q, s, zp)).unwrap_or(0),
        }
    }

    /// `sum (a - zp)^2`, squared int8 steps.
    pub fn norm_sq(&self) -> u64 {
        self.norm_sq
    }
}

/// Floor of the square root of `n`, one result bit per step from the top (a 32 x 32 -> 64
/// bit multiply and a compare per bit, no division). Equal to [`super::input::isqrt_u64`]
/// for every `n`.
pub const fn isqrt_u64_bits(n: u64) -> u64 {
    if n == 0 {
        return 0;
    }
    // floor(sqrt(n)) < 2^32, and its top bit is bit floor(log2(n) / 2).
    let mut bit = 1u32 << ((63 - n.leading_zeros()) / 2);
    let mut root = 0u32;
    while bit != 0 {
        let c = root | bit;
        // c < 2^32, so c^2 < 2^64: no overflow.
        if (c as u64) * (c as u64) <= n {
            root = c;
        }
        bit >>= 1;
    }
    root as u64
}

/// `clamp(trunc(num / den), -32768, 32768)` for `den > 0`, 0 for `den == 0`: the Q15
/// quotient of [`cosine_q15`] (`(dot << 15).checked_div(den)`, clamped), found one bit per
/// step (a 32 x 32 -> 64 bit multiply and a compare) instead of a 64-bit division.
pub const fn q15_quotient(num: i64, den: u32) -> i32 {
    if den == 0 {
        return 0;
    }
    let mag = num.unsigned_abs();
    let d = den as u64;
    // floor(mag / d) >= 32768 exactly when mag >= 32768 d (< 2^47: no overflow); the clamp
    // then gives 32768 in magnitude.
    let q = if mag >= 32768 * d {
        32768
    } else {
        // floor(mag / d) < 2^15: the largest q with q d <= mag, bit by bit.
        let mut q = 0u32;
        let mut bit = 1u32 << 14;
        while bit != 0 {
            let c = q | bit;
            if c as u64 * d <= mag {
                q = c;
            }
            bit >>= 1;
        }
        q
    };
    // Truncation toward zero: the magnitude's floor with num's sign.
    if num < 0 {
        -(q as i32)
    } else {
        q as i32
    }
}

/// Windows scored per pass by the flight stage ([`cosine_q15_windows`]): the rover's
/// embedding is loaded and split once for all of them. Measured on the firmware (dense
/// grid, instructions per embedding element of `nn_match`): 3 windows 2.12, 4: 2.07,
/// 5: 2.05, 6: 2.03, 8: 2.10 (from 4 on LLVM keeps a pointer or two on the stack, which
/// costs less than the shared loads save, until 8).
pub const WINDOWS_PER_PASS: usize = 6;

/// The 32-bit little-endian word at byte `off` of `b` (0 past the end, which the callers'
/// loop bounds never reach).
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
fn word_at(b: &[u8; EMBED_LEN], off: usize) -> u32 {
    match b.get(off..off + 4) {
        Some(&[b0, b1, b2, b3]) => u32::from_le_bytes([b0, b1, b2, b3]),
        _ => 0,
    }
}

/// Raw int8 dot products `sum_i a_i * b_k,i` of `a` with each of `K` embeddings (all given
/// as two's-complement bytes) in one pass over `a`.
///
/// Bound: `|a_i * b_i| <= 128 * 128 = 16,384` and there are [`EMBED_LEN`] = 2048 products,
/// so `|sum| <= 33,554,432 < 2^31`: `i32` accumulators cannot overflow.
#[inline(always)]
fn dot_i8<const K: usize>(a: &[u8; EMBED_LEN], bs: [&[u8; EMBED_LEN]; K]) -> [i32; K] {
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        dot_i8_dsp(a, bs)
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    {
        bs.map(|b| {
            let mut acc = 0i32;
            for (&p, &q) in a.iter().zip(b.iter()) {
                acc += (p as i8 as i32) * (q as i8 as i32);
            }
            acc
        })
    }
}

/// Armv7E-M form of [`dot_i8`]: per 32-bit word of `a`, two `SXTB16` split its four int8
/// values into two pairs of int16 (bytes 0, 2 and, rotated by 8, bytes 1, 3), shared by
/// all `K` windows; per window, one word load, two `SXTB16` and two `SMLAD` add the four
/// products (no overflow: bound on [`dot_i8`]). `3 + 5 K` instructions per word of `K`
/// windows plus the loop's.
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
fn dot_i8_dsp<const K: usize>(a: &[u8; EMBED_LEN], bs: [&[u8; EMBED_LEN]; K]) -> [i32; K] {
    use super::dsp::{smlad_pair, sxtb16_pair};
    let mut s = [0i32; K];
    let mut off = 0;
    while off + 4 <= EMBED_LEN {
        let (xe, xo) = sxtb16_pair(word_at(a, off));
        for (acc, b) in s.iter_mut().zip(bs.iter()) {
            *acc = smlad_pair(*acc, xe, xo, word_at(b, off));
        }
        off += 4;
    }
    s
}

/// The rover's embedding as its two's-complement bytes.
fn as_bytes(a: &[i8; EMBED_LEN]) -> &[u8; EMBED_LEN] {
    // Safety: i8 and u8 have the same size and alignment, and every bit pattern is valid
    // for both, so an `[i8; N]` may be read as an `[u8; N]`; the borrow is kept.
    unsafe { &*(a as *const [i8; EMBED_LEN]).cast::<[u8; EMBED_LEN]>() }
}

/// Q15 cosine (32768 = 1.0) of the rover's embedding `a` (statistics `t` from
/// [`TemplateStats::new`] with the network's zero point) and a stored map window `w`:
/// exactly [`cosine_q15`]`(a, w's embedding, zp)` for every input, including 0 when
/// either embedding is all zero point. A record whose sums do not belong to its embedding
/// (corrupted data) gives some value in `[-32768, 32768]`, never a panic.
pub fn cosine_q15_window(a: &[i8; EMBED_LEN], t: &TemplateStats, w: &WindowRecord<'_>) -> i32 {
    let [c] = cosine_q15_windows(a, t, &[*w]);
    c
}

/// [`cosine_q15_window`] of `K` windows in one pass over the rover's embedding (loaded
/// and split once for all of them; [`WINDOWS_PER_PASS`] is the flight stage's `K`): each
/// result exactly as [`cosine_q15_window`] gives it.
pub fn cosine_q15_windows<const K: usize>(
    a: &[i8; EMBED_LEN],
    t: &TemplateStats,
    ws: &[WindowRecord<'_>; K],
) -> [i32; K] {
    let raw = dot_i8(as_bytes(a), ws.map(|w| w.emb));
    let mut out = [0i32; K];
    for ((o, r), w) in out.iter_mut().zip(raw).zip(ws.iter()) {
        *o = score_from_sums(r as i64, t, w.sum, w.sum_sq);
    }
    out
}

/// The per-window arithmetic after the dot product (all i64/u64, no overflow for any
/// header values: |dot| < 2^40, so `dot << 15` < 2^55).
#[inline]
fn score_from_sums(raw_dot: i64, t: &TemplateStats, sum_b: i32, sum_sq_b: u32) -> i32 {
    let zp = t.zp;
    let dot = raw_dot - zp * (t.sum as i64 + sum_b as i64) + EMBED_LEN as i64 * zp * zp;
    let nb = u64::try_from(shifted_norm(sum_sq_b, sum_b, zp)).unwrap_or(0);
    // den <= floor(sqrt(u64::MAX)) < 2^32.
    let den = isqrt_u64_bits(t.norm_sq.saturating_mul(nb)) as u32;
    q15_quotient(dot << 15, den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::input::isqrt_u64;
    use crate::nn::model::cosine_q15;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
    }

    #[test]
    fn isqrt_bits_matches_newton() {
        let mut r = Rng(0x9e37_79b9_7f4a_7c15);
        for n in (0..5000u64).chain([u64::MAX, u64::MAX - 1, 1 << 62, (1 << 62) - 1]) {
            assert_eq!(isqrt_u64_bits(n), isqrt_u64(n), "n = {n}");
        }
        for _ in 0..20_000 {
            let n = r.next() >> (r.next() % 64);
            assert_eq!(isqrt_u64_bits(n), isqrt_u64(n), "n = {n}");
            let s = n >> 32;
            for m in [s * s, (s * s).wrapping_sub(1), s * s + 1] {
                assert_eq!(isqrt_u64_bits(m), isqrt_u64(m), "m = {m}");
            }
        }
    }

    /// `cosine_q15`'s quotient, for comparison.
    fn reference_quotient(num: i64, den: u32) -> i32 {
        num.checked_div(den as i64)
            .map_or(0, |c| c.clamp(-32768, 32768) as i32)
    }

    #[test]
    fn q15_quotient_matches_the_division() {
        let mut r = Rng(0x1234_5678_9abc_def1);
        let edges = [0u32, 1, 2, 3, 255, 65535, 1 << 27, u32::MAX - 1, u32::MAX];
        for &den in &edges {
            for num in [0i64, 1, -1, 32767, -32768, 1 << 40, -(1 << 40), 1 << 47] {
                for k in [0i64, 1, -1] {
                    let Some(num) = num.checked_mul(den as i64).map(|m| m + k) else {
                        continue;
                    };
                    assert_eq!(q15_quotient(num, den), reference_quotient(num, den));
                }
            }
        }
        for _ in 0..100_000 {
            let den = (r.next() >> (32 + r.next() % 32)) as u32;
            // |num| up to 2^55 (dot << 15 for any header values) and near multiples of den.
            let num =
                ((r.next() >> (9 + r.next() % 55)) as i64) * if r.next() & 1 == 0 { 1 } else { -1 };
            let near = (num / den.max(1) as i64) * den as i64 + (r.next() % 3) as i64 - 1;
            for n in [num, near] {
                assert_eq!(
                    q15_quotient(n, den),
                    reference_quotient(n, den),
                    "{n} / {den}"
                );
            }
        }
    }

    #[test]
    fn record_roundtrip_and_equal_scores_on_extremes() {
        let mut rec = [0u8; WINDOW_RECORD_BYTES];
        let a = [127i8; EMBED_LEN];
        let mut b = [-128i8; EMBED_LEN];
        b[5] = 3;
        write_window_record(&b, &mut rec).unwrap();
        let w = WindowRecord::parse(&rec).unwrap();
        assert_eq!(w.sum(), -128 * 2047 + 3);
        assert_eq!(w.sum_sq(), 16384 * 2047 + 9);
        for zp in [-128i8, -1, 0, 1, 127] {
            let t = TemplateStats::new(&a, zp);
            assert_eq!(cosine_q15_window(&a, &t, &w), cosine_q15(&a, &b, zp as i32));
        }
        assert_eq!(
            WindowRecord::parse(&rec[..WINDOW_RECORD_BYTES - 1]).err(),
            Some(NnError::BufferSize)
        );
        assert_eq!(
            write_window_record(&a, &mut [0u8; 10]),
            Err(NnError::BufferSize)
        );
    }

    /// An embedding of one of several shapes: uniform int8, a narrow band around a centre
    /// (embeddings sit near their zero point), constant, extremes only, or mostly one value.
    fn embedding(r: &mut Rng, out: &mut [i8; EMBED_LEN]) {
        let kind = r.next() % 5;
        let centre = (r.next() % 256) as i32 - 128;
        let spread = 1 + (r.next() % 40) as i32;
        for v in out.iter_mut() {
            let x = r.next();
            *v = match kind {
                0 => x as i8,
                1 => {
                    (centre + (x % (2 * spread as u64 + 1)) as i32 - spread).clamp(-128, 127) as i8
                }
                2 => centre as i8,
                3 => {
                    if x & 1 == 0 {
                        -128
                    } else {
                        127
                    }
                }
                _ => {
                    if x % 16 == 0 {
                        x as i8
                    } else {
                        centre as i8
                    }
                }
            };
        }
    }

    #[test]
    fn equals_cosine_q15_on_random_embeddings_and_zero_points() {
        let mut r = Rng(0x2545_f491_4f6c_dd1d);
        let mut a = [0i8; EMBED_LEN];
        let mut b = [0i8; EMBED_LEN];
        let mut rec = [0u8; WINDOW_RECORD_BYTES];
        let mut nonzero = 0;
        let mut prev_rec = [0u8; WINDOW_RECORD_BYTES];
        let mut prev_b = [0i8; EMBED_LEN];
        write_window_record(&prev_b, &mut prev_rec).unwrap();
        for i in 0..1500 {
            embedding(&mut r, &mut a);
            embedding(&mut r, &mut b);
            if i % 7 == 0 {
                b = a; // identical pair: 32768 (or 0 if all zero point)
            }
            write_window_record(&b, &mut rec).unwrap();
            let w = WindowRecord::parse(&rec).unwrap();
            let prev = WindowRecord::parse(&prev_rec).unwrap();
            let zps = [
                -128i8,
                127,
                0,
                r.next() as i8,
                a[(r.next() % EMBED_LEN as u64) as usize],
            ];
            for zp in zps {
                let t = TemplateStats::new(&a, zp);
                let want = cosine_q15(&a, &b, zp as i32);
                assert_eq!(cosine_q15_window(&a, &t, &w), want, "pair {i}, zp {zp}");
                let prev_want = cosine_q15(&a, &prev_b, zp as i32);
                let pair = cosine_q15_windows(&a, &t, &[w, prev]);
                assert_eq!(pair, [want, prev_want], "pair {i}, zp {zp}");
                let three = cosine_q15_windows(&a, &t, &[prev, w, prev]);
                assert_eq!(three, [prev_want, want, prev_want], "pair {i}, zp {zp}");
                let pick = |k: usize| {
                    if k % 2 == 0 {
                        (w, want)
                    } else {
                        (prev, prev_want)
                    }
                };
                let ws: [WindowRecord<'_>; WINDOWS_PER_PASS] = core::array::from_fn(|k| pick(k).0);
                let flight = cosine_q15_windows(&a, &t, &ws);
                assert_eq!(
                    flight,
                    core::array::from_fn(|k| pick(k).1),
                    "pair {i}, zp {zp}"
                );
                if want != 0 {
                    nonzero += 1;
                }
            }
            prev_rec = rec;
            prev_b = b;
        }
        // The comparison is not vacuous: most scores are not the 0 of a zero norm.
        assert!(nonzero > 5000, "{nonzero}");
    }

    #[test]
    fn corrupted_records_give_a_bounded_score() {
        let mut r = Rng(77);
        let mut a = [0i8; EMBED_LEN];
        embedding(&mut r, &mut a);
        let t = TemplateStats::new(&a, -3);
        let mut rec = [0u8; WINDOW_RECORD_BYTES];
        for _ in 0..200 {
            for v in rec.iter_mut() {
                *v = r.next() as u8;
            }
            for (i, head) in [[0xFFu8; 8], [0u8; 8], [0x80, 0, 0, 0, 0, 0, 0, 0x80]]
                .iter()
                .enumerate()
            {
                if r.next() % 4 == i as u64 {
                    rec[..8].copy_from_slice(head);
                }
            }
            let w = WindowRecord::parse(&rec).unwrap();
            let c = cosine_q15_window(&a, &t, &w);
            assert!((-32768..=32768).contains(&c));
        }
    }
}
