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
mod tests {
    use super::*;
    use crate::camera::{Camera, RoverPose, View};

    /// The default rig without the horizon rows (`horizon_grade` 0): the flat ground's
    /// ranges these tests check (the horizon rows have their own test).
    fn flat_rig() -> StereoParams {
        StereoParams {
            horizon_grade: 0.0,
            ..StereoParams::default()
        }
    }

    #[test]
    fn flat_ground_inside_each_range_and_sky_skipped() {
        let cam = CameraParams::default();
        // Rows at the working size (`row_factor` 1); `row_factor` 2 below. Relief +0.5 m.
        // Disparities, not residuals (the shear: `windows_follow_the_flat_ground`).
        let p = StereoParams {
            row_factor: 1,
            relief_above_m: 0.5,
            ground_shear: false,
            ..flat_rig()
        };
        let r = RowRanges::new(&cam, &p, 0);
        let f = r.focal_px();
        assert!((f - 160.0).abs() < 1e-3);
        let first = r.first_active();
        // Horizon at yn = -tan(15 deg) - margin: about row 90 - 43 - a few (row 35); rows
        // 35-41 could see ground only beyond the 35.4 m range, even 0.5 m up with 2 deg of
        // pitch and roll (their largest disparity below f B / Zmax), so row 42 is the first.
        assert_eq!(first, 42, "first row that can see the square");
        let above = |v: f32| {
            let yn = (v + 0.5 - 90.0) / f;
            let (tm, m) = ((15f32 + 2.0).to_radians(), 2f32.to_radians());
            let s_hi = libm::sinf(tm) + yn * libm::cosf(tm) + libm::sinf(m);
            f * 0.3 * s_hi / 1.5
        };
        let zmax = libm::sqrtf(p.max_ground_range_m * p.max_ground_range_m + 16.0);
        assert!(above(41.0) < f * 0.3 / zmax && above(42.0) >= f * 0.3 / zmax);
        let t = 15f32.to_radians();
        for v in first..180 {
            let (lo, hi) = r.row(v).unwrap();
            let yn = (v as f32 + 0.5 - 90.0) / f;
            let s = libm::sinf(t) + yn * libm::cosf(t);
            let z = 2.0 / s;
            let d = f * 0.3 / z;
            if s > 0.0 && z * libm::cosf(t) < 35.0 {
                assert!(
                    lo as f32 + 1.0 <= d && d <= hi as f32 - 1.0,
                    "{v}: {lo} {d} {hi}"
                );
            }
        }
        // The bottom row: flat ground at ~19 px; relief +0.5 m: 26 px, -2 m: 9.6 px.
        let (lo, hi) = r.row(179).unwrap();
        assert!(
            (6..=9).contains(&lo) && (27..=32).contains(&hi),
            "{lo} {hi}"
        );
        assert!(r.row(0).is_none());
        assert!(r.max_disparities() >= hi - r.row(first).unwrap().0);
        // Rows reduced twice more: half the rows, the same columns and focal length; row
        // `q` covers working rows `2q, 2q + 1`, and the flat ground of both lies inside
        // its range.
        let r2 = RowRanges::new(&cam, &StereoParams { row_factor: 2, ..p }, 0);
        assert_eq!(r2.size(), (320, 90));
        assert_eq!(r2.focal_px(), f);
        let mut rows = 0;
        for q in 0..90 {
            let Some((lo, hi)) = r2.row(q) else {
                assert!(r.row(2 * q + 1).is_none() || r.row(2 * q).is_none(), "{q}");
                continue;
            };
            for v in [2 * q, 2 * q + 1] {
                let yn = (v as f32 + 0.5 - 90.0) / f;
                let s = libm::sinf(t) + yn * libm::cosf(t);
                let z = 2.0 / s;
                if s > 0.0 && z * libm::cosf(t) < 35.0 {
                    let d = f * 0.3 / z;
                    assert!(
                        lo as f32 + 0.5 <= d && d <= hi as f32 - 0.5,
                        "{q} {v}: {lo} {d} {hi}"
                    );
                    rows += 1;
                }
            }
        }
        assert!(rows > 100, "{rows}");
    }

