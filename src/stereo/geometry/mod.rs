//! Disparity range of each row from the rig and the ground the top-down square holds.
//!
//! For a level rover the flat ground seen by a row at normalized coordinate
//! `yn = (v + 0.5 - cy) / f` lies at depth `Z = h / s` with `s = sin t + yn cos t` (`h`:
//! camera height, metres; `t`: tilt): its disparity `f B s / h` grows linearly down the
//! image and is the same along the row. Relief between `+above` and `-below` metres around
//! the ground under the rover moves it to `f B s / (h - dz)` (with a near bound `a0` and a
//! grade `g`, `relief_above_near_m` and `relief_above_grade`, a point at depth `Z` stands at
//! most `min(above, a0 + g Z)` high: the row's largest disparity is also at most
//! `f B (s + g) / (h - a0)`). A rover that is not level
//! sees the ground under normalized pixel `(xn, yn)` at depth `h / s` with
//! `s = a xn + b yn + c`, `(a, b, c)` the world's down in the view camera's coordinates
//! ([`Attitude`], from the pitch and roll the fix is given); an uncertainty of `m` degrees
//! in each turns that unit vector by at most `acos(cos^2 m)`, which moves `s` by at most
//! `2 sin(acos(cos^2 m) / 2) |(xn, yn, 1)|`; `s_lo`, `s_hi` are `s`'s extremes over the row
//! (`|xn| <= tan(hfov / 2)`) and that uncertainty. So a
//! row searches `[f B max(s_lo / (h + below), 1 / Zmax), f B s_hi / (h - above)]`, widened by
//! one pixel on each side so that every true disparity in range is an interior winner
//! (`Zmax`: the largest depth of a point within `max_ground_range_m`). Rows with
//! `s_hi <= 0` only see sky (nothing there is lower than the camera minus `above`), and rows
//! whose range is empty before the widening (`f B s_hi / (h - above) < f B / Zmax`: only
//! points beyond the range could be that high in the image) see nothing the top-down square
//! holds; both are skipped. Set-up math (`f32`, once per rig and per row of a band).
//!
//! A rig has one [`RowRanges`] per matching level ([`super::scale`]): level `L` works on the
//! frames reduced by `downsample * 2^L` (and `row_factor` times more down), so its focal
//! length, columns and disparities are `2^L` times smaller, its rows `row_factor 2^L`.

use super::shear::shear_at;
use super::StereoParams;
use crate::camera::{Camera, CameraError, CameraParams, RoverPose, View};

/// The per-row disparity search ranges of one rig (integer pixels at the working size).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowRanges {
    focal: f32,
    /// Focal length in this level's rows (`focal / row_factor`), pixels.
    focal_rows: f32,
    cy: f32,
    height: usize,
    width: usize,
    fb: f32,
    h: f32,
    above: f32,
    /// The near bound of the relief above (`relief_above_near_m`, below `above`) and its
    /// grade, metres per metre of depth; `None`: `above` everywhere.
    near: Option<(f32, f32)>,
    below: f32,
    inv_zmax: f32,
    /// The horizon rows' relief: `(a0, g)`, a point at depth `Z` stands at most `a0 + g Z`
    /// above the ground, no cap (`StereoParams::horizon_grade`); `None`: those rows are
    /// not searched.
    horizon: Option<(f32, f32)>,
    /// The nominal ground slope terms of this view's camera: the flat ground under pixel
    /// `(xn, yn)` (normalized coordinates) lies at depth `h / s` with `s = a xn + b yn + c`,
    /// `(a, b, c)` minus the world's up in camera coordinates ([`Attitude::ground_terms`]).
    nom: [f32; 3],
    /// `tan(hfov / 2)`: the largest `|xn|` of a row.
    half: f32,
    /// `sqrt(half^2 + 1)`: `|(xn, yn, 1)| <= root + yn^2 / (2 root)` on a row.
    root: f32,
    /// How far the attitude's uncertainty can move `(a, b, c)` (a unit vector turned by at
    /// most the angle between two up vectors `m` of pitch and `m` of roll apart).
    marg: f32,
    radius: usize,
    /// The windows' shear, Q8 pixels: the right image's row `v` is moved `a + s v` pixels
    /// right before matching ([`RowRanges::shear_q8`]); `(0, 0)`: none.
    shear: (i32, i32),
    /// The rows the shear was fitted to ([`RowRanges::fit_shear`]): the level's matched
    /// rows, the only ones [`RowRanges::max_groups`] sizes for.
    fitted: Option<(usize, usize)>,
}

