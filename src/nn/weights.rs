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
//! The parser never trusts the file: it checks the magic and the CRC first (so damage reads
//! as corruption, not as a strange structure), then the version, every shape against the
//! network compiled into the core, and every quantization parameter's range, including a
//! bound that keeps every int32 accumulator from overflowing; it reports the first problem
//! as a typed [`WeightsError`].

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
    /// A bias (with the shift that follows it) could make an int32 accumulator of layer
    /// `layer`, output channel `channel`, overflow for some input.
    AccumulatorOverflow {
        /// Zero-based layer index.
        layer: usize,
        /// Zero-based output channel.
        channel: usize,
    },
}

impl core::fmt::Display for WeightsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Truncated { needed, got } => write!(
                f,
                "the weight file is truncated: it has {got} bytes, the network needs {needed}; copy or export it again"
            ),
            Self::TrailingBytes { extra } => write!(
                f,
                "the weight file has {extra} unexpected bytes after its layers; it was not written by `orbfix quantize` for this network"
            ),
            Self::BadMagic => write!(
                f,
                "this is not an orbfix weight file (it does not start with OFW1); pass a .ofw file written by `orbfix quantize`"
            ),
            Self::UnsupportedVersion(v) => write!(
                f,
                "the weight file has format version {v}, this build reads version {VERSION}; export it again with this version's `orbfix quantize`"
            ),
            Self::CrcMismatch { stored, computed } => write!(
                f,
                "the weight file is corrupt: its CRC-32 is {computed:#010x} but {stored:#010x} is stored; restore it from a good copy"
            ),
            Self::LayerCount { expected, found } => write!(
                f,
                "the weight file has {found} layers, this build's network has {expected}; it is for another network"
            ),
            Self::ShapeMismatch { layer } => write!(
                f,
                "layer {layer} of the weight file has another kind or shape than this build's network; it is for another network"
            ),
            Self::BadQuantization { layer } => write!(
                f,
                "layer {layer} of the weight file has an out-of-range quantization parameter (zero point, activation range, multiplier, shift or a -128 weight); quantize the model again"
            ),
            Self::AccumulatorOverflow { layer, channel } => write!(
                f,
                "layer {layer}, channel {channel} of the weight file has a bias too large for 32-bit accumulators (some input would overflow); quantize the model again"
            ),
        }
    }
}

impl core::error::Error for WeightsError {}

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

/// One validated, quantized layer; its parameters and weights borrow the file.
///
/// Fields are private: a `QLayer` exists only as part of a [`QNetwork`] returned by
/// [`parse`], so every value below passed the range checks of `docs/weights-format.md`
/// (among them the accumulator bound: no int32 accumulator of this layer can overflow for
/// any input).
#[derive(Clone, Copy, Debug)]
pub struct QLayer<'a> {
    spec: LayerSpec,
    input_zp: i32,
    output_zp: i32,
    act_min: i32,
    act_max: i32,
    output_scale: f32,
    /// `out_c` little-endian i32 biases.
    bias: &'a [u8],
    /// `out_c` little-endian i32 Q0.31 multipliers.
    multiplier: &'a [u8],
    /// `out_c` i8 shifts.
    shift: &'a [u8],
    weights: &'a [i8],
}

fn le_i32(s: &[u8], i: usize) -> Option<i32> {
    match *s.get(i.checked_mul(4)?..i.checked_mul(4)?.checked_add(4)?)? {
        [a, b, c, d] => Some(i32::from_le_bytes([a, b, c, d])),
        _ => None,
    }
}