    #[test]
    fn relief_above_grows_with_depth_from_its_near_bound() {
        let cam = CameraParams::default();
        let full = StereoParams {
            relief_above_near_m: f32::INFINITY,
            ..flat_rig()
        };
        let p = StereoParams {
            relief_above_near_m: 0.5,
            relief_above_grade: 0.05,
            ..full
        };
        let (a, b) = (RowRanges::new(&cam, &full, 0), RowRanges::new(&cam, &p, 0));
        let t = 15f32.to_radians();
        let f = a.focal_px();
        let mut narrower = 0;
        for v in 0..180 {
            let (Some((lo_a, hi_a)), Some((lo_b, hi_b))) = (a.row(v), b.row(v)) else {
                assert!(b.row(v).is_none(), "{v}");
                continue;
            };
            // Disparities (the shears may differ by whole pixels: the groups each touches).
            let abs = |r: &RowRanges, d: usize| d as i32 * 256 + r.shear_q8(v);
            let (ga, gb) = (a.shear_q8(v), b.shear_q8(v));
            assert_eq!((ga - gb) % 256, 0, "{v}");
            assert!(
                abs(&a, lo_a) == abs(&b, lo_b) && abs(&b, hi_b) <= abs(&a, hi_a),
                "{v}"
            );
            narrower += usize::from(abs(&b, hi_b) < abs(&a, hi_a));
            // A point on the row's centre ray (level rover) standing the bound's height
            // above the ground at its depth lies inside the range.
            let yn = (v as f32 + 0.5 - 90.0) / f;
            let s = libm::sinf(t) + yn * libm::cosf(t);
            if s <= 0.0 {
                continue;
            }
            // Depth with dz = h - Z s = min(1, 0.5 + 0.05 Z).
            let z = (1.5 / (s + 0.05)).max(1.0 / s);
            // The searched disparities are residuals of the shear.
            let d = f * 0.3 / z - b.shear_q8(v) as f32 / 256.0;
            if z < 35.0 {
                assert!(d <= hi_b as f32 - 1.0 + 1e-3, "{v}: {d} {hi_b}");
            }
        }
        // The near rows (flat ground within 10 m: the bound below 1 m) search fewer.
        assert!(narrower > 60, "{narrower}");
        // Off: a near bound at or above the full one changes nothing.
        let off = StereoParams {
            relief_above_near_m: 1.0,
            relief_above_grade: 0.3,
            ..full
        };
        assert_eq!(RowRanges::new(&cam, &off, 0), a);
    }

