//! Every stored (multiplier, shift) is TFLite's derivation from the file's own f32 scales,
//! so the network runs bit-exact in TensorFlow Lite Micro.

use orbfix::nn::model::SHIPPED_WEIGHTS;
use orbfix_host::nn::float_model::FloatNet;
use orbfix_host::nn::multiplier::{multiplier_mismatches, rederive_multipliers, tflite_multiplier};
use orbfix_host::nn::qmodel::HostQModel;
use orbfix_host::nn::quantize::quantize;

#[test]
fn shipped_multipliers_are_derived_from_the_stored_scales() {
    let q = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    let channels: usize = q.layers.iter().map(|l| l.out_c).sum();
    assert_eq!(channels, 208);
    // Recompute every channel independently of `multiplier_mismatches`.
    let mut s_in = q.input_scale;
    for (i, l) in q.layers.iter().enumerate() {
        for c in 0..l.out_c {
            let derived = tflite_multiplier(s_in, l.weight_scale[c], l.output_scale);
            assert_eq!(
                (l.multiplier[c], l.shift[c]),
                derived,
                "layer {i} channel {c}"
            );
        }
        s_in = l.output_scale;
    }
    assert!(multiplier_mismatches(&q).is_empty());
}

#[test]
fn quantizer_writes_the_tflite_multipliers() {
    let net = FloatNet::init(7).unwrap();
    let ranges = [(-0.5, 2.0), (0.0, 3.3), (0.0, 1.7), (0.0, 0.9), (-1.3, 1.1)];
    let q = quantize(&net, &ranges).unwrap();
    assert!(multiplier_mismatches(&q).is_empty());
}

#[test]
fn rederivation_rewrites_only_multipliers() {
    let orig = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    let mut q = orig.clone();
    // Spoil a few multipliers and shifts; the re-derivation restores exactly those.
    q.layers[0].multiplier[3] += 215;
    q.layers[2].multiplier[0] -= 1;
    q.layers[4].shift[31] -= 1;
    assert_eq!(multiplier_mismatches(&q).len(), 3);
    assert_eq!(rederive_multipliers(&mut q), 3);
    assert_eq!(q, orig);
    assert_eq!(q.to_bytes(), SHIPPED_WEIGHTS);
}
