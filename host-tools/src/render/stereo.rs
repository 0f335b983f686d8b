//! Stereo pairs of the rover's four views: the left camera is the view camera, the right
//! camera sits `baseline_m` along the left camera's `+x` axis (right) with the same
//! intrinsics and orientation (a rectified pair, `docs/frames.md`), and the truth that
//! stereo is judged against (range images, disparities).

use super::{
    render_jobs, terrain::TileCache, view_cameras, RenderError, RenderOptions, Sun, Surface,
    ViewSet,
};
use image::GrayImage;
use orbfix::camera::{Camera, RoverPose};
use serde::{Deserialize, Serialize};

/// Default baseline, metres (the core's default, `orbfix::stereo::DEFAULT_BASELINE_M`).
pub const DEFAULT_BASELINE_M: f64 = 0.30;

/// Noise stream offset of the right cameras (the left views use streams 1..=4).
const RIGHT_STREAM: u64 = 100;

/// Settings of the stereo rig in the renderer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StereoRender {
    /// Baseline, metres: right camera along the left camera's `+x` axis. Finite, in (0, 10].
    pub baseline_m: f64,
    /// Gain of the right camera relative to the left (on gray levels, before the sensor
    /// noise and quantization), e.g. 1.02; finite, in [0.5, 2].
    pub right_gain: f64,
}

impl Default for StereoRender {
    /// 0.30 m baseline, equal gains.
    fn default() -> Self {
        Self {
            baseline_m: DEFAULT_BASELINE_M,
            right_gain: 1.0,
        }
    }
}

impl StereoRender {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(self.baseline_m.is_finite() && self.baseline_m > 0.0 && self.baseline_m <= 10.0) {
            return Err(RenderError::Option(format!(
                "stereo baseline {} m must be finite and in (0, 10]",
                self.baseline_m
            )));
        }
        if !(self.right_gain.is_finite() && (0.5..=2.0).contains(&self.right_gain)) {
            return Err(RenderError::Option(format!(
                "right camera gain {} must be in [0.5, 2]",
                self.right_gain
            )));
        }
        Ok(())
    }
}

/// The right camera of the pair whose left camera is `left`.
pub fn right_camera(left: &Camera, baseline_m: f64) -> Camera {
    let x_axis = left.world_to_cam.row(0).transpose();
    Camera {
        centre: left.centre + x_axis * baseline_m as f32,
        ..*left
    }
}

/// Four stereo pairs and their truth.
#[derive(Clone, Debug)]
pub struct StereoSet {
    /// The left views (the mono views, unchanged), their range images and cameras.
    pub left: ViewSet,
    /// The right views, order front, right, rear, left.
    pub right: [GrayImage; 4],
    /// The right cameras.
    pub right_cameras: [Camera; 4],
    /// The rig.
    pub rig: StereoRender,
}

/// Renders the four stereo pairs of a rover over one prepared terrain (left images identical
/// to [`super::render_views_cached`]'s; the right cameras draw their own noise streams).
pub fn render_stereo_views(
    world: &dyn Surface,
    pose: &RoverPose,
    sun: Sun,
    opts: &RenderOptions,
    rig: &StereoRender,
    cache: Option<&TileCache>,
) -> Result<StereoSet, RenderError> {
    rig.validate()?;
    let cams = view_cameras(pose, opts)?;
    let rights = cams.map(|c| right_camera(&c, rig.baseline_m));
    let mut jobs: Vec<(Camera, u64, f64)> = Vec::with_capacity(8);
    for (k, c) in cams.iter().enumerate() {
        jobs.push((*c, k as u64 + 1, 1.0));
    }
    for (k, c) in rights.iter().enumerate() {
        jobs.push((*c, RIGHT_STREAM + k as u64 + 1, rig.right_gain));
    }
    let mut out = render_jobs(world, pose, sun, opts, cache, &jobs)?.into_iter();
    let mut next = || {
        out.next()
            .unwrap_or_else(|| (GrayImage::new(1, 1), Vec::new()))
    };
    let l: [(GrayImage, Vec<f32>); 4] = [next(), next(), next(), next()];
    let r: [GrayImage; 4] = [next().0, next().0, next().0, next().0];
    let [(v0, r0), (v1, r1), (v2, r2), (v3, r3)] = l;
    Ok(StereoSet {
        left: ViewSet {
            views: [v0, v1, v2, v3],
            range_m: [r0, r1, r2, r3],
            cameras: cams,
        },
        right: r,
        right_cameras: rights,
        rig: *rig,
    })
}

