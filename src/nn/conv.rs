//! Int8 2-D convolution, NHWC activations, OHWI weights, per-output-channel requantization.
//!
//! Padding is symmetric (`pad` pixels of the input zero point on every side), as in PyTorch /
//! candle, so `out = (in + 2 pad - k) / stride + 1`. Each output pixel gathers its receptive
//! field once into an int16 scratch row (`input + input_offset`, CMSIS-NN's im2col with
//! widening), then every output channel is an int16 x int8 dot product accumulated in int32,
//! a loop shape the Cortex-M7 DSP extension (SMLAD) handles two MACs at a time: with the
//! `armv7em-dsp` feature on Arm, every pixel's output channels run through
//! `channels_dsp` (four output channels per pass, four MACs per pair of SMLAD), bit-exact
//! with the portable loop (the QEMU budget checks it on every stop).

use super::requant::requantize;
use super::NnError;

/// Height, width and channels of an NHWC tensor (batch 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Dims {
    /// Rows, pixels.
    pub h: usize,
    /// Columns, pixels.
    pub w: usize,
    /// Channels.
    pub c: usize,
}

impl Dims {
    /// Number of elements `h * w * c`.
    pub const fn len(&self) -> usize {
        self.h * self.w * self.c
    }

    /// True when any dimension is zero.
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Geometry and quantization of one convolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ConvParams {
    /// Kernel height and width, pixels.
    pub kernel: usize,
    /// Stride, pixels.
    pub stride: usize,
    /// Zero padding on every side, pixels.
    pub pad: usize,
    /// Added to every input value: minus the input zero point.
    pub input_offset: i32,
    /// Added after scaling: the output zero point.
    pub output_offset: i32,
    /// Lowest output value (the output zero point for a fused ReLU, else -128).
    pub act_min: i32,
    /// Highest output value (127).
    pub act_max: i32,
}

/// Output size of a convolution along one axis, or `None` when the kernel does not fit.
pub const fn conv_out_size(
    input: usize,
    kernel: usize,
    stride: usize,
    pad: usize,
) -> Option<usize> {
    if stride == 0 || kernel == 0 || input + 2 * pad < kernel {
        return None;
    }
    Some((input + 2 * pad - kernel) / stride + 1)
}

/// Scratch needed by [`conv2d_s8`], in `i16` elements: one receptive field.
pub const fn conv2d_s8_buffer_size(kernel: usize, in_c: usize) -> usize {
    kernel * kernel * in_c
}

/// Multiply-accumulates of one convolution.
pub const fn conv2d_macs(out: Dims, kernel: usize, in_c: usize) -> u64 {
    (out.len() * kernel * kernel * in_c) as u64
}

/// Int8 convolution.
///
/// - `input`: NHWC int8, `in_dims`;
/// - `weights`: OHWI int8 (`out.c x kernel x kernel x in.c`), symmetric (zero point 0);
/// - `bias`, `multiplier`, `shift`: one per output channel (int32 bias in units of
///   `scale_in * scale_w[c]`; Q0.31 multiplier and shift, see [`super::requant`]);
/// - `output`: NHWC int8, `out_dims` (must equal the geometry's output size);
/// - `scratch`: at least [`conv2d_s8_buffer_size`] elements.
#[allow(clippy::too_many_arguments)]
pub fn conv2d_s8(
    p: &ConvParams,
    input: &[i8],
    in_dims: Dims,
    weights: &[i8],
    bias: &[i32],
    multiplier: &[i32],
    shift: &[i32],
    output: &mut [i8],
    out_dims: Dims,
    scratch: &mut [i16],
) -> Result<(), NnError> {
    let k = p.kernel;
    let oh = conv_out_size(in_dims.h, k, p.stride, p.pad).ok_or(NnError::BadGeometry)?;
    let ow = conv_out_size(in_dims.w, k, p.stride, p.pad).ok_or(NnError::BadGeometry)?;
    if oh != out_dims.h || ow != out_dims.w {
        return Err(NnError::BadGeometry);
    }
    let (ic, oc) = (in_dims.c, out_dims.c);
    let field = conv2d_s8_buffer_size(k, ic);
    if input.len() < in_dims.len()
        || output.len() < out_dims.len()
        || weights.len() < oc * field
        || bias.len() < oc
        || multiplier.len() < oc
        || shift.len() < oc
    {
        return Err(NnError::BufferSize);
    }
    if scratch.len() < field {
        return Err(NnError::ScratchTooSmall);
    }
    let (Some(col), Some(weights)) = (scratch.get_mut(..field), weights.get(..oc * field)) else {
        return Err(NnError::BufferSize);
    };
    let mut outs = output.iter_mut();
    for oy in 0..oh {
        for ox in 0..ow {
            // Gather the receptive field, widened to i16 with the input offset applied;
            // padding is the input zero point, i.e. 0 after the offset.
            let mut ci = 0usize;
            for ky in 0..k {
                let iy = (oy * p.stride + ky) as isize - p.pad as isize;
                for kx in 0..k {
                    let ix = (ox * p.stride + kx) as isize - p.pad as isize;
                    let dst = col.get_mut(ci..ci + ic).ok_or(NnError::ScratchTooSmall)?;
                    if iy < 0 || ix < 0 || iy as usize >= in_dims.h || ix as usize >= in_dims.w {
                        dst.fill(0);
                    } else {
                        let base = (iy as usize * in_dims.w + ix as usize) * ic;
                        let src = input.get(base..base + ic).ok_or(NnError::BufferSize)?;
                        for (d, &s) in dst.iter_mut().zip(src) {
                            *d = (s as i32 + p.input_offset) as i16;
                        }
                    }
                    ci += ic;
                }
            }
            #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
            {
                channels_dsp(
                    p.output_offset,
                    (p.act_min, p.act_max),
                    col,
                    weights,
                    bias,
                    multiplier,
                    shift,
                    oc,
                    &mut outs,
                )?;
            }
            #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
            {
                let col: &[i16] = col;
                // One output channel per `field` weights (validated lengths above; the
                // checked splits keep this loop free of panic paths).
                let mut rest = weights;
                for ((&b, &m), &sh) in bias.iter().zip(multiplier).zip(shift).take(oc) {
                    let (Some((w, r)), Some(y)) = (rest.split_at_checked(field), outs.next())
                    else {
                        return Err(NnError::BufferSize);
                    };
                    rest = r;
                    let mut acc = b;
                    for (&a, &b) in col.iter().zip(w) {
                        acc += a as i32 * b as i32;
                    }
                    *y = requantize(acc, m, sh, p.output_offset, p.act_min, p.act_max);
                }
            }
        }
    }
    Ok(())
}

/// The output channels of one pixel on the Armv7E-M DSP path: `col` (one receptive field)
/// is reordered in groups of four to `c0 c2 c1 c3`, so that each
/// 32-bit word holds the int16 pair [`super::dsp::smlad_pair`] multiplies with the
/// `SXTB16`-split bytes of a weight word; four channels share every load of `col`.
///
/// No overflow: the weight file's validation bounds every accumulator below `2^31` for any
/// input (`nn::weights`), so SMLAD's wrapping adds equal the portable `i32` sums.
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub(crate) fn channels_dsp<'o, I: Iterator<Item = &'o mut i8>>(
    output_offset: i32,
    act: (i32, i32),
    col: &mut [i16],
    weights: &[i8],
    bias: &[i32],
    multiplier: &[i32],
    shift: &[i32],
    oc: usize,
    outs: &mut I,
) -> Result<(), NnError> {
    for g in col.chunks_exact_mut(4) {
        g.swap(1, 2);
    }
    let col: &[i16] = col;
    let field = col.len();
    if field == 0 {
        return Err(NnError::BadGeometry);
    }
    let (Some(weights), Some(bias), Some(multiplier), Some(shift)) = (
        weights.get(..oc * field),
        bias.get(..oc),
        multiplier.get(..oc),
        shift.get(..oc),
    ) else {
        return Err(NnError::BufferSize);
    };
    let mut put = |acc: i32, m: i32, sh: i32| -> Result<(), NnError> {
        let y = outs.next().ok_or(NnError::BufferSize)?;
        *y = requantize(acc, m, sh, output_offset, act.0, act.1);
        Ok(())
    };
    let quads = oc / 4;
    let (w4, w_rest) = weights
        .split_at_checked(quads * 4 * field)
        .ok_or(NnError::BufferSize)?;
    for (q, w) in w4.chunks_exact(4 * field).enumerate() {
        let (Some(b), Some(m), Some(sh)) = (
            bias.get(4 * q..4 * q + 4),
            multiplier.get(4 * q..4 * q + 4),
            shift.get(4 * q..4 * q + 4),
        ) else {
            return Err(NnError::BufferSize);
        };
        let (Some((w0, w1)), Some((w2, w3))) = (
            w.get(..2 * field).and_then(|h| h.split_at_checked(field)),
            w.get(2 * field..).and_then(|h| h.split_at_checked(field)),
        ) else {
            return Err(NnError::BufferSize);
        };
        let b: [i32; 4] = b.try_into().map_err(|_| NnError::BufferSize)?;
        let acc = dot4_dsp(col, [w0, w1, w2, w3], b);
        for ((&a, &m), &sh) in acc.iter().zip(m).zip(sh) {
            put(a, m, sh)?;
        }
    }
    // The last `oc % 4` channels, one at a time.
    for (i, w) in w_rest.chunks_exact(field).enumerate() {
        let c = quads * 4 + i;
        let (Some(&b), Some(&m), Some(&sh)) = (bias.get(c), multiplier.get(c), shift.get(c)) else {
            return Err(NnError::BufferSize);
        };
        let acc = dot4_dsp(col, [w, w, w, w], [b, 0, 0, 0]);
        put(acc[0], m, sh)?;
    }
    Ok(())
}

/// `b_k + col . w_k` for four channels, `col` reordered as [`channels_dsp`] says (a tail of
/// `col.len() % 4` values, not reordered, is multiplied one by one).
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
#[inline(always)]
fn dot4_dsp(col: &[i16], w: [&[i8]; 4], b: [i32; 4]) -> [i32; 4] {
    use super::dsp::smlad_pair;
    let word = |w: &[i8]| match *w {
        [a, b, c, d] => u32::from_le_bytes([a as u8, b as u8, c as u8, d as u8]),
        _ => 0,
    };
    let [mut a0, mut a1, mut a2, mut a3] = b;
    let [w0, w1, w2, w3] = w;
    let (c4, (x0, x1), (x2, x3)) = (
        col.chunks_exact(4),
        (w0.chunks_exact(4), w1.chunks_exact(4)),
        (w2.chunks_exact(4), w3.chunks_exact(4)),
    );
    let tails = [
        x0.remainder(),
        x1.remainder(),
        x2.remainder(),
        x3.remainder(),
    ];
    let ctail = c4.remainder();
    for (c, ((x0, x1), (x2, x3))) in c4.zip(x0.zip(x1).zip(x2.zip(x3))) {
        let p = c.as_ptr().cast::<u32>();
        // Safety: `c` is four `i16` (8 bytes), so both 4-byte reads are inside it;
        // `read_unaligned` allows any alignment (one LDR on the Cortex-M7) and every bit
        // pattern is a valid `u32`.
        let (xe, xo) = unsafe { (p.read_unaligned(), p.add(1).read_unaligned()) };
        a0 = smlad_pair(a0, xe, xo, word(x0));
        a1 = smlad_pair(a1, xe, xo, word(x1));
        a2 = smlad_pair(a2, xe, xo, word(x2));
        a3 = smlad_pair(a3, xe, xo, word(x3));
    }
    let mut acc = [a0, a1, a2, a3];
    for (a, t) in acc.iter_mut().zip(tails) {
        for (&c, &w) in ctail.iter().zip(t) {
            *a += c as i32 * w as i32;
        }
    }
    acc
}
