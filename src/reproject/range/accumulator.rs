//! The incremental range reprojection ([`RangeAccumulator`]): one view or one band of
//! depth rows at a time into the per-cell sums, then the averages, the hole filling and the
//! top-down image.

use super::depth_band::{DepthBand, DepthExpander};
use super::place::{drop_sky, place_row};
use super::relief_pass::{relief_row, relief_steps};
use super::setup::{to_q, Limits, ViewSetup};
use super::{
    check_len, range_scratch_len, scratch_words, DepthView, RangeError, RangeOptions, RangeReport,
    POS_FRAC_BITS, RAY_LIMIT,
};
use crate::camera::{Camera, CameraParams, RoverPose, View};
use crate::image::ImageView;
use crate::reproject::relief::{ReliefCells, ReliefGrid};
use crate::reproject::{classify_frame, Buffer, FrameStatus, GridSpec, ReprojectError};

/// The per-cell accumulator: gray sums (`u16`, in the caller's scratch) and sample counts
/// (`u8`, in the caller's mask until [`RangeAccumulator::finish`]).
#[derive(Debug)]
pub(super) struct Cells<'s> {
    pub(super) sums: &'s mut [u16],
    pub(super) counts: &'s mut [u8],
    /// The relief blocks, when asked for ([`RangeAccumulator::with_relief`]).
    pub(super) relief: Option<ReliefCells<'s>>,
}

/// Incremental range reprojection for callers that produce one view (or one depth image)
/// at a time: [`RangeAccumulator::new`] clears the scratch, [`RangeAccumulator::add_view`]
/// places one view's pixels, [`RangeAccumulator::finish`] averages, fills holes and writes
/// the top-down image. [`reproject_range`](crate::reproject::reproject_range) does all three for four views.
#[derive(Debug)]
pub struct RangeAccumulator<'s> {
    cells: Cells<'s>,
    params: CameraParams,
    pose: RoverPose,
    grid: GridSpec,
    opts: RangeOptions,
    report: RangeReport,
}

impl<'s> RangeAccumulator<'s> {
    /// Checks the parameters and clears `scratch` ([`range_scratch_len`]`(grid.n)`
    /// elements) and `mask` (`n * n` bytes, the sample counts until
    /// [`RangeAccumulator::finish`] writes the validity mask there).
    pub fn new(
        params: &CameraParams,
        pose: &RoverPose,
        grid: &GridSpec,
        opts: &RangeOptions,
        scratch: &'s mut [u32],
        mask: &'s mut [u8],
    ) -> Result<Self, RangeError> {
        grid.validate()?;
        params.validate().map_err(ReprojectError::from)?;
        pose.validate().map_err(ReprojectError::from)?;
        opts.validate()?;
        let cells = grid.cells();
        let needed = range_scratch_len(grid.n);
        if scratch.len() != needed {
            return Err(RangeError::ScratchSize {
                needed,
                got: scratch.len(),
            });
        }
        check_len(Buffer::Mask, mask.len(), cells)?;
        // Safety: `u16` is valid for every bit pattern and its alignment divides `u32`'s,
        // so `align_to_mut` views the whole word buffer as half-words (empty prefix and
        // suffix).
        let (_, sums, _) = unsafe { scratch.align_to_mut::<u16>() };
        let halves = sums.len();
        let sums = sums.get_mut(..cells).ok_or(RangeError::ScratchSize {
            needed,
            got: scratch_words(halves),
        })?;
        sums.fill(0);
        mask.fill(0);
        Ok(Self {
            cells: Cells {
                sums,
                counts: mask,
                relief: None,
            },
            params: *params,
            pose: *pose,
            grid: *grid,
            opts: *opts,
            report: RangeReport {
                status: [FrameStatus::Missing; 4],
                depth_missing: [false; 4],
                pixels_read: 0,
                points_used: 0,
                points_dropped: 0,
                cells_visited: 0,
                valid_cells: 0,
                filled_cells: 0,
            },
        })
    }