/// The rover's pitch and roll seen from one view's camera, and the uncertainty the row
/// ranges allow around them: the world's up in the camera's coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attitude {
    /// `-up` in camera coordinates (`x` right, `y` down, `z` the optical axis): the flat
    /// ground under normalized pixel `(xn, yn)` lies `h / (a xn + b yn + c)` deep.
    terms: [f32; 3],
}

impl Attitude {
    /// A level rover: the camera only tilted down by `tilt_deg`.
    pub fn level(tilt_deg: f32) -> Self {
        let t = tilt_deg.to_radians();
        Self {
            terms: [0.0, libm::cosf(t), libm::sinf(t)],
        }
    }

    /// The camera of `view` on a rover with the pitch and roll of `pose` (its position and
    /// heading do not matter here).
    pub fn of_view(
        camera: &CameraParams,
        pose: &RoverPose,
        view: View,
    ) -> Result<Self, CameraError> {
        pose.validate()?;
        if pose.pitch_deg == 0.0 && pose.roll_deg == 0.0 {
            // Exactly the level rig's terms (the rotations below round in the last bits).
            return Ok(Self::level(camera.tilt_deg));
        }
        let at = RoverPose {
            x_m: 0.0,
            y_m: 0.0,
            ground_z_m: 0.0,
            heading_deg: 0.0,
            ..*pose
        };
        let cam = Camera::new(camera, &at, view)?;
        // The rows of `world_to_cam` are the camera axes in the world: their `z`
        // components are the world's up in camera coordinates.
        let m = &cam.world_to_cam;
        Ok(Self {
            terms: [-m[(0, 2)], -m[(1, 2)], -m[(2, 2)]],
        })
    }

    /// `(a, b, c)`: the flat ground under normalized pixel `(xn, yn)` lies at depth
    /// `h / (a xn + b yn + c)` (metres, `h` the camera height).
    pub fn ground_terms(&self) -> [f32; 3] {
        self.terms
    }
}

impl RowRanges {
    /// The ranges of matching level `level` (frames reduced by `downsample << level`), level
    /// rover.
    #[cfg(test)]
    pub(crate) fn new(camera: &CameraParams, p: &StereoParams, level: u8) -> Self {
        Self::with_rows(camera, p, level, 1, &Attitude::level(camera.tilt_deg))
    }

    /// As [`RowRanges::new`] with the rows reduced `row_mult` times more (the paired rows of
    /// [`super::scale`]), for a camera of attitude `att`.
    pub(crate) fn with_rows(
        camera: &CameraParams,
        p: &StereoParams,
        level: u8,
        row_mult: u32,
        att: &Attitude,
    ) -> Self {
        let factor = u32::from(p.downsample) << level.min(8);
        let rf = u32::from(p.row_factor.max(1)) * row_mult.max(1);
        let width = camera.width_px.checked_div(factor).unwrap_or(0) as usize;
        let height = camera.height_px.checked_div(factor * rf).unwrap_or(0) as usize;
        let k = factor as f32;
        let kv = (factor * rf) as f32;
        let focal = camera.focal_px() / k;
        let m = p.attitude_margin_deg.to_radians();
        // Up vectors `m` of pitch and `m` of roll apart are `acos(cos^2 m)` apart; a unit
        // vector turned by `theta` moves by `2 sin(theta / 2)`.
        let cm = libm::cosf(m);
        let theta = libm::acosf((cm * cm).min(1.0));
        let half = libm::tanf(0.5 * camera.hfov_deg.to_radians());
        let depth_lim = camera.height_m + p.relief_below_m;
        let zmax = libm::sqrtf(p.max_ground_range_m * p.max_ground_range_m + depth_lim * depth_lim);
        let mut out = Self {
            focal,
            focal_rows: camera.focal_px() / kv,
            cy: 0.5 * camera.height_px as f32 / kv,
            height,
            width,
            fb: focal * p.baseline_m,
            h: camera.height_m,
            above: p.relief_above_m,
            near: (p.relief_above_near_m < p.relief_above_m)
                .then_some((p.relief_above_near_m, p.relief_above_grade)),
            below: p.relief_below_m,
            inv_zmax: 1.0 / zmax,
            horizon: (p.horizon_grade > 0.0)
                .then_some((p.relief_above_near_m.min(p.relief_above_m), p.horizon_grade)),
            nom: att.terms,
            half,
            root: libm::sqrtf(half * half + 1.0),
            marg: 2.0 * libm::sinf(0.5 * theta),
            radius: usize::from(p.radius_px),
            shear: (0, 0),
            fitted: None,
        };
        if p.ground_shear {
            out.shear = out.ground_shear();
        }
        out
    }

