//! The versioned int8 weight file (`.ofw`, "orbfix weights"): parsing and validation.
//!
//! Layout (little-endian; full description in `docs/weights-format.md`):
//!
//! ```text
//! header   magic "OFW1" | u16 version (1) | u16 layer count | f32 input scale | i32 input zp
//! layer*   u8 kind (1 conv, 2 dense per pixel) | u8 kernel | u8 stride | u8 pad | u8 relu
//!          | u8 0 | u16 0 | u16 in_c | u16 out_c | u16 in_h | u16 in_w
//!          | i32 input zp | i32 output zp | i32 act_min | i32 act_max | f32 output scale
//!          | out_c x f32 weight scale | out_c x i32 bias | out_c x i32 multiplier (Q0.31)
//!          | out_c x i8 shift | out_c * kernel^2 * in_c x i8 weights (OHWI)
//! trailer  u32 CRC-32 (IEEE) of every preceding byte
//! ```
//!
//! The parser never trusts the file: it checks the length, magic, version, CRC, every shape
//! against the network compiled into the core, and every quantization parameter's range, and
//! reports the first problem as a typed [`WeightsError`].

use super::conv::conv_out_size;
use super::requant::{SHIFT_MAX, SHIFT_MIN};

/// File magic.
pub const MAGIC: [u8; 4] = *b"OFW1";
/// Format version this core reads.
pub const VERSION: u16 = 1;
/// Most output channels of any layer the core can hold.
pub const MAX_CHANNELS: usize = 64;
/// Bytes of the file header.
pub const HEADER_BYTES: usize = 16;
/// Bytes of a layer record before its per-channel arrays.
pub const LAYER_HEADER_BYTES: usize = 36;

/// Errors reading a weight file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WeightsError {
    /// The file ends before the structure it declares.
    Truncated {
        /// Bytes the declared structure needs.
        needed: usize,
        /// Bytes present.
        got: usize,
    },
    /// Bytes left over after the CRC trailer.
    TrailingBytes {
        /// Extra bytes.
        extra: usize,
    },
    /// Not an orbfix weight file.
    BadMagic,
    /// A format version this core cannot read.
    UnsupportedVersion(u16),
    /// The stored CRC-32 differs from the content's: the file is corrupted.
    CrcMismatch {
        /// CRC stored in the trailer.
        stored: u32,
        /// CRC of the content.
        computed: u32,
    },
    /// The file has a different number of layers than the compiled network.
    LayerCount {
        /// Layers of the compiled network.
        expected: usize,
        /// Layers in the file.
        found: usize,
    },
    /// Layer `layer`'s kind or shapes differ from the compiled network.
    ShapeMismatch {
        /// Zero-based layer index.
        layer: usize,
    },
    /// Layer `layer` has an out-of-range quantization parameter (zero point, activation range,
    /// multiplier, shift or a zero point that does not chain with the previous layer's).
    BadQuantization {
        /// Zero-based layer index.
        layer: usize,
    },
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320), the checksum of zip and PNG.
pub fn crc32(data: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut t = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            t[i] = c;
            i += 1;
        }
        t
    };
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc = TABLE[((crc ^ b as u32) & 0xFF) as usize] ^ (crc >> 8);
    }
    !crc
}

/// Kind of a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LayerKind {
    /// Square-kernel convolution ([`super::conv::conv2d_s8`]).
    Conv = 1,
    /// Fully connected layer applied to every pixel, a 1x1 convolution
    /// ([`super::dense::dense_s8`]).
    DensePerPixel = 2,
}

/// Shape of one layer of a compiled network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LayerSpec {
    /// Layer kind.
    pub kind: LayerKind,
    /// Kernel side, pixels (1 for dense).
    pub kernel: usize,
    /// Stride, pixels.
    pub stride: usize,
    /// Symmetric zero padding, pixels.
    pub pad: usize,
    /// Fused ReLU.
    pub relu: bool,
    /// Input rows, pixels.
    pub in_h: usize,
    /// Input columns, pixels.
    pub in_w: usize,
    /// Input channels.
    pub in_c: usize,
    /// Output channels.
    pub out_c: usize,
}