    #[test]
    fn horizon_rows_reach_rising_terrain_and_only_them_change() {
        let cam = CameraParams::default();
        let (t, h) = (cam.tilt_deg.to_radians(), cam.height_m);
        // Disparities, not residuals.
        let base = StereoParams {
            ground_shear: false,
            ..flat_rig()
        };
        let hz = StereoParams {
            horizon_grade: 0.3,
            ..base
        };
        let (a, b) = (RowRanges::new(&cam, &base, 0), RowRanges::new(&cam, &hz, 0));
        let f = a.focal_px();
        let zmax = libm::sqrtf(base.max_ground_range_m.powi(2) + (h + 2.0).powi(2));
        let s_of = |v: usize| {
            let yn = (v as f32 + 0.5 - 90.0) / f;
            libm::sinf(t) + yn * libm::cosf(t)
        };
        let (mut new_rows, mut checked) = (0, 0);
        for v in 0..180 {
            let s = s_of(v);
            // `s` over the row and 2 deg of pitch and roll reaches `s + 0.0707` to
            // `s + 0.0715` here (`s_hi`). Rows that can see flat ground within the range:
            // unchanged. Rows near that edge are left out of both checks.
            if s + 0.072 > h / zmax {
                if s + 0.0707 > h / zmax {
                    assert_eq!(a.row(v), b.row(v), "row {v}");
                }
                continue;
            }
            if a.row(v).is_none() && b.row(v).is_some() {
                new_rows += 1;
            }
            // A slope rising 0.25 m per metre from under the rover, seen by the row's centre
            // ray at depth Z (`h - Z s = 0.25 Z`): inside the range when within Zmax.
            let z = h / (s + 0.25);
            if z > 0.0 && z < zmax {
                let d = f * 0.3 / z;
                let (lo, hi) = b
                    .row(v)
                    .expect("a horizon row that sees the slope is searched");
                assert!(
                    lo as f32 + 1.0 <= d + 1e-3 && d <= hi as f32 - 1.0 + 1e-3,
                    "{v}: {d}"
                );
                checked += 1;
            }
            // Nothing nearer than the grade allows (0.5 m + 0.3 Z up): the range ends there.
            if let Some((_, hi)) = b.row(v) {
                let z_near = 1.5 / (s + 0.3 + 0.076);
                assert!(hi as f32 <= f * 0.3 / z_near + 2.0 + 1e-3, "{v}: {hi}");
            }
        }
        // Rows above the flat ground's horizon and those whose flat ground lies beyond the
        // range: at grade 0.3 every row from the image's top (row 0) to row 39 is new.
        assert!(new_rows >= 25, "{new_rows}");
        assert!(checked >= 25, "{checked}");
        assert!(b.first_active() < a.first_active());
        assert!(b.row_work(0, 180) > a.row_work(0, 180));
        // Checked by the rig: a NaN or negative grade is refused.
        for g in [f32::NAN, -0.1, 11.0] {
            let p = StereoParams {
                horizon_grade: g,
                ..base
            };
            assert!(super::super::StereoRig::new(&cam, &p).is_err(), "{g}");
        }
    }

