//! The fix as one call with per-stage hooks: the code the flight firmware times on the
//! target and the host re-runs for the bit-exactness check (`orbfix budget`).
//!
//! [`run`] takes the inputs (camera rig, pose prior, four frames and the orbital map region,
//! all borrowed: on the target they live in external memory) and calls a [`StageClock`]
//! around each stage, so the firmware can read its instruction counter there while the host
//! passes [`NoClock`]. Both get the same [`FlightOutputs`]; [`FlightOutputs::digest`] folds
//! every output bit into one 32-bit FNV-1a value.
//!
//! Stages so far: camera set-up for the four views (floats, set-up only), then the input
//! checks over every frame and map pixel (integer only: min, max, sum, FNV-1a hash); a frame
//! that is black or saturated is rejected with a typed error.

use crate::camera::{Camera, CameraError, CameraParams, RoverPose, View};
use crate::geo::GeoRef;
use crate::image::ImageView;

/// The stages of the fix, in run order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Camera models of the four views from the rig and the pose prior.
    Cameras,
    /// Checks and statistics of the four frames (every pixel).
    FrameCheck,
    /// Checks and statistics of the orbital map region (every pixel).
    MapCheck,
}

impl Stage {
    /// Every stage, in run order.
    pub const ALL: [Stage; 3] = [Stage::Cameras, Stage::FrameCheck, Stage::MapCheck];

    /// Short lower-case name used in reports and the budget table.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Cameras => "cameras",
            Stage::FrameCheck => "frame_check",
            Stage::MapCheck => "map_check",
        }
    }
}

/// Called around every stage (the firmware reads its instruction counter here).
pub trait StageClock {
    /// `stage` is about to start.
    fn begin(&mut self, stage: Stage);
    /// `stage` has finished.
    fn end(&mut self, stage: Stage);
}

/// A [`StageClock`] that does nothing (host runs).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl StageClock for NoClock {
    fn begin(&mut self, _stage: Stage) {}
    fn end(&mut self, _stage: Stage) {}
}

/// Why a fix could not be run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlightError {
    /// Camera rig or pose prior out of range.
    Camera(CameraError),
    /// A frame is not `width_px x height_px` of the rig. `view` is 0..4 in dataset order.
    FrameSize {
        /// View index 0..4 (front, right, rear, left).
        view: u8,
    },
    /// A frame is black: its brightest pixel is at most [`BLACK_LEVEL`].
    BlackFrame {
        /// View index 0..4 (front, right, rear, left).
        view: u8,
    },
    /// A frame is saturated: its darkest pixel is at least [`SATURATED_LEVEL`].
    SaturatedFrame {
        /// View index 0..4 (front, right, rear, left).
        view: u8,
    },
    /// The map region is uniform (no contrast to match against).
    FlatMap,
}

impl From<CameraError> for FlightError {
    fn from(e: CameraError) -> Self {
        FlightError::Camera(e)
    }
}

/// A frame whose maximum is at or below this grey level is black.
pub const BLACK_LEVEL: u8 = 4;
/// A frame whose minimum is at or above this grey level is saturated.
pub const SATURATED_LEVEL: u8 = 251;

/// Everything the fix reads. Frames and the map are borrowed (external memory on target).
#[derive(Clone, Copy, Debug)]
pub struct FlightInputs<'a> {
    /// The camera rig.
    pub params: CameraParams,
    /// Pose prior: last known position (metres), heading (degrees clockwise from north).
    pub pose: RoverPose,
    /// Frames in dataset order (front, right, rear, left), `width_px x height_px` each.
    pub frames: [ImageView<'a>; 4],
    /// Orbital map region around the prior, north-up.
    pub map: ImageView<'a>,
    /// Georeference of `map` (north-west corner, metres per pixel).
    pub map_geo: GeoRef,
}

/// Integer statistics of an 8-bit image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImageStats {
    /// Darkest grey level.
    pub min: u8,
    /// Brightest grey level.
    pub max: u8,
    /// Sum of all grey levels.
    pub sum: u64,
    /// FNV-1a (32-bit) of the pixels in row-major order.
    pub hash: u32,
}

/// What the fix produced (bit for bit the same on host and target).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlightOutputs {
    /// FNV-1a over the bits of the four cameras' focal length, centre and rotation (`f32`).
    pub camera_hash: u32,
    /// Statistics of the four frames, dataset order.
    pub frames: [ImageStats; 4],
    /// Statistics of the map region.
    pub map: ImageStats,
}

const FNV_OFFSET: u32 = 0x811c_9dc5;
const FNV_PRIME: u32 = 0x0100_0193;

/// FNV-1a (32-bit) of `bytes`, continuing from `h` (start with [`fnv1a_start`]).
pub fn fnv1a(mut h: u32, bytes: &[u8]) -> u32 {
    for &b in bytes {
        h = (h ^ b as u32).wrapping_mul(FNV_PRIME);
    }
    h
}

/// The FNV-1a start value.
pub const fn fnv1a_start() -> u32 {
    FNV_OFFSET
}

impl FlightOutputs {
    /// One 32-bit FNV-1a over every output field (little-endian).
    pub fn digest(&self) -> u32 {
        let mut h = fnv1a(fnv1a_start(), &self.camera_hash.to_le_bytes());
        for s in self.frames.iter().chain(core::iter::once(&self.map)) {
            h = fnv1a(h, &[s.min, s.max]);
            h = fnv1a(h, &s.sum.to_le_bytes());
            h = fnv1a(h, &s.hash.to_le_bytes());
        }
        h
    }
}