impl<'a> QLayer<'a> {
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
        bias: &[],
        multiplier: &[],
        shift: &[],
        weights: &[],
    };

    /// Shape (equal to the compiled network's).
    pub fn spec(&self) -> &LayerSpec {
        &self.spec
    }
    /// Input zero point.
    pub fn input_zp(&self) -> i32 {
        self.input_zp
    }
    /// Output zero point.
    pub fn output_zp(&self) -> i32 {
        self.output_zp
    }
    /// Lowest output value (fused activation).
    pub fn act_min(&self) -> i32 {
        self.act_min
    }
    /// Highest output value.
    pub fn act_max(&self) -> i32 {
        self.act_max
    }
    /// Output scale (real value per unit), for information.
    pub fn output_scale(&self) -> f32 {
        self.output_scale
    }
    /// OHWI int8 weights (`-127..=127`).
    pub fn weights(&self) -> &'a [i8] {
        self.weights
    }
    /// Int32 bias of output channel `c` (units of input scale x weight scale), `None` past
    /// the last channel.
    pub fn bias(&self, c: usize) -> Option<i32> {
        le_i32(self.bias, c)
    }
    /// Q0.31 requantization multiplier of output channel `c`.
    pub fn multiplier(&self, c: usize) -> Option<i32> {
        le_i32(self.multiplier, c)
    }
    /// Requantization shift of output channel `c` (positive: left).
    pub fn shift(&self, c: usize) -> Option<i32> {
        self.shift.get(c).map(|&s| s as i8 as i32)
    }
    /// Decodes every channel's bias, multiplier and shift into the caller's arrays (the
    /// layout the kernels take); returns the channel count (`out_c <= MAX_CHANNELS`).
    pub fn channel_params(
        &self,
        bias: &mut [i32; MAX_CHANNELS],
        multiplier: &mut [i32; MAX_CHANNELS],
        shift: &mut [i32; MAX_CHANNELS],
    ) -> usize {
        let oc = self.spec.out_c.min(MAX_CHANNELS);
        for c in 0..oc {
            if let (Some(b), Some(m), Some(s), Some(db), Some(dm), Some(ds)) = (
                self.bias(c),
                self.multiplier(c),
                self.shift(c),
                bias.get_mut(c),
                multiplier.get_mut(c),
                shift.get_mut(c),
            ) {
                (*db, *dm, *ds) = (b, m, s);
            }
        }
        oc
    }
}

/// A validated weight file for a network of `N` layers (about 100 bytes a layer: the
/// parameters borrow the file).
#[derive(Clone, Copy, Debug)]
pub struct QNetwork<'a, const N: usize> {
    input_scale: f32,
    input_zp: i32,
    layers: [QLayer<'a>; N],
}