/// True disparity of the left image of a pair, pixels at the size reduced by `k` (the
/// stereo working size: `width / k x height / k`, row-major): `f B / Z` per full-resolution
/// pixel (`Z` the depth along the optical axis from the range image), averaged over each
/// `k x k` block and divided by `k`; NaN where any pixel of the block sees sky.
pub fn true_disparity(
    range_m: &[f32],
    cam: &Camera,
    baseline_m: f64,
    k: usize,
) -> anyhow::Result<(Vec<f32>, usize, usize)> {
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    anyhow::ensure!(
        range_m.len() == w * h,
        "range image has {} pixels, the camera {w} x {h} (render and camera disagree)",
        range_m.len()
    );
    anyhow::ensure!((1..=8).contains(&k), "reduction {k} must be 1..=8");
    let (wo, ho) = (w / k, h / k);
    let f = cam.focal_px as f64;
    let mut out = vec![f32::NAN; wo * ho];
    for yo in 0..ho {
        for xo in 0..wo {
            let mut sum = 0.0f64;
            let mut ok = true;
            for y in yo * k..yo * k + k {
                for x in xo * k..xo * k + k {
                    let r = range_m[y * w + x] as f64;
                    if !(r.is_finite() && r > 0.0) {
                        ok = false;
                        continue;
                    }
                    let xn = (x as f64 + 0.5 - cam.cx as f64) / f;
                    let yn = (y as f64 + 0.5 - cam.cy as f64) / f;
                    let z = r / (1.0 + xn * xn + yn * yn).sqrt();
                    sum += f * baseline_m / z;
                }
            }
            if ok {
                out[yo * wo + xo] = (sum / (k * k) as f64 / k as f64) as f32;
            }
        }
    }
    Ok((out, wo, ho))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use orbfix::camera::{CameraParams, View};

    #[test]
    fn default_baseline_is_the_cores() {
        assert_eq!(
            DEFAULT_BASELINE_M as f32,
            orbfix::stereo::DEFAULT_BASELINE_M
        );
    }

    #[test]
    fn right_camera_sees_points_shifted_left_by_the_disparity() {
        let p = CameraParams::default();
        let pose = RoverPose::level(3.0, 4.0, 1.0, 30.0);
        let left = Camera::new(&p, &pose, View::Rear).unwrap();
        let right = right_camera(&left, 0.3);
        let q = left.centre + left.ray(100.5, 250.5) * 8.0;
        let (ul, vl) = left.project(q).unwrap();
        let (ur, vr) = right.project(q).unwrap();
        let z = left.to_camera(q).z;
        assert!((vl - vr).abs() < 1e-3, "rectified: same row");
        assert!(((ul - ur) - left.focal_px * 0.3 / z).abs() < 1e-2);
    }

    #[test]
    fn flat_truth_matches_the_plane_formula() {
        let p = CameraParams {
            width_px: 64,
            height_px: 36,
            ..CameraParams::default()
        };
        let cam = Camera::new(&p, &RoverPose::level(0.0, 0.0, 0.0, 0.0), View::Front).unwrap();
        // Range of flat ground at each pixel.
        let mut range = vec![0f32; 64 * 36];
        for j in 0..36 {
            for i in 0..64 {
                let r = cam.ray(i as f32 + 0.5, j as f32 + 0.5);
                if r.z < -1e-3 {
                    range[j * 64 + i] = 2.0 / -r.z;
                }
            }
        }
        let (d, w, h) = true_disparity(&range, &cam, 0.3, 2).unwrap();
        assert_eq!((w, h), (32, 18));
        let t = 15f32.to_radians();
        let f = cam.focal_px / 2.0;
        let y = 15usize;
        let yn = (y as f32 + 0.5 - 9.0) / f;
        let want = f * 0.3 * (t.sin() + yn * t.cos()) / 2.0;
        assert!(
            (d[y * w + 10] - want).abs() < 0.02,
            "{} {want}",
            d[y * w + 10]
        );
        assert!(d[0].is_nan());
        let _ = Vector3::<f32>::zeros();
    }
}
