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
//! Level `L` takes whole coarse rows: coarse row `q` covers working rows `q 2^L ..
//! (q + 1) 2^L`, and its output is expanded onto them (each working pixel takes the value of
//! the coarse pixel it lies in, disparities scaled to working-size pixels). Level `L` covers
//! the working rows from `start[L]` (a multiple of `2^L`, the first coarse row from which
//! every coarse row down to the last whole one is eligible) to the last whole coarse row; a
//! row takes the coarsest level that covers it. Set-up math (`f32`, once per rig).

use super::geometry::RowRanges;
use super::StereoParams;
use crate::camera::CameraParams;

/// Matching levels a rig can have: the working size and two coarser scales (2x, 4x).
pub const LEVELS: usize = 3;

/// The per-row matching levels of one rig, with each level's disparity ranges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    geo: [RowRanges; LEVELS],
    /// Levels in use (1..=LEVELS): levels `used..` are never chosen.
    used: usize,
    /// First working row of each level (`height` when the level has no rows).
    start: [usize; LEVELS],
    /// One past the last working row of each level.
    end: [usize; LEVELS],
    /// First working row that is matched (sees ground at its level), `height` if none.
    first: usize,
    /// First row of each level's image that sees ground (that level's rows).
    first_of: [usize; LEVELS],
    /// Working height, rows.
    height: usize,
}

impl Scales {
    /// The levels of `camera` and `params` (`params` checked by the caller); `usable(l)`
    /// says whether level `l` can be matched at all (image large enough for the window and
    /// its disparities).
    pub(crate) fn new(
        camera: &CameraParams,
        params: &StereoParams,
        usable: impl Fn(&RowRanges) -> bool,
    ) -> Self {
        let geo: [RowRanges; LEVELS] = [0u8, 1, 2].map(|l| RowRanges::new(camera, params, l));
        let height = geo[0].size().1;
        let mut start = [height; LEVELS];
        let mut end = [height; LEVELS];
        start[0] = 0;
        let mut used = 1;
        let wanted = usize::from(params.scale_levels).min(LEVELS - 1);
        for (l, g) in geo.iter().enumerate().take(wanted + 1).skip(1) {
            if !usable(g) {
                break;
            }
            let h_l = g.size().1;
            // Coarse rows from the bottom up while eligible.
            let mut q0 = h_l;
            while q0 > 0 {
                let q = q0 - 1;
                let ok = g.row(q).is_some()
                    && g.quarter_px_depth_error(q, camera.tilt_deg)
                        .is_some_and(|e| e <= params.scale_error_m);
                if !ok {
                    break;
                }
                q0 = q;
            }
            if let (Some(s), Some(e)) = (start.get_mut(l), end.get_mut(l)) {
                *s = (q0 << l).min(height);
                *e = (h_l << l).min(height);
            }
            used = l + 1;
        }
        let mut me = Self {
            geo,
            used,
            start,
            end,
            first: height,
            first_of: geo.map(|g| g.first_active()),
            height,
        };
        me.first = (0..height)
            .find(|&y| {
                let l = me.level_of_row(y);
                me.level(l).row(y >> l).is_some()
            })
            .unwrap_or(height);
        me
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

    /// The level working row `y` is matched at.
    pub fn level_of_row(&self, y: usize) -> usize {
        (1..self.used)
            .rev()
            .find(|&l| {
                matches!((self.start.get(l), self.end.get(l)), (Some(&s), Some(&e)) if s <= y && y < e)
            })
            .unwrap_or(0)
    }

    /// First working row of level `l` and one past its last (`(height, height)` when the
    /// level has no rows; level 0 spans the image).
    pub fn rows_of_level(&self, l: usize) -> (usize, usize) {
        match (self.start.get(l), self.end.get(l)) {
            (Some(&s), Some(&e)) if l < self.used && s < e => (s, e),
            _ => (self.height, self.height),
        }
    }

    /// The first working row that is matched (rows above only see sky); the height if none.
    pub fn first_active(&self) -> usize {
        self.first
    }

    /// The first row of level `l`'s image (its own rows) that sees ground.
    pub fn first_active_of(&self, l: usize) -> usize {
        self.first_of.get(l).copied().unwrap_or(0)
    }

    /// The largest number of disparities of any band at any level in use.
    pub fn max_disparities(&self) -> usize {
        self.geo
            .iter()
            .take(self.used)
            .map(RowRanges::max_disparities)
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
            let q = y >> l;
            sum += self.level(l).row_work(q, q + 1);
            y = (q + 1) << l;
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_rows_go_coarse_only_where_a_quarter_pixel_stays_below_the_limit() {
        let cam = CameraParams::default();
        let p = StereoParams::default();
        let s = Scales::new(&cam, &p, |_| true);
        assert!(s.used() >= 2, "the default rig uses a coarser level");
        let (a, b) = s.rows_of_level(1);
        assert!(a < b && b == 180 && a % 2 == 0, "{a} {b}");
        // Every working row of level 1 has its quarter-pixel error (level 1) within the
        // limit; the row just above it does not.
        let g1 = s.level(1);
        for y in a..b {
            assert_eq!(s.level_of_row(y), 1);
            let e = g1.quarter_px_depth_error(y >> 1, cam.tilt_deg).unwrap();
            assert!(e <= p.scale_error_m, "{y} {e}");
        }
        let e_above = g1
            .quarter_px_depth_error((a >> 1) - 1, cam.tilt_deg)
            .unwrap();
        assert!(e_above > p.scale_error_m, "{e_above}");
        // Rows above stay at the working size; the first matched row is level 0's.
        assert_eq!(s.level_of_row(a - 1), 0);
        assert_eq!(s.first_active(), s.level(0).first_active());
        // At level 0 a quarter pixel stays within the same limit further out than at
        // level 1 (the far rows keep the finer scale).
        let e0 = s
            .level(0)
            .quarter_px_depth_error(a - 1, cam.tilt_deg)
            .unwrap();
        assert!(e0 < e_above / 1.9, "{e0} {e_above}");
        // Less work than matching every row at the working size.
        let one = Scales::new(
            &cam,
            &StereoParams {
                scale_levels: 0,
                ..p
            },
            |_| true,
        );
        assert_eq!(one.used(), 1);
        assert_eq!(one.rows_of_level(1), (180, 180));
        assert!(s.row_work(0, 180) < one.row_work(0, 180) * 3 / 4);
        assert_eq!(one.row_work(0, 180), one.level(0).row_work(0, 180));
    }

    #[test]
    fn a_looser_limit_uses_the_coarsest_level_for_the_nearest_rows() {
        let cam = CameraParams::default();
        let p = StereoParams {
            scale_levels: 2,
            scale_error_m: 0.3,
            ..StereoParams::default()
        };
        let s = Scales::new(&cam, &p, |_| true);
        assert_eq!(s.used(), 3);
        let (a1, b1) = s.rows_of_level(1);
        let (a2, b2) = s.rows_of_level(2);
        assert!(
            a1 < a2 && a2 < b2 && b2 == 180 && a2 % 4 == 0,
            "{a1} {a2} {b2}"
        );
        assert_eq!(b1, 180);
        assert_eq!(s.level_of_row(a2), 2);
        assert_eq!(s.level_of_row(a2 - 1), 1);
        assert_eq!(s.level_of_row(a1 - 1), 0);
        // A level that cannot be matched is not used, nor any coarser one.
        let t = Scales::new(&cam, &p, |g| g.size().0 >= 160);
        assert_eq!(t.used(), 2);
        assert_eq!(t.rows_of_level(2), (180, 180));
    }
}
