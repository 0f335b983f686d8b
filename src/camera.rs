//! Pinhole camera model of the rover's four ground views.
//!
//! Conventions (also in `docs/frames.md`):
//! - world: `x` east, `y` north, `z` up, metres;
//! - rover heading: degrees clockwise from north; pitch: nose up positive; roll: right side
//!   down positive; applied in that order (yaw, then pitch about the rover's right axis,
//!   then roll about its forward axis);
//! - views: [`View::Front`], [`View::Right`], [`View::Rear`], [`View::Left`] look along
//!   heading + 0, 90, 180, 270 degrees in the rover body, each tilted down by `tilt_deg`;
//! - camera centre: `height_m` above the ground under the rover (`ground_z_m`), straight up
//!   in the world frame (pitch and roll turn the cameras, not the mast);
//! - camera frame (OpenCV): `x` right, `y` down, `z` along the optical axis;
//! - pixels: `(u, v)` continuous, pixel `(i, j)` covers `[i, i + 1) x [j, j + 1)`, its centre
//!   at `(i + 0.5, j + 0.5)`; square pixels, principal point at the image centre,
//!   `fx = fy = (width / 2) / tan(hfov / 2)`.
//!
//! This is set-up math (floats, `f32`); per-pixel work uses tables built from it.

use nalgebra::{Matrix3, Vector3};

/// Errors in camera or pose parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CameraError {
    /// Image width or height is zero.
    ZeroImageSize,
    /// Horizontal field of view not in (0, 180) degrees exclusive, or not finite.
    FovOutOfRange,
    /// Tilt not in [-89, 89] degrees, or not finite.
    TiltOutOfRange,
    /// Camera height not in (0, 100] metres, or not finite.
    HeightOutOfRange,
    /// Pitch or roll not in [-60, 60] degrees, or not finite.
    AttitudeOutOfRange,
    /// Heading or position not finite.
    NonFinitePose,
}

impl core::fmt::Display for CameraError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::ZeroImageSize => "the camera image has a width or height of 0 pixels; give the cameras' real size",
            Self::FovOutOfRange => "the camera's horizontal field of view must be a number of degrees between 0 and 180 (exclusive)",
            Self::TiltOutOfRange => "the camera tilt must be a number of degrees between -89 and 89",
            Self::HeightOutOfRange => "the camera height must be a number of metres above 0 and at most 100",
            Self::AttitudeOutOfRange => "the rover's pitch and roll must be numbers of degrees between -60 and 60",
            Self::NonFinitePose => "the rover's heading and position must be finite numbers",
        })
    }
}

impl core::error::Error for CameraError {}

/// The rover's camera rig: one model shared by its four views.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CameraParams {
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Horizontal field of view, degrees, in (0, 180).
    pub hfov_deg: f32,
    /// Height of the optical centre above the ground, metres.
    pub height_m: f32,
    /// Downward tilt of the optical axis below the horizontal, degrees.
    pub tilt_deg: f32,
}

impl Default for CameraParams {
    /// The study's rig at the project's default size: 640 x 360, 90 deg HFOV, 2 m, 15 deg down.
    fn default() -> Self {
        Self {
            width_px: 640,
            height_px: 360,
            hfov_deg: 90.0,
            height_m: 2.0,
            tilt_deg: 15.0,
        }
    }
}

impl CameraParams {
    /// Checks every field; the error says which is wrong.
    pub fn validate(&self) -> Result<(), CameraError> {
        if self.width_px == 0 || self.height_px == 0 {
            return Err(CameraError::ZeroImageSize);
        }
        if !(self.hfov_deg.is_finite() && self.hfov_deg > 0.0 && self.hfov_deg < 180.0) {
            return Err(CameraError::FovOutOfRange);
        }
        if !(self.tilt_deg.is_finite() && (-89.0..=89.0).contains(&self.tilt_deg)) {
            return Err(CameraError::TiltOutOfRange);
        }
        if !(self.height_m.is_finite() && self.height_m > 0.0 && self.height_m <= 100.0) {
            return Err(CameraError::HeightOutOfRange);
        }
        Ok(())
    }

    /// Focal length in pixels (`fx = fy`).
    pub fn focal_px(&self) -> f32 {
        0.5 * self.width_px as f32 / libm::tanf(0.5 * self.hfov_deg.to_radians())
    }
}

