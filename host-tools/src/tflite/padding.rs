//! orbfix's symmetric convolution padding expressed with TFLite's padding modes.
//!
//! orbfix pads `pad` pixels of the input zero point on every side, so output `o` reads input
//! rows from `o * stride - pad` and `out = (in + 2 pad - k) / stride + 1`. TFLite's `SAME`
//! pads `total = max((out - 1) stride + k - in, 0)` pixels with `total / 2` before (the odd
//! pixel goes after: bottom, right) and `VALID` pads nothing. For stride 2 on even sizes
//! (`in = 64, k = 3, pad = 1`) `SAME` puts no pixel before, so it reads other inputs; there a
//! `PAD` operator (filled with the input zero point) followed by a `VALID` convolution reads
//! exactly what orbfix reads.

/// How one convolution is written in TFLite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PaddingPlan {
    /// A `SAME` convolution reads what orbfix reads.
    Same,
    /// A `VALID` convolution reads what orbfix reads (no padding).
    Valid,
    /// `PAD` by `pad` pixels on every side (input zero point), then a `VALID` convolution.
    PadThenValid {
        /// Pixels added on each side of both spatial axes.
        pad: usize,
    },
}

/// orbfix's output size along one axis, `None` when the kernel does not fit.
fn orbfix_out(input: usize, k: usize, stride: usize, pad: usize) -> Option<usize> {
    orbfix::nn::conv::conv_out_size(input, k, stride, pad)
}

/// TFLite `SAME`: output size and padding before, along one axis.
pub fn same_geometry(input: usize, k: usize, stride: usize) -> (usize, usize) {
    let out = input.div_ceil(stride);
    let total = ((out.saturating_sub(1)) * stride + k).saturating_sub(input);
    (out, total / 2)
}

/// The TFLite form of an orbfix convolution over an `in_h x in_w` input with a `k x k`
/// kernel, `stride` and symmetric `pad`; `None` when the geometry is invalid.
pub fn plan(in_h: usize, in_w: usize, k: usize, stride: usize, pad: usize) -> Option<PaddingPlan> {
    if stride == 0 {
        return None;
    }
    let axis_same = |input: usize| -> Option<bool> {
        let out = orbfix_out(input, k, stride, pad)?;
        Some(same_geometry(input, k, stride) == (out, pad))
    };
    let (same_h, same_w) = (axis_same(in_h)?, axis_same(in_w)?);
    Some(if pad == 0 {
        PaddingPlan::Valid
    } else if same_h && same_w {
        PaddingPlan::Same
    } else {
        PaddingPlan::PadThenValid { pad }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stride_two_on_even_sizes_needs_an_explicit_pad() {
        for side in [64, 32, 16] {
            assert_eq!(
                plan(side, side, 3, 2, 1),
                Some(PaddingPlan::PadThenValid { pad: 1 })
            );
            // SAME would pad 0 before and 1 after.
            assert_eq!(same_geometry(side, 3, 2), (side / 2, 0));
        }
    }

    #[test]
    fn stride_one_and_odd_sizes_are_same() {
        assert_eq!(plan(8, 8, 3, 1, 1), Some(PaddingPlan::Same));
        assert_eq!(plan(65, 65, 3, 2, 1), Some(PaddingPlan::Same));
        assert_eq!(
            plan(9, 8, 3, 2, 1),
            Some(PaddingPlan::PadThenValid { pad: 1 })
        );
        assert_eq!(plan(8, 8, 1, 1, 0), Some(PaddingPlan::Valid));
        assert_eq!(plan(8, 8, 3, 1, 0), Some(PaddingPlan::Valid));
        assert_eq!(plan(2, 2, 5, 1, 0), None);
        assert_eq!(plan(8, 8, 3, 0, 1), None);
    }

    #[test]
    fn every_plan_reads_what_orbfix_reads() {
        // Output size and first input row of the TFLite form equal orbfix's.
        for input in 3..40 {
            for k in [1, 3, 5] {
                for stride in 1..4 {
                    for pad in 0..3 {
                        let Some(out) = orbfix_out(input, k, stride, pad) else {
                            continue;
                        };
                        let (tf_out, first) = match plan(input, input, k, stride, pad).unwrap() {
                            PaddingPlan::Same => {
                                let (o, before) = same_geometry(input, k, stride);
                                (o, -(before as isize))
                            }
                            PaddingPlan::Valid => ((input - k) / stride + 1, 0),
                            PaddingPlan::PadThenValid { pad: p } => {
                                ((input + 2 * p - k) / stride + 1, -(p as isize))
                            }
                        };
                        assert_eq!(
                            (tf_out, first),
                            (out, -(pad as isize)),
                            "in {input} k {k} s {stride} p {pad}"
                        );
                    }
                }
            }
        }
    }
}
