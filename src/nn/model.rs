//! The shipped siamese matcher network, its compile-time shape, and its static arena.
//!
//! Trunk (shared by both sides; NHWC, int8):
//!
//! | layer | op                         | output      | MACs      |
//! |-------|----------------------------|-------------|-----------|
//! | 0     | conv 3x3 s2 p1, ReLU       | 32x32x16    | 147,456   |
//! | 1     | conv 3x3 s2 p1, ReLU       | 16x16x32    | 1,179,648 |
//! | 2     | conv 3x3 s2 p1, ReLU       | 8x8x64      | 1,179,648 |
//! | 3     | conv 3x3 s1 p1, ReLU       | 8x8x64      | 2,359,296 |
//! | 4     | dense per pixel (1x1) 64->32, linear | 8x8x32 | 131,072 |
//!
//! The embedding is the 8x8x32 map (2048 values, 6.25 m cells) compared by cosine similarity
//! ([`cosine_q15`]). Satellite windows depend only on the map, so their embeddings can be
//! computed once per map and stored.

use super::conv::{conv2d_s8, conv2d_s8_buffer_size, ConvParams, Dims};
use super::dense::{dense_s8, DenseParams};
use super::input::{isqrt_u64, INPUT_LEN, INPUT_SIDE};
use super::weights::{
    file_bytes, parse, LayerKind, LayerSpec, QNetwork, WeightsError, MAX_CHANNELS,
};
use super::NnError;

const fn conv(in_side: usize, in_c: usize, out_c: usize, stride: usize) -> LayerSpec {
    LayerSpec {
        kind: LayerKind::Conv,
        kernel: 3,
        stride,
        pad: 1,
        relu: true,
        in_h: in_side,
        in_w: in_side,
        in_c,
        out_c,
    }
}

/// Number of layers.
pub const LAYERS: usize = 5;

/// The compiled network: what a weight file must describe.
pub const SPEC: [LayerSpec; LAYERS] = [
    conv(INPUT_SIDE, 1, 16, 2),
    conv(32, 16, 32, 2),
    conv(16, 32, 64, 2),
    conv(8, 64, 64, 1),
    LayerSpec {
        kind: LayerKind::DensePerPixel,
        kernel: 1,
        stride: 1,
        pad: 0,
        relu: false,
        in_h: 8,
        in_w: 8,
        in_c: 64,
        out_c: 32,
    },
];

/// Embedding shape: 8 x 8 cells (6.25 m each) x 32 channels.
pub const EMBED_DIMS: Dims = Dims { h: 8, w: 8, c: 32 };
/// Embedding length, int8 values.
pub const EMBED_LEN: usize = EMBED_DIMS.len();

const fn max_activation() -> usize {
    let mut m = INPUT_LEN;
    let mut i = 0;
    while i < LAYERS {
        let n = SPEC[i].out_h() * SPEC[i].out_w() * SPEC[i].out_c;
        if n > m {
            m = n;
        }
        i += 1;
    }
    m
}

const fn max_scratch() -> usize {
    let mut m = 0;
    let mut i = 0;
    while i < LAYERS {
        let n = conv2d_s8_buffer_size(SPEC[i].kernel, SPEC[i].in_c);
        if n > m {
            m = n;
        }
        i += 1;
    }
    m
}

/// Bytes of each of the two ping-pong activation buffers.
pub const ACTIVATION_BYTES: usize = max_activation();
/// `i16` elements of the convolution scratch.
pub const SCRATCH_LEN: usize = max_scratch();
/// Bytes of a valid weight file for [`SPEC`].
pub const WEIGHT_FILE_BYTES: usize = file_bytes(&SPEC);

/// Multiply-accumulates of one embedding.
pub const fn embedding_macs() -> u64 {
    let mut m = 0;
    let mut i = 0;
    while i < LAYERS {
        m += SPEC[i].macs();
        i += 1;
    }
    m
}

/// Int8 weights of the network (bytes of weight memory, biases and scales excluded).
pub const fn weight_count() -> usize {
    let mut m = 0;
    let mut i = 0;
    while i < LAYERS {
        m += SPEC[i].weight_count();
        i += 1;
    }
    m
}

/// Working memory of one embedding, sized at compile time for [`SPEC`]:
/// two ping-pong activation buffers and the convolution scratch
/// (`2 * ACTIVATION_BYTES + 2 * SCRATCH_LEN` bytes). Place it in a `static`, or view a
/// caller's word buffer as one (the fix keeps it in its work area, `orbfix::fix`).
/// `repr(C)` of `i8` and `i16` arrays: no padding, valid for every bit pattern.
#[repr(C)]
pub struct Arena {
    a: [i8; ACTIVATION_BYTES],
    b: [i8; ACTIVATION_BYTES],
    scratch: [i16; SCRATCH_LEN],
}

impl Arena {
    /// A zeroed arena (usable in a `static` initializer).
    pub const fn new() -> Self {
        Self {
            a: [0; ACTIVATION_BYTES],
            b: [0; ACTIVATION_BYTES],
            scratch: [0; SCRATCH_LEN],
        }
    }
}