impl<'a, const N: usize> QNetwork<'a, N> {
    /// Scale of the int8 input (real value per unit).
    pub fn input_scale(&self) -> f32 {
        self.input_scale
    }
    /// Zero point of the int8 input.
    pub fn input_zp(&self) -> i32 {
        self.input_zp
    }
    /// The layers, in order.
    pub fn layers(&self) -> &[QLayer<'a>; N] {
        &self.layers
    }
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

/// Largest `|x - zp| * |w|` term of an accumulator: int8 activations and zero points
/// (`-128..=127`) differ by at most 255, weights are `-127..=127`.
pub const MAX_TERM: i64 = 255 * 127;

/// Largest magnitude an accumulator of a layer with `field` (`kernel^2 * in_c`) terms reaches
/// before the bias: `field * 255 * 127`.
pub const fn accumulator_terms_bound(field: usize) -> i64 {
    field as i64 * MAX_TERM
}

/// Parses and validates a weight file against the compiled network `spec`.
///
/// Order (each step trusts only what the previous ones checked): size and magic; the CRC-32
/// of the whole content (a short file whose CRC fails is [`WeightsError::Truncated`], any
/// other damage [`WeightsError::CrcMismatch`]); version; layer count; every record's
/// shape; every quantization parameter's range, including the accumulator bound
/// (`docs/weights-format.md`).
pub fn parse<'a, const N: usize>(
    bytes: &'a [u8],
    spec: &[LayerSpec; N],
) -> Result<QNetwork<'a, N>, WeightsError> {
    if bytes.get(..4).is_some_and(|m| m != MAGIC) {
        return Err(WeightsError::BadMagic);
    }
    let expected_len = file_bytes(spec);
    let Some(content_len) = bytes.len().checked_sub(4).filter(|&n| n >= HEADER_BYTES) else {
        return Err(WeightsError::Truncated {
            needed: expected_len.max(HEADER_BYTES + 4),
            got: bytes.len(),
        });
    };
    let (content, trailer) =
        bytes
            .split_at_checked(content_len)
            .ok_or(WeightsError::Truncated {
                needed: expected_len,
                got: bytes.len(),
            })?;
    let stored = match *trailer {
        [a, b, c, d] => u32::from_le_bytes([a, b, c, d]),
        _ => {
            return Err(WeightsError::Truncated {
                needed: expected_len,
                got: bytes.len(),
            })
        }
    };
    let computed = crc32(content);
    if stored != computed {
        if bytes.len() < expected_len {
            return Err(WeightsError::Truncated {
                needed: expected_len,
                got: bytes.len(),
            });
        }
        return Err(WeightsError::CrcMismatch { stored, computed });
    }
    // The content is what was written: now its structure.
    let mut r = Reader {
        b: bytes,
        pos: 4,
        end: content_len,
    };
    let version = r.u16()?;
    if version != VERSION {
        return Err(WeightsError::UnsupportedVersion(version));
    }
    let count = r.u16()? as usize;
    if count != N {
        return Err(WeightsError::LayerCount {
            expected: N,
            found: count,
        });
    }
    let input_scale = r.f32()?;
    let input_zp = r.i32()?;
    let mut net = QNetwork {
        input_scale,
        input_zp,
        layers: [QLayer::EMPTY; N],
    };
    for (i, (l, want)) in net.layers.iter_mut().zip(spec).enumerate() {
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
        let kind = match kind {
            1 => LayerKind::Conv,
            2 => LayerKind::DensePerPixel,
            _ => return Err(WeightsError::ShapeMismatch { layer: i }),
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
        if file_spec != *want || out_c > MAX_CHANNELS {
            return Err(WeightsError::ShapeMismatch { layer: i });
        }
        l.spec = file_spec;
        l.input_zp = r.i32()?;
        l.output_zp = r.i32()?;
        l.act_min = r.i32()?;
        l.act_max = r.i32()?;
        l.output_scale = r.f32()?;
        // The shape equals the compiled one (small numbers), so these products cannot wrap.
        let _weight_scales = r.take(out_c * 4)?;
        l.bias = r.take(out_c * 4)?;
        l.multiplier = r.take(out_c * 4)?;
        l.shift = r.take(out_c)?;
        l.weights = as_i8(r.take(file_spec.weight_count())?);
    }
    if r.pos < r.end {
        return Err(WeightsError::TrailingBytes {
            extra: r.end - r.pos,
        });
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
        if l.weights.contains(&i8::MIN) {
            return Err(bad);
        }
        let terms = accumulator_terms_bound(l.spec.kernel * l.spec.kernel * l.spec.in_c);
        for c in 0..l.spec.out_c {
            let (Some(b), Some(m), Some(s)) = (l.bias(c), l.multiplier(c), l.shift(c)) else {
                return Err(bad);
            };
            if !(m == 0 || m >= 1 << 30) || !(SHIFT_MIN..=SHIFT_MAX).contains(&s) {
                return Err(bad);
            }
            // |acc| <= |bias| + field * 255 * 127, and the requantization first shifts the
            // accumulator left by max(shift, 0): both must stay within i32.
            let acc = b.unsigned_abs() as i64 + terms;
            if acc << s.max(0) > i32::MAX as i64 {
                return Err(WeightsError::AccumulatorOverflow {
                    layer: i,
                    channel: c,
                });
            }
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
        // A damaged short file is truncated; with a valid CRC, its version is read.
        let mut v = [0u8; 20];
        v[..4].copy_from_slice(&MAGIC);
        v[4] = 9;
        assert!(matches!(
            parse(&v, &spec),
            Err(WeightsError::Truncated { .. })
        ));
        let crc = crc32(&v[..16]).to_le_bytes();
        v[16..].copy_from_slice(&crc);
        assert_eq!(
            parse(&v, &spec).err(),
            Some(WeightsError::UnsupportedVersion(9))
        );
    }
}
