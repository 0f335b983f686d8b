//! The core's weight-file validation: every corruption is a typed error, never a panic.

use orbfix::nn::model::{SiameseNet, SHIPPED_WEIGHTS, SPEC, WEIGHT_FILE_BYTES};
use orbfix::nn::weights::{parse, WeightsError};
use orbfix_host::nn::qmodel::HostQModel;

fn shipped() -> Vec<u8> {
    SHIPPED_WEIGHTS.to_vec()
}

#[test]
fn shipped_file_is_valid_and_sized_for_the_network() {
    assert_eq!(SHIPPED_WEIGHTS.len(), WEIGHT_FILE_BYTES);
    assert!(SiameseNet::from_bytes(SHIPPED_WEIGHTS).is_ok());
}

#[test]
fn flipped_byte_is_crc_mismatch() {
    let b = shipped();
    for pos in [20usize, 100, b.len() / 2, b.len() - 5] {
        let mut c = b.clone();
        c[pos] ^= 0x10;
        assert!(
            matches!(parse(&c, &SPEC), Err(WeightsError::CrcMismatch { .. })),
            "flip at {pos}: {:?}",
            parse(&c, &SPEC).err()
        );
    }
    // A corrupted trailer too.
    let mut c = b.clone();
    let n = c.len();
    c[n - 1] ^= 1;
    assert!(matches!(
        parse(&c, &SPEC),
        Err(WeightsError::CrcMismatch { .. })
    ));
}

#[test]
fn truncated_is_truncated() {
    let b = shipped();
    for len in [0usize, 3, 10, 19, 60, b.len() / 2, b.len() - 1] {
        let r = parse(&b[..len], &SPEC);
        assert!(
            matches!(r, Err(WeightsError::Truncated { .. })),
            "len {len}: {:?}",
            r.err()
        );
    }
    let mut long = b.clone();
    long.push(0);
    assert!(matches!(
        parse(&long, &SPEC),
        Err(WeightsError::TrailingBytes { .. }) | Err(WeightsError::CrcMismatch { .. })
    ));
}

#[test]
fn wrong_shapes_are_shape_mismatch() {
    let mut m = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    // Layer 2 with 48 instead of 64 output channels (a consistent, valid-CRC file).
    let l = &mut m.layers[2];
    let per = l.kernel * l.kernel * l.in_c;
    l.out_c = 48;
    l.weights.truncate(48 * per);
    for v in [&mut l.bias, &mut l.multiplier] {
        v.truncate(48);
    }
    l.shift.truncate(48);
    l.weight_scale.truncate(48);
    let bytes = m.to_bytes();
    assert_eq!(
        parse(&bytes, &SPEC).err(),
        Some(WeightsError::ShapeMismatch { layer: 2 })
    );

    let mut m = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    m.layers.pop();
    assert_eq!(
        parse(&m.to_bytes(), &SPEC).err(),
        Some(WeightsError::LayerCount {
            expected: 5,
            found: 4
        })
    );
}

#[test]
fn bad_quantization_is_rejected() {
    let mut m = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    m.layers[1].shift[0] = 40;
    assert_eq!(
        parse(&m.to_bytes(), &SPEC).err(),
        Some(WeightsError::BadQuantization { layer: 1 })
    );
    let mut m = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    m.layers[3].input_zp += 1;
    assert_eq!(
        parse(&m.to_bytes(), &SPEC).err(),
        Some(WeightsError::BadQuantization { layer: 3 })
    );
    let mut m = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    m.layers[0].weights[0] = -128;
    assert_eq!(
        parse(&m.to_bytes(), &SPEC).err(),
        Some(WeightsError::BadQuantization { layer: 0 })
    );
    let mut b = shipped();
    b[0] = b'X';
    assert_eq!(parse(&b, &SPEC).err(), Some(WeightsError::BadMagic));
}

#[test]
fn flipped_layer_count_is_corruption_not_truncation() {
    // Byte 6 is the low byte of the layer count: 5 -> 0x05 ^ 0xE8 = 237 layers.
    let mut b = shipped();
    b[6] ^= 0xE8;
    let e = parse(&b, &SPEC).err();
    assert!(matches!(e, Some(WeightsError::CrcMismatch { .. })), "{e:?}");
    let msg = e.unwrap().to_string();
    assert!(msg.contains("corrupt"), "{msg}");
}

/// Accumulator bound of layer `l` (field * 255 * 127) and the largest bias its channel
/// `c` may have.
fn bias_limit(m: &HostQModel, l: usize, c: usize) -> i64 {
    let layer = &m.layers[l];
    let field = (layer.kernel * layer.kernel * layer.in_c) as i64;
    let shift = layer.shift[c].max(0) as u32;
    (i32::MAX as i64 >> shift) - field * 255 * 127
}

#[test]
fn bias_of_i32_max_with_a_valid_crc_is_refused() {
    let mut m = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    m.layers[1].bias[3] = i32::MAX;
    let bytes = m.to_bytes(); // a valid CRC
    let e = parse(&bytes, &SPEC).err();
    assert_eq!(
        e,
        Some(WeightsError::AccumulatorOverflow {
            layer: 1,
            channel: 3
        })
    );
    let msg = e.unwrap().to_string();
    assert!(
        msg.contains("layer 1, channel 3") && msg.contains("bias"),
        "{msg}"
    );
    assert!(!msg.contains("AccumulatorOverflow"), "{msg}");
    // i32::MIN too (its magnitude does not fit an i32).
    m.layers[1].bias[3] = i32::MIN;
    assert!(matches!(
        parse(&m.to_bytes(), &SPEC),
        Err(WeightsError::AccumulatorOverflow { .. })
    ));
}

#[test]
fn bias_bound_is_tight_and_safe_at_the_limit() {
    let base = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    // One past the limit is refused, the limit itself is accepted, on every layer.
    for l in 0..base.layers.len() {
        let lim = bias_limit(&base, l, 0);
        assert!(lim > 0);
        let mut m = base.clone();
        m.layers[l].bias[0] = (lim + 1) as i32;
        assert_eq!(
            parse(&m.to_bytes(), &SPEC).err(),
            Some(WeightsError::AccumulatorOverflow {
                layer: l,
                channel: 0
            }),
            "layer {l}"
        );
        m.layers[l].bias[0] = -(lim + 1) as i32;
        assert!(parse(&m.to_bytes(), &SPEC).is_err(), "layer {l}");
        m.layers[l].bias[0] = lim as i32;
        assert!(parse(&m.to_bytes(), &SPEC).is_ok(), "layer {l}");
    }
    // Every bias of every layer at its limit (both signs), on extreme inputs: the embedding
    // runs without an overflow (this test is built with overflow checks in the dev profile).
    for sign in [1i64, -1] {
        let mut m = base.clone();
        for l in 0..m.layers.len() {
            for c in 0..m.layers[l].out_c {
                m.layers[l].bias[c] = (sign * bias_limit(&base, l, c)) as i32;
            }
        }
        let bytes = m.to_bytes();
        let net = SiameseNet::from_bytes(&bytes).expect("biases at the limit are valid");
        let mut arena = Box::new(orbfix::nn::model::Arena::new());
        let mut out = [0i8; orbfix::nn::model::EMBED_LEN];
        for fill in [i8::MIN, -1, 0, 1, i8::MAX] {
            let input = [fill; orbfix::nn::input::INPUT_LEN];
            net.embed(&input, &mut arena, &mut out).unwrap();
        }
    }
}