    /// Also accumulates the relief on `grid`'s blocks ([`super::ReliefGrid`]) into `words`
    /// ([`crate::reproject::relief_words`] long, cleared here): the mean height of the points of each
    /// block, which [`crate::reproject::relief_template`] reads once the accumulator is finished. The
    /// heights come from a sparse pass over the depths of each row, separate from the
    /// gray-level placement (about 8 points per block side at every distance), so the
    /// relief costs a few per cent of the reprojection; the image is the same with or
    /// without it.
    /// `grid` must be made for this accumulator's grid side.
    pub fn with_relief(
        mut self,
        grid: ReliefGrid,
        words: &'s mut [i32],
    ) -> Result<Self, RangeError> {
        if grid.offset_px() * 2 + grid.blocks() * grid.block_px() > self.grid.n {
            return Err(RangeError::BadOption);
        }
        self.cells.relief = Some(ReliefCells::new(grid, words)?);
        Ok(self)
    }

    /// Checks that `frame` and `depth` have the rig's size (errors as [`reproject_range`](crate::reproject::reproject_range)).
    pub(super) fn check_sizes(
        &self,
        view: View,
        frame: &ImageView<'_>,
        depth: Option<&DepthView<'_>>,
    ) -> Result<(), RangeError> {
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        if (frame.width(), frame.height()) != (w, h) {
            return Err(ReprojectError::FrameSize {
                view: view.index(),
                expected: (w, h),
                got: (frame.width(), frame.height()),
            }
            .into());
        }
        if let Some(d) = depth {
            if (d.width(), d.height()) != (w, h) {
                return Err(RangeError::DepthSize {
                    view: view.index(),
                    expected: (w, h),
                    got: (d.width(), d.height()),
                });
            }
        }
        Ok(())
    }

    /// Places the pixels of `view`'s `frame` at the points given by `depth` (same size as
    /// the frame, `params.width_px x params.height_px`). Returns the frame's status: a
    /// black or saturated frame, or a missing depth image, adds nothing (recorded in the
    /// report). Adding a view twice accumulates it twice.
    pub fn add_view(
        &mut self,
        view: View,
        frame: &ImageView<'_>,
        depth: Option<&DepthView<'_>>,
    ) -> Result<FrameStatus, RangeError> {
        self.check_sizes(view, frame, depth)?;
        let vi = view.index();
        let st = classify_frame(frame);
        if let Some(s) = self.report.status.get_mut(vi) {
            *s = st;
        }
        if st != FrameStatus::Ok {
            return Ok(st);
        }
        let Some(d) = depth else {
            if let Some(m) = self.report.depth_missing.get_mut(vi) {
                *m = true;
            }
            return Ok(st);
        };
        let setup = self.setup(view)?;
        let h = self.params.height_px as usize;
        for j in 0..h {
            let (Some(frow), Some(drow)) = (frame.row(j), d.row(j)) else {
                break;
            };
            self.place(&setup, j, frow, drow)?;
        }
        Ok(st)
    }

    /// Records `view`'s frame status (and that it has no depth) without placing pixels:
    /// for callers that place a view row by row ([`RangeAccumulator::add_rows`]).
    pub fn set_view_status(&mut self, view: View, status: FrameStatus, depth_missing: bool) {
        let vi = view.index();
        if let Some(s) = self.report.status.get_mut(vi) {
            *s = status;
        }
        if let Some(m) = self.report.depth_missing.get_mut(vi) {
            *m = depth_missing;
        }
    }

