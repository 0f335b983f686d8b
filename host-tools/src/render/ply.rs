//! Point clouds from range images, written as binary little-endian PLY.

use anyhow::Context;
use image::GrayImage;
use orbfix::camera::Camera;
use std::path::Path;

/// One surface point: world position (metres) and gray level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// East, metres.
    pub x: f32,
    /// North, metres.
    pub y: f32,
    /// Up, metres.
    pub z: f32,
    /// Gray level of the pixel.
    pub gray: u8,
}

/// World points of every non-sky pixel of a view, every `stride`-th pixel in each direction.
pub fn points_from_range(
    cam: &Camera,
    range_m: &[f32],
    gray: &GrayImage,
    stride: usize,
) -> Vec<Point> {
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    let stride = stride.max(1);
    let mut out = Vec::new();
    for j in (0..h).step_by(stride) {
        for i in (0..w).step_by(stride) {
            let r = range_m.get(j * w + i).copied().unwrap_or(0.0);
            if r > 0.0 {
                let d = cam.ray(i as f32 + 0.5, j as f32 + 0.5);
                let p = cam.centre + d * r;
                out.push(Point {
                    x: p.x,
                    y: p.y,
                    z: p.z,
                    gray: gray.get_pixel(i as u32, j as u32)[0],
                });
            }
        }
    }
    out
}

/// PLY bytes (binary little endian: float x, y, z, uchar gray) of `points`.
pub fn ply_bytes(points: &[Point]) -> Vec<u8> {
    let mut b = Vec::with_capacity(200 + points.len() * 13);
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment orbfix point cloud, world frame: x east, y north, z up, metres\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar gray\nend_header\n",
        points.len()
    );
    b.extend_from_slice(header.as_bytes());
    for p in points {
        b.extend_from_slice(&p.x.to_le_bytes());
        b.extend_from_slice(&p.y.to_le_bytes());
        b.extend_from_slice(&p.z.to_le_bytes());
        b.push(p.gray);
    }
    b
}

/// Writes `points` to `path` as PLY, atomically.
pub fn write_ply(path: &Path, points: &[Point]) -> anyhow::Result<()> {
    crate::fsutil::write_atomic(path, &ply_bytes(points))
        .with_context(|| format!("writing point cloud {}", path.display()))
}
