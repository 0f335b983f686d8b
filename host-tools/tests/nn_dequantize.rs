//! `orbfix quantize --dequantize`: the float network of an int8 weight file, quantized
//! again, gives back the same int8 weights and biases (per-channel symmetric scales are
//! recovered from each channel's largest weight).

use orbfix_host::nn::qmodel::HostQModel;
use orbfix_host::nn::quantize::{dequantize, quantize};

#[test]
fn dequantized_shipped_weights_quantize_back_to_themselves() {
    let bytes = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../weights/matcher-v2.ofw"
    ))
    .unwrap();
    let q = HostQModel::from_bytes(&bytes).unwrap();
    let net = dequantize(&q).unwrap();
    // The shipped activation ranges, so that the input scales (and so the biases) match.
    let ranges: Vec<(f32, f32)> = q
        .layers
        .iter()
        .map(|l| {
            let lo = (-128 - l.output_zp) as f32 * l.output_scale;
            (lo, lo + 255.0 * l.output_scale)
        })
        .collect();
    let back = quantize(&net, &ranges).unwrap();
    for (i, (a, b)) in q.layers.iter().zip(&back.layers).enumerate() {
        assert_eq!(a.weights, b.weights, "layer {i} weights");
        for (c, (x, y)) in a.bias.iter().zip(&b.bias).enumerate() {
            assert!((x - y).abs() <= 1, "layer {i} channel {c} bias {x} vs {y}");
        }
        for (x, y) in a.weight_scale.iter().zip(&b.weight_scale) {
            assert!(
                (x - y).abs() <= 1e-6 * x.abs(),
                "layer {i} scale {x} vs {y}"
            );
        }
    }
}
