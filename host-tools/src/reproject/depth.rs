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

/// Half-side of the window [`drop_untextured`] measures texture over, frame pixels: 15 x 15,
/// about the core's 7 x 7 stereo window at its working size (frames halved).
pub const TEXTURE_RADIUS_PX: usize = 7;

/// Keeps a depth only where the frame has texture to match: every pixel of `depth` whose
/// `(2 radius + 1)^2` window of `frame` (clipped at the borders) has a gray-level standard
/// deviation below `min_std` becomes 0 ("no depth"). Exact depth through this is what an
/// ideal stereo engine could give at best: nothing in black shadow or on featureless ground.
/// Returns the number of depths dropped.
pub fn drop_untextured(
    depth: &mut [u16],
    frame: &image::GrayImage,
    radius: usize,
    min_std: f64,
) -> anyhow::Result<usize> {
    let (w, h) = (frame.width() as usize, frame.height() as usize);
    anyhow::ensure!(
        depth.len() == w * h,
        "depth image has {} pixels, its frame {w} x {h} = {}",
        depth.len(),
        w * h
    );
    anyhow::ensure!(
        min_std.is_finite() && min_std >= 0.0,
        "the texture threshold must be a gray-level deviation >= 0, got {min_std}"
    );
    // Integral images of the gray levels and their squares, one row and column of zeros
    // ahead.
    let (iw, ih) = (w + 1, h + 1);
    let mut s1 = vec![0u64; iw * ih];
    let mut s2 = vec![0u64; iw * ih];
    let px = frame.as_raw();
    for y in 0..h {
        let (mut r1, mut r2) = (0u64, 0u64);
        for x in 0..w {
            let g = u64::from(px[y * w + x]);
            r1 += g;
            r2 += g * g;
            s1[(y + 1) * iw + x + 1] = s1[y * iw + x + 1] + r1;
            s2[(y + 1) * iw + x + 1] = s2[y * iw + x + 1] + r2;
        }
    }
    let box_sum = |s: &[u64], x0: usize, y0: usize, x1: usize, y1: usize| {
        s[y1 * iw + x1] + s[y0 * iw + x0] - s[y0 * iw + x1] - s[y1 * iw + x0]
    };
    let mut dropped = 0;
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(radius), (y + radius + 1).min(h));
        for x in 0..w {
            let d = &mut depth[y * w + x];
            if *d == 0 {
                continue;
            }
            let (x0, x1) = (x.saturating_sub(radius), (x + radius + 1).min(w));
            let n = ((x1 - x0) * (y1 - y0)) as f64;
            let m = box_sum(&s1, x0, y0, x1, y1) as f64 / n;
            let var = box_sum(&s2, x0, y0, x1, y1) as f64 / n - m * m;
            if var.max(0.0).sqrt() < min_std {
                *d = 0;
                dropped += 1;
            }
        }
    }
    Ok(dropped)
}

/// [`drop_untextured`] on each of four views' depth images with its frame, at
/// [`TEXTURE_RADIUS_PX`], when a threshold is given (`None`: nothing dropped).
pub fn drop_untextured_views(
    depths: &mut [Vec<u16>; 4],
    frames: &[image::GrayImage; 4],
    min_std: Option<f64>,
) -> anyhow::Result<()> {
    if let Some(t) = min_std {
        for (d, f) in depths.iter_mut().zip(frames) {
            drop_untextured(d, f, TEXTURE_RADIUS_PX, t)?;
        }
    }
    Ok(())
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

#[cfg(test)]
mod texture_tests {
    use super::*;

    #[test]
    fn depth_is_dropped_where_the_frame_is_flat_and_kept_where_it_is_textured() {
        // 40 x 20: the left half a flat gray (a shadow), the right half a checkerboard.
        let frame = image::GrayImage::from_fn(40, 20, |x, y| {
            image::Luma([if x < 20 {
                30
            } else if (x + y) % 2 == 0 {
                100
            } else {
                140
            }])
        });
        let mut depth = vec![5000u16; 40 * 20];
        depth[39] = 0;
        let dropped = drop_untextured(&mut depth, &frame, 3, 1.0).unwrap();
        // Columns 0..17 see only the flat half (window of 7 reaches x + 3 < 20).
        for y in 0..20 {
            for x in 0..17 {
                assert_eq!(depth[y * 40 + x], 0, "({x}, {y}) kept in the flat half");
            }
            for x in 17..40 {
                let want = if y == 0 && x == 39 { 0 } else { 5000 };
                assert_eq!(depth[y * 40 + x], want, "({x}, {y})");
            }
        }
        assert_eq!(dropped, 17 * 20);
        // Threshold 0 keeps everything; one above any 8-bit deviation (127.5) drops all.
        let mut all = vec![1u16; 40 * 20];
        assert_eq!(drop_untextured(&mut all, &frame, 3, 0.0).unwrap(), 0);
        assert_eq!(drop_untextured(&mut all, &frame, 3, 128.0).unwrap(), 800);
        // A depth image of the wrong size, a NaN threshold: errors, nothing changed.
        let mut short = vec![7u16; 10];
        assert!(drop_untextured(&mut short, &frame, 3, 1.0).is_err());
        assert!(drop_untextured(&mut depth, &frame, 3, f64::NAN).is_err());
        assert_eq!(short, vec![7u16; 10]);
    }
}
