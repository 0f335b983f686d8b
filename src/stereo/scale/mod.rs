//! The matching scale of each row: near rows at a coarser level, far rows at the working
//! size.
//!
//! The top-down image keeps 0.25 m cells, but a near row of the working-size image (320
//! columns) sees 1 to 2 cm of ground per pixel: matching it at a coarser scale cuts its
//! columns, rows and disparities each by the scale factor. What a coarser scale costs is
//! depth precision: a disparity error `dd` (pixels of the level) moves a point at depth `Z`
//! by `dZ = Z^2 dd / (f B)`, and `f` halves with every level. So a row is matched at level
//! `L` (frames reduced by `downsample * 2^L`, `L <= StereoParams::scale_levels`) only
//! where a quarter-pixel error there moves its flat ground by at most
//! `StereoParams::scale_error_m` ([`RowRanges::quarter_px_depth_error`], at the coarse
//! row's top edge, its farthest ground); far rows stay at the working size (level 0).
//!
//! Level `L` takes whole coarse rows: coarse row `q` covers working rows `q m .. (q + 1) m`
//! (`m = row_factor 2^L`, [`Scales::rows_per`]), and its output is expanded onto them
//! (module `expand`: each working pixel takes the disparity of the coarse pixel it lies
//! in, moved to its own row's distance, scaled to working-size pixels). Level `L` covers
//! the working rows from `start[L]` (a multiple of `m`, the first coarse row from which
//! every coarse row down to the last whole one is eligible) to the last whole coarse row; a
//! row takes the coarsest level that covers it. With `row_factor` 2 every level's rows are
//! twice as tall (level 0 too). Set-up math (`f32`, once per rig).

use super::geometry::{Attitude, RowRanges};
use super::StereoParams;
use crate::camera::CameraParams;

/// Matching levels a rig can have: the working size and two coarser scales (2x, 4x).
pub const LEVELS: usize = 3;

/// Matching scales a rig can have: the levels, then level 0 with its rows in pairs near
/// the rover and at the horizon.
pub const SLOTS: usize = LEVELS + 2;

/// The slot of level 0's paired rows: the working size's columns, rows reduced twice more
/// (`StereoParams::pair_rows_m`).
pub const PAIRED: usize = LEVELS;

/// The slot of the horizon rows matched at level 1 (`StereoParams::horizon_coarse`): a run
/// of rows at the image's top, level 1's columns, rows and disparities, `pair_radius_rows_px`
/// rows down, every `column_step`-th column decided, its depths taken unscaled by both
/// working rows of a level row.
pub const HORIZON: usize = LEVELS + 1;

/// Whether slot `l` takes the paired rows' window radius down.
fn is_pair_slot(l: usize) -> bool {
    l == PAIRED || l == HORIZON
}

/// The per-row matching levels of one rig, with each level's disparity ranges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    /// The ranges of each slot: levels 0, 1, 2, the paired rows ([`PAIRED`]) and the
    /// paired horizon rows ([`HORIZON`]).
    geo: [RowRanges; SLOTS],
    /// Levels in use (1..=LEVELS): levels `used..` are never chosen.
    used: usize,
    /// Whether the paired rows are in use.
    paired: bool,
    /// Whether the coarse horizon rows are in use.
    horizon: bool,
    /// Window radius down of the paired rows, rows of that slot.
    pair_radius: usize,
    /// Window radius down of the levels, rows of the level.
    radius: usize,
    /// First working row of each slot (`height` when the slot has no rows).
    start: [usize; SLOTS],
    /// One past the last working row of each slot.
    end: [usize; SLOTS],
    /// First working row that is matched (sees ground at its level), `height` if none.
    first: usize,
    /// First row of each slot's image that sees ground (that slot's rows).
    first_of: [usize; SLOTS],
    /// Working height, rows.
    height: usize,
    /// Working rows per row of level 0 (`StereoParams::row_factor`).
    row_factor: usize,
    /// First row of each level's image from which on every row decides every
    /// `near_step`-th column (`height` of the level when none does).
    near_from: [usize; SLOTS],
    /// Columns decided: `StereoParams::column_step` and `near_column_step`.
    step: usize,
    near_step: usize,
    /// Flat-ground slope of working row `y`'s centre ray: `s(y) = s0 + y ds`
    /// (`s = sin t + yn cos t`, `h / s` its flat-ground depth), for the rows of a coarse
    /// row ([`Scales::row_scale_q15`]).
    s0: f32,
    ds: f32,
    /// The most groups of four disparities any row of each slot touches
    /// ([`RowRanges::max_groups`], computed once: the band matcher's column-sum stride).
    groups: [usize; SLOTS],
}

