//! The Armv7E-M DSP path of the int8 convolution and dense layer, in CMSIS-NN's
//! mat-mult shape: two output pixels' receptive fields are gathered at once into one
//! interleaved int16 buffer (the im2col columns, input offset applied), and every pair of
//! output channels runs over both: 2 pixels x 2 channels per pass, so that each
//! `SXTB16`-split weight word feeds two `SMLAD` and each loaded column word two.
//!
//! Column layout for a field of `F = 4 Q + T` values (`T < 4`), in 32-bit words (two int16
//! lanes, lane 0 in the low half): for quad `q < Q`, words `4 q .. 4 q + 4` hold
//! `(x0[4q], x0[4q+2])`, `(x1[4q], x1[4q+2])`, `(x0[4q+1], x0[4q+3])`,
//! `(x1[4q+1], x1[4q+3])` (`x0`, `x1`: the two pixels), which are the lanes `SXTB16` and
//! `SXTB16 ROR 8` take out of a weight word; the `T` tail words hold `(x0[i], x1[i])`. The
//! column is `F` words, `2 F` int16.
//!
//! Per pass of four field values: two weight loads, two column double-word loads, four
//! `SXTB16`, eight `SMLAD` for 16 MACs. Requantization is [`ChannelQ`], prepared once per
//! channel pair and equal to [`super::requant::requantize`] for every input.
//!
//! On Arm with the `armv7em-dsp` feature this is the kernels' path (`nn::conv`,
//! `nn::dense`); host unit tests run it on the instruction models of `nn::dsp_model` and
//! compare it with the portable kernels.

use super::conv::{conv_out_size, ConvParams, Dims};
use super::requant::requantize;
use super::NnError;

#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
use super::dsp::{mac_2x2, sxtab16, sxtab16_ror8};
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
use super::dsp_model::{mac_2x2, sxtab16, sxtab16_ror8};

/// `i16` scratch elements the DSP path needs for a field of `field` values: two
/// interleaved columns (`2 field`) plus one element to align them to 32 bits.
pub(crate) const fn scratch_len(field: usize) -> usize {
    2 * field + 2
}

/// Widest row of the dense layer's DSP path (its two columns live on the stack: 4 bytes
/// per value, 516 bytes at this width); wider rows run the portable loop.
pub(crate) const DENSE_MAX_IN: usize = 128;

/// The input offset in both int16 lanes (each modulo `2^16`, as the portable kernels'
/// `as i16` truncates `x + offset`), for `SXTAB16`.
const fn offset_pair(offset: i32) -> u32 {
    (offset as u32 & 0xffff) * 0x1_0001
}

/// Writes the values `src + offset` (int16, truncated as the portable kernel truncates) of
/// field positions `start ..` into slot `slot` (0 or 1) of `col`, any alignment of `start`
/// (the general gather, used when the channels are not a multiple of four): one int16 store
/// each, at the lane the module's layout gives it. `None` values are padding (0 after the
/// offset).
fn put_values<I: Iterator<Item = Option<i8>>>(
    col: &mut [u32],
    slot: usize,
    start: usize,
    src: I,
    offset: i32,
) -> Result<(), NnError> {
    let quad_end = col.len() / 4 * 4;
    // Safety: `i16` has no invalid bit patterns and `u32`'s alignment is a multiple of
    // `i16`'s, so the view is the whole of `col` (empty prefix and suffix), borrowed
    // exclusively for this call.
    let (_, col, _) = unsafe { col.align_to_mut::<i16>() };
    let s = slot & 1;
    for (i, v) in src.enumerate() {
        let e = start + i;
        let v = v.map_or(0, |x| (x as i32).wrapping_add(offset)) as i16;
        // Word `4 q + 2 (r & 1) + s`, lane `r >> 1` for `e = 4 q + r` in the quads; word
        // `e`, lane `s` in the tail; lane 0 is the lower address on a little-endian target.
        let at = if e < quad_end {
            2 * (e & !3) + 4 * (e & 1) + 2 * s + ((e >> 1) & 1)
        } else {
            2 * e + s
        };
        let at = if cfg!(target_endian = "big") {
            at ^ 1
        } else {
            at
        };
        *col.get_mut(at).ok_or(NnError::ScratchTooSmall)? = v;
    }
    Ok(())
}

