//! Host representation of the quantized network and its `.ofw` weight file (writer and
//! reader), plus the TFLite-style quantization arithmetic (multiplier / shift encoding).
//!
//! The byte layout is the one the core parses (`orbfix::nn::weights`, `docs/weights-format.md`).

use anyhow::{bail, ensure, Context, Result};
use orbfix::nn::weights::{crc32, MAGIC, VERSION};

/// One quantized layer, owned.
#[derive(Clone, Debug, PartialEq)]
pub struct HostQLayer {
    /// 1 = convolution, 2 = dense per pixel (1x1 convolution).
    pub kind: u8,
    /// Kernel side, pixels.
    pub kernel: usize,
    /// Stride, pixels.
    pub stride: usize,
    /// Symmetric zero padding, pixels.
    pub pad: usize,
    /// Fused ReLU.
    pub relu: bool,
    /// Input rows, columns, channels.
    pub in_h: usize,
    /// Input columns.
    pub in_w: usize,
    /// Input channels.
    pub in_c: usize,
    /// Output channels.
    pub out_c: usize,
    /// Input zero point.
    pub input_zp: i32,
    /// Output zero point.
    pub output_zp: i32,
    /// Lowest output value.
    pub act_min: i32,
    /// Highest output value.
    pub act_max: i32,
    /// Output scale (real per unit).
    pub output_scale: f32,
    /// Per-output-channel weight scale (real per unit).
    pub weight_scale: Vec<f32>,
    /// Int32 bias per output channel.
    pub bias: Vec<i32>,
    /// Q0.31 multiplier per output channel.
    pub multiplier: Vec<i32>,
    /// Shift per output channel (positive: left).
    pub shift: Vec<i8>,
    /// OHWI int8 weights.
    pub weights: Vec<i8>,
}

impl HostQLayer {
    /// Output rows.
    pub fn out_h(&self) -> usize {
        (self.in_h + 2 * self.pad - self.kernel) / self.stride + 1
    }
    /// Output columns.
    pub fn out_w(&self) -> usize {
        (self.in_w + 2 * self.pad - self.kernel) / self.stride + 1
    }
}

/// A quantized network, owned.
#[derive(Clone, Debug, PartialEq)]
pub struct HostQModel {
    /// Input scale (real per unit).
    pub input_scale: f32,
    /// Input zero point.
    pub input_zp: i32,
    /// Layers in order.
    pub layers: Vec<HostQLayer>,
}

/// Encodes a real multiplier `m >= 0` as `(q, shift)` with `m ~= q / 2^31 * 2^shift`,
/// `q` in `[2^30, 2^31)`, exactly as TFLite's `QuantizeMultiplier` does (`frexp`, round half
/// away from zero, `q == 2^31` renormalized). Multipliers below `2^-32` become `(0, 0)`;
/// above `2^30` they saturate to `(i32::MAX, 30)` (the core's shift range).
pub fn quantize_multiplier(m: f64) -> (i32, i8) {
    if m <= 0.0 || !m.is_finite() {
        return (0, 0);
    }
    // m = frac * 2^exp with frac in [0.5, 1).
    let (frac, mut exp) = libm::frexp(m);
    let mut q = (frac * (1u64 << 31) as f64).round() as i64;
    if q == 1i64 << 31 {
        q /= 2;
        exp += 1;
    }
    if exp < -31 {
        return (0, 0);
    }
    if exp > 30 {
        return (i32::MAX, 30);
    }
    (q as i32, exp as i8)
}