/// Statistics of an image, every pixel, integer only.
pub fn image_stats(img: &ImageView<'_>) -> ImageStats {
    let mut st = ImageStats {
        min: u8::MAX,
        max: 0,
        sum: 0,
        hash: fnv1a_start(),
    };
    for y in 0..img.height() {
        if let Some(row) = img.row(y) {
            let mut rmin = u8::MAX;
            let mut rmax = 0u8;
            let mut rsum = 0u32; // a row of up to 2^24 pixels cannot overflow
            let mut h = st.hash;
            for &p in row {
                rmin = rmin.min(p);
                rmax = rmax.max(p);
                rsum += p as u32;
                h = (h ^ p as u32).wrapping_mul(FNV_PRIME);
            }
            st.min = st.min.min(rmin);
            st.max = st.max.max(rmax);
            st.sum += rsum as u64;
            st.hash = h;
        }
    }
    st
}

fn camera_hash(h: u32, cam: &Camera) -> u32 {
    let mut h = fnv1a(h, &cam.focal_px.to_bits().to_le_bytes());
    for v in cam.centre.iter().chain(cam.world_to_cam.iter()) {
        h = fnv1a(h, &v.to_bits().to_le_bytes());
    }
    h
}

/// Runs the fix on `inputs`, calling `clock` around every stage.
pub fn run<C: StageClock>(
    inputs: &FlightInputs<'_>,
    clock: &mut C,
) -> Result<FlightOutputs, FlightError> {
    let mut out = FlightOutputs::default();

    clock.begin(Stage::Cameras);
    let mut h = fnv1a_start();
    for view in View::ALL {
        let cam = Camera::new(&inputs.params, &inputs.pose, view)?;
        h = camera_hash(h, &cam);
    }
    out.camera_hash = h;
    clock.end(Stage::Cameras);

    clock.begin(Stage::FrameCheck);
    for (i, (frame, stats)) in inputs.frames.iter().zip(out.frames.iter_mut()).enumerate() {
        let view = i as u8;
        if frame.width() != inputs.params.width_px as usize
            || frame.height() != inputs.params.height_px as usize
        {
            return Err(FlightError::FrameSize { view });
        }
        *stats = image_stats(frame);
        if stats.max <= BLACK_LEVEL {
            return Err(FlightError::BlackFrame { view });
        }
        if stats.min >= SATURATED_LEVEL {
            return Err(FlightError::SaturatedFrame { view });
        }
    }
    clock.end(Stage::FrameCheck);

    clock.begin(Stage::MapCheck);
    out.map = image_stats(&inputs.map);
    if out.map.min == out.map.max {
        return Err(FlightError::FlatMap);
    }
    clock.end(Stage::MapCheck);

    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Order {
        log: [Option<(Stage, bool)>; 8],
        n: usize,
    }
    impl StageClock for Order {
        fn begin(&mut self, s: Stage) {
            if let Some(slot) = self.log.get_mut(self.n) {
                *slot = Some((s, true));
            }
            self.n += 1;
        }
        fn end(&mut self, s: Stage) {
            if let Some(slot) = self.log.get_mut(self.n) {
                *slot = Some((s, false));
            }
            self.n += 1;
        }
    }

    fn frame_buf(seed: u8) -> [u8; 64] {
        let mut b = [0u8; 64];
        for (i, v) in b.iter_mut().enumerate() {
            *v = (i as u8).wrapping_mul(37).wrapping_add(seed);
        }
        b
    }

    #[test]
    fn stages_run_in_order_and_frames_are_checked() {
        let params = CameraParams {
            width_px: 8,
            height_px: 8,
            ..CameraParams::default()
        };
        let bufs = [frame_buf(1), frame_buf(2), frame_buf(3), frame_buf(4)];
        let black = [0u8; 64];
        let frames = [
            ImageView::new(&bufs[0], 8, 8).unwrap(),
            ImageView::new(&bufs[1], 8, 8).unwrap(),
            ImageView::new(&bufs[2], 8, 8).unwrap(),
            ImageView::new(&bufs[3], 8, 8).unwrap(),
        ];
        let mut inputs = FlightInputs {
            params,
            pose: RoverPose::level(1.0, 2.0, 0.0, 30.0),
            frames,
            map: ImageView::new(&bufs[0], 8, 8).unwrap(),
            map_geo: GeoRef::new(0.0, 8.0, 1.0).unwrap(),
        };
        let mut clock = Order {
            log: [None; 8],
            n: 0,
        };
        let out = run(&inputs, &mut clock).unwrap();
        assert_eq!(clock.n, 6);
        assert_eq!(clock.log[0], Some((Stage::Cameras, true)));
        assert_eq!(clock.log[5], Some((Stage::MapCheck, false)));
        let s = out.frames[1];
        let sum: u64 = bufs[1].iter().map(|&v| v as u64).sum();
        assert_eq!(s.sum, sum);
        assert_eq!(s.hash, fnv1a(fnv1a_start(), &bufs[1]));
        assert_eq!(s.min, *bufs[1].iter().min().unwrap());
        // Same inputs, same digest; a changed pose changes the camera hash.
        assert_eq!(run(&inputs, &mut NoClock).unwrap().digest(), out.digest());
        inputs.pose.heading_deg = 31.0;
        let moved = run(&inputs, &mut NoClock).unwrap();
        assert_ne!(moved.camera_hash, out.camera_hash);
        assert_ne!(moved.digest(), out.digest());
        // A black right view is rejected by index.
        inputs.frames[1] = ImageView::new(&black, 8, 8).unwrap();
        assert_eq!(
            run(&inputs, &mut NoClock),
            Err(FlightError::BlackFrame { view: 1 })
        );
        // A frame of the wrong size too.
        inputs.frames[1] = ImageView::new(&bufs[1], 4, 16).unwrap();
        assert_eq!(
            run(&inputs, &mut NoClock),
            Err(FlightError::FrameSize { view: 1 })
        );
    }
}
