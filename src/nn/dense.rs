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
    let weights = &weights[..in_f * out_f];
    for (row, out) in input
        .chunks_exact(in_f)
        .take(rows)
        .zip(output.chunks_exact_mut(out_f))
    {
        for (o, (w, y)) in weights.chunks_exact(in_f).zip(out.iter_mut()).enumerate() {
            let mut acc = bias[o];
            for (&a, &b) in row.iter().zip(w) {
                acc += (a as i32 + p.input_offset) * b as i32;
            }
            *y = requantize(
                acc,
                multiplier[o],
                shift[o],
                p.output_offset,
                p.act_min,
                p.act_max,
            );
        }
    }
    Ok(())
}