/// Where the rover stands and how it is oriented.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RoverPose {
    /// East, metres.
    pub x_m: f32,
    /// North, metres.
    pub y_m: f32,
    /// Ground elevation under the rover, metres.
    pub ground_z_m: f32,
    /// Heading, degrees clockwise from north.
    pub heading_deg: f32,
    /// Pitch, degrees, nose up positive.
    pub pitch_deg: f32,
    /// Roll, degrees, right side down positive.
    pub roll_deg: f32,
}

impl RoverPose {
    /// A level rover at `(x_m, y_m)` on ground at `ground_z_m` with a heading.
    pub fn level(x_m: f32, y_m: f32, ground_z_m: f32, heading_deg: f32) -> Self {
        Self {
            x_m,
            y_m,
            ground_z_m,
            heading_deg,
            pitch_deg: 0.0,
            roll_deg: 0.0,
        }
    }

    /// Checks that every field is finite and the attitude is in range.
    pub fn validate(&self) -> Result<(), CameraError> {
        if !(self.x_m.is_finite()
            && self.y_m.is_finite()
            && self.ground_z_m.is_finite()
            && self.heading_deg.is_finite())
        {
            return Err(CameraError::NonFinitePose);
        }
        let ok = |a: f32| a.is_finite() && (-60.0..=60.0).contains(&a);
        if !(ok(self.pitch_deg) && ok(self.roll_deg)) {
            return Err(CameraError::AttitudeOutOfRange);
        }
        Ok(())
    }
}

/// One of the rover's four views.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum View {
    /// Along the heading.
    Front = 0,
    /// Heading + 90 degrees.
    Right = 1,
    /// Heading + 180 degrees.
    Rear = 2,
    /// Heading + 270 degrees.
    Left = 3,
}

impl View {
    /// The four views in dataset order: front, right, rear, left.
    pub const ALL: [View; 4] = [View::Front, View::Right, View::Rear, View::Left];

    /// Yaw of this view relative to the heading, degrees clockwise.
    pub fn yaw_offset_deg(self) -> f32 {
        90.0 * self as u8 as f32
    }

    /// Index 0..4 in dataset order.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// A posed pinhole camera: projects world points to pixels and pixels to world rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Focal length, pixels.
    pub focal_px: f32,
    /// Principal point `u`, pixels (image centre).
    pub cx: f32,
    /// Principal point `v`, pixels (image centre).
    pub cy: f32,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Optical centre in the world, metres.
    pub centre: Vector3<f32>,
    /// World-to-camera rotation: its rows are the camera's `x` (right), `y` (down) and
    /// `z` (optical axis) unit vectors in world coordinates.
    pub world_to_cam: Matrix3<f32>,
}

fn sin_cos_deg(a: f32) -> (f32, f32) {
    let r = a.to_radians();
    (libm::sinf(r), libm::cosf(r))
}

impl Camera {
    /// The camera of `view` on a rover at `pose`.
    pub fn new(params: &CameraParams, pose: &RoverPose, view: View) -> Result<Self, CameraError> {
        params.validate()?;
        pose.validate()?;
        // Rover body axes in the world: yaw, then pitch about right, then roll about forward.
        let (sy, cy) = sin_cos_deg(pose.heading_deg);
        let f0 = Vector3::new(sy, cy, 0.0);
        let r0 = Vector3::new(cy, -sy, 0.0);
        let u0 = Vector3::new(0.0, 0.0, 1.0);
        let (sp, cp) = sin_cos_deg(pose.pitch_deg);
        let f1 = f0 * cp + u0 * sp;
        let u1 = u0 * cp - f0 * sp;
        let (sr, cr) = sin_cos_deg(pose.roll_deg);
        let r2 = r0 * cr - u1 * sr;
        let u2 = u1 * cr + r0 * sr;
        let f2 = f1;
        // The view's horizontal direction and its right in the body, then the tilt.
        let (sb, cb) = sin_cos_deg(view.yaw_offset_deg());
        let h = f2 * cb + r2 * sb;
        let hr = r2 * cb - f2 * sb;
        let (st, ct) = sin_cos_deg(params.tilt_deg);
        let z = h * ct - u2 * st;
        let x = hr;
        let y = z.cross(&x);
        let world_to_cam = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        Ok(Self {
            focal_px: params.focal_px(),
            cx: 0.5 * params.width_px as f32,
            cy: 0.5 * params.height_px as f32,
            width_px: params.width_px,
            height_px: params.height_px,
            centre: Vector3::new(pose.x_m, pose.y_m, pose.ground_z_m + params.height_m),
            world_to_cam,
        })
    }

