//! Requantization multipliers derived from the scales a weight file stores, the way TFLite
//! and TensorFlow Lite Micro derive them.
//!
//! A `.ofw` file stores every scale as an `f32` (input scale, each layer's output scale and
//! per-channel weight scales) next to the Q0.31 multiplier and shift the core applies.
//! TFLite's kernels (`PopulateConvolutionQuantizationParams`) compute the real multiplier of
//! output channel `c` as `double(s_in) * double(s_w[c]) / double(s_out)` from those `f32`
//! values and encode it with `QuantizeMultiplier`; deriving it from unrounded `f64` scales
//! gives multipliers that differ in the last Q31 units, so some outputs differ by one. This
//! module is the one place that derivation lives: the quantizer uses it, and
//! `orbfix quantize --rederive-multipliers` rewrites an existing file with it.

use super::qmodel::{quantize_multiplier, HostQModel};

/// `(multiplier, shift)` of one output channel from its `f32` scales, as TFLite derives it:
/// `QuantizeMultiplier(double(s_in) * double(s_w) / double(s_out))`.
pub fn tflite_multiplier(s_in: f32, s_w: f32, s_out: f32) -> (i32, i8) {
    quantize_multiplier(s_in as f64 * s_w as f64 / s_out as f64)
}

/// One stored `(multiplier, shift)` that differs from the one its scales give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MultiplierMismatch {
    /// Zero-based layer index.
    pub layer: usize,
    /// Output channel.
    pub channel: usize,
    /// `(multiplier, shift)` stored in the file.
    pub stored: (i32, i8),
    /// `(multiplier, shift)` derived from the file's scales.
    pub derived: (i32, i8),
}

/// Every channel of `model` whose stored `(multiplier, shift)` is not the TFLite derivation
/// from the stored scales (the input scale of layer `i` is layer `i - 1`'s output scale, the
/// file's input scale for layer 0).
pub fn multiplier_mismatches(model: &HostQModel) -> Vec<MultiplierMismatch> {
    let mut out = Vec::new();
    let mut s_in = model.input_scale;
    for (i, l) in model.layers.iter().enumerate() {
        for (c, ((&sw, &m), &sh)) in l
            .weight_scale
            .iter()
            .zip(&l.multiplier)
            .zip(&l.shift)
            .enumerate()
        {
            let derived = tflite_multiplier(s_in, sw, l.output_scale);
            if derived != (m, sh) {
                out.push(MultiplierMismatch {
                    layer: i,
                    channel: c,
                    stored: (m, sh),
                    derived,
                });
            }
        }
        s_in = l.output_scale;
    }
    out
}

/// Rewrites every multiplier and shift of `model` from its stored scales (TFLite's
/// derivation); weights, biases, scales and zero points are left as they are. Returns the
/// number of channels whose `(multiplier, shift)` changed.
pub fn rederive_multipliers(model: &mut HostQModel) -> usize {
    let changed = multiplier_mismatches(model);
    for m in &changed {
        let l = &mut model.layers[m.layer];
        l.multiplier[m.channel] = m.derived.0;
        l.shift[m.channel] = m.derived.1;
    }
    changed.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivation_uses_the_f32_scales() {
        // 1/3 is not an f32; the f32-rounded scales give a different real multiplier than
        // the f64 ones, and the derivation must follow the f32 values.
        let (s_in, s_w, s_out) = (1.0f64 / 32.0, 1.0f64 / 3.0 / 127.0, 0.1f64);
        let from_f64 = quantize_multiplier(s_in * s_w / s_out);
        let from_f32 = tflite_multiplier(s_in as f32, s_w as f32, s_out as f32);
        let expected =
            quantize_multiplier((s_in as f32) as f64 * (s_w as f32) as f64 / (s_out as f32) as f64);
        assert_eq!(from_f32, expected);
        assert_ne!(from_f32, from_f64);
    }

    #[test]
    fn quantize_multiplier_matches_tflite_edges() {
        // Exact powers of two: frac 0.5.
        assert_eq!(quantize_multiplier(0.5), (1 << 30, 0));
        assert_eq!(quantize_multiplier(0.25), (1 << 30, -1));
        assert_eq!(quantize_multiplier(1.0), (1 << 30, 1));
        // Just below 1: q rounds to 2^31 and renormalizes.
        assert_eq!(quantize_multiplier(1.0 - 1e-12), (1 << 30, 1));
        // Below 2^-32 the multiplier is zero (shift < -31).
        assert_eq!(quantize_multiplier(2f64.powi(-33)), (0, 0));
        assert_eq!(quantize_multiplier(2f64.powi(-32)), (1 << 30, -31));
    }
}
