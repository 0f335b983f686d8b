//! Building the lookup table (set-up math, `f32`; once per stop).

use super::{
    Buffer, Cell, GridSpec, ReprojectError, Tap, FRAC_BITS, FRAC_STEPS, NODATA, OFF_MASK,
    VIEW_SHIFT,
};
use crate::camera::{Camera, CameraParams, RoverPose, View};

/// Smallest depth along the optical axis (metres per metre of ground offset, i.e. the
/// homography's third coordinate) accepted as "in front of the camera".
const MIN_DEPTH: f32 = 1e-3;

/// What a table build produced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BuildStats {
    /// Cells with data.
    pub valid_cells: usize,
    /// Cells blended from two views (one secondary tap each).
    pub blended_cells: usize,
    /// Overlap cells whose secondary tap did not fit the secondary table (kept with their
    /// better view only: no data lost, feathering dropped there).
    pub dropped_taps: usize,
    /// Cells whose primary tap is in each view (front, right, rear, left).
    pub cells_per_view: [usize; 4],
}

/// A built lookup table borrowing its caller-provided storage.
///
/// Invariant (established by [`Lut::build`], relied on by [`Lut::apply`]): every valid
/// tap's offset `off` satisfies `off + stride + 1 < stride * (height - 1) + width`, so all
/// four bilinear taps lie inside any frame of the table's size and stride.
#[derive(Debug)]
pub struct Lut<'a> {
    pub(super) cells: &'a [Cell],
    pub(super) extra: &'a [Tap],
    pub(super) grid: GridSpec,
    /// First grid row (north-up) of the table's cells: 0 for a whole table.
    pub(super) row0: usize,
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) stride: usize,
    pub(super) stats: BuildStats,
}

/// Homography rows of one view: `(U, V, W) = K [R | t]` applied to a ground offset
/// `(dx, dy)` (metres east / north of the rover): each row is `a * dx + b * dy + c`.
#[derive(Clone, Copy, Default)]
struct Hom {
    u: [f32; 3],
    v: [f32; 3],
    w: [f32; 3],
}

fn homography(params: &CameraParams, pose: &RoverPose, view: View) -> Result<Hom, ReprojectError> {
    let cam = Camera::new(params, pose, view)?;
    let r = cam.world_to_cam;
    let h = params.height_m;
    // Camera coordinates of the ground point: c = R (dx, dy, -h).
    let row = |i: usize| [r[(i, 0)], r[(i, 1)], -h * r[(i, 2)]];
    let (cx, cy, cz) = (row(0), row(1), row(2));
    let f = cam.focal_px;
    // Pixel coordinates u = U / W, v = V / W with pixel centres at +0.5 (docs/frames.md);
    // we fold the -0.5 into U and V so that U / W is the coordinate in pixel-centre units.
    let pu = cam.cx - 0.5;
    let pv = cam.cy - 0.5;
    let mut hom = Hom::default();
    for k in 0..3 {
        hom.u[k] = f * cx[k] + pu * cz[k];
        hom.v[k] = f * cy[k] + pv * cz[k];
        hom.w[k] = cz[k];
    }
    Ok(hom)
}

/// One candidate tap: view, position in pixel-centre units, distance to the image edge.
#[derive(Clone, Copy)]
struct Cand {
    view: u32,
    x: f32,
    y: f32,
    edge: f32,
}

/// Encodes a position (pixel-centre units, `0 <= x < width - 1`, `0 <= y < height - 1`)
/// as (offset | view, weight index), clamping the bottom-right taps inside the frame.
fn encode(c: &Cand, width: usize, height: usize, stride: usize) -> (u32, u16) {
    let steps = FRAC_STEPS as f32;
    // Casts saturate (never panic); positions are non-negative here.
    let qx = (c.x * steps + 0.5) as u32;
    let qy = (c.y * steps + 0.5) as u32;
    let (mut x0, mut fx) = ((qx >> FRAC_BITS) as usize, qx & (FRAC_STEPS - 1));
    let (mut y0, mut fy) = ((qy >> FRAC_BITS) as usize, qy & (FRAC_STEPS - 1));
    if x0 > width - 2 {
        x0 = width - 2;
        fx = FRAC_STEPS - 1;
    }
    if y0 > height - 2 {
        y0 = height - 2;
        fy = FRAC_STEPS - 1;
    }
    let off = (y0 * stride + x0) as u32 | (c.view << VIEW_SHIFT);
    (off, ((fy << FRAC_BITS) | fx) as u16)
}