    /// The shear that makes a window follow the flat ground down the image: its disparity
    /// `f B (b yn + c) / h` grows by `f B b / (h f_rows)` pixels per row, so moving the right
    /// image's row `v` right by `g(v)`, that line less a constant `K`, leaves the ground at
    /// one residual disparity `d - g(v)` over the window's rows. `K` keeps every row's
    /// residual range at least 1 (`(a, s)`, Q8 pixels, `g(v) = a + s v`).
    fn ground_shear(&self) -> (i32, i32) {
        let [_, b, _] = self.nom;
        let s = self.fb * b / (self.h * self.focal_rows);
        // `as` saturates (NaN: 0); the values are a few hundred pixels at most.
        let s_q8 = libm::roundf(s * 256.0) as i32;
        self.shear_offset_q8(s, 0..self.height, 0.0)
            .map_or((0, 0), |a_q8| (a_q8, s_q8))
    }

    /// The constant `a` of the shear `a + s v` (slope `s`, pixels per row) for rows `rows`:
    /// the smallest whole-pixel line below `K` (from `k_floor` up) that keeps each of their
    /// residual ranges at least 1, Q8 pixels (`None`: no row of `rows` is searched).
    #[inline(always)]
    fn shear_offset_q8(&self, s: f32, rows: core::ops::Range<usize>, k_floor: f32) -> Option<i32> {
        let [_, b, c] = self.nom;
        let a0 = self.fb * (b * (0.5 - self.cy) / self.focal_rows + c) / self.h;
        let k = rows
            .filter_map(|v| Some(a0 + s * v as f32 - self.span(v)?.0))
            .fold(None, |m: Option<f32>, x| Some(m.map_or(x, |m| m.max(x))))?
            .max(k_floor);
        Some(libm::roundf((a0 - (libm::ceilf(k) + 1.0)) * 256.0) as i32)
    }

    /// Moves the shear by the whole pixels (0 to 3 further) that make the ranges of rows
    /// `rows` (the ones this level matches) touch the fewest groups of four disparities,
    /// the matcher's unit of work ([`super::scale`] calls it once the rows are known).
    pub(crate) fn fit_shear(&mut self, rows: core::ops::Range<usize>) {
        let (_, s_q8) = self.shear;
        // The constant again, for these rows only (a window whose residual reaches past the
        // image's left edge is not matched, so a smaller constant loses fewer columns there).
        let s = s_q8 as f32 / 256.0;
        let a_q8 = match self.shear_offset_q8(s, rows.clone(), f32::NEG_INFINITY) {
            Some(a) if self.shear != (0, 0) => a,
            _ => return,
        };
        let mut best = (usize::MAX, a_q8);
        for j in 0..4 {
            let a = a_q8.saturating_sub(256 * j);
            let groups: usize = rows
                .clone()
                .filter_map(|v| {
                    let (d_lo, d_hi) = self.span(v)?;
                    let (lo, hi) = self.widen(d_lo, d_hi, shear_at((a, s_q8), v));
                    Some(hi / 4 + 1 - lo / 4)
                })
                .sum();
            if groups < best.0 {
                best = (groups, a);
            }
        }
        self.shear = (best.1, s_q8);
        self.fitted = Some((rows.start, rows.end));
    }

    /// The right image's shift before matching row `v` of this level, Q8 pixels (moved
    /// right; 0 without the ground shear): the searched disparities of [`RowRanges::row`]
    /// are residuals, the disparity is the residual plus this.
    #[inline]
    pub fn shear_q8(&self, v: usize) -> i32 {
        shear_at(self.shear, v)
    }

    /// `(a, s)` of the shear `a + s v` (Q8 pixels; `(0, 0)`: none), for [`super::shear::shear_at`].
    pub(crate) fn shear_terms(&self) -> (i32, i32) {
        self.shear
    }