/// [`put_values`] for one kernel tap of `ic` values at field position `start`: `src` (plus
/// `offset`), or padding (0) for `None`; a plain loop for the gather's inner level.
#[inline(always)]
fn put_tap(
    col: &mut [u32],
    slot: usize,
    start: usize,
    src: Option<&[i8]>,
    ic: usize,
    offset: i32,
) -> Result<(), NnError> {
    let quad_end = col.len() / 4 * 4;
    // Safety: as in `put_values`: the `i16` view is the whole of `col`, borrowed
    // exclusively for this call.
    let (_, col, _) = unsafe { col.align_to_mut::<i16>() };
    let s = slot & 1;
    let mut put = |e: usize, v: i16| -> Result<(), NnError> {
        // The lane of field position `e`, as in `put_values`.
        let at = if e < quad_end {
            2 * (e & !3) + 4 * (e & 1) + 2 * s + ((e >> 1) & 1)
        } else {
            2 * e + s
        };
        let at = if cfg!(target_endian = "big") {
            at ^ 1
        } else {
            at
        };
        *col.get_mut(at).ok_or(NnError::ScratchTooSmall)? = v;
        Ok(())
    };
    match src {
        Some(src) => {
            for (i, &x) in src.iter().enumerate() {
                put(start + i, (x as i32).wrapping_add(offset) as i16)?;
            }
        }
        None => {
            for i in 0..ic {
                put(start + i, 0)?;
            }
        }
    }
    Ok(())
}

/// Writes `src.len() / 4` quads of `src + offset` into slot `slot` of the column words
/// `dst` (4 words per quad): one word load and two `SXTAB16` per quad.
#[inline(always)]
fn put_quads(dst: &mut [u32], slot: usize, src: &[i8], off2: u32) {
    let s = slot & 1;
    for (d, x) in dst.chunks_exact_mut(4).zip(src.chunks_exact(4)) {
        let w = match *x {
            [a, b, c, e] => u32::from_le_bytes([a as u8, b as u8, c as u8, e as u8]),
            _ => 0,
        };
        if let [d0, d1, d2, d3] = d {
            let (lo, hi) = if s == 0 { (d0, d2) } else { (d1, d3) };
            *lo = sxtab16(off2, w);
            *hi = sxtab16_ror8(off2, w);
        }
    }
}

/// Zeroes slot `slot` of the column words `dst` (padding: the input zero point plus the
/// offset is 0).
#[inline(always)]
fn zero_quads(dst: &mut [u32], slot: usize) {
    let s = slot & 1;
    for d in dst.chunks_exact_mut(4) {
        if let [d0, d1, d2, d3] = d {
            let (lo, hi) = if s == 0 { (d0, d2) } else { (d1, d3) };
            *lo = 0;
            *hi = 0;
        }
    }
}

/// Geometry of one convolution as the gather needs it.
struct Geometry {
    kernel: usize,
    stride: usize,
    pad: usize,
    in_dims: Dims,
    off2: u32,
    offset: i32,
}

/// Gathers output pixel `(oy, ox)`'s receptive field into slot `slot` of `col`.
fn gather(
    col: &mut [u32],
    slot: usize,
    input: &[i8],
    g: &Geometry,
    (oy, ox): (usize, usize),
) -> Result<(), NnError> {
    let (k, ic) = (g.kernel, g.in_dims.c);
    let mut start = 0usize;
    for ky in 0..k {
        let iy = (oy * g.stride + ky) as isize - g.pad as isize;
        for kx in 0..k {
            let ix = (ox * g.stride + kx) as isize - g.pad as isize;
            let inside =
                iy >= 0 && ix >= 0 && (iy as usize) < g.in_dims.h && (ix as usize) < g.in_dims.w;
            let src = if inside {
                let base = (iy as usize * g.in_dims.w + ix as usize) * ic;
                Some(input.get(base..base + ic).ok_or(NnError::BufferSize)?)
            } else {
                None
            };
            if ic % 4 == 0 {
                // Quads start on a quad: whole words, no lane merging.
                let dst = col
                    .get_mut(start..start + ic)
                    .ok_or(NnError::ScratchTooSmall)?;
                match src {
                    Some(src) => put_quads(dst, slot, src, g.off2),
                    None => zero_quads(dst, slot),
                }
            } else {
                put_tap(col, slot, start, src, ic, g.offset)?;
            }
            start += ic;
        }
    }
    Ok(())
}

/// One output channel's requantization, prepared once: [`ChannelQ::scale`] followed by the
/// output offset and clamp equals [`requantize`] for every accumulator, multiplier and shift
/// (unit tests compare them), with the shifts, the rounding mask and the saturation case
/// decided per channel instead of per value.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ChannelQ {
    multiplier: i32,
    /// Left shift, bits (`max(shift, 0)`, taken modulo 32 as the portable
    /// `wrapping_mul(1.wrapping_shl(left))` does).
    left: u32,
    /// Right shift, bits (`-min(shift, 0)` clamped to `0..=31`).
    right: u32,
    /// `2^right - 1`.
    mask: i32,
}

