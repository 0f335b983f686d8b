//! Int8 2-D convolution, NHWC activations, OHWI weights, per-output-channel requantization.
//!
//! Padding is symmetric (`pad` pixels of the input zero point on every side), as in PyTorch /
//! candle, so `out = (in + 2 pad - k) / stride + 1`. Each output pixel gathers its receptive
//! field once into an int16 scratch row (`input + input_offset`, CMSIS-NN's im2col with
//! widening), then every output channel is an int16 x int8 dot product accumulated in int32,
//! a loop shape the Cortex-M7 DSP extension (SMLAD) handles two MACs at a time: with the
//! `armv7em-dsp` feature on Arm the kernel runs `nn::mat_mult` instead (two output pixels'
//! fields gathered at once, two pixels x two output channels per pass, 16 MACs per eight
//! SMLAD), bit-exact with the portable loop (host unit tests run it on instruction models;
//! the QEMU budget checks the embedding on every stop).

#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
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

/// Scratch needed by [`conv2d_s8`], in `i16` elements: two receptive fields (the DSP path
/// gathers two output pixels at once) and one element to align them to 32 bits.
pub const fn conv2d_s8_buffer_size(kernel: usize, in_c: usize) -> usize {
    2 * kernel * kernel * in_c + 2
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
    let field = k * k * ic;
    if input.len() < in_dims.len()
        || output.len() < out_dims.len()
        || weights.len() < oc * field
        || bias.len() < oc
        || multiplier.len() < oc
        || shift.len() < oc
    {
        return Err(NnError::BufferSize);
    }
    if scratch.len() < conv2d_s8_buffer_size(k, ic) {
        return Err(NnError::ScratchTooSmall);
    }
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    {
        let (Some(weights), Some(bias), Some(multiplier), Some(shift)) = (
            weights.get(..oc * field),
            bias.get(..oc),
            multiplier.get(..oc),
            shift.get(..oc),
        ) else {
            return Err(NnError::BufferSize);
        };
        let ch = super::mat_mult::Channels {
            weights,
            bias,
            multiplier,
            shift,
            out: super::mat_mult::OutputQ {
                offset: p.output_offset,
                min: p.act_min,
                max: p.act_max,
            },
        };
        super::mat_mult::conv2d(p, input, in_dims, &ch, output, out_dims, scratch)
    }
    #[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
    conv2d_portable(
        p,
        input,
        in_dims,
        (weights, bias, multiplier, shift),
        output,
        (oh, ow, oc),
        scratch,
    )
}

/// The portable convolution (every target without the DSP path): one receptive field at a
/// time into `scratch`, then one output channel at a time. Lengths checked by the caller.
#[cfg(not(all(target_arch = "arm", feature = "armv7em-dsp")))]
#[allow(clippy::type_complexity)]
fn conv2d_portable(
    p: &ConvParams,
    input: &[i8],
    in_dims: Dims,
    (weights, bias, multiplier, shift): (&[i8], &[i32], &[i32], &[i32]),
    output: &mut [i8],
    (oh, ow, oc): (usize, usize, usize),
    scratch: &mut [i16],
) -> Result<(), NnError> {
    let (k, ic) = (p.kernel, in_dims.c);
    let field = k * k * ic;
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