impl LayerSpec {
    /// Output rows, pixels (0 if the kernel does not fit).
    pub const fn out_h(&self) -> usize {
        match conv_out_size(self.in_h, self.kernel, self.stride, self.pad) {
            Some(v) => v,
            None => 0,
        }
    }

    /// Output columns, pixels (0 if the kernel does not fit).
    pub const fn out_w(&self) -> usize {
        match conv_out_size(self.in_w, self.kernel, self.stride, self.pad) {
            Some(v) => v,
            None => 0,
        }
    }

    /// Number of int8 weights.
    pub const fn weight_count(&self) -> usize {
        self.out_c * self.kernel * self.kernel * self.in_c
    }

    /// Multiply-accumulates of one evaluation.
    pub const fn macs(&self) -> u64 {
        (self.out_h() * self.out_w() * self.out_c * self.kernel * self.kernel * self.in_c) as u64
    }

    /// Bytes of this layer's record in the weight file.
    pub const fn record_bytes(&self) -> usize {
        LAYER_HEADER_BYTES + self.out_c * 13 + self.weight_count()
    }
}

/// Bytes of the weight file of a network.
pub const fn file_bytes(spec: &[LayerSpec]) -> usize {
    let mut n = HEADER_BYTES + 4;
    let mut i = 0;
    while i < spec.len() {
        n += spec[i].record_bytes();
        i += 1;
    }
    n
}

/// One validated, quantized layer; its weights borrow the file.
#[derive(Clone, Copy, Debug)]
pub struct QLayer<'a> {
    /// Shape (equal to the compiled network's).
    pub spec: LayerSpec,
    /// Input zero point.
    pub input_zp: i32,
    /// Output zero point.
    pub output_zp: i32,
    /// Lowest output value (fused activation).
    pub act_min: i32,
    /// Highest output value.
    pub act_max: i32,
    /// Output scale (real value per unit), for information.
    pub output_scale: f32,
    /// Int32 bias per output channel.
    pub bias: [i32; MAX_CHANNELS],
    /// Q0.31 multiplier per output channel.
    pub multiplier: [i32; MAX_CHANNELS],
    /// Shift per output channel (positive: left).
    pub shift: [i32; MAX_CHANNELS],
    /// OHWI int8 weights.
    pub weights: &'a [i8],
}

impl QLayer<'_> {
    const EMPTY: QLayer<'static> = QLayer {
        spec: LayerSpec {
            kind: LayerKind::Conv,
            kernel: 0,
            stride: 0,
            pad: 0,
            relu: false,
            in_h: 0,
            in_w: 0,
            in_c: 0,
            out_c: 0,
        },
        input_zp: 0,
        output_zp: 0,
        act_min: 0,
        act_max: 0,
        output_scale: 0.0,
        bias: [0; MAX_CHANNELS],
        multiplier: [0; MAX_CHANNELS],
        shift: [0; MAX_CHANNELS],
        weights: &[],
    };
}

/// A validated weight file for a network of `N` layers.
#[derive(Clone, Copy, Debug)]
pub struct QNetwork<'a, const N: usize> {
    /// Scale of the int8 input (real value per unit).
    pub input_scale: f32,
    /// Zero point of the int8 input.
    pub input_zp: i32,
    /// The layers, in order.
    pub layers: [QLayer<'a>; N],
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    /// Length of the content, without the CRC trailer.
    end: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], WeightsError> {
        let stop = self.pos.saturating_add(n);
        if stop > self.end {
            return Err(WeightsError::Truncated {
                needed: stop.saturating_add(4),
                got: self.b.len(),
            });
        }
        let s = self.b.get(self.pos..stop).ok_or(WeightsError::Truncated {
            needed: stop.saturating_add(4),
            got: self.b.len(),
        })?;
        self.pos = stop;
        Ok(s)
    }
    fn array<const M: usize>(&mut self) -> Result<[u8; M], WeightsError> {
        let mut a = [0u8; M];
        for (d, &v) in a.iter_mut().zip(self.take(M)?) {
            *d = v;
        }
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, WeightsError> {
        let [v] = self.array::<1>()?;
        Ok(v)
    }
    fn u16(&mut self) -> Result<u16, WeightsError> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    fn i32(&mut self) -> Result<i32, WeightsError> {
        Ok(i32::from_le_bytes(self.array()?))
    }
    fn f32(&mut self) -> Result<f32, WeightsError> {
        Ok(f32::from_le_bytes(self.array()?))
    }
}