impl ChannelQ {
    /// Prepares a Q0.31 `multiplier` and `shift` (positive: left), see [`super::requant`].
    #[inline(always)]
    pub(crate) fn new(multiplier: i32, shift: i32) -> Self {
        let left = if shift > 0 { shift as u32 } else { 0 };
        // `wrapping_neg` as the portable `-shift` in a release build (only `i32::MIN`
        // differs, and it is clamped to 0 either way).
        let right = if shift > 0 { 0 } else { shift.wrapping_neg() }.clamp(0, 31) as u32;
        Self {
            multiplier,
            left,
            right,
            mask: ((1i64 << right) - 1) as i32,
        }
    }

    /// `acc * multiplier / 2^31 * 2^shift` with gemmlowp's roundings
    /// ([`super::requant::multiply_by_quantized_multiplier`]), without the saturating case
    /// `acc << left == multiplier == i32::MIN`, which the caller sends to [`requantize`].
    ///
    /// `(x m + nudge) / 2^31` truncated, with `nudge = 2^30` for `x m >= 0` and
    /// `1 - 2^30` below, equals `floor((x m + 2^30) / 2^31)` in both cases (below zero,
    /// truncation is the ceiling: `ceil((y) / 2^31) = floor((y + 2^31 - 1) / 2^31)` with
    /// `y = x m + 1 - 2^30`). Without the excluded case `|x m| <= 2^62 - 2^31`, so the
    /// quotient lies in `-2^31 + 1 ..= 2^31 - 1` and the cast is exact; the rounding divide
    /// by `2^right` is gemmlowp's, `half + (h < 0) <= 2^30` cannot overflow.
    #[inline(always)]
    fn scale(&self, acc: i32) -> i32 {
        let x = acc.wrapping_shl(self.left);
        let h = ((x as i64 * self.multiplier as i64 + (1 << 30)) >> 31) as i32;
        let threshold = (self.mask >> 1) + i32::from(h < 0);
        (h >> self.right) + i32::from((h & self.mask) > threshold)
    }

    /// True when some accumulator would hit gemmlowp's saturating case (`multiplier` is
    /// `i32::MIN`, which a validated weight file never has).
    #[inline(always)]
    fn saturates(&self) -> bool {
        self.multiplier == i32::MIN
    }
}

/// Output offset and clamp of one layer, and the requantization of an accumulator.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OutputQ {
    /// Output zero point.
    pub(crate) offset: i32,
    /// Lowest output value.
    pub(crate) min: i32,
    /// Highest output value.
    pub(crate) max: i32,
}

impl OutputQ {
    /// [`requantize`] of `acc` with the prepared channel `q` (raw `multiplier` and `shift`
    /// for the saturating case).
    #[inline(always)]
    fn put(&self, q: &ChannelQ, (m, sh): (i32, i32), acc: i32) -> i8 {
        if q.saturates() {
            return requantize(acc, m, sh, self.offset, self.min, self.max);
        }
        self.put_fast(q, acc)
    }

    /// [`requantize`] of `acc` for a channel `q` that does not saturate
    /// (`!q.saturates()`).
    #[inline(always)]
    fn put_fast(&self, q: &ChannelQ, acc: i32) -> i8 {
        // max-then-min as `requantize` (no clamp panic path).
        q.scale(acc)
            .saturating_add(self.offset)
            .max(self.min)
            .min(self.max) as i8
    }
}