    /// `(width, height)` of this level's image, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Depth, metres, of the flat ground under row edge `e` of this level (`e = v`: the top
    /// edge of row `v`, its farthest ground; level rover at tilt `tilt_deg`), or `None` when
    /// that edge sees no ground (at or above the horizon).
    fn flat_depth_at_edge(&self, e: f32, tilt_deg: f32) -> Option<f32> {
        let t = tilt_deg.to_radians();
        let yn = (e - self.cy) / self.focal_rows;
        let s = libm::sinf(t) + yn * libm::cosf(t);
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        Some(self.h / s)
    }

    /// Depth error, metres, that a quarter-pixel disparity error at this level causes at
    /// the flat ground under the top edge of row `v` (its farthest ground: `dZ = Z^2 / (4 f
    /// B)`), or `None` when that edge sees no ground.
    pub fn quarter_px_depth_error(&self, v: usize, tilt_deg: f32) -> Option<f32> {
        let z = self.flat_depth_at_edge(v as f32, tilt_deg)?;
        Some(z * z / (4.0 * self.fb))
    }

    /// Ground span down row `v` of this level, metres: the flat ground's depth under its top
    /// edge less that under its bottom edge, or `None` when the top edge sees no ground.
    pub fn row_ground_span_m(&self, v: usize, tilt_deg: f32) -> Option<f32> {
        let top = self.flat_depth_at_edge(v as f32, tilt_deg)?;
        let bottom = self.flat_depth_at_edge(v as f32 + 1.0, tilt_deg)?;
        Some(top - bottom)
    }

    /// Ground span across one column of this level, metres, at the flat ground under the
    /// top edge of row `v` (`Z / f`), or `None` when that edge sees no ground.
    pub fn column_span_m(&self, v: usize, tilt_deg: f32) -> Option<f32> {
        Some(self.flat_depth_at_edge(v as f32, tilt_deg)? / self.focal)
    }

    /// Focal length at the working size, pixels.
    pub fn focal_px(&self) -> f32 {
        self.focal
    }

    /// The disparities searched in row `v` (working size), inclusive, or `None` when the
    /// row only sees sky (or lies outside the image). With the ground shear these are
    /// residuals: the disparity is the residual plus [`RowRanges::shear_q8`]`(v)`.
    pub fn row(&self, v: usize) -> Option<(usize, usize)> {
        let (d_lo, d_hi) = self.span(v)?;
        Some(self.widen(d_lo, d_hi, self.shear_q8(v)))
    }

    /// The searched range of disparities `d_lo ..= d_hi` less a shear `g_q8` (Q8 pixels),
    /// widened by a pixel each side, whole pixels.
    fn widen(&self, d_lo: f32, d_hi: f32, g_q8: i32) -> (usize, usize) {
        let g = g_q8 as f32 / 256.0;
        let (d_lo, d_hi) = (d_lo - g, d_hi - g);
        // Leave the columns a window needs: at most width - 2r - 2.
        let cap = self.width.saturating_sub(2 * self.radius + 2) as f32;
        // `max` / `min` rather than `clamp`: no assertion (panic path) in the flight build.
        let lo = (libm::floorf(d_lo) - 1.0).max(0.0).min(cap);
        let hi = (libm::ceilf(d_hi) + 1.0)
            .max(lo + 2.0)
            .min(cap.max(lo + 2.0));
        (lo as usize, hi as usize)
    }

    /// The disparities, pixels, that row `v` can see within the range (before the shear
    /// and the widening), or `None` when it only sees sky.
    fn span(&self, v: usize) -> Option<(f32, f32)> {
        let (s_lo, s_hi) = self.slope_bounds(v)?;
        if let Some((a0, g)) = self.horizon {
            // A horizon row: its flat ground lies beyond `Zmax` (or it sees none). A point
            // at depth `Z <= Zmax` on its ray stands `h - Z s` over the ground, at most
            // `a0 + g Z`: `Z >= (h - a0) / (s + g)`.
            if s_hi < self.h * self.inv_zmax {
                let d_lo = self.fb * self.inv_zmax;
                let d_hi = self.fb * (s_hi + g) / (self.h - a0);
                return (d_hi >= d_lo).then_some((d_lo, d_hi));
            }
        }
        if s_hi <= 0.0 {
            return None;
        }
        let d_lo = self.fb * (s_lo / (self.h + self.below)).max(self.inv_zmax);
        let mut d_hi = self.fb * s_hi / (self.h - self.above);
        if let Some((a0, g)) = self.near {
            // A point at depth Z stands at most `a0 + g Z` above the ground: on this row's
            // ray (`dz = h - Z s`) at depth `Z >= (h - a0) / (s + g)`.
            d_hi = d_hi.min(self.fb * (s_hi + g) / (self.h - a0));
        }
        // Every point this row sees within `Zmax` would stand more than `above` over the
        // ground: the row only sees sky or ground beyond the range.
        if d_hi < d_lo {
            return None;
        }
        Some((d_lo, d_hi))
    }