    /// Places rows `rows` of `view`'s `frame` (the rig's size) with depth from `band`, a
    /// depth image at the size reduced by `band.factor` (e.g. on-board stereo at half
    /// resolution): full-resolution pixel `(i, j)` takes the depth of reduced pixel
    /// `(i / factor, j / factor)`, which must lie in the band, scaled to row `j`. `row_buf` (at least the
    /// frame width, `u16`) holds the expanded depth row ([`DepthExpander`]: each depth
    /// scaled to its frame row). Does not classify the frame (see
    /// [`RangeAccumulator::set_view_status`]); the result of a row does not depend on how
    /// the rows are cut into calls.
    pub fn add_rows(
        &mut self,
        view: View,
        frame: &ImageView<'_>,
        rows: core::ops::Range<usize>,
        band: &DepthBand<'_>,
        row_buf: &mut [u16],
    ) -> Result<(), RangeError> {
        self.check_sizes(view, frame, None)?;
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        let k = band.factor.max(1);
        let bad = RangeError::DepthSize {
            view: view.index(),
            expected: (w.div_ceil(k), h.div_ceil(k)),
            got: (
                band.width,
                band.data.len().checked_div(band.width).unwrap_or(0),
            ),
        };
        if band.width * k < w || row_buf.len() < w {
            return Err(bad);
        }
        let setup = self.setup(view)?;
        let expander = DepthExpander::from_setup(&setup, w);
        for j in rows.start..rows.end.min(h) {
            let Some(frow) = frame.row(j) else { break };
            let y = (j / k).checked_sub(band.first_row).ok_or(bad)?;
            let src = band
                .data
                .get(y * band.width..(y + 1) * band.width)
                .ok_or(bad)?;
            let sky = self.opts.sky_below_gray;
            let drow = if k == 1 && sky == 0 {
                src.get(..w).ok_or(bad)?
            } else {
                let out = row_buf.get_mut(..w).ok_or(bad)?;
                if k == 1 {
                    out.copy_from_slice(src.get(..w).ok_or(bad)?);
                } else {
                    // Each frame row at its own distance ([`DepthExpander`]).
                    expander.expand_row(j, k, src, out);
                }
                if sky > 0 {
                    drop_sky(frow, out, sky);
                }
                &*out
            };
            self.place(&setup, j, frow, drow)?;
        }
        Ok(())
    }

    /// Fixed-point set-up of one view (limits, camera axes, column steps).
    fn setup(&self, view: View) -> Result<ViewSetup, RangeError> {
        let (params, grid, opts) = (&self.params, &self.grid, &self.opts);
        let n = grid.n;
        // Limits in the fixed-point units.
        let max_depth_units = {
            let q = opts.max_depth_m / opts.depth_scale_m;
            if q >= u16::MAX as f32 {
                u16::MAX
            } else {
                libm::floorf(q) as u16
            }
        };
        let one = (1u64 << POS_FRAC_BITS) as f32;
        let scale_z = opts.depth_scale_m * one;
        let scale_xy = scale_z / grid.m_per_px;
        // Heights relative to the optical centre, metres Q32 (saturating casts keep
        // infinities).
        let h_lo = ((opts.min_height_m - params.height_m) * one) as i64;
        let h_hi = ((opts.max_height_m - params.height_m) * one) as i64;
        // Ground range limit on cell centres: (2c + 1 - n)^2 + (2r + 1 - n)^2 <= (2 R/res)^2.
        let range_lim: Option<i64> = if grid.max_range_m.is_finite() {
            let r = 2.0 * grid.max_range_m / grid.m_per_px;
            if r * r < 4.0e18 {
                Some((r * r) as i64)
            } else {
                None
            }
        } else {
            None
        };
        // The optical centre is straight above the rover: n / 2 cells from the west and
        // north edges.
        let height_band = h_lo > i64::MIN || h_hi < i64::MAX;
        let lim = Limits {
            max_depth: max_depth_units,
            h_lo,
            h_hi,
            c_q: (n as i64) << (POS_FRAC_BITS - 1),
            n: n as u32,
            range_lim: range_lim.unwrap_or(i64::MAX),
        };

        let cam = Camera::new(params, &self.pose, view).map_err(ReprojectError::from)?;
        let r = cam.world_to_cam;
        // Camera right, down, forward axes in the world.
        let ax_r = [r[(0, 0)], r[(0, 1)], r[(0, 2)]];
        let ax_d = [r[(1, 0)], r[(1, 1)], r[(1, 2)]];
        let ax_f = [r[(2, 0)], r[(2, 1)], r[(2, 2)]];
        let f = cam.focal_px;
        let u0 = (0.5 - cam.cx) / f;
        // Steps per column, Q32 per depth unit: east (cells), south (cells), up (metres).
        let bx = ax_r[0] / f * scale_xy;
        let by = -ax_r[1] / f * scale_xy;
        let bz = ax_r[2] / f * scale_z;
        let b_q = [to_q(bx)?, to_q(by)?, to_q(bz)?];
        Ok(ViewSetup {
            lim,
            height_band,
            range_lim,
            ax: [ax_r, ax_d, ax_f],
            f,
            u0,
            cy: cam.cy,
            b: [bx, by, bz],
            b_q,
            scale_xy,
            scale_z,
        })
    }

