//! What can go wrong with a stereo pair or its buffers ([`StereoError`]), and which image
//! or buffer it was.

use crate::camera::CameraError;
use crate::reproject::FrameStatus;
use core::fmt;

/// Which image of the pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Side {
    /// The left (view) camera.
    Left,
    /// The right camera, `baseline_m` to the right.
    Right,
}

/// Which caller buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StereoBuffer {
    /// The byte scratch.
    Bytes,
    /// The `u16` scratch.
    Words,
    /// The output band.
    Output,
}

/// Errors of the stereo matcher; `Display` says what to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StereoError {
    /// The camera parameters were rejected.
    Camera(CameraError),
    /// The baseline is not finite or not in (0, 10] metres.
    Baseline,
    /// Another setting is out of range (named).
    Param(&'static str),
    /// The reduced image is too small for the window and the disparity range.
    TooSmall,
    /// No right image was given.
    MissingRight,
    /// A frame is black or saturated.
    Frame {
        /// Which image.
        side: Side,
        /// Black or saturated.
        status: FrameStatus,
    },
    /// The two images differ in size.
    PairSize {
        /// Left `(width, height)`, pixels.
        left: (usize, usize),
        /// Right `(width, height)`, pixels.
        right: (usize, usize),
    },
    /// The frames are not the size the camera parameters give.
    FrameSize {
        /// `(width, height)` expected, pixels.
        expected: (usize, usize),
        /// `(width, height)` given, pixels.
        got: (usize, usize),
    },
    /// Rows `y0..y1` are empty or not inside the output image.
    Rows {
        /// First row.
        y0: usize,
        /// One past the last row.
        y1: usize,
        /// Output height, rows.
        height: usize,
    },
    /// A buffer is too short.
    BufferSize {
        /// Which buffer.
        buffer: StereoBuffer,
        /// Elements needed.
        needed: usize,
        /// Elements given.
        got: usize,
    },
}

impl From<CameraError> for StereoError {
    fn from(e: CameraError) -> Self {
        StereoError::Camera(e)
    }
}

impl fmt::Display for StereoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            StereoError::Camera(e) => write!(
                f,
                "the camera parameters are not usable ({e}): size must be > 0, HFOV in (0, 180) deg, tilt in [-89, 89] deg, height in (0, 100] m"
            ),
            StereoError::Baseline => f.write_str(
                "the stereo baseline must be a finite distance in (0, 10] metres; without one the pair gives no depth",
            ),
            StereoError::Param(what) => write!(f, "stereo setting out of range: {what}"),
            StereoError::TooSmall => f.write_str(
                "the reduced image is too small for the matching window and the disparity range; use a smaller downsample or radius",
            ),
            StereoError::MissingRight => f.write_str(
                "no right image for this view: the view gets no stereo depth (give the pair's right frame)",
            ),
            StereoError::Frame { side, status } => write!(
                f,
                "the {} image is {}: the view gets no stereo depth",
                match side {
                    Side::Left => "left",
                    Side::Right => "right",
                },
                match status {
                    FrameStatus::Black => "black",
                    FrameStatus::Saturated => "saturated",
                    FrameStatus::Missing => "missing",
                    FrameStatus::Ok => "usable",
                }
            ),
            StereoError::PairSize { left, right } => write!(
                f,
                "the stereo pair's images differ in size: left {} x {}, right {} x {} pixels; both cameras must have the same size",
                left.0, left.1, right.0, right.1
            ),
            StereoError::FrameSize { expected, got } => write!(
                f,
                "the frames are {} x {} pixels but the camera parameters say {} x {}",
                got.0, got.1, expected.0, expected.1
            ),
            StereoError::Rows { y0, y1, height } => write!(
                f,
                "rows {y0}..{y1} are not a non-empty range inside the {height} output rows"
            ),
            StereoError::BufferSize {
                buffer,
                needed,
                got,
            } => write!(
                f,
                "the stereo {} buffer has {got} elements but needs {needed} (size it with stereo_buffer_sizes)",
                match buffer {
                    StereoBuffer::Bytes => "byte scratch",
                    StereoBuffer::Words => "u16 scratch",
                    StereoBuffer::Output => "output band",
                }
            ),
        }
    }
}

impl core::error::Error for StereoError {}