    /// A world point in camera coordinates (metres; `z` is depth along the optical axis).
    pub fn to_camera(&self, p: Vector3<f32>) -> Vector3<f32> {
        self.world_to_cam * (p - self.centre)
    }

    /// Continuous pixel coordinates `(u, v)` of a world point, or `None` if it is not in
    /// front of the camera (depth below 1 mm). The point may fall outside the image.
    pub fn project(&self, p: Vector3<f32>) -> Option<(f32, f32)> {
        let c = self.to_camera(p);
        if c.z < 1e-3 {
            return None;
        }
        Some((
            self.focal_px * c.x / c.z + self.cx,
            self.focal_px * c.y / c.z + self.cy,
        ))
    }

    /// Unit direction, in the world, of the ray through continuous pixel `(u, v)`.
    pub fn ray(&self, u: f32, v: f32) -> Vector3<f32> {
        let d = Vector3::new(
            (u - self.cx) / self.focal_px,
            (v - self.cy) / self.focal_px,
            1.0,
        );
        (self.world_to_cam.transpose() * d).normalize()
    }

    /// Whether continuous pixel `(u, v)` lies inside the image.
    pub fn in_image(&self, u: f32, v: f32) -> bool {
        u >= 0.0 && v >= 0.0 && u < self.width_px as f32 && v < self.height_px as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn principal_ray_hits_ground_at_tilt_distance() {
        let p = CameraParams::default();
        let pose = RoverPose::level(10.0, 20.0, 5.0, 0.0);
        let cam = Camera::new(&p, &pose, View::Front).unwrap();
        // Facing north, tilted 15 deg: the axis meets the ground 2 / tan(15 deg) m north.
        let d = 2.0 / libm::tanf(15f32.to_radians());
        let (u, v) = cam.project(Vector3::new(10.0, 20.0 + d, 5.0)).unwrap();
        assert!(close(u, 320.0, 1e-2) && close(v, 180.0, 1e-2), "{u} {v}");
        // A point to the east appears right of centre.
        let (u2, _) = cam.project(Vector3::new(12.0, 20.0 + d, 5.0)).unwrap();
        assert!(u2 > 330.0);
    }

    #[test]
    fn views_turn_clockwise() {
        let p = CameraParams::default();
        let pose = RoverPose::level(0.0, 0.0, 0.0, 90.0); // facing east
        let ahead = |v: View| {
            let cam = Camera::new(&p, &pose, v).unwrap();
            let r = cam.ray(cam.cx, cam.cy);
            (r.x, r.y)
        };
        let (x, y) = ahead(View::Front);
        assert!(x > 0.9 && y.abs() < 1e-3); // east
        let (x, y) = ahead(View::Right);
        assert!(y < -0.9 && x.abs() < 1e-3); // south
        let (x, y) = ahead(View::Rear);
        assert!(x < -0.9 && y.abs() < 1e-3); // west
        let (x, y) = ahead(View::Left);
        assert!(y > 0.9 && x.abs() < 1e-3); // north
    }

    #[test]
    fn ray_and_project_agree() {
        let p = CameraParams::default();
        let mut pose = RoverPose::level(3.0, -4.0, 1.0, 33.0);
        pose.pitch_deg = 4.0;
        pose.roll_deg = -3.0;
        let cam = Camera::new(&p, &pose, View::Left).unwrap();
        let r = cam.ray(100.5, 250.5);
        let q = cam.centre + r * 7.0;
        let (u, v) = cam.project(q).unwrap();
        assert!(close(u, 100.5, 1e-2) && close(v, 250.5, 1e-2));
        // Image top edge looks up (15 deg tilt, ~29 deg half vertical FOV).
        assert!(cam.ray(320.0, 0.0).z > 0.0 || pose.pitch_deg < 0.0);
    }

    #[test]
    fn rejects_bad_parameters() {
        let base = CameraParams::default();
        let p = CameraParams {
            hfov_deg: 180.0,
            ..base
        };
        assert_eq!(p.validate(), Err(CameraError::FovOutOfRange));
        let p = CameraParams {
            tilt_deg: f32::NAN,
            ..base
        };
        assert_eq!(p.validate(), Err(CameraError::TiltOutOfRange));
        let p = CameraParams {
            width_px: 0,
            ..base
        };
        assert_eq!(p.validate(), Err(CameraError::ZeroImageSize));
        let mut pose = RoverPose::level(0.0, 0.0, 0.0, 0.0);
        pose.heading_deg = f32::INFINITY;
        assert_eq!(pose.validate(), Err(CameraError::NonFinitePose));
    }
}