impl Default for Arena {
    fn default() -> Self {
        Self::new()
    }
}

/// The weight file shipped with the core (`weights/matcher-v2.ofw`, produced by
/// `orbfix train` then `orbfix quantize`, see `docs/matcher.md`).
pub static SHIPPED_WEIGHTS: &[u8] = include_bytes!("../../weights/matcher-v2.ofw");

/// The quantized siamese trunk with validated weights.
#[derive(Clone, Copy, Debug)]
pub struct SiameseNet<'a> {
    net: QNetwork<'a, LAYERS>,
}

impl<'a> SiameseNet<'a> {
    /// Validates a weight file against [`SPEC`].
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, WeightsError> {
        Ok(Self {
            net: parse(bytes, &SPEC)?,
        })
    }

    /// The validated quantized network (scales, zero points, weights).
    pub fn quantized(&self) -> &QNetwork<'a, LAYERS> {
        &self.net
    }

    /// Zero point of the embedding's int8 values.
    pub fn embedding_zero_point(&self) -> i32 {
        self.net.layers()[LAYERS - 1].output_zp()
    }

    /// Embeds one prepared input ([`super::input::prepare_input`]) into `out`
    /// ([`EMBED_LEN`] int8 values, NHWC 8x8x32, zero point [`Self::embedding_zero_point`]).
    pub fn embed(
        &self,
        input: &[i8; INPUT_LEN],
        arena: &mut Arena,
        out: &mut [i8; EMBED_LEN],
    ) -> Result<(), NnError> {
        for (d, &v) in arena.a.iter_mut().zip(input) {
            *d = v;
        }
        let Arena { a, b, scratch } = arena;
        let (mut src, mut dst): (&mut [i8], &mut [i8]) = (&mut a[..], &mut b[..]);
        // Per-channel parameters of the current layer, decoded from the file (768 bytes).
        let mut bias = [0i32; MAX_CHANNELS];
        let mut multiplier = [0i32; MAX_CHANNELS];
        let mut shift = [0i32; MAX_CHANNELS];
        for (i, l) in self.net.layers().iter().enumerate() {
            let s = l.spec();
            let in_dims = Dims {
                h: s.in_h,
                w: s.in_w,
                c: s.in_c,
            };
            let out_dims = Dims {
                h: s.out_h(),
                w: s.out_w(),
                c: s.out_c,
            };
            let last = i + 1 == LAYERS;
            let target: &mut [i8] = if last { &mut out[..] } else { &mut dst[..] };
            let oc = l.channel_params(&mut bias, &mut multiplier, &mut shift);
            // Sizes were validated against SPEC when the weights were parsed; a mismatch
            // here is a typed error, never a panic.
            let (Some(input), Some(bias), Some(multiplier), Some(shift)) = (
                src.get(..in_dims.len()),
                bias.get(..oc),
                multiplier.get(..oc),
                shift.get(..oc),
            ) else {
                return Err(NnError::BufferSize);
            };
            match s.kind {
                LayerKind::Conv => conv2d_s8(
                    &ConvParams {
                        kernel: s.kernel,
                        stride: s.stride,
                        pad: s.pad,
                        input_offset: -l.input_zp(),
                        output_offset: l.output_zp(),
                        act_min: l.act_min(),
                        act_max: l.act_max(),
                    },
                    input,
                    in_dims,
                    l.weights(),
                    bias,
                    multiplier,
                    shift,
                    target,
                    out_dims,
                    &mut scratch[..],
                )?,
                LayerKind::DensePerPixel => dense_s8(
                    &DenseParams {
                        input_offset: -l.input_zp(),
                        output_offset: l.output_zp(),
                        act_min: l.act_min(),
                        act_max: l.act_max(),
                    },
                    in_dims.h * in_dims.w,
                    s.in_c,
                    oc,
                    input,
                    l.weights(),
                    bias,
                    multiplier,
                    shift,
                    target,
                )?,
            }
            core::mem::swap(&mut src, &mut dst);
        }
        Ok(())
    }
}

/// The network with the shipped weights.
pub fn shipped() -> Result<SiameseNet<'static>, WeightsError> {
    SiameseNet::from_bytes(SHIPPED_WEIGHTS)
}

/// Cosine similarity of two int8 embeddings with zero point `zp`, in Q15 (32768 = 1.0);
/// 0 when either is all zero point. Both slices must have the same length (the shorter
/// length is used otherwise).
pub fn cosine_q15(a: &[i8], b: &[i8], zp: i32) -> i32 {
    let (mut dot, mut na, mut nb) = (0i64, 0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x as i32 - zp, y as i32 - zp);
        dot += (x * y) as i64;
        na += (x * x) as u64;
        nb += (y * y) as u64;
    }
    let den = isqrt_u64(na.saturating_mul(nb)) as i64;
    // None for den == 0 (an all-zero-point embedding).
    (dot << 15)
        .checked_div(den)
        .map_or(0, |c| c.clamp(-32768, 32768) as i32)
}