/// The first of rows `0..h` from which on `ok` holds for every row down to the last (`h`
/// when it fails for the last): the run of rows at the image's bottom that `ok` accepts.
fn first_of_run(h: usize, ok: impl Fn(usize) -> bool) -> usize {
    let mut q0 = h;
    while q0 > 0 && ok(q0 - 1) {
        q0 -= 1;
    }
    q0
}

/// Fractional bits of [`Scales::row_scale_q15`].
pub const ROW_SCALE_BITS: u32 = 15;

impl Scales {
    /// The levels of `camera` and `params` (`params` checked by the caller); `usable(l)`
    /// says whether level `l` can be matched at all (image large enough for the window and
    /// its disparities).
    pub(crate) fn new(
        camera: &CameraParams,
        params: &StereoParams,
        att: &Attitude,
        usable: impl Fn(&RowRanges) -> bool,
    ) -> Self {
        let geo: [RowRanges; SLOTS] = [(0u8, 1u32), (1, 1), (2, 1), (0, 2), (1, 1)]
            .map(|(l, m)| RowRanges::with_rows(camera, params, l, m, att));
        let rf = usize::from(params.row_factor.max(1));
        let height = camera
            .height_px
            .checked_div(u32::from(params.downsample))
            .unwrap_or(0) as usize;
        // Working rows per row of slot `l`.
        let per = |l: usize| match l {
            PAIRED => 2 * rf,
            HORIZON => rf << 1,
            _ => rf << l,
        };
        let mut start = [height; SLOTS];
        let mut end = [height; SLOTS];
        start[0] = 0;
        let mut used = 1;
        // Slot `l`'s rows from the bottom up while `ok(row)`: `(start, end)` in working rows.
        let bottom_up = |l: usize, ok: &dyn Fn(&RowRanges, usize) -> bool| {
            let g = &geo[l.min(SLOTS - 1)];
            let h_l = g.size().1;
            let q0 = first_of_run(h_l, |q| g.row(q).is_some() && ok(g, q));
            ((q0 * per(l)).min(height), (h_l * per(l)).min(height))
        };
        let wanted = usize::from(params.scale_levels).min(LEVELS - 1);
        for l in 1..=wanted {
            if !geo.get(l).is_some_and(&usable) {
                break;
            }
            let (s, e) = bottom_up(l, &|g, q| {
                g.quarter_px_depth_error(q, camera.tilt_deg)
                    .is_some_and(|e| e <= params.scale_error_m)
            });
            if let (Some(a), Some(b)) = (start.get_mut(l), end.get_mut(l)) {
                (*a, *b) = (s, e);
            }
            used = l + 1;
        }
        // Level 0's rows in pairs where the flat ground of a pair spans at most
        // `pair_rows_m` down the image.
        let pair_radius = usize::from(params.pair_radius_rows_px.max(1));
        let mut paired = false;
        if params.pair_rows_m > 0.0
            && usable(&geo[PAIRED])
            && geo[PAIRED].size().1 >= 2 * pair_radius + 2
        {
            let (s, e) = bottom_up(PAIRED, &|g, q| {
                g.row_ground_span_m(q, camera.tilt_deg)
                    .is_some_and(|m| m <= params.pair_rows_m)
            });
            if s < e {
                (start[PAIRED], end[PAIRED]) = (s, e);
                paired = true;
            }
        }
        // The horizon rows at level 1: the run of level rows at the image's top that only
        // see sky or are horizon rows, from the first that is one.
        let mut horizon = false;
        if params.horizon_coarse
            && usable(&geo[HORIZON])
            && geo[HORIZON].size().1 >= 2 * pair_radius + 2
        {
            let g = &geo[HORIZON];
            let h_l = g.size().1;
            let run = (0..h_l)
                .find(|&q| g.row(q).is_some() && !g.is_horizon_row(q))
                .unwrap_or(h_l);
            let first = (0..run).find(|&q| g.is_horizon_row(q));
            if let Some(q0) = first {
                (start[HORIZON], end[HORIZON]) = (
                    (q0 * per(HORIZON)).min(height),
                    (run * per(HORIZON)).min(height),
                );
                horizon = start[HORIZON] < end[HORIZON];
            }
        }
        // Near rows decide every `near_step`-th column: from the first slot row from which
        // on that many columns span at most `near_column_span_m` at every row's flat ground
        // (the span shrinks down the image).
        let near_step = usize::from(params.near_column_step.max(params.column_step).max(1));
        let near_from = geo.map(|g| {
            first_of_run(g.size().1, |q| {
                g.column_span_m(q, camera.tilt_deg)
                    .is_some_and(|m| m * near_step as f32 <= params.near_column_span_m)
            })
        });
        let k = camera.height_px as f32 / height.max(1) as f32;
        let f = camera.focal_px() / k;
        // The centre column's flat ground at the view's attitude: `s = c + yn b`.
        let [_, ct, st] = att.ground_terms();
        let cy = 0.5 * height as f32;
        let mut me = Self {
            geo,
            used,
            paired,
            horizon,
            pair_radius,
            radius: usize::from(params.radius_rows_px.max(1)),
            start,
            end,
            first: height,
            first_of: geo.map(|g| g.first_active()),
            height,
            row_factor: rf,
            near_from,
            step: usize::from(params.column_step.max(1)),
            near_step,
            s0: st + (0.5 - cy) / f * ct,
            ds: ct / f,
            groups: geo.map(|g| g.max_groups()),
        };
        me.first = (0..height)
            .find(|&y| {
                let l = me.level_of_row(y);
                let q = y.checked_div(me.rows_per(l)).unwrap_or(usize::MAX);
                me.level(l).row(q).is_some()
            })
            .unwrap_or(height);
        // Each slot's shear fitted to the rows it matches (and the windows' rows beyond).
        for l in 0..SLOTS {
            let (lo, hi) = (0..height)
                .filter(|&y| me.level_of_row(y) == l)
                .fold((usize::MAX, 0), |(a, b), y| (a.min(y), b.max(y + 1)));
            if lo < hi {
                let (r, rv) = (me.rows_per(l), me.radius_rows(l));
                let rows = (lo / r).saturating_sub(rv + 1)..hi.div_ceil(r) + rv + 1;
                if let Some(g) = me.geo.get_mut(l) {
                    g.fit_shear(rows);
                }
            }
        }
        me.groups = me.geo.map(|g| g.max_groups());
        // The coarse horizon rows decide every `column_step`-th column (of level 1).
        me.near_from[HORIZON] = me.geo[HORIZON].size().1;
        me
    }

