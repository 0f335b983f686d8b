//! Fault injection into the shipped weight file: every injected bit flip is detected (the
//! CRC-32 check runs before anything the file declares is used).
//!
//! Flipped: every bit of every byte that carries structure or quantization (header, layer
//! headers, per-channel scales / biases / multipliers / shifts, CRC trailer), every bit of
//! every 16th weight byte, and 2,000 random double flips. `ORBFIX_FAULTS_ALL=1` flips every
//! one of the 520,000 bits instead (about 40 s in release).

use orbfix::nn::model::{SHIPPED_WEIGHTS, SPEC};
use orbfix::nn::weights::{parse, WeightsError, HEADER_BYTES, LAYER_HEADER_BYTES};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Byte offsets whose every bit is flipped.
fn positions(all: bool) -> Vec<usize> {
    let n = SHIPPED_WEIGHTS.len();
    if all {
        return (0..n).collect();
    }
    let mut v: Vec<usize> = (0..HEADER_BYTES).collect();
    let mut pos = HEADER_BYTES;
    for s in &SPEC {
        let params = LAYER_HEADER_BYTES + 13 * s.out_c;
        v.extend(pos..pos + params);
        let w0 = pos + params;
        v.extend((w0..w0 + s.weight_count()).step_by(16));
        pos = w0 + s.weight_count();
    }
    assert_eq!(pos + 4, n, "layout walk must end at the trailer");
    v.extend(pos..n);
    v
}

/// Refused as damaged: a CRC mismatch, or (a flip in the 4 magic bytes, checked first so
/// that another kind of file reads as "not an orbfix weight file") a wrong magic.
fn is_detected(e: Option<WeightsError>) -> bool {
    matches!(
        e,
        Some(WeightsError::CrcMismatch { .. } | WeightsError::BadMagic)
    )
}

#[test]
fn every_injected_bit_flip_is_detected() {
    let all = std::env::var_os("ORBFIX_FAULTS_ALL").is_some();
    let mut b = SHIPPED_WEIGHTS.to_vec();
    let (mut tried, mut detected) = (0usize, 0usize);
    for p in positions(all) {
        for bit in 0..8 {
            b[p] ^= 1 << bit;
            let e = parse(&b, &SPEC).err();
            tried += 1;
            if is_detected(e) {
                detected += 1;
            } else {
                panic!("flip of bit {bit} of byte {p} not detected: {e:?}");
            }
            b[p] ^= 1 << bit;
        }
    }
    // Double flips anywhere (CRC-32 detects every 2-bit error at this length).
    let mut rng = StdRng::seed_from_u64(12);
    let nbits = b.len() * 8;
    for _ in 0..2000 {
        let i = rng.random_range(0..nbits);
        let j = (i + rng.random_range(1..nbits)) % nbits;
        for k in [i, j] {
            b[k / 8] ^= 1 << (k % 8);
        }
        let e = parse(&b, &SPEC).err();
        tried += 1;
        assert!(
            is_detected(e),
            "flips of bits {i} and {j} not detected: {e:?}"
        );
        detected += 1;
        for k in [i, j] {
            b[k / 8] ^= 1 << (k % 8);
        }
    }
    assert_eq!(b, SHIPPED_WEIGHTS, "the file is restored");
    assert!(parse(&b, &SPEC).is_ok());
    println!(
        "fault injection: {tried} corrupted weight files, {detected} refused (CRC mismatch, or wrong magic for a flip in its 4 bytes), 0 accepted"
    );
    assert_eq!(tried, detected);
}
