//! Tests of the int8 matrix kernels: the per-channel requantization, and the DSP path equal
//! to the portable kernel.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::super::conv::conv2d_s8_buffer_size;
use super::super::requant::requantize;
use super::*;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + (self.next() % (hi - lo + 1) as u64) as i64
    }
}

#[test]
fn channel_q_equals_requantize() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let edges = [i32::MIN, i32::MIN + 1, -1, 0, 1, i32::MAX - 1, i32::MAX];
    let mut checked = 0;
    for i in 0..200_000 {
        let acc = if i % 7 == 0 {
            edges[(rng.next() % 7) as usize]
        } else if i % 3 == 0 {
            rng.next() as i32
        } else {
            rng.range(-40_000, 40_000) as i32
        };
        let m = match i % 11 {
            0 => edges[(rng.next() % 7) as usize],
            1 => rng.next() as i32,
            _ => rng.range(1 << 30, i32::MAX as i64) as i32,
        };
        let shift = if i % 5 == 0 {
            rng.range(-40, 40) as i32
        } else {
            rng.range(-14, 2) as i32
        };
        let (off, lo, hi) = (rng.range(-130, 130) as i32, -128, 127);
        let (lo, hi) = if i % 4 == 0 {
            (off.clamp(-128, 127), hi)
        } else {
            (lo, hi)
        };
        let q = OutputQ {
            offset: off,
            min: lo,
            max: hi,
        };
        let want = requantize(acc, m, shift, off, lo, hi);
        let got = q.put(&ChannelQ::new(m, shift), (m, shift), acc);
        assert_eq!(got, want, "acc {acc} m {m} shift {shift} off {off}");
        checked += 1;
    }
    assert_eq!(checked, 200_000);
}

/// Largest tensors of the comparisons (the shipped network's layers), elements.
const MAX_IN: usize = 16_384;
const MAX_WEIGHTS: usize = 36_864;
const MAX_OUT: usize = 16_384;
const MAX_OC: usize = 64;

/// Buffers of one comparison (no heap in the core's tests).
struct Case {
    input: [i8; MAX_IN],
    weights: [i8; MAX_WEIGHTS],
    want: [i8; MAX_OUT],
    got: [i8; MAX_OUT],
    scratch: [i16; 2 * 576 + 3],
}

/// The portable kernel (`conv2d_s8` off Arm) and this module's path on the instruction
/// models give the same bytes; returns how many distinct output values there were.
fn compare(
    rng: &mut Rng,
    b: &mut Case,
    (h, w, ic): (usize, usize, usize),
    oc: usize,
    (kernel, stride, pad): (usize, usize, usize),
) -> usize {
    let field = kernel * kernel * ic;
    let input = &mut b.input[..h * w * ic];
    input.iter_mut().for_each(|v| *v = rng.next() as i8);
    let weights = &mut b.weights[..oc * field];
    weights
        .iter_mut()
        .for_each(|v| *v = rng.range(-127, 127) as i8);
    let (mut bias, mut multiplier, mut shift) = ([0i32; MAX_OC], [0i32; MAX_OC], [0i32; MAX_OC]);
    for c in 0..oc {
        bias[c] = rng.range(-5000, 5000) as i32;
        multiplier[c] = rng.range(1 << 30, i32::MAX as i64) as i32;
        shift[c] = rng.range(-12, 0) as i32;
    }
    let (bias, multiplier, shift) = (&bias[..oc], &multiplier[..oc], &shift[..oc]);
    let zp = rng.range(-128, 127) as i32;
    let relu = rng.next() % 2 == 0;
    let out_zp = if relu {
        -128
    } else {
        rng.range(-20, 20) as i32
    };
    let p = ConvParams {
        kernel,
        stride,
        pad,
        input_offset: -zp,
        output_offset: out_zp,
        act_min: if relu { out_zp } else { -128 },
        act_max: 127,
    };
    let oh = conv_out_size(h, kernel, stride, pad).unwrap();
    let ow = conv_out_size(w, kernel, stride, pad).unwrap();
    let (in_dims, out_dims) = (
        Dims { h, w, c: ic },
        Dims {
            h: oh,
            w: ow,
            c: oc,
        },
    );
    let want = &mut b.want[..out_dims.len()];
    // An odd offset into the scratch buffer tries the realignment.
    let len = conv2d_s8_buffer_size(kernel, ic);
    super::super::conv::conv2d_s8(
        &p,
        input,
        in_dims,
        weights,
        bias,
        multiplier,
        shift,
        want,
        out_dims,
        &mut b.scratch[1..1 + len],
    )
    .unwrap();
    let ch = Channels {
        weights,
        bias,
        multiplier,
        shift,
        out: OutputQ {
            offset: p.output_offset,
            min: p.act_min,
            max: p.act_max,
        },
    };
    let got = &mut b.got[..out_dims.len()];
    got.fill(0x55);
    let start = (rng.next() % 2) as usize;
    conv2d(
        &p,
        input,
        in_dims,
        &ch,
        got,
        out_dims,
        &mut b.scratch[start..start + len],
    )
    .unwrap();
    assert_eq!(
        got, want,
        "{h}x{w}x{ic} -> {oc}, k {kernel} s {stride} p {pad}"
    );
    if kernel == 1 && stride == 1 && pad == 0 && ic <= DENSE_MAX_IN {
        got.fill(0x55);
        dense(p.input_offset, h * w, ic, input, &ch, got).unwrap();
        assert_eq!(got, want, "dense {h}x{w}x{ic} -> {oc}");
    }
    let mut seen = [false; 256];
    want.iter().for_each(|&v| seen[v as u8 as usize] = true);
    seen.iter().filter(|&&s| s).count()
}

#[test]
fn dsp_path_equals_portable_kernel() {
    let mut rng = Rng(12345);
    let mut b = Case {
        input: [0; MAX_IN],
        weights: [0; MAX_WEIGHTS],
        want: [0; MAX_OUT],
        got: [0; MAX_OUT],
        scratch: [0; 2 * 576 + 3],
    };
    // The shipped network's layers, then odd shapes: channel counts not a multiple of
    // four (the general gather and tails), odd pixel and channel counts.
    let shapes = [
        ((64, 64, 1), 16, (3, 2, 1)),
        ((32, 32, 16), 32, (3, 2, 1)),
        ((16, 16, 32), 64, (3, 2, 1)),
        ((8, 8, 64), 64, (3, 1, 1)),
        ((8, 8, 64), 32, (1, 1, 0)),
    ];
    for &(d, oc, g) in &shapes {
        assert!(
            compare(&mut rng, &mut b, d, oc, g) > 20,
            "outputs too uniform to test"
        );
    }
    for case in 0..150 {
        let kernel = [1, 3, 5, 2][case % 4];
        let (stride, pad) = (1 + case % 3, (case / 3) % 3);
        let h = kernel + (rng.next() % 9) as usize;
        let w = kernel + (rng.next() % 9) as usize;
        let ic = 1 + (rng.next() % 13) as usize;
        let oc = 1 + (rng.next() % 9) as usize;
        compare(&mut rng, &mut b, (h, w, ic), oc, (kernel, stride, pad));
    }
}
