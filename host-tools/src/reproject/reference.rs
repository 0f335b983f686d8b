//! Float (`f64`) reference of the top-down reprojection, and a flat-ground scene renderer
//! used to test it.
//!
//! The reference follows the same definitions as the core's integer table
//! (`orbfix::reproject`, `docs/reprojection.md`) but computes everything in `f64` per cell:
//! its own camera rotation from the conventions of `docs/frames.md`, exact ground-to-pixel
//! projection, exact bilinear interpolation at pixel-centre coordinates and exact feather
//! weights. Tests compare the core against it.

use anyhow::{bail, ensure, Result};
use image::GrayImage;
use nalgebra::{Matrix3, Vector3};
use orbfix::camera::{CameraParams, RoverPose, View};

/// World-to-camera rotation (rows: camera x right, y down, z optical axis) and the
/// optical centre of `view`, in `f64`, from the conventions of `docs/frames.md`.
pub fn camera_f64(
    params: &CameraParams,
    pose: &RoverPose,
    view: View,
) -> (Matrix3<f64>, Vector3<f64>) {
    let sc = |a: f64| {
        let r = a.to_radians();
        (r.sin(), r.cos())
    };
    let (sy, cy) = sc(pose.heading_deg as f64);
    let f0 = Vector3::new(sy, cy, 0.0);
    let r0 = Vector3::new(cy, -sy, 0.0);
    let u0 = Vector3::new(0.0, 0.0, 1.0);
    let (sp, cp) = sc(pose.pitch_deg as f64);
    let f1 = f0 * cp + u0 * sp;
    let u1 = u0 * cp - f0 * sp;
    let (sr, cr) = sc(pose.roll_deg as f64);
    let r2 = r0 * cr - u1 * sr;
    let u2 = u1 * cr + r0 * sr;
    let (sb, cb) = sc(90.0 * view.index() as f64);
    let h = f1 * cb + r2 * sb;
    let hr = r2 * cb - f1 * sb;
    let (st, ct) = sc(params.tilt_deg as f64);
    let z = h * ct - u2 * st;
    let x = hr;
    let y = z.cross(&x);
    let rot = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let centre = Vector3::new(
        pose.x_m as f64,
        pose.y_m as f64,
        (pose.ground_z_m + params.height_m) as f64,
    );
    (rot, centre)
}

fn focal_f64(params: &CameraParams) -> f64 {
    0.5 * params.width_px as f64 / (0.5 * (params.hfov_deg as f64).to_radians()).tan()
}

/// The four posed cameras in `f64`, projecting ground offsets to pixels.
struct Geometry {
    cams: Vec<(Matrix3<f64>, Vector3<f64>)>,
    ground: Vector3<f64>,
    f: f64,
    cx: f64,
    cy: f64,
    xmax: f64,
    ymax: f64,
}

impl Geometry {
    fn new(params: &CameraParams, pose: &RoverPose) -> Self {
        let (w, h) = (params.width_px as usize, params.height_px as usize);
        Self {
            cams: View::ALL
                .iter()
                .map(|&v| camera_f64(params, pose, v))
                .collect(),
            ground: Vector3::new(pose.x_m as f64, pose.y_m as f64, pose.ground_z_m as f64),
            f: focal_f64(params),
            cx: 0.5 * w as f64,
            cy: 0.5 * h as f64,
            xmax: (w - 1) as f64,
            ymax: (h - 1) as f64,
        }
    }

    /// Up to two views that see the ground point `(dx, dy)` metres east / north of the
    /// rover, best (farthest from its image edge) first: `(view, x, y, edge)` with `(x, y)`
    /// in pixel-centre units (pixel `(i, j)` centre at `(i, j)`).
    fn candidates(&self, dx: f64, dy: f64) -> Vec<(usize, f64, f64, f64)> {
        let p = self.ground + Vector3::new(dx, dy, 0.0);
        let mut cands: Vec<(usize, f64, f64, f64)> = Vec::with_capacity(4);
        for (vi, (rot, c)) in self.cams.iter().enumerate() {
            let q = rot * (p - c);
            if q.z < 1e-3 {
                continue;
            }
            let x = self.f * q.x / q.z + self.cx - 0.5;
            let y = self.f * q.y / q.z + self.cy - 0.5;
            if !(x >= 0.0 && x < self.xmax && y >= 0.0 && y < self.ymax) {
                continue;
            }
            let e = x.min(self.xmax - x).min(y).min(self.ymax - y);
            cands.push((vi, x, y, e));
        }
        cands.sort_by(|a, b| b.3.total_cmp(&a.3));
        cands.truncate(2);
        cands
    }
}

