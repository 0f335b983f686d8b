//! Depth at a reduced size: a band of a reduced depth image ([`DepthBand`]) and the
//! expansion of its rows to the frame's rows ([`DepthExpander`]).

use super::setup::ViewSetup;
use super::RangeError;
use crate::camera::{Camera, CameraParams, RoverPose, View};
use crate::reproject::ReprojectError;

/// Bits of the depth scale of an expanded row ([`DepthExpander`]): Q16.
pub(super) const ROW_SCALE_BITS: u32 = 16;
/// 1.0 in that format.
pub(super) const ROW_SCALE_ONE: u32 = 1 << ROW_SCALE_BITS;

/// Expands the rows of a depth image reduced by an integer factor `k` (e.g. on-board stereo
/// at half resolution) to the frame's rows, as [`RangeAccumulator::add_rows`](crate::reproject::RangeAccumulator::add_rows) places them:
/// frame pixel `(i, j)` takes the depth of reduced pixel `(i / k, j / k)`, scaled by the
/// ratio of the flat-ground depths of frame row `j` and of the reduced row's centre row
/// (`(j / k + 0.5) k - 0.5`). A reduced pixel's depth belongs to its centre; without the
/// scale, the `k` frame rows of one reduced row would all fall at the centre row's
/// distance, leaving stripes with gaps between them far from the rover. The ratio is that
/// of the downward slopes of the two rows' rays at the centre column (`h / Z` on flat
/// ground): exact for ground parallel to the rover's, within 1 % elsewhere for `k <= 4`.
#[derive(Clone, Copy, Debug)]
pub struct DepthExpander {
    /// Upward component of the centre column's ray at the principal point row, per unit
    /// of camera depth.
    up0: f32,
    /// Its change per frame row.
    up_row: f32,
    /// Principal point row, pixels.
    cy: f32,
}

impl DepthExpander {
    /// The expander of `view` of the rig `params` at `pose` (checked as
    /// [`crate::camera::Camera::new`] checks them).
    pub fn new(params: &CameraParams, pose: &RoverPose, view: View) -> Result<Self, RangeError> {
        let cam = Camera::new(params, pose, view).map_err(ReprojectError::from)?;
        let r = cam.world_to_cam;
        let f = cam.focal_px;
        let up = [r[(0, 2)], r[(1, 2)], r[(2, 2)]];
        Ok(Self::from_axes(
            up,
            f,
            (0.5 - cam.cx) / f,
            cam.cy,
            params.width_px as usize,
        ))
    }

    /// From a view's set-up (the same axes, the same arithmetic).
    pub(super) fn from_setup(s: &ViewSetup, w: usize) -> Self {
        let [ax_r, ax_d, ax_f] = s.ax;
        Self::from_axes([ax_r[2], ax_d[2], ax_f[2]], s.f, s.u0, s.cy, w)
    }

    /// `up`: the world up components of the camera's right, down and forward axes; `u0`
    /// the normalized x of the first column's centre.
    fn from_axes(up: [f32; 3], f: f32, u0: f32, cy: f32, w: usize) -> Self {
        let [r, d, fw] = up;
        Self {
            up0: fw + r * (u0 + (0.5 * w as f32 - 0.5) / f),
            up_row: d / f,
            cy,
        }
    }

    #[inline]
    fn up_at(&self, row: f32) -> f32 {
        self.up0 + self.up_row * (row + 0.5 - self.cy)
    }

    /// Depth scale of frame row `j` (Q16); 1 where either ray does not point down, and
    /// bounded to `[1/4, 4]` near the horizon.
    fn scale(&self, j: usize, k: usize) -> u32 {
        let centre = ((j / k) as f32 + 0.5) * k as f32 - 0.5;
        let (uc, uj) = (self.up_at(centre), self.up_at(j as f32));
        if !(uc < -1e-4 && uj < -1e-4) {
            return ROW_SCALE_ONE;
        }
        let r = (uc / uj).clamp(0.25, 4.0);
        (r * ROW_SCALE_ONE as f32 + 0.5) as u32
    }

    /// Writes frame row `j` of the depth image reduced by `k` whose reduced row `j / k` is
    /// `src` into `out` (the frame's width; `src` at least `out.len() / k` long, rounded
    /// up, else the missing pixels get no depth). Depth 0 (no data) stays 0; a scaled depth
    /// beyond `u16::MAX` units is `u16::MAX`.
    pub fn expand_row(&self, j: usize, k: usize, src: &[u16], out: &mut [u16]) {
        let k = k.max(1);
        let scale = if k == 1 {
            ROW_SCALE_ONE
        } else {
            self.scale(j, k)
        };
        let mut chunks = out.chunks_mut(k);
        for (c, &o) in (&mut chunks).zip(src) {
            let d = if o == 0 || scale == ROW_SCALE_ONE {
                o
            } else {
                // In u64: a depth of up to 65,535 units times a scale of up to 4 in Q16
                // exceeds u32; a result beyond u16 saturates (the farthest depth).
                let v = (u64::from(o) * u64::from(scale) + u64::from(ROW_SCALE_ONE >> 1))
                    >> ROW_SCALE_BITS;
                u16::try_from(v).unwrap_or(u16::MAX).max(1)
            };
            c.fill(d);
        }
        for c in chunks {
            c.fill(0);
        }
    }
}

/// A band of a depth image at a reduced size, for [`RangeAccumulator::add_rows`](crate::reproject::RangeAccumulator::add_rows).
#[derive(Clone, Copy, Debug)]
pub struct DepthBand<'a> {
    /// Depths (units of [`RangeOptions::depth_scale_m`](crate::reproject::RangeOptions::depth_scale_m), 0 = no depth), row-major,
    /// `width` per row, starting at reduced row `first_row`.
    pub data: &'a [u16],
    /// Reduced width, pixels (at least the frame width / `factor`, rounded up).
    pub width: usize,
    /// Reduced row of the band's first row.
    pub first_row: usize,
    /// Reduction factor (1..): frame pixel `(i, j)` reads reduced pixel `(i / factor, j /
    /// factor)`.
    pub factor: usize,
}