    /// Whether row `v` is searched as a horizon row (`StereoParams::horizon_grade` on, and
    /// its flat ground lies beyond the range under every attitude the margin allows, or it
    /// sees none).
    pub fn is_horizon_row(&self, v: usize) -> bool {
        self.horizon.is_some()
            && self
                .slope_bounds(v)
                .is_some_and(|(_, s_hi)| s_hi < self.h * self.inv_zmax)
            && self.span(v).is_some()
    }

    /// The least and greatest flat-ground slope `s` of row `v` (its flat ground at depth
    /// `h / s`) over its columns and the attitude's uncertainty, or `None` outside the
    /// image.
    fn slope_bounds(&self, v: usize) -> Option<(f32, f32)> {
        if v >= self.height {
            return None;
        }
        let yn = (v as f32 + 0.5 - self.cy) / self.focal_rows;
        let [a, b, c] = self.nom;
        // `s` over the row (`|xn| <= half`) and over the attitude's uncertainty (`|d (a, b,
        // c)| <= marg`, so `s` moves by at most `marg |(xn, yn, 1)|`, and `sqrt(r^2 + yn^2)
        // <= r + yn^2 / (2 r)`: no square root per row).
        let s_mid = b * yn + c;
        let spread =
            libm::fabsf(a) * self.half + self.marg * (self.root + yn * yn / (2.0 * self.root));
        let s_lo = s_mid - spread;
        let s_hi = s_mid + spread;
        if s_hi.is_nan() {
            return None;
        }
        Some((s_lo, s_hi))
    }

    /// The first row that is searched (rows above only see sky, or nothing within the
    /// range); `height` if none.
    pub fn first_active(&self) -> usize {
        (0..self.height)
            .find(|&v| self.row(v).is_some())
            .unwrap_or(self.height)
    }

    /// Union of the ranges of rows `a..b`: `(lo, hi)` inclusive, or `None` if all are sky.
    pub fn union(&self, a: usize, b: usize) -> Option<(usize, usize)> {
        let mut out: Option<(usize, usize)> = None;
        for v in a..b.min(self.height) {
            if let Some((lo, hi)) = self.row(v) {
                out = Some(match out {
                    Some((l, h)) => (l.min(lo), h.max(hi)),
                    None => (lo, hi),
                });
            }
        }
        out
    }

    /// Largest disparity searched anywhere, pixels (with the ground shear: the largest
    /// residual plus its row's shear, rounded up).
    pub fn global_max(&self) -> usize {
        (0..self.height)
            .filter_map(|v| {
                let (_, hi) = self.row(v)?;
                let q8 = (hi as i32)
                    .saturating_mul(256)
                    .saturating_add(self.shear_q8(v));
                Some((q8.max(0) as usize).div_ceil(256))
            })
            .max()
            .unwrap_or(0)
    }

    /// Disparities in the union of all rows (an upper bound for any band).
    pub fn max_disparities(&self) -> usize {
        self.union(0, self.height).map_or(0, |(l, h)| h + 1 - l)
    }

    /// The most groups of four disparities (`4g .. 4g + 4`) that the range of any row this
    /// level matches touches: what the column sums of a row hold (the band matcher's).
    pub fn max_groups(&self) -> usize {
        let (a, b) = self.fitted.unwrap_or((0, self.height));
        (a..b.min(self.height))
            .filter_map(|v| self.row(v))
            .map(|(lo, hi)| hi / 4 + 1 - lo / 4)
            .max()
            .unwrap_or(0)
    }

    /// Pixel-disparities the winner-take-all of rows `a..b` evaluates (columns with a full
    /// window times the row's range): the instruction-relevant work.
    pub fn row_work(&self, a: usize, b: usize) -> u64 {
        let cols = self.width.saturating_sub(2 * self.radius) as u64;
        (a..b.min(self.height))
            .filter_map(|v| self.row(v))
            .map(|(lo, hi)| cols * (hi + 1 - lo) as u64)
            .sum()
    }
}

#[cfg(test)]
mod tests;