/// `[ba + col0 . wa, ba + col1 . wa, bb + col0 . wb, bb + col1 . wb]` for the two
/// interleaved columns `col` (the module's layout, `wa.len()` words) and two channels'
/// weights `wa`, `wb` (same length).
///
/// No overflow: the weight file's validation bounds every accumulator below `2^31` for any
/// input (`nn::weights`), so `SMLAD`'s wrapping adds equal the portable `i32` sums.
#[inline(always)]
fn dot_2x2(col: &[u32], wa: &[i8], wb: &[i8], (ba, bb): (i32, i32)) -> [i32; 4] {
    let quads = col.len() / 4;
    let mut acc = [ba, ba, bb, bb];
    if wa.len() >= 4 * quads && wb.len() >= 4 * quads {
        let (mut c, mut pa, mut pb) = (col.as_ptr(), wa.as_ptr(), wb.as_ptr());
        for _ in 0..quads {
            // Safety: pass `i < quads` reads column words `4 i .. 4 i + 4` (< `col.len()`,
            // aligned as `col` is a `u32` slice) and weight bytes `4 i .. 4 i + 4` of `wa`
            // and `wb` (< `4 quads`, checked above); each pass advances the pointers by
            // exactly that much.
            unsafe { mac_2x2(&mut acc, &mut c, &mut pa, &mut pb) };
        }
    }
    let [mut a0, mut a1, mut b0, mut b1] = acc;
    let (ct, ta, tb) = (
        col.get(4 * quads..).unwrap_or(&[]),
        wa.get(4 * quads..).unwrap_or(&[]),
        wb.get(4 * quads..).unwrap_or(&[]),
    );
    for (&c, (&wa, &wb)) in ct.iter().zip(ta.iter().zip(tb)) {
        let (x0, x1) = (c as u16 as i16 as i32, (c >> 16) as u16 as i16 as i32);
        let (wa, wb) = (wa as i32, wb as i32);
        a0 += x0 * wa;
        a1 += x1 * wa;
        b0 += x0 * wb;
        b1 += x1 * wb;
    }
    [a0, a1, b0, b1]
}

/// Per-output-channel parameters of one layer.
pub(crate) struct Channels<'a> {
    /// `oc x field` int8 weights, channel after channel.
    pub(crate) weights: &'a [i8],
    /// Int32 biases, one per channel.
    pub(crate) bias: &'a [i32],
    /// Q0.31 multipliers, one per channel.
    pub(crate) multiplier: &'a [i32],
    /// Shifts (positive: left), one per channel.
    pub(crate) shift: &'a [i32],
    /// Output offset and clamp.
    pub(crate) out: OutputQ,
}

/// All output channels of the two pixels whose columns are in `col` (`field` words): pixel 0
/// into `out0`, pixel 1 into `out1` when `TWO` (else `out1` is not touched); `oc` values
/// each.
fn channels_2px<const TWO: bool>(
    col: &[u32],
    ch: &Channels<'_>,
    out0: &mut [i8],
    out1: &mut [i8],
) -> Result<(), NnError> {
    let field = col.len();
    let oc = ch.bias.len();
    let (Some(weights), Some(multiplier), Some(shift), Some(o0)) = (
        ch.weights.get(..oc * field),
        ch.multiplier.get(..oc),
        ch.shift.get(..oc),
        out0.get_mut(..oc),
    ) else {
        return Err(NnError::BufferSize);
    };
    let o1: &mut [i8] = if TWO {
        out1.get_mut(..oc).ok_or(NnError::BufferSize)?
    } else {
        &mut []
    };
    let o = &ch.out;
    let pair_len = field
        .checked_mul(2)
        .filter(|&n| n > 0)
        .ok_or(NnError::BadGeometry)?;
    // Channel pairs (iterators over equal-length chunks: no bounds checks inside).
    let mut o1p = o1.chunks_exact_mut(2);
    let pairs = weights
        .chunks_exact(pair_len)
        .zip(ch.bias.chunks_exact(2))
        .zip(multiplier.chunks_exact(2).zip(shift.chunks_exact(2)))
        .zip(o0.chunks_exact_mut(2));
    for (((w, b), (m, sh)), y0) in pairs {
        let (Some((wa, wb)), [ba, bb], [ma, mb], [sa, sb], [y0a, y0b]) =
            (w.split_at_checked(field), b, m, sh, y0)
        else {
            return Err(NnError::BufferSize);
        };
        let [a0, a1, b0, b1] = dot_2x2(col, wa, wb, (*ba, *bb));
        let (qa, qb) = (ChannelQ::new(*ma, *sa), ChannelQ::new(*mb, *sb));
        let fast = !(qa.saturates() || qb.saturates());
        let put = |q: &ChannelQ, m: i32, sh: i32, acc: i32| {
            if fast {
                o.put_fast(q, acc)
            } else {
                requantize(acc, m, sh, o.offset, o.min, o.max)
            }
        };
        *y0a = put(&qa, *ma, *sa, a0);
        *y0b = put(&qb, *mb, *sb, b0);
        if TWO {
            if let Some([y1a, y1b]) = o1p.next() {
                *y1a = put(&qa, *ma, *sa, a1);
                *y1b = put(&qb, *mb, *sb, b1);
            }
        }
    }
    // An odd channel count's last channel, as a pair with itself.
    if oc % 2 == 1 {
        let c = oc - 1;
        let (Some(w), Some(&b), Some(&m), Some(&sh)) = (
            weights.get(c * field..),
            ch.bias.get(c),
            multiplier.get(c),
            shift.get(c),
        ) else {
            return Err(NnError::BufferSize);
        };
        let [a0, a1, _, _] = dot_2x2(col, w, w, (b, b));
        let q = ChannelQ::new(m, sh);
        *o0.get_mut(c).ok_or(NnError::BufferSize)? = o.put(&q, (m, sh), a0);
        if TWO {
            *o1.get_mut(c).ok_or(NnError::BufferSize)? = o.put(&q, (m, sh), a1);
        }
    }
    Ok(())
}