    /// Columns row `q` of level `l` decides: every `column_step`-th, or every
    /// `near_column_step`-th in the near rows (`StereoParams`).
    pub fn column_step(&self, l: usize, q: usize) -> usize {
        match self.near_from.get(l) {
            Some(&from) if q >= from => self.near_step,
            _ => self.step,
        }
    }

    /// Working rows per row of slot `l` (`row_factor * 2^l` for level `l`, `2 row_factor`
    /// for the paired rows and the coarse horizon rows; at least 1).
    pub fn rows_per(&self, l: usize) -> usize {
        match l {
            PAIRED | HORIZON => 2 * self.row_factor.max(1),
            _ => (self.row_factor << l.min(LEVELS)).max(1),
        }
    }

    /// Working columns per column of slot `l`, as a shift (the level; 0 for the paired
    /// rows, 1 for the coarse horizon rows).
    pub fn col_shift(&self, l: usize) -> usize {
        match l {
            PAIRED => 0,
            HORIZON => 1,
            _ => l.min(LEVELS - 1),
        }
    }

    /// Window radius down in slot `l`, rows of that slot (`StereoParams::radius_rows_px`,
    /// `pair_radius_rows_px` for the paired rows and the coarse horizon rows).
    pub fn radius_rows(&self, l: usize) -> usize {
        if is_pair_slot(l) {
            self.pair_radius
        } else {
            self.radius
        }
    }

    /// Frame reduction of slot `l` across and down (`downsample` times its columns and
    /// rows per working pixel).
    pub fn reduction(&self, l: usize, downsample: usize) -> (usize, usize) {
        (
            downsample << self.col_shift(l),
            downsample * self.rows_per(l),
        )
    }

    /// The slots in use: the levels in use, then the paired rows and the coarse horizon
    /// rows if in use.
    pub fn slots(&self) -> impl Iterator<Item = usize> + Clone {
        (0..self.used)
            .chain(self.paired.then_some(PAIRED))
            .chain(self.horizon.then_some(HORIZON))
    }

