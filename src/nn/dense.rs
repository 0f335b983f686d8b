//! Int8 fully connected layer over a batch of rows (also a 1x1 convolution on NHWC data,
//! where every pixel is a row), per-output-channel requantization.

use super::requant::requantize;
use super::NnError;

/// Quantization of one fully connected layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DenseParams {
    /// Added to every input value: minus the input zero point.
    pub input_offset: i32,
    /// Added after scaling: the output zero point.
    pub output_offset: i32,
    /// Lowest output value.
    pub act_min: i32,
    /// Highest output value.
    pub act_max: i32,
}

/// Multiply-accumulates of a dense layer over `rows` rows.
pub const fn dense_macs(rows: usize, in_f: usize, out_f: usize) -> u64 {
    (rows * in_f * out_f) as u64
}

/// `output[r][o] = requant(bias[o] + sum_i (input[r][i] + input_offset) * weights[o][i])`.
///
/// `input`: `rows x in_f` int8; `weights`: `out_f x in_f` int8 symmetric; `bias`,
/// `multiplier`, `shift`: `out_f` each; `output`: `rows x out_f` int8. No scratch needed.
#[allow(clippy::too_many_arguments)]
pub fn dense_s8(
    p: &DenseParams,
    rows: usize,
    in_f: usize,
    out_f: usize,
    input: &[i8],
    weights: &[i8],
    bias: &[i32],
    multiplier: &[i32],
    shift: &[i32],
    output: &mut [i8],
) -> Result<(), NnError> {
    if in_f == 0 || out_f == 0 {
        return Err(NnError::BadGeometry);
    }
    if input.len() < rows * in_f
        || output.len() < rows * out_f
        || weights.len() < in_f * out_f
        || bias.len() < out_f
        || multiplier.len() < out_f
        || shift.len() < out_f
    {
        return Err(NnError::BufferSize);
    }
    let (Some(weights), Some(input), Some(output)) = (
        weights.get(..in_f * out_f),
        input.get(..rows * in_f),
        output.get_mut(..rows * out_f),
    ) else {
        return Err(NnError::BufferSize);
    };
    // The Armv7E-M DSP path: a 1 x 1 convolution, two rows x two outputs per pass
    // (`nn::mat_mult`, its two columns on the stack: 516 bytes).
    #[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
    if in_f <= super::mat_mult::DENSE_MAX_IN {
        let (Some(bias), Some(multiplier), Some(shift)) = (
            bias.get(..out_f),
            multiplier.get(..out_f),
            shift.get(..out_f),
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
        return super::mat_mult::dense(p.input_offset, rows, in_f, input, &ch, output);
    }
    // Checked splits instead of `chunks_exact` keep this free of panic paths.
    let (mut rows_in, mut outs) = (input, output.iter_mut());
    for _ in 0..rows {
        let Some((row, r)) = rows_in.split_at_checked(in_f) else {
            return Err(NnError::BufferSize);
        };
        rows_in = r;
        let mut rest = weights;
        for ((&b, &m), &sh) in bias.iter().zip(multiplier).zip(shift).take(out_f) {
            let (Some((w, r)), Some(y)) = (rest.split_at_checked(in_f), outs.next()) else {
                return Err(NnError::BufferSize);
            };
            rest = r;
            let mut acc = b;
            for (&a, &b) in row.iter().zip(w) {
                acc += (a as i32 + p.input_offset) * b as i32;
            }
            *y = requantize(acc, m, sh, p.output_offset, p.act_min, p.act_max);
        }
    }
    Ok(())
}