fn as_i8(s: &[u8]) -> &[i8] {
    // Safety: `u8` and `i8` have the same size and alignment and every bit pattern is a
    // valid `i8`; the returned slice borrows `s` for the same lifetime and length.
    unsafe { core::slice::from_raw_parts(s.as_ptr().cast::<i8>(), s.len()) }
}

/// Parses and validates a weight file against the compiled network `spec`.
pub fn parse<'a, const N: usize>(
    bytes: &'a [u8],
    spec: &[LayerSpec; N],
) -> Result<QNetwork<'a, N>, WeightsError> {
    if bytes.len() < HEADER_BYTES + 4 {
        if bytes.get(..4).is_some_and(|m| m != MAGIC) {
            return Err(WeightsError::BadMagic);
        }
        return Err(WeightsError::Truncated {
            needed: HEADER_BYTES + 4,
            got: bytes.len(),
        });
    }
    let mut r = Reader {
        b: bytes,
        pos: 0,
        end: bytes.len() - 4,
    };
    if r.array::<4>()? != MAGIC {
        return Err(WeightsError::BadMagic);
    }
    let version = r.u16()?;
    if version != VERSION {
        return Err(WeightsError::UnsupportedVersion(version));
    }
    let count = r.u16()? as usize;
    let input_scale = r.f32()?;
    let input_zp = r.i32()?;
    let mut net = QNetwork {
        input_scale,
        input_zp,
        layers: [QLayer::EMPTY; N],
    };
    // Structure first (lengths), so that a short file reads as truncated; layers beyond the
    // compiled network's are walked for their length only.
    let mut shape_error: Option<WeightsError> = None;
    if count != N {
        shape_error = Some(WeightsError::LayerCount {
            expected: N,
            found: count,
        });
    }
    #[allow(clippy::needless_range_loop)] // `count` may exceed `N`: walk every record.
    for i in 0..count {
        let kind = r.u8()?;
        let kernel = r.u8()? as usize;
        let stride = r.u8()? as usize;
        let pad = r.u8()? as usize;
        let relu = r.u8()?;
        let _reserved = (r.u8()?, r.u16()?);
        let in_c = r.u16()? as usize;
        let out_c = r.u16()? as usize;
        let in_h = r.u16()? as usize;
        let in_w = r.u16()? as usize;
        let l_input_zp = r.i32()?;
        let output_zp = r.i32()?;
        let act_min = r.i32()?;
        let act_max = r.i32()?;
        let output_scale = r.f32()?;
        let _weight_scales = r.take(out_c * 4)?;
        let bias = r.take(out_c * 4)?;
        let mult = r.take(out_c * 4)?;
        let shift = r.take(out_c)?;
        let weights = r.take(out_c * kernel * kernel * in_c)?;
        if i >= N {
            continue;
        }
        let kind = match kind {
            1 => LayerKind::Conv,
            2 => LayerKind::DensePerPixel,
            _ => {
                shape_error.get_or_insert(WeightsError::ShapeMismatch { layer: i });
                continue;
            }
        };
        let file_spec = LayerSpec {
            kind,
            kernel,
            stride,
            pad,
            relu: relu != 0,
            in_h,
            in_w,
            in_c,
            out_c,
        };
        if file_spec != spec[i] || out_c > MAX_CHANNELS {
            shape_error.get_or_insert(WeightsError::ShapeMismatch { layer: i });
            continue;
        }
        let Some(l) = net.layers.get_mut(i) else {
            continue;
        };
        l.spec = file_spec;
        l.input_zp = l_input_zp;
        l.output_zp = output_zp;
        l.act_min = act_min;
        l.act_max = act_max;
        l.output_scale = output_scale;
        // out_c <= MAX_CHANNELS (checked above); `take` gave exactly out_c entries each.
        let le = |s: &[u8]| match *s {
            [a, b, c, d] => i32::from_le_bytes([a, b, c, d]),
            _ => 0,
        };
        for (((b, m), sh), ((bs, ms), &ss)) in l
            .bias
            .iter_mut()
            .zip(l.multiplier.iter_mut())
            .zip(l.shift.iter_mut())
            .zip(bias.chunks_exact(4).zip(mult.chunks_exact(4)).zip(shift))
        {
            *b = le(bs);
            *m = le(ms);
            *sh = ss as i8 as i32;
        }
        l.weights = as_i8(weights);
    }
    if r.pos < r.end {
        return Err(WeightsError::TrailingBytes {
            extra: r.end - r.pos,
        });
    }
    let (content, trailer) = bytes
        .split_at_checked(r.end)
        .ok_or(WeightsError::Truncated {
            needed: r.end.saturating_add(4),
            got: bytes.len(),
        })?;
    let stored = match *trailer {
        [a, b, c, d] => u32::from_le_bytes([a, b, c, d]),
        _ => {
            return Err(WeightsError::Truncated {
                needed: r.end.saturating_add(4),
                got: bytes.len(),
            })
        }
    };
    let computed = crc32(content);
    if stored != computed {
        return Err(WeightsError::CrcMismatch { stored, computed });
    }
    if let Some(e) = shape_error {
        return Err(e);
    }
    validate_quantization(&net)?;
    Ok(net)
}