    /// The scale, Q15 ([`ROW_SCALE_BITS`]), that takes the depth (`depth`) or the
    /// disparity (`!depth`) matched for row `q` of level `l` to working row `y` inside it:
    /// the ratio of the two rows' flat-ground depths (of their centre rays), so the
    /// `rows_per(l)` working rows of a coarse row keep the ground's slope instead of
    /// stepping. 1.0 where either row sees no ground, where the ratio leaves `[0.5, 2]`
    /// (next to the horizon), and in the coarse horizon rows ([`HORIZON`]: terrain rising
    /// toward the skyline, not flat ground). Set-up math, once per output row.
    pub fn row_scale_q15(&self, l: usize, q: usize, y: usize, depth: bool) -> u32 {
        let one = 1u32 << ROW_SCALE_BITS;
        let m = self.rows_per(l);
        if m <= 1 || l == HORIZON {
            return one;
        }
        // Centre of the coarse row, in working rows (minus 0.5: `s0` is row 0's centre).
        let c = (q as f32 + 0.5) * m as f32 - 0.5;
        let s_q = self.s0 + c * self.ds;
        let s_y = self.s0 + y as f32 * self.ds;
        if !(s_q > 0.0 && s_y > 0.0) {
            return one;
        }
        // Depth at y = depth at q * s_q / s_y; disparity the inverse.
        let ratio = if depth { s_q / s_y } else { s_y / s_q };
        if !(0.5..=2.0).contains(&ratio) {
            return one;
        }
        libm::roundf(ratio * one as f32) as u32
    }

    /// The disparity ranges of level `l` (the working size for `l = 0` or out of range).
    pub fn level(&self, l: usize) -> &RowRanges {
        match self.geo.get(l) {
            Some(g) => g,
            None => &self.geo[0],
        }
    }

    /// Levels in use (1 = every row at the working size).
    pub fn used(&self) -> usize {
        self.used
    }

    /// The slot working row `y` is matched at: the coarsest level in use whose rows hold
    /// it, else the paired rows or the coarse horizon rows if they hold it, else level 0.
    pub fn level_of_row(&self, y: usize) -> usize {
        let holds = |l: usize| matches!((self.start.get(l), self.end.get(l)), (Some(&s), Some(&e)) if s <= y && y < e);
        (1..self.used)
            .rev()
            .find(|&l| holds(l))
            .or_else(|| (self.paired && holds(PAIRED)).then_some(PAIRED))
            .or_else(|| (self.horizon && holds(HORIZON)).then_some(HORIZON))
            .unwrap_or(0)
    }

    /// First working row of level `l` and one past its last (`(height, height)` when the
    /// level has no rows; level 0 spans the image).
    pub fn rows_of_level(&self, l: usize) -> (usize, usize) {
        let in_use =
            l < self.used || (l == PAIRED && self.paired) || (l == HORIZON && self.horizon);
        match (self.start.get(l), self.end.get(l)) {
            (Some(&s), Some(&e)) if in_use && s < e => (s, e),
            _ => (self.height, self.height),
        }
    }

    /// The first working row that is matched (rows above only see sky); the height if none.
    pub fn first_active(&self) -> usize {
        self.first
    }

    /// The most groups of four disparities any row of slot `l` touches
    /// ([`RowRanges::max_groups`] of [`Scales::level`]`(l)`, level 0's for a slot that
    /// does not exist, as there).
    pub fn max_groups(&self, l: usize) -> usize {
        self.groups.get(l).copied().unwrap_or(self.groups[0])
    }

    /// The first row of level `l`'s image (its own rows) that sees ground.
    pub fn first_active_of(&self, l: usize) -> usize {
        self.first_of.get(l).copied().unwrap_or(0)
    }

    /// The largest number of disparities of any band at any level in use.
    pub fn max_disparities(&self) -> usize {
        self.slots()
            .map(|l| self.level(l).max_disparities())
            .max()
            .unwrap_or(0)
    }

    /// Pixel-disparities the winner-take-all of working rows `a..b` evaluates at their
    /// levels (each coarse row once).
    pub fn row_work(&self, a: usize, b: usize) -> u64 {
        let mut sum = 0;
        let mut y = a;
        while y < b.min(self.height) {
            let l = self.level_of_row(y);
            let m = self.rows_per(l).max(1);
            let q = y.checked_div(m).unwrap_or(0);
            sum += self.level(l).row_work(q, q + 1);
            y = (q + 1) * m;
        }
        sum
    }
}

#[cfg(test)]
mod tests;
