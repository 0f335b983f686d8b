//! Int8 pooling (NHWC, no padding): max and average over `k x k` windows.
//!
//! Pooling keeps the quantization of its input (same scale and zero point), as in TFLite.

use super::conv::{conv_out_size, Dims};
use super::NnError;

/// Which reduction a pooling window applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PoolKind {
    /// Largest value of the window.
    Max,
    /// Mean of the window, rounded half away from zero.
    Average,
}

/// `k x k` pooling at `stride`; `out_dims` must be the pooled size with the same channels.
pub fn pool_s8(
    kind: PoolKind,
    k: usize,
    stride: usize,
    input: &[i8],
    in_dims: Dims,
    output: &mut [i8],
    out_dims: Dims,
) -> Result<(), NnError> {
    let oh = conv_out_size(in_dims.h, k, stride, 0).ok_or(NnError::BadGeometry)?;
    let ow = conv_out_size(in_dims.w, k, stride, 0).ok_or(NnError::BadGeometry)?;
    if oh != out_dims.h || ow != out_dims.w || in_dims.c != out_dims.c {
        return Err(NnError::BadGeometry);
    }
    if input.len() < in_dims.len() || output.len() < out_dims.len() {
        return Err(NnError::BufferSize);
    }
    let c = in_dims.c;
    let count = (k * k) as i32;
    for oy in 0..oh {
        for ox in 0..ow {
            for ch in 0..c {
                let mut max = i8::MIN;
                let mut sum = 0i32;
                for ky in 0..k {
                    let row = (oy * stride + ky) * in_dims.w;
                    for kx in 0..k {
                        let v = input[(row + ox * stride + kx) * c + ch];
                        max = max.max(v);
                        sum += v as i32;
                    }
                }
                output[(oy * ow + ox) * c + ch] = match kind {
                    PoolKind::Max => max,
                    PoolKind::Average => {
                        let half = if sum >= 0 { count / 2 } else { -(count / 2) };
                        ((sum + half) / count).clamp(-128, 127) as i8
                    }
                };
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_and_average_2x2() {
        // 2x2x1 -> 1x1x1
        let input = [1i8, -4, 6, 2];
        let d_in = Dims { h: 2, w: 2, c: 1 };
        let d_out = Dims { h: 1, w: 1, c: 1 };
        let mut out = [0i8; 1];
        pool_s8(PoolKind::Max, 2, 2, &input, d_in, &mut out, d_out).unwrap();
        assert_eq!(out[0], 6);
        pool_s8(PoolKind::Average, 2, 2, &input, d_in, &mut out, d_out).unwrap();
        assert_eq!(out[0], 1); // 5/4 = 1.25 -> 1
        let input = [-1i8, -2, -3, -4]; // -2.5 -> -3
        pool_s8(PoolKind::Average, 2, 2, &input, d_in, &mut out, d_out).unwrap();
        assert_eq!(out[0], -3);
        assert_eq!(
            pool_s8(PoolKind::Max, 2, 2, &input, d_in, &mut out, d_in),
            Err(NnError::BadGeometry)
        );
    }
}