fn validate_quantization<const N: usize>(net: &QNetwork<'_, N>) -> Result<(), WeightsError> {
    let zp_ok = |z: i32| (-128..=127).contains(&z);
    if !zp_ok(net.input_zp) || !net.input_scale.is_finite() || net.input_scale <= 0.0 {
        return Err(WeightsError::BadQuantization { layer: 0 });
    }
    let mut prev_zp = net.input_zp;
    for (i, l) in net.layers.iter().enumerate() {
        let bad = WeightsError::BadQuantization { layer: i };
        if l.input_zp != prev_zp || !zp_ok(l.output_zp) {
            return Err(bad);
        }
        if !(-128..=127).contains(&l.act_min)
            || !(-128..=127).contains(&l.act_max)
            || l.act_min > l.act_max
            || (l.spec.relu && l.act_min != l.output_zp)
        {
            return Err(bad);
        }
        let oc = l.spec.out_c.min(MAX_CHANNELS);
        for (&m, &s) in l.multiplier.iter().zip(&l.shift).take(oc) {
            if !(m == 0 || m >= 1 << 30) || !(SHIFT_MIN..=SHIFT_MAX).contains(&s) {
                return Err(bad);
            }
        }
        if l.weights.contains(&i8::MIN) {
            return Err(bad);
        }
        prev_zp = l.output_zp;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn short_inputs_are_typed_errors() {
        let spec = [LayerSpec {
            kind: LayerKind::Conv,
            kernel: 3,
            stride: 1,
            pad: 1,
            relu: true,
            in_h: 4,
            in_w: 4,
            in_c: 1,
            out_c: 2,
        }];
        assert!(matches!(
            parse(&[], &spec),
            Err(WeightsError::Truncated { .. })
        ));
        assert_eq!(
            parse(b"NOPE0000000000000000", &spec).err(),
            Some(WeightsError::BadMagic)
        );
        let mut v = [0u8; 20];
        v[..4].copy_from_slice(&MAGIC);
        v[4] = 9;
        assert_eq!(
            parse(&v, &spec).err(),
            Some(WeightsError::UnsupportedVersion(9))
        );
    }
}
