//! Where the rover stands at a stop: level on the terrain, or on the slope under it.

use super::Surface;
use orbfix::camera::RoverPose;

/// The rover standing level on the terrain at `(x_m, y_m)` with a heading (degrees clockwise
/// from north); `ground_z_m` is the terrain height there.
pub fn ground_pose(world: &dyn Surface, x_m: f64, y_m: f64, heading_deg: f64) -> RoverPose {
    RoverPose::level(
        x_m as f32,
        y_m as f32,
        world.height_m(x_m, y_m) as f32,
        heading_deg as f32,
    )
}

/// The rover standing on the terrain at `(x_m, y_m)` with a heading (degrees clockwise from
/// north), pitched and rolled by the slope under it: the least-squares plane through the
/// heights of a 5 x 5 grid over its `wheelbase_m` x `track_m` footprint (metres), so
/// pebbles and clods under one wheel do not tip it. `ground_z_m` is the terrain height at
/// the centre, as for [`ground_pose`].
pub fn terrain_pose(
    world: &dyn Surface,
    x_m: f64,
    y_m: f64,
    heading_deg: f64,
    wheelbase_m: f64,
    track_m: f64,
) -> RoverPose {
    let (sh, ch) = heading_deg.to_radians().sin_cos();
    // Forward (east, north) = (sin h, cos h); right = (cos h, -sin h) (`camera::Camera`).
    let (mut suz, mut suu, mut svz, mut svv) = (0.0, 0.0, 0.0, 0.0);
    for i in -2..=2 {
        for j in -2..=2 {
            let u = 0.25 * i as f64 * wheelbase_m;
            let v = 0.25 * j as f64 * track_m;
            let z = world.height_m(x_m + u * sh + v * ch, y_m + u * ch - v * sh);
            suz += u * z;
            suu += u * u;
            svz += v * z;
            svv += v * v;
        }
    }
    let pitch = (suz / suu).atan();
    // Right side down positive: the ground falling to the right.
    let roll = (-svz / svv).atan();
    RoverPose {
        pitch_deg: pitch.to_degrees() as f32,
        roll_deg: roll.to_degrees() as f32,
        ..ground_pose(world, x_m, y_m, heading_deg)
    }
}

/// As [`ground_pose`] on any [`Surface`].
pub fn ground_pose_on(surface: &dyn Surface, x_m: f64, y_m: f64, heading_deg: f64) -> RoverPose {
    RoverPose::level(
        x_m as f32,
        y_m as f32,
        surface.height_m(x_m, y_m) as f32,
        heading_deg as f32,
    )
}

/// How far the rover of `pose` tilts from level, degrees: the angle between its up axis and
/// the vertical, from its pitch `p` and roll `r` as [`terrain_pose`] gives them (slopes `tan
/// p` forward and `tan r` sideways of one plane): `acos(1 / sqrt(1 + tan^2 p + tan^2 r))`.
pub fn tilt_deg(pose: &RoverPose) -> f64 {
    let (p, r) = (
        f64::from(pose.pitch_deg).to_radians(),
        f64::from(pose.roll_deg).to_radians(),
    );
    (1.0 / (1.0 + p.tan().powi(2) + r.tan().powi(2)).sqrt())
        .acos()
        .to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::RenderOptions;

    /// Ground rising `k` metres per metre to the east.
    struct Ramp(f64);

    impl Surface for Ramp {
        fn height_m(&self, x: f64, _y: f64) -> f64 {
            self.0 * x
        }
        fn albedo(&self, _x: f64, _y: f64) -> f64 {
            0.5
        }
    }

    #[test]
    fn terrain_pose_pitches_up_a_rise_and_rolls_right_side_down_on_a_fall() {
        let ramp = Ramp(0.2);
        let slope = 0.2f64.atan().to_degrees() as f32;
        let near = |a: f32, b: f32| (a - b).abs() < 1e-3;
        // Facing east: the ground rises ahead, nose up.
        let p = terrain_pose(&ramp, 10.0, 5.0, 90.0, 2.0, 2.0);
        assert!(near(p.pitch_deg, slope) && near(p.roll_deg, 0.0), "{p:?}");
        assert!(near(p.ground_z_m, 2.0));
        // Facing north: east is on the right and higher, so the right side is up.
        let p = terrain_pose(&ramp, 10.0, 5.0, 0.0, 2.0, 2.0);
        assert!(near(p.pitch_deg, 0.0) && near(p.roll_deg, -slope), "{p:?}");
        // Facing south: the right (west) side is down.
        let p = terrain_pose(&ramp, 10.0, 5.0, 180.0, 2.0, 2.0);
        assert!(near(p.pitch_deg, 0.0) && near(p.roll_deg, slope), "{p:?}");
        // On the level, level.
        let p = terrain_pose(&Ramp(0.0), 10.0, 5.0, 33.0, 2.0, 2.0);
        assert_eq!((p.pitch_deg, p.roll_deg), (0.0, 0.0));
        // The camera of a rover facing east on the rise sees its ground as a level rover
        // sees flat ground: the centre pixel's ray meets the ramp about h / sin(tilt) away.
        let p = terrain_pose(&ramp, 0.0, 0.0, 90.0, 2.0, 2.0);
        let params = RenderOptions::default().camera_params();
        let cam = orbfix::camera::Camera::new(&params, &p, orbfix::camera::View::Front).unwrap();
        let d = cam.world_to_cam.row(2).transpose();
        let (c, h) = (cam.centre, params.height_m);
        // c + t d on the plane z = 0.2 x.
        let t = (c.z - 0.2 * c.x) / (0.2 * d.x - d.z);
        let level = h / params.tilt_deg.to_radians().sin();
        assert!(t > 0.0 && (t - level).abs() < 0.25 * level, "{t} {level}");
    }

    #[test]
    fn tilt_is_the_angle_of_the_slope_plane() {
        let pose = |p: f32, r: f32| RoverPose {
            pitch_deg: p,
            roll_deg: r,
            ..RoverPose::level(0.0, 0.0, 0.0, 0.0)
        };
        assert!(tilt_deg(&pose(0.0, 0.0)).abs() < 1e-9);
        assert!((tilt_deg(&pose(10.0, 0.0)) - 10.0).abs() < 1e-4);
        assert!((tilt_deg(&pose(0.0, -10.0)) - 10.0).abs() < 1e-4);
        // Both: the plane's steepest slope, sqrt(tan^2 p + tan^2 r), about 14.0 deg.
        let both = tilt_deg(&pose(10.0, 10.0));
        let want = (2.0 * 10f64.to_radians().tan().powi(2))
            .sqrt()
            .atan()
            .to_degrees();
        assert!(
            (both - want).abs() < 1e-4 && both > 13.9 && both < 14.1,
            "{both}"
        );
    }
}