    /// Places frame row `j` (`frow`, its depths `drow`, both the frame's width).
    fn place(
        &mut self,
        s: &ViewSetup,
        j: usize,
        frow: &[u8],
        drow: &[u16],
    ) -> Result<(), RangeError> {
        let (params, grid, opts) = (&self.params, &self.grid, &self.opts);
        let w = params.width_px as usize;
        let [ax_r, ax_d, ax_f] = s.ax;
        let (f, u0) = (s.f, s.u0);
        let [bx, by, bz] = s.b;
        let [bx_q, by_q, bz_q] = s.b_q;
        let vv = (j as f32 + 0.5 - s.cy) / f;
        let a = [
            ax_f[0] + ax_d[0] * vv + ax_r[0] * u0,
            ax_f[1] + ax_d[1] * vv + ax_r[1] * u0,
            ax_f[2] + ax_d[2] * vv + ax_r[2] * u0,
        ];
        let ax = a[0] * s.scale_xy;
        let ay = -a[1] * s.scale_xy;
        let az = a[2] * s.scale_z;
        // The ray at both ends of the row must stay inside RAY_LIMIT (so i32 steps
        // cannot overflow: the rounding drift over a row is below `w` units).
        let end = w as f32;
        for (a0, b0) in [(ax, bx), (ay, by), (az, bz)] {
            if libm::fabsf(a0) + libm::fabsf(b0) * end >= RAY_LIMIT {
                return Err(RangeError::Overflow);
            }
        }
        let ray = [to_q(ax)?, to_q(ay)?, to_q(az)?];
        // The row's flat-ground depth at its centre column, metres (`None` at or above the
        // horizon).
        let up_mid = a[2] + ax_r[2] * (0.5 * w as f32 - 0.5) / f;
        let flat_m = (up_mid < 0.0).then(|| params.height_m / -up_mid);
        // Column stride from that depth.
        let mut stride = 1usize;
        if let (true, Some(t)) = (opts.max_column_stride > 1, flat_m) {
            let st = libm::floorf(grid.m_per_px * f / (2.0 * t));
            if st >= 2.0 {
                stride = (st as usize).min(usize::from(opts.max_column_stride));
            }
        }
        stride = stride.min(w.max(1));
        let k = stride as i32;
        let step = [
            bx_q.wrapping_mul(k),
            by_q.wrapping_mul(k),
            bz_q.wrapping_mul(k),
        ];
        let read = w.div_ceil(stride.max(1)) as u64;
        let lim = &s.lim;
        let scratch = &mut self.cells;
        // The relief: a sparse pass of its own, about RELIEF_SAMPLES points per block side.
        if let Some(rc) = scratch.relief.as_mut() {
            let block_m = grid.m_per_px * rc.grid.block_px() as f32;
            // Half the grid's diagonal: beyond it, only terrain that rises lands in a block.
            let reach_m = grid.n as f32 * grid.m_per_px * core::f32::consts::FRAC_1_SQRT_2;
            let (rows, cols) = relief_steps(flat_m, reach_m, block_m, f, params.height_m);
            if j % rows == 0 {
                let c = cols.min(w.max(1));
                let kc = c as i32;
                let rstep = [
                    bx_q.wrapping_mul(kc),
                    by_q.wrapping_mul(kc),
                    bz_q.wrapping_mul(kc),
                ];
                relief_row(drow, c, ray, rstep, lim, rc);
            }
        }
        // Monomorphized per limit set so the default (no height band, no range limit)
        // loop keeps its state in registers.
        macro_rules! row {
            ($h:literal, $r:literal) => {
                place_row::<$h, $r>(frow, drow, stride, ray, step, lim, scratch)
            };
        }
        let used = match (s.height_band, s.range_lim.is_some()) {
            (false, false) => row!(false, false),
            (true, false) => row!(true, false),
            (false, true) => row!(false, true),
            (true, true) => row!(true, true),
        };
        self.report.pixels_read += read;
        self.report.points_used += u64::from(used);
        self.report.points_dropped += read - u64::from(used);
        Ok(())
    }

