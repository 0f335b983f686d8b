//! Bit-exact host reference of the quantized network, written independently of the core's
//! kernels: exact 128-bit rational rounding instead of gemmlowp's nudge-and-shift, direct
//! convolution sums without im2col. `tests/` check it against the core bit for bit.

use super::qmodel::{HostQLayer, HostQModel};

/// `a * b / 2^31` rounded to nearest, halves up (towards +infinity); `MIN * MIN` saturates.
pub fn high_mul(a: i32, b: i32) -> i32 {
    if a == i32::MIN && b == i32::MIN {
        return i32::MAX;
    }
    let ab = a as i128 * b as i128;
    (ab + (1i128 << 30)).div_euclid(1i128 << 31) as i32
}

/// `x / 2^e` rounded to nearest, halves away from zero.
pub fn div_pot(x: i32, e: u32) -> i32 {
    if e == 0 {
        return x;
    }
    let m = (x as i64).abs();
    let r = (m + (1i64 << (e - 1))) >> e;
    (if x < 0 { -r } else { r }) as i32
}

/// Real-valued `acc * q / 2^31 * 2^shift` in the fixed-point arithmetic of TFLite.
pub fn scale(acc: i32, q: i32, shift: i8) -> i32 {
    let shift = shift as i32;
    let x = if shift > 0 {
        ((acc as i64) << shift) as i32 // wraps like the target's 32-bit multiply
    } else {
        acc
    };
    div_pot(high_mul(x, q), (-shift).max(0) as u32)
}

/// Runs one layer on an NHWC int8 input.
pub fn run_layer(l: &HostQLayer, input: &[i8]) -> Vec<i8> {
    let (oh, ow) = (l.out_h(), l.out_w());
    let mut out = vec![0i8; oh * ow * l.out_c];
    for oy in 0..oh {
        for ox in 0..ow {
            for oc in 0..l.out_c {
                let mut acc = l.bias[oc] as i64;
                for ky in 0..l.kernel {
                    for kx in 0..l.kernel {
                        let iy = (oy * l.stride + ky) as i64 - l.pad as i64;
                        let ix = (ox * l.stride + kx) as i64 - l.pad as i64;
                        if iy < 0 || ix < 0 || iy >= l.in_h as i64 || ix >= l.in_w as i64 {
                            continue;
                        }
                        for ic in 0..l.in_c {
                            let a = input[((iy as usize * l.in_w) + ix as usize) * l.in_c + ic]
                                as i64
                                - l.input_zp as i64;
                            let w = l.weights[((oc * l.kernel + ky) * l.kernel + kx) * l.in_c + ic]
                                as i64;
                            acc += a * w;
                        }
                    }
                }
                let v =
                    scale(acc as i32, l.multiplier[oc], l.shift[oc]) as i64 + l.output_zp as i64;
                out[(oy * ow + ox) * l.out_c + oc] =
                    v.clamp(l.act_min as i64, l.act_max as i64) as i8;
            }
        }
    }
    out
}

/// Runs the quantized network on one int8 input (NHWC); returns the last layer's output
/// and, when `acts` is given, pushes every layer's output onto it.
pub fn run(m: &HostQModel, input: &[i8], mut acts: Option<&mut Vec<Vec<i8>>>) -> Vec<i8> {
    let mut x = input.to_vec();
    for l in &m.layers {
        x = run_layer(l, &x);
        if let Some(a) = acts.as_deref_mut() {
            a.push(x.clone());
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use orbfix::nn::requant;

    #[test]
    fn reference_rounding_matches_core_on_edge_cases() {
        let vals = [
            0,
            1,
            -1,
            2,
            -2,
            3,
            -3,
            1 << 30,
            -(1 << 30),
            (3 << 29) + 7,
            i32::MAX,
            i32::MIN,
            i32::MIN + 1,
            123_456_789,
            -987_654_321,
        ];
        for &a in &vals {
            for &b in &vals {
                assert_eq!(
                    high_mul(a, b),
                    requant::saturating_rounding_doubling_high_mul(a, b),
                    "{a} * {b}"
                );
            }
            for e in 0..31 {
                assert_eq!(
                    div_pot(a, e),
                    requant::rounding_divide_by_pot(a, e as i32),
                    "{a} >> {e}"
                );
            }
        }
    }
}