/// Source maps of the best view per cell for an `n x n` grid, as OpenCV's `remap` wants
/// them for the four frames stacked vertically (view `k` occupies rows `k h .. (k + 1) h`):
/// `(map_x, map_y)` in pixel-centre units, `-10` where no view sees the cell. Used by the
/// benchmark to run OpenCV on exactly the same output.
pub fn stacked_source_maps(
    params: &CameraParams,
    pose: &RoverPose,
    n: usize,
    m_per_px: f64,
) -> (Vec<f32>, Vec<f32>) {
    let geom = Geometry::new(params, pose);
    let h = params.height_px as f64;
    let half = 0.5 * n as f64;
    let mut mx = vec![-10f32; n * n];
    let mut my = vec![-10f32; n * n];
    for row in 0..n {
        let dy = (half - row as f64 - 0.5) * m_per_px;
        for col in 0..n {
            let dx = (col as f64 + 0.5 - half) * m_per_px;
            if let Some(&(vi, x, y, _)) = geom.candidates(dx, dy).first() {
                mx[row * n + col] = x as f32;
                my[row * n + col] = (y + vi as f64 * h) as f32;
            }
        }
    }
    (mx, my)
}

/// Output of the float reference: `n x n` north-up values (gray levels, unrounded) and
/// validity.
#[derive(Clone, Debug)]
pub struct RefTopDown {
    /// Cells per side.
    pub n: usize,
    /// Gray level per cell (0 where not valid).
    pub value: Vec<f64>,
    /// Whether each cell has data.
    pub valid: Vec<bool>,
}

/// Exact bilinear sample at pixel-centre coordinates `(x, y)` (pixel `(i, j)` centre at
/// `(i, j)`), `0 <= x <= w - 1`, `0 <= y <= h - 1`.
fn bilinear(img: &GrayImage, x: f64, y: f64) -> f64 {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let x0 = (x.floor() as usize).min(w - 2);
    let y0 = (y.floor() as usize).min(h - 2);
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let raw = img.as_raw();
    let p = |i: usize, j: usize| raw[j * w + i] as f64;
    (1.0 - fy) * ((1.0 - fx) * p(x0, y0) + fx * p(x0 + 1, y0))
        + fy * ((1.0 - fx) * p(x0, y0 + 1) + fx * p(x0 + 1, y0 + 1))
}

