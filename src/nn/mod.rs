//! Quantized siamese CNN matcher: int8 kernels (TFLite / CMSIS-NN conventions), the weight
//! file format, the shipped network and its static arena.
//!
//! Conventions: activations NHWC int8, asymmetric per tensor (scale, zero point); weights
//! int8 symmetric per output channel (zero point 0, -127..=127); biases int32 in units of
//! `input scale * weight scale`; requantization by a Q0.31 multiplier and a shift with
//! gemmlowp rounding ([`requant`]). Nothing allocates; scratch is caller-provided and sized
//! by `*_buffer_size` functions.
//!
//! - [`requant`]: fixed-point rescaling;
//! - [`conv`]: convolution; [`dense`]: fully connected; [`pool`]: max / average pooling;
//! - [`input`]: raster + mask to normalized int8 input;
//! - [`weights`]: `.ofw` weight file parsing with CRC-32 validation;
//! - [`model`]: the shipped network, its arena, cosine scoring;
//! - [`matcher`]: the network behind the localization engine's `Matcher` trait;
//! - [`window_cosine`]: the flight path's cosine against stored map-window records;
//! - `dsp` (Arm with the `armv7em-dsp` feature only): the SXTB16 / SXTAB16 / SMLAD helpers
//!   of the kernels' DSP paths; `dsp_model`: their portable models for host tests;
//! - `mat_mult` (Arm with `armv7em-dsp`, and host tests): the DSP path of the convolution
//!   and dense layer, two output pixels x two output channels per pass.

pub mod conv;
pub mod dense;
#[cfg(all(target_arch = "arm", feature = "armv7em-dsp"))]
mod dsp;
#[cfg(all(test, not(all(target_arch = "arm", feature = "armv7em-dsp"))))]
mod dsp_model;
pub mod input;
#[cfg(any(test, all(target_arch = "arm", feature = "armv7em-dsp")))]
mod mat_mult;
pub mod matcher;
pub mod model;
pub mod pool;
pub mod requant;
pub mod weights;
pub mod window_cosine;

/// Errors running a kernel or the network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NnError {
    /// Kernel, stride, padding and tensor sizes do not agree.
    BadGeometry,
    /// A tensor or parameter buffer is shorter than its shape needs.
    BufferSize,
    /// The scratch buffer is smaller than the kernel's `*_buffer_size`.
    ScratchTooSmall,
    /// Too few valid pixels in the input window to match.
    TooFewValid,
    /// The valid pixels have (almost) no contrast: black, saturated or flat frame.
    FlatInput,
    /// The input is larger than the network input code can sum without overflow
    /// ([`input::MAX_SOURCE_SIDE`]).
    TooLarge,
}

impl core::fmt::Display for NnError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::BadGeometry => "the layer's kernel, stride, padding and tensor sizes do not agree; the weights do not fit this network",
            Self::BufferSize => "a tensor or parameter buffer is shorter than its shape needs, or the input image is not square and at least 64 pixels a side",
            Self::ScratchTooSmall => "the scratch buffer is smaller than the kernel needs; size it with the kernel's buffer-size function",
            Self::TooFewValid => "too few valid pixels in the window to match (less than one eighth); check the mask",
            Self::FlatInput => "the valid pixels have no contrast (black, saturated or flat frame); check the camera exposure",
            Self::TooLarge => "the input image is larger than 65536 pixels a side; downsample it first",
        })
    }
}

impl core::error::Error for NnError {}