impl HostQModel {
    /// Serializes to the `.ofw` format (with the CRC-32 trailer).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&(self.layers.len() as u16).to_le_bytes());
        b.extend_from_slice(&self.input_scale.to_le_bytes());
        b.extend_from_slice(&self.input_zp.to_le_bytes());
        for l in &self.layers {
            b.extend_from_slice(&[
                l.kind,
                l.kernel as u8,
                l.stride as u8,
                l.pad as u8,
                l.relu as u8,
                0,
                0,
                0,
            ]);
            for v in [l.in_c, l.out_c, l.in_h, l.in_w] {
                b.extend_from_slice(&(v as u16).to_le_bytes());
            }
            for v in [l.input_zp, l.output_zp, l.act_min, l.act_max] {
                b.extend_from_slice(&v.to_le_bytes());
            }
            b.extend_from_slice(&l.output_scale.to_le_bytes());
            l.weight_scale
                .iter()
                .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
            l.bias
                .iter()
                .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
            l.multiplier
                .iter()
                .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
            l.shift.iter().for_each(|&v| b.push(v as u8));
            l.weights.iter().for_each(|&v| b.push(v as u8));
        }
        let crc = crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    /// Reads a `.ofw` file's bytes (structure and CRC checked; shapes not compared with any
    /// compiled network).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        ensure!(
            bytes.len() >= 20,
            "weight file too short ({} bytes)",
            bytes.len()
        );
        ensure!(bytes[..4] == MAGIC, "not an orbfix weight file (bad magic)");
        let body = &bytes[..bytes.len() - 4];
        let stored = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into()?);
        ensure!(
            crc32(body) == stored,
            "weight file CRC mismatch: the file is corrupted, regenerate it with `orbfix quantize`"
        );
        let mut p = 4usize;
        let mut take = |n: usize| -> Result<&[u8]> {
            let s = body.get(p..p + n).context("weight file truncated")?;
            p += n;
            Ok(s)
        };
        let version = u16::from_le_bytes(take(2)?.try_into()?);
        ensure!(
            version == VERSION,
            "unsupported weight file version {version}"
        );
        let n = u16::from_le_bytes(take(2)?.try_into()?) as usize;
        let input_scale = f32::from_le_bytes(take(4)?.try_into()?);
        let input_zp = i32::from_le_bytes(take(4)?.try_into()?);
        let mut layers = Vec::with_capacity(n);
        for _ in 0..n {
            let h = take(8)?.to_vec();
            let mut u16s = [0usize; 4];
            for v in u16s.iter_mut() {
                *v = u16::from_le_bytes(take(2)?.try_into()?) as usize;
            }
            let mut i32s = [0i32; 4];
            for v in i32s.iter_mut() {
                *v = i32::from_le_bytes(take(4)?.try_into()?);
            }
            let output_scale = f32::from_le_bytes(take(4)?.try_into()?);
            let oc = u16s[1];
            let f32s = |s: &[u8]| -> Vec<f32> {
                s.chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            };
            let i32v = |s: &[u8]| -> Vec<i32> {
                s.chunks_exact(4)
                    .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            };
            let weight_scale = f32s(take(oc * 4)?);
            let bias = i32v(take(oc * 4)?);
            let multiplier = i32v(take(oc * 4)?);
            let shift = take(oc)?.iter().map(|&v| v as i8).collect();
            let kernel = h[1] as usize;
            let weights = take(oc * kernel * kernel * u16s[0])?
                .iter()
                .map(|&v| v as i8)
                .collect();
            layers.push(HostQLayer {
                kind: h[0],
                kernel,
                stride: h[2] as usize,
                pad: h[3] as usize,
                relu: h[4] != 0,
                in_c: u16s[0],
                out_c: oc,
                in_h: u16s[2],
                in_w: u16s[3],
                input_zp: i32s[0],
                output_zp: i32s[1],
                act_min: i32s[2],
                act_max: i32s[3],
                output_scale,
                weight_scale,
                bias,
                multiplier,
                shift,
                weights,
            });
        }
        if p != body.len() {
            bail!(
                "weight file has {} unexpected trailing bytes",
                body.len() - p
            );
        }
        Ok(Self {
            input_scale,
            input_zp,
            layers,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multiplier_round_trips() {
        for m in [0.5, 0.75, 1.0, 1.5, 3.0e-3, 0.999_999_999_9, 1.2345e-7, 7.0] {
            let (q, s) = quantize_multiplier(m);
            assert!(q >= 1 << 30, "{m}: {q}");
            let back = q as f64 / 2f64.powi(31) * 2f64.powi(s as i32);
            assert!((back - m).abs() / m < 1e-9, "{m} -> {back}");
        }
        assert_eq!(quantize_multiplier(0.0), (0, 0));
        assert_eq!(quantize_multiplier(1e-30), (0, 0));
    }
}