/// The 32-bit words of `scratch` (from its first 4-byte aligned element).
fn words(scratch: &mut [i16]) -> &mut [u32] {
    // Safety: `u32` has no invalid bit patterns and is at least as large and aligned as
    // two `i16`, so `align_to_mut` returns an aligned middle slice inside `scratch` (the
    // edges stay unused); the borrow keeps `scratch` exclusively ours for its lifetime.
    let (_, mid, _) = unsafe { scratch.align_to_mut::<u32>() };
    mid
}

/// The convolution on the DSP path; the caller ([`super::conv::conv2d_s8`]) has checked the
/// geometry and every buffer's length. `scratch` holds at least
/// [`scratch_len`]`(kernel^2 in_c)` elements.
pub(crate) fn conv2d(
    p: &ConvParams,
    input: &[i8],
    in_dims: Dims,
    ch: &Channels<'_>,
    output: &mut [i8],
    out_dims: Dims,
    scratch: &mut [i16],
) -> Result<(), NnError> {
    let oh = conv_out_size(in_dims.h, p.kernel, p.stride, p.pad).ok_or(NnError::BadGeometry)?;
    let ow = conv_out_size(in_dims.w, p.kernel, p.stride, p.pad).ok_or(NnError::BadGeometry)?;
    let (field, oc) = (p.kernel * p.kernel * in_dims.c, out_dims.c);
    if oh != out_dims.h || ow != out_dims.w || ch.bias.len() != oc {
        return Err(NnError::BadGeometry);
    }
    if oc == 0 {
        return Ok(());
    }
    let col = words(scratch)
        .get_mut(..field)
        .ok_or(NnError::ScratchTooSmall)?;
    let g = Geometry {
        kernel: p.kernel,
        stride: p.stride,
        pad: p.pad,
        in_dims,
        off2: offset_pair(p.input_offset),
        offset: p.input_offset,
    };
    let out = output.get_mut(..oh * ow * oc).ok_or(NnError::BufferSize)?;
    let mut rows = out.chunks_exact_mut(oc);
    let (mut oy, mut ox) = (0usize, 0usize);
    let mut next = || {
        let at = (oy, ox);
        ox += 1;
        if ox == ow {
            (oy, ox) = (oy + 1, 0);
        }
        at
    };
    while let Some(out0) = rows.next() {
        gather(col, 0, input, &g, next())?;
        match rows.next() {
            Some(out1) => {
                gather(col, 1, input, &g, next())?;
                channels_2px::<true>(col, ch, out0, out1)?;
            }
            None => {
                // An odd pixel count's last pixel: its partner's column is zero (its sums
                // are not written).
                put_values(col, 1, 0, (0..field).map(|_| None), 0)?;
                channels_2px::<false>(col, ch, out0, &mut [])?;
            }
        }
    }
    Ok(())
}

/// The dense layer on the DSP path: `rows` rows of `in_f` values (at most
/// [`DENSE_MAX_IN`]), as a 1 x 1 convolution; the caller ([`super::dense::dense_s8`]) has
/// checked every buffer's length.
pub(crate) fn dense(
    input_offset: i32,
    rows: usize,
    in_f: usize,
    input: &[i8],
    ch: &Channels<'_>,
    output: &mut [i8],
) -> Result<(), NnError> {
    let mut scratch = [0i16; scratch_len(DENSE_MAX_IN)];
    let p = ConvParams {
        kernel: 1,
        stride: 1,
        pad: 0,
        input_offset,
        output_offset: ch.out.offset,
        act_min: ch.out.min,
        act_max: ch.out.max,
    };
    let dims = |c| Dims { h: rows, w: 1, c };
    conv2d(
        &p,
        input,
        dims(in_f),
        ch,
        output,
        dims(ch.bias.len()),
        &mut scratch,
    )
}

#[cfg(test)]
mod tests;