    #[test]
    fn ranges_follow_the_rovers_attitude() {
        let cam = CameraParams::default();
        let p = StereoParams {
            attitude_margin_deg: 0.5,
            ..flat_rig()
        };
        let level = RowRanges::with_rows(&cam, &p, 0, 1, &Attitude::level(cam.tilt_deg));
        let f = level.focal_px();
        // Whether the flat ground under working pixel `(u, v)` of `truth` lies inside row
        // `v`'s range of `r` (with the pixel of widening each side), when it is within the
        // ground range.
        let inside =
            |r: &RowRanges, truth: &Camera, u: usize, v: usize| -> Option<bool> {
                let (xn, yn) = ((u as f32 + 0.5 - 160.0) / f, (v as f32 + 0.5 - 90.0) / f);
                let m = &truth.world_to_cam;
                let s = -(m[(0, 2)] * xn + m[(1, 2)] * yn + m[(2, 2)]);
                if s <= 1e-3 {
                    return None;
                }
                let z = cam.height_m / s;
                if z * libm::sqrtf(1.0 + xn * xn + yn * yn) > 35.0 {
                    return None;
                }
                // The residual of the row's shear.
                let d = f * p.baseline_m / z - r.shear_q8(v) as f32 / 256.0;
                Some(r.row(v).is_some_and(|(lo, hi)| {
                    lo as f32 + 1.0 <= d + 1e-3 && d <= hi as f32 - 1.0 + 1e-3
                }))
            };
        let mut checked = 0;
        let mut level_misses = 0;
        for (pitch, roll) in [(0.0, 0.0), (6.0, 0.0), (0.0, -6.0), (4.0, 5.0), (-8.0, 3.0)] {
            let pose = RoverPose {
                pitch_deg: pitch,
                roll_deg: roll,
                ..RoverPose::level(10.0, -4.0, 1.0, 37.0)
            };
            for view in View::ALL {
                let att = Attitude::of_view(&cam, &pose, view).unwrap();
                let r = RowRanges::with_rows(&cam, &p, 0, 1, &att);
                // The true attitude anywhere within the margin of the given one (a hair
                // inside it: the bound is exact for a level nominal, to fourth order
                // otherwise).
                for (dp, dr) in [
                    (0.0, 0.0),
                    (0.49, 0.49),
                    (-0.49, 0.49),
                    (0.49, -0.49),
                    (-0.49, -0.49),
                ] {
                    let at = RoverPose {
                        pitch_deg: pitch + dp,
                        roll_deg: roll + dr,
                        ..pose
                    };
                    let truth = Camera::new(&cam, &at, view).unwrap();
                    for v in 0..180 {
                        for u in [0, 80, 160, 240, 319] {
                            if let Some(ok) = inside(&r, &truth, u, v) {
                                assert!(
                                    ok,
                                    "pitch {pitch} roll {roll} {view:?} +({dp}, {dr}): ({u}, {v})"
                                );
                                checked += 1;
                                level_misses +=
                                    usize::from(inside(&level, &truth, u, v) == Some(false));
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 20_000, "{checked}");
        // The level rover's ranges miss the ground of a tilted one: the rig must follow
        // the attitude.
        assert!(level_misses > 1_000, "{level_misses}");
    }

    #[test]
    fn windows_follow_the_flat_ground() {
        let cam = CameraParams::default();
        let on = flat_rig();
        assert!(on.ground_shear);
        let off = StereoParams {
            ground_shear: false,
            ..on
        };
        for (level, rows) in [(0u8, 1u32), (0, 2), (1, 2), (2, 2)] {
            let att = Attitude::level(cam.tilt_deg);
            let a = RowRanges::with_rows(&cam, &on, level, rows, &att);
            let b = RowRanges::with_rows(&cam, &off, level, rows, &att);
            let (w, h) = a.size();
            let (f, fr) = (a.focal_px(), a.focal_rows);
            let t = cam.tilt_deg.to_radians();
            // The level's rows: the flat ground's disparity grows by f B cos t / (h fr)
            // pixels per row, and the shear by the same (Q8).
            let slope = f * on.baseline_m * libm::cosf(t) / (cam.height_m * fr);
            let g = |v: usize| a.shear_q8(v) as f32 / 256.0;
            assert!(
                ((g(h - 1) - g(0)) / (h - 1) as f32 - slope).abs() < 0.01,
                "level {level} x{rows}"
            );
            assert_eq!(b.shear_q8(h - 1), 0);
            // The largest disparity searched is a disparity, not a residual.
            assert!(
                a.global_max().abs_diff(b.global_max()) <= 1,
                "level {level} x{rows}"
            );
            let mut residuals = [f32::INFINITY, f32::NEG_INFINITY];
            let mut checked = 0;
            for v in 0..h {
                let (Some((lo, hi)), Some(_)) = (a.row(v), b.row(v)) else {
                    assert!(a.row(v).is_none() && b.row(v).is_none(), "{v}");
                    continue;
                };
                // Each residual range holds the row's disparities less its shear, with the
                // widening pixel each side, and within the columns.
                let (d0, d1) = a.span(v).unwrap();
                assert_eq!(b.span(v), Some((d0, d1)));
                let (d0, d1) = (d0 - g(v), d1 - g(v));
                assert!(
                    lo as f32 + 1.0 <= d0 + 1e-3 && d1 <= hi as f32 - 1.0 + 1e-3,
                    "level {level} x{rows} row {v}: {lo}..{hi} vs {d0}..{d1}"
                );
                assert!(hi <= w - 2 * usize::from(on.radius_px) - 2 || hi == lo + 2);
                // The flat ground's residual is one value down the image.
                let yn = (v as f32 + 0.5 - a.cy) / fr;
                let s = libm::sinf(t) + yn * libm::cosf(t);
                if s > 0.0 {
                    let r = f * on.baseline_m * s / cam.height_m - g(v);
                    residuals = [residuals[0].min(r), residuals[1].max(r)];
                    checked += 1;
                }
            }
            assert!(checked > 10, "level {level} x{rows}: {checked}");
            let spread = residuals[1] - residuals[0];
            assert!(spread < 0.05, "level {level} x{rows}: {residuals:?}");
        }
    }
}
