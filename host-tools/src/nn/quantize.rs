//! Post-training int8 quantization (TFLite / CMSIS-NN conventions) of the float trunk,
//! calibrated on prepared inputs (validation data).
//!
//! - weights: int8 symmetric per output channel, zero point 0, range -127..=127,
//!   `scale_w[c] = max|w[c]| / 127`;
//! - activations: int8 asymmetric per tensor from the calibration min / max (the range
//!   always contains 0 so that 0 is exact; after ReLU the zero point is -128);
//! - input: the core's fixed input quantization (scale 1/32, zero point 0);
//! - biases: int32, `round(b / (scale_in * scale_w[c]))`;
//! - requantization: `scale_in * scale_w[c] / scale_out` as Q0.31 multiplier + shift,
//!   derived from the `f32` scales the file stores, as TFLite derives it
//!   ([`super::multiplier::tflite_multiplier`]), so the file runs bit-exact in TFLite Micro.

use super::float_model::{batch_tensor, FloatNet};
use super::multiplier::tflite_multiplier;
use super::qmodel::{HostQLayer, HostQModel};
use anyhow::{ensure, Result};
use orbfix::nn::input::{INPUT_LEN, INPUT_UNITS_PER_SIGMA};
use orbfix::nn::model::SPEC;
use orbfix::nn::weights::LayerKind;

/// Per-layer float output range observed on the calibration set.
pub fn calibrate(net: &FloatNet, inputs: &[[i8; INPUT_LEN]]) -> Result<Vec<(f32, f32)>> {
    ensure!(!inputs.is_empty(), "calibration needs at least one input");
    let mut ranges = vec![(0f32, 0f32); SPEC.len()];
    for chunk in inputs.chunks(64) {
        let refs: Vec<&[i8; INPUT_LEN]> = chunk.iter().collect();
        let outs = net.forward_all(&batch_tensor(&refs)?)?;
        for (r, o) in ranges.iter_mut().zip(outs) {
            let v = o.flatten_all()?.to_vec1::<f32>()?;
            for x in v {
                r.0 = r.0.min(x);
                r.1 = r.1.max(x);
            }
        }
    }
    Ok(ranges)
}

/// Quantizes `net` with the calibrated per-layer `ranges`.
pub fn quantize(net: &FloatNet, ranges: &[(f32, f32)]) -> Result<HostQModel> {
    ensure!(
        ranges.len() == SPEC.len(),
        "one calibration range per layer needed"
    );
    let input_scale = 1.0 / INPUT_UNITS_PER_SIGMA as f32;
    let (mut s_in, mut zp_in) = (input_scale as f64, 0i32);
    let mut layers = Vec::new();
    for (i, s) in SPEC.iter().enumerate() {
        let (lo, hi) = (ranges[i].0.min(0.0) as f64, ranges[i].1.max(0.0) as f64);
        let s_out = ((hi - lo) / 255.0).max(1e-8);
        let zp_out = ((-128.0 - lo / s_out).round() as i32).clamp(-128, 127);
        let w = net.weights[i].as_tensor().flatten_all()?.to_vec1::<f32>()?;
        let b = net.biases[i].as_tensor().to_vec1::<f32>()?;
        let k = s.kernel;
        let fan = s.in_c * k * k;
        let (mut wq, mut ws, mut bq, mut mult, mut shift) =
            (vec![0i8; w.len()], vec![], vec![], vec![], vec![]);
        for oc in 0..s.out_c {
            // OIHW source.
            let wc = &w[oc * fan..(oc + 1) * fan];
            let max = wc.iter().fold(0f32, |m, &v| m.max(v.abs()));
            let sw = if max > 0.0 { max as f64 / 127.0 } else { 1.0 };
            for ic in 0..s.in_c {
                for ky in 0..k {
                    for kx in 0..k {
                        let v = wc[(ic * k + ky) * k + kx] as f64 / sw;
                        // OHWI destination.
                        wq[((oc * k + ky) * k + kx) * s.in_c + ic] =
                            v.round().clamp(-127.0, 127.0) as i8;
                    }
                }
            }
            ws.push(sw as f32);
            bq.push(
                (b[oc] as f64 / (s_in * sw))
                    .round()
                    .clamp(i32::MIN as f64, i32::MAX as f64) as i32,
            );
            // From the stored (f32) scales, not the f64 ones: what TFLite computes.
            let (m, sh) = tflite_multiplier(s_in as f32, sw as f32, s_out as f32);
            mult.push(m);
            shift.push(sh);
        }
        layers.push(HostQLayer {
            kind: match s.kind {
                LayerKind::Conv => 1,
                LayerKind::DensePerPixel => 2,
            },
            kernel: k,
            stride: s.stride,
            pad: s.pad,
            relu: s.relu,
            in_h: s.in_h,
            in_w: s.in_w,
            in_c: s.in_c,
            out_c: s.out_c,
            input_zp: zp_in,
            output_zp: zp_out,
            act_min: if s.relu { zp_out } else { -128 },
            act_max: 127,
            output_scale: s_out as f32,
            weight_scale: ws,
            bias: bq,
            multiplier: mult,
            shift,
            weights: wq,
        });
        s_in = s_out;
        zp_in = zp_out;
    }
    Ok(HostQModel {
        input_scale,
        input_zp: 0,
        layers,
    })
}

/// The float network an int8 model stands for: weights `w[c] * scale_w[c]` (OHWI back to
/// OIHW), biases `b[c] * scale_in * scale_w[c]`. A starting point for fine-tuning shipped
/// weights whose float checkpoint is not at hand (`orbfix quantize --dequantize`); the
/// activations' ranges are not kept (the next quantization calibrates them again).
pub fn dequantize(q: &HostQModel) -> Result<FloatNet> {
    use candle_core::{Device, Tensor, Var};
    ensure!(
        q.layers.len() == SPEC.len(),
        "the model has {} layers, the network {}",
        q.layers.len(),
        SPEC.len()
    );
    let mut s_in = q.input_scale as f64;
    let (mut weights, mut biases) = (Vec::new(), Vec::new());
    for (l, s) in q.layers.iter().zip(SPEC.iter()) {
        let k = s.kernel;
        ensure!(
            l.in_c == s.in_c && l.out_c == s.out_c && l.kernel == k,
            "a layer's shape differs from the network's"
        );
        let fan = s.in_c * k * k;
        ensure!(
            l.weights.len() == s.out_c * fan
                && l.weight_scale.len() == s.out_c
                && l.bias.len() == s.out_c,
            "a layer's weight, scale or bias count differs from its shape"
        );
        let mut w = vec![0f32; s.out_c * fan];
        let mut b = vec![0f32; s.out_c];
        for oc in 0..s.out_c {
            let sw = l.weight_scale[oc] as f64;
            for ic in 0..s.in_c {
                for ky in 0..k {
                    for kx in 0..k {
                        let v = l.weights[((oc * k + ky) * k + kx) * s.in_c + ic];
                        w[oc * fan + (ic * k + ky) * k + kx] = (f64::from(v) * sw) as f32;
                    }
                }
            }
            b[oc] = (f64::from(l.bias[oc]) * s_in * sw) as f32;
        }
        let wt = Tensor::from_vec(w, (s.out_c, s.in_c, k, k), &Device::Cpu)?;
        weights.push(Var::from_tensor(&wt)?);
        biases.push(Var::from_tensor(&Tensor::from_vec(
            b,
            s.out_c,
            &Device::Cpu,
        )?)?);
        s_in = l.output_scale as f64;
    }
    Ok(FloatNet { weights, biases })
}
