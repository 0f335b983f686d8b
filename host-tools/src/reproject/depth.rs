//! Depth images for the core's range reprojection (`orbfix::reproject::reproject_range`):
//! the renderer's range images (distance along each pixel's ray, metres) converted to `u16`
//! depth along the optical axis in millimetres, optionally with a stereo noise model.

use crate::render::ViewSet;
use orbfix::camera::Camera;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Metres per depth unit of the images made here (millimetres, the core's default).
pub const DEPTH_SCALE_M: f32 = orbfix::reproject::DEFAULT_DEPTH_SCALE_M;

/// Stereo depth noise: a Gaussian error of standard deviation `k_per_m * z^2` metres at
/// depth `z` metres (disparity noise grows quadratically with depth), seeded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoNoise {
    /// Coefficient `k`, 1/metres (e.g. 0.001: 1 cm at 3.2 m, 10 cm at 10 m, 0.9 m at 30 m).
    pub k_per_m: f64,
    /// Seed of the noise stream.
    pub seed: u64,
}

/// One view's depth image: `u16` millimetres along the optical axis, row-major, 0 = none.
pub fn depth_image(
    range_m: &[f32],
    cam: &Camera,
    noise: Option<StereoNoise>,
) -> anyhow::Result<Vec<u16>> {
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    anyhow::ensure!(
        range_m.len() == w * h,
        "range image has {} pixels, the camera {w} x {h} = {} (render and camera disagree)",
        range_m.len(),
        w * h
    );
    let mut rng = noise.map(|n| ChaCha8Rng::seed_from_u64(n.seed));
    let unit = Normal::new(0.0f64, 1.0).map_err(|e| anyhow::anyhow!("normal: {e}"))?;
    let mut out = vec![0u16; w * h];
    for (i, (o, &r)) in out.iter_mut().zip(range_m).enumerate() {
        if !(r.is_finite() && r > 0.0) {
            continue;
        }
        // cos(angle to the axis) of the pixel centre's ray: 1 / |(xn, yn, 1)|.
        let xn = ((i % w) as f64 + 0.5 - cam.cx as f64) / cam.focal_px as f64;
        let yn = ((i / w) as f64 + 0.5 - cam.cy as f64) / cam.focal_px as f64;
        let mut z = r as f64 / (1.0 + xn * xn + yn * yn).sqrt();
        if let (Some(n), Some(rng)) = (noise, rng.as_mut()) {
            z += n.k_per_m * z * z * unit.sample(rng);
        }
        let q = (z / DEPTH_SCALE_M as f64).round();
        if q >= 1.0 && q <= u16::MAX as f64 {
            *o = q as u16;
        }
    }
    Ok(out)
}

/// Depth images of the four views of `set` (front, right, rear, left); view `v` uses the
/// noise seed `seed + v`.
pub fn depth_images(set: &ViewSet, noise: Option<StereoNoise>) -> anyhow::Result<[Vec<u16>; 4]> {
    let mut out: [Vec<u16>; 4] = Default::default();
    for (v, ((o, r), cam)) in out
        .iter_mut()
        .zip(&set.range_m)
        .zip(&set.cameras)
        .enumerate()
    {
        let n = noise.map(|n| StereoNoise {
            seed: n.seed.wrapping_add(v as u64),
            ..n
        });
        *o = depth_image(r, cam, n)?;
    }
    Ok(out)
}

/// Depth images of four stereo pairs computed by the core's own matcher
/// ([`orbfix::stereo::StereoRig`], the same code the fix runs as its `stereo` stage), at
/// the frames' size: each frame pixel takes the depth of the working-size pixel it lies in,
/// scaled to its row by the core's [`orbfix::reproject::DepthExpander`] (what the fix's
/// banded stereo stage places; the rig at `pose`). A pair the matcher cannot use (black or
/// saturated image, sizes differ) gives an all-zero image ("no depth"); settings it refuses
/// are an error.
pub fn stereo_depth_images(
    left: &[image::GrayImage; 4],
    right: &[image::GrayImage; 4],
    params: &orbfix::camera::CameraParams,
    pose: &orbfix::camera::RoverPose,
    stereo: &orbfix::stereo::StereoParams,
) -> anyhow::Result<[Vec<u16>; 4]> {
    use orbfix::image::ImageView;
    use orbfix::stereo::{StereoError, StereoRig};
    let (w, h) = (params.width_px as usize, params.height_px as usize);
    let k = usize::from(stereo.downsample);
    let mut out: [Vec<u16>; 4] = Default::default();
    for ((o, (l, r)), which) in out
        .iter_mut()
        .zip(left.iter().zip(right))
        .zip(orbfix::camera::View::ALL)
    {
        *o = vec![0u16; w * h];
        // The view's row ranges follow the rover's pitch and roll (the fix's rig).
        let rig = StereoRig::for_view(params, stereo, pose, which)
            .map_err(|e| anyhow::anyhow!("the stereo settings were refused: {e}"))?;
        let s = rig.buffer_sizes();
        let (wo, ho) = rig.output_size();
        let mut bytes = vec![0u8; s.bytes];
        let mut words = vec![0u16; s.words];
        let mut small = vec![0u16; wo * ho];
        let expander = orbfix::reproject::DepthExpander::new(params, pose, which)
            .map_err(|e| anyhow::anyhow!("bad rig or pose: {e}"))?;
        fn view(g: &image::GrayImage) -> anyhow::Result<ImageView<'_>> {
            ImageView::new(g.as_raw(), g.width() as usize, g.height() as usize)
                .map_err(|e| anyhow::anyhow!("bad stereo image: {e}"))
        }
        let (lv, rv) = (view(l)?, view(r)?);
        match rig.image(
            &lv,
            Some(&rv),
            ho,
            false,
            &mut bytes,
            &mut words,
            &mut small,
        ) {
            Ok(_) => {}
            Err(
                StereoError::MissingRight
                | StereoError::Frame { .. }
                | StereoError::PairSize { .. }
                | StereoError::FrameSize { .. },
            ) => continue,
            Err(e) => anyhow::bail!("stereo matching failed: {e}"),
        }
        for y in 0..(ho * k).min(h) {
            let src = &small[(y / k) * wo..(y / k + 1) * wo];
            expander.expand_row(y, k, src, &mut o[y * w..(y + 1) * w]);
        }
    }
    Ok(out)
}