    /// Averages the samples per cell into `out` (`n * n` gray levels, north-up, 0 where no
    /// data) and the mask given to [`RangeAccumulator::new`] (255 valid, 0 no data), fills
    /// holes, and returns the report of the whole reprojection.
    pub fn finish(self, out: &mut [u8]) -> Result<RangeReport, RangeError> {
        let n = self.grid.n;
        let cells = self.grid.cells();
        check_len(Buffer::Output, out.len(), cells)?;
        let Cells {
            sums, counts: mask, ..
        } = self.cells;
        let mut report = self.report;
        // Per cell: mean of the samples; the sum's slot then keeps whether the cell was
        // sampled (1) or not (0), the validity the hole filling reads.
        let mut valid = 0usize;
        for ((s, o), m) in sums.iter_mut().zip(out.iter_mut()).zip(mask.iter_mut()) {
            let cnt = u32::from(*m);
            match (u32::from(*s) + cnt / 2).checked_div(cnt) {
                Some(v) => {
                    *o = v.min(255) as u8;
                    *m = 255;
                    *s = 1;
                    valid += 1;
                }
                None => {
                    *o = 0;
                    *m = 0;
                    *s = 0;
                }
            }
        }
        let scratch = &*sums;
        report.cells_visited += cells as u64;
        // Hole filling: validity from the accumulator (unchanged), values from sampled
        // cells.
        let mut filled = 0usize;
        if self.opts.fill_min_neighbours > 0 {
            let need = u32::from(self.opts.fill_min_neighbours);
            for r in 0..n {
                for c in 0..n {
                    let k = r * n + c;
                    if scratch.get(k).is_none_or(|&a| a != 0) {
                        continue;
                    }
                    let (mut nv, mut sum) = (0u32, 0u32);
                    for rr in r.saturating_sub(1)..(r + 2).min(n) {
                        for cc in c.saturating_sub(1)..(c + 2).min(n) {
                            let kk = rr * n + cc;
                            if kk == k {
                                continue;
                            }
                            if let (Some(&a), Some(&v)) = (scratch.get(kk), out.get(kk)) {
                                if a != 0 {
                                    nv += 1;
                                    sum += u32::from(v);
                                }
                            }
                        }
                    }
                    if nv >= need {
                        if let (Some(o), Some(m)) = (out.get_mut(k), mask.get_mut(k)) {
                            *o = ((sum + nv / 2) / nv).min(255) as u8;
                            *m = 255;
                            filled += 1;
                        }
                    }
                }
            }
            report.cells_visited += cells as u64;
        }
        report.valid_cells = valid + filled;
        report.filled_cells = filled;
        Ok(report)
    }
}