impl<'a> Lut<'a> {
    /// Builds the table of `grid` for a rover at `pose` into `cells` (exactly
    /// `grid.n * grid.n`) and `extra` (any capacity; secondary taps of overlap cells).
    /// Frames sampled through it must be `params.width_px x params.height_px` with rows
    /// `stride` bytes apart (`stride >= width`).
    ///
    /// Ground plane: `z = pose.ground_z_m`. Cells beyond `grid.max_range_m`, above the
    /// horizon or outside every view are "no data".
    pub fn build(
        cells: &'a mut [Cell],
        extra: &'a mut [Tap],
        params: &CameraParams,
        pose: &RoverPose,
        grid: &GridSpec,
        stride: usize,
    ) -> Result<Self, ReprojectError> {
        Self::build_rows(cells, extra, params, pose, grid, stride, 0..grid.n)
    }

    /// Builds the band of grid rows `rows` (north-up row indices, `start < end <= grid.n`)
    /// of the table of `grid` into `cells` (exactly `(end - start) * grid.n`) and `extra`
    /// (any capacity; secondary taps of that band's overlap cells). Every cell is the one
    /// [`Lut::build`] makes for the whole grid, so applying the bands one after the other
    /// to the matching row ranges of the output ([`Lut::apply`] with
    /// `out[start * n..end * n]`) gives the whole table's image bit for bit, with only one
    /// band of cells resident (8 bytes per cell). The statistics are the band's.
    pub fn build_rows(
        cells: &'a mut [Cell],
        extra: &'a mut [Tap],
        params: &CameraParams,
        pose: &RoverPose,
        grid: &GridSpec,
        stride: usize,
        rows: core::ops::Range<usize>,
    ) -> Result<Self, ReprojectError> {
        grid.validate()?;
        if rows.start >= rows.end || rows.end > grid.n {
            return Err(ReprojectError::BadBand);
        }
        let row0 = rows.start;
        params.validate()?;
        pose.validate()?;
        let width = params.width_px as usize;
        let height = params.height_px as usize;
        let min = super::MIN_FRAME_PX as usize;
        if width < min || height < min || stride < width {
            return Err(ReprojectError::FrameTooSmall);
        }
        match stride.checked_mul(height) {
            Some(s) if s <= OFF_MASK as usize => {}
            _ => return Err(ReprojectError::FrameTooLarge),
        }
        let n = grid.n;
        let needed = (rows.end - rows.start) * n;
        if cells.len() != needed {
            return Err(ReprojectError::BufferSize {
                buffer: Buffer::Cells,
                needed,
                got: cells.len(),
            });
        }
        let mut homs = [Hom::default(); 4];
        for (h, v) in homs.iter_mut().zip(View::ALL) {
            *h = homography(params, pose, v)?;
        }
        let xmax = (width - 1) as f32;
        let ymax = (height - 1) as f32;
        let res = grid.m_per_px;
        let half = 0.5 * n as f32;
        let max_r2 = grid.max_range_m * grid.max_range_m;
        let mut stats = BuildStats::default();
        let mut n_extra = 0usize;

        for (row, row_cells) in (row0..).zip(cells.chunks_exact_mut(n)) {
            let dy = (half - row as f32 - 0.5) * res;
            // Per view: the row's constant part of U, V, W.
            let mut base = [[0f32; 3]; 4];
            for (b, h) in base.iter_mut().zip(homs.iter()) {
                *b = [
                    h.u[1] * dy + h.u[2],
                    h.v[1] * dy + h.v[2],
                    h.w[1] * dy + h.w[2],
                ];
            }
            for (col, cell) in row_cells.iter_mut().enumerate() {
                let dx = (col as f32 + 0.5 - half) * res;
                *cell = Cell::EMPTY;
                if dx * dx + dy * dy > max_r2 {
                    continue;
                }
                let mut best: Option<Cand> = None;
                let mut second: Option<Cand> = None;
                for (vi, (h, b)) in homs.iter().zip(base.iter()).enumerate() {
                    let w = h.w[0] * dx + b[2];
                    if w < MIN_DEPTH {
                        continue;
                    }
                    let u = h.u[0] * dx + b[0];
                    let v = h.v[0] * dx + b[1];
                    // Inside the frame without a division: 0 <= u / w < xmax, same for v.
                    if !(u >= 0.0 && u < xmax * w && v >= 0.0 && v < ymax * w) {
                        continue;
                    }
                    let inv = 1.0 / w;
                    let x = u * inv;
                    let y = v * inv;
                    if !(x < xmax && y < ymax) {
                        continue;
                    }
                    let edge = x.min(xmax - x).min(y).min(ymax - y);
                    let c = Cand {
                        view: vi as u32,
                        x,
                        y,
                        edge,
                    };
                    match best {
                        Some(bst) if bst.edge >= edge => {
                            if second.is_none_or(|s| s.edge < edge) {
                                second = Some(c);
                            }
                        }
                        _ => {
                            second = best;
                            best = Some(c);
                        }
                    }
                }
                let Some(b1) = best else { continue };
                let (off, wi) = encode(&b1, width, height, stride);
                let mut w2 = 0u8;
                if let Some(b2) = second {
                    let total = b1.edge + b2.edge;
                    let q = if total > 0.0 {
                        (256.0 * b2.edge / total + 0.5) as u32
                    } else {
                        0
                    };
                    if q > 0 {
                        match extra.get_mut(n_extra) {
                            Some(t) => {
                                let (o2, wi2) = encode(&b2, width, height, stride);
                                *t = Tap {
                                    off: o2,
                                    wi: wi2,
                                    _pad: 0,
                                };
                                n_extra += 1;
                                w2 = q.min(255) as u8;
                                stats.blended_cells += 1;
                            }
                            None => stats.dropped_taps += 1,
                        }
                    }
                }
                *cell = Cell {
                    off,
                    wi: wi & !NODATA,
                    w2,
                    run: 0,
                };
                stats.valid_cells += 1;
                if let Some(c) = stats.cells_per_view.get_mut(b1.view as usize) {
                    *c += 1;
                }
            }
        }
        // Runs of single-tap cells in one view, counted backwards.
        let mut next: Option<Cell> = None;
        for c in cells.iter_mut().rev() {
            c.run = if c.is_valid() && c.w2 == 0 {
                match next {
                    Some(nx) if nx.run > 0 && nx.view() == c.view() => nx.run.saturating_add(1),
                    _ => 1,
                }
            } else {
                0
            };
            next = Some(*c);
        }
        let extra: &'a [Tap] = extra;
        Ok(Self {
            cells,
            extra: extra.get(..n_extra).unwrap_or(&[]),
            grid: *grid,
            row0,
            width,
            height,
            stride,
            stats,
        })
    }

    /// The grid this table covers.
    pub fn grid(&self) -> &GridSpec {
        &self.grid
    }

    /// Grid rows `(first, end)` this table covers (north-up; `(0, n)` for a whole table).
    pub fn rows(&self) -> (usize, usize) {
        let n = self.grid.n.max(1);
        (self.row0, self.row0 + self.cells.len() / n)
    }

    /// What the build produced.
    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }

    /// Frame `(width, height)` the table samples, pixels.
    pub fn frame_size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Row stride of the frames the table samples, bytes.
    pub fn frame_stride(&self) -> usize {
        self.stride
    }

    /// The primary cells, row-major north-up.
    pub fn cells(&self) -> &[Cell] {
        self.cells
    }

    /// Bytes of table in use: 8 per cell plus 8 per secondary tap.
    pub fn bytes(&self) -> usize {
        core::mem::size_of_val(self.cells) + core::mem::size_of_val(self.extra)
    }
}