/// Float reference of the top-down reprojection on the flat ground `z = pose.ground_z_m`:
/// an `n x n` grid of `m_per_px` cells centred on the rover, north-up; cells beyond
/// `max_range_m` (`f64::INFINITY`: none) or outside every view are not valid; in overlaps
/// the two views nearest their image centres are blended with weights proportional to
/// their distances to the image edge. `None` frames are skipped (the other view of an
/// overlap is used alone).
pub fn reproject_f64(
    frames: &[Option<&GrayImage>; 4],
    params: &CameraParams,
    pose: &RoverPose,
    n: usize,
    m_per_px: f64,
    max_range_m: f64,
) -> Result<RefTopDown> {
    params
        .validate()
        .map_err(|e| anyhow::anyhow!("bad camera parameters: {e}"))?;
    pose.validate()
        .map_err(|e| anyhow::anyhow!("bad rover pose: {e}"))?;
    ensure!(
        n > 0 && m_per_px > 0.0,
        "grid must be non-empty with a positive resolution"
    );
    let (w, h) = (params.width_px as usize, params.height_px as usize);
    for f in frames.iter().flatten() {
        if (f.width() as usize, f.height() as usize) != (w, h) {
            bail!(
                "frame is {}x{}, camera parameters say {w}x{h}",
                f.width(),
                f.height()
            );
        }
    }
    let geom = Geometry::new(params, pose);
    let half = 0.5 * n as f64;
    let mut value = vec![0.0; n * n];
    let mut valid = vec![false; n * n];
    for row in 0..n {
        let dy = (half - row as f64 - 0.5) * m_per_px;
        for col in 0..n {
            let dx = (col as f64 + 0.5 - half) * m_per_px;
            if (dx * dx + dy * dy).sqrt() > max_range_m {
                continue;
            }
            let cands = geom.candidates(dx, dy);
            let used: Vec<_> = cands
                .iter()
                .filter_map(|&(vi, x, y, e)| frames[vi].map(|img| (bilinear(img, x, y), e)))
                .collect();
            let k = row * n + col;
            match used.as_slice() {
                [] => {}
                [(a, _)] => {
                    value[k] = *a;
                    valid[k] = true;
                }
                [(a, ea), (b, eb), ..] => {
                    let t = ea + eb;
                    let wb = if t > 0.0 { eb / t } else { 0.0 };
                    value[k] = a * (1.0 - wb) + b * wb;
                    valid[k] = true;
                }
            }
        }
    }
    Ok(RefTopDown { n, value, valid })
}

/// A smooth test albedo pattern (gray levels 0..=255) on the ground: overlapping ripples
/// with wavelengths of 1.5 to 9 m, so that every part of a 50 m grid is distinctive.
pub fn ripple_texture(x: f64, y: f64) -> f64 {
    let v = 128.0
        + 40.0 * (x / 1.4).sin() * (y / 1.9).cos()
        + 30.0 * ((x + 0.6 * y) / 1.1).sin()
        + 25.0 * ((y - 0.3 * x) / 0.9).cos()
        + 20.0 * ((x * x + y * y).sqrt() / 1.5).sin();
    v.clamp(0.0, 255.0)
}

/// Renders the four views of a rover at `pose` over the flat ground `z = pose.ground_z_m`
/// painted with `albedo(x, y)` (gray levels), by ray/plane intersection with 2 x 2
/// supersampling per pixel; sky (rays that miss the ground) is 0 (black).
pub fn render_flat_ground(
    params: &CameraParams,
    pose: &RoverPose,
    albedo: impl Fn(f64, f64) -> f64 + Sync,
) -> Result<[GrayImage; 4]> {
    use rayon::prelude::*;
    params
        .validate()
        .map_err(|e| anyhow::anyhow!("bad camera parameters: {e}"))?;
    pose.validate()
        .map_err(|e| anyhow::anyhow!("bad rover pose: {e}"))?;
    let (w, h) = (params.width_px, params.height_px);
    let f = focal_f64(params);
    let (cx, cy) = (0.5 * w as f64, 0.5 * h as f64);
    let hgt = params.height_m as f64;
    let render = |view: View| {
        let (rot, c) = camera_f64(params, pose, view);
        let to_world = rot.transpose();
        let mut data = vec![0u8; (w * h) as usize];
        data.par_chunks_mut(w as usize)
            .enumerate()
            .for_each(|(j, row)| {
                for (i, px) in row.iter_mut().enumerate() {
                    let mut acc = 0.0;
                    for (su, sv) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                        let d = to_world
                            * Vector3::new((i as f64 + su - cx) / f, (j as f64 + sv - cy) / f, 1.0);
                        if d.z < -1e-9 {
                            let t = hgt / -d.z;
                            acc += albedo(c.x + t * d.x, c.y + t * d.y);
                        }
                    }
                    *px = (0.25 * acc).round().clamp(0.0, 255.0) as u8;
                }
            });
        GrayImage::from_raw(w, h, data)
    };
    let mut out = Vec::with_capacity(4);
    for v in View::ALL {
        match render(v) {
            Some(img) => out.push(img),
            None => bail!("internal: frame buffer size mismatch"),
        }
    }
    out.try_into()
        .map_err(|_| anyhow::anyhow!("internal: expected four frames"))
}
