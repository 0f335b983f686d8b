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
