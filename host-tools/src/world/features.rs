//! The craters and boulders of a rectangle: listed for statistics and overlays
//! ([`World::craters_in`], [`World::rocks_in`], [`World::visit_boulders`]), and visited in the
//! one fixed order in which their contributions are summed.

use super::footprint::{Feature, Filter};
use super::grid::check_rect;
use super::{Crater, Rock, World, WorldError};

impl World {
    /// Every crater whose centre lies in `[x0, x1) x [y0, y1)` (metres) with diameter at
    /// least `d_min_m`, for statistics and overlays. The rectangle may span at most 10^8
    /// cells of the smallest wanted class.
    pub fn craters_in(
        &self,
        x0: f64,
        y0: f64,
        x1: f64,
        y1: f64,
        d_min_m: f64,
    ) -> Result<Vec<Crater>, WorldError> {
        let cell = self.cfg.ejecta_extent_radii * d_min_m.max(self.cfg.crater_d_min_m);
        check_rect(x0, y0, x1, y1, cell)?;
        if self.dem.is_some() {
            return Ok(Vec::new());
        }
        Ok(self.craters.in_rect(x0, y0, x1, y1, d_min_m))
    }

    /// Every background boulder (not those of fresh craters) whose centre lies in
    /// `[x0, x1) x [y0, y1)` metres. The rectangle may span at most 10^8 cells of the
    /// smallest class.
    pub fn rocks_in(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Result<Vec<Rock>, WorldError> {
        check_rect(x0, y0, x1, y1, 2.0 * self.cfg.rock_d_min_m)?;
        if self.dem.is_some() {
            return Ok(Vec::new());
        }
        Ok(self.rocks.in_rect(x0, y0, x1, y1))
    }

    /// Calls `f` for every boulder, background or of a fresh crater, whose footprint
    /// reaches into `rect` (`[x0, y0, x1, y1]` metres): the rocks of the height field, e.g.
    /// for the renderer to draw the near ones finer than its mesh. Nothing for a DEM site.
    pub fn visit_boulders(&self, rect: [f64; 4], mut f: impl FnMut(&Rock)) {
        if self.dem.is_some() || !self.cfg.relief {
            return;
        }
        self.features(rect, false, &Filter::POINT, |feat| {
            if let Feature::Rock(r) = feat {
                f(r);
            }
        });
    }

    /// The distance (metres) beyond which no crater reaches: the largest crater's ejecta.
    pub fn max_feature_reach_m(&self) -> f64 {
        self.craters.max_reach()
    }

    /// Calls `f` for every crater and boulder that reaches into `rect` (`[x0, y0, x1, y1]`
    /// metres), in the one fixed order in which their contributions are summed.
    /// With a footprint filter, `rect` must already be grown by half the footprint, and
    /// boulder classes below `filt.first_rock_class` are skipped (they enter by their mean).
    #[inline]
    pub(super) fn features(
        &self,
        rect: [f64; 4],
        fresh_only: bool,
        filt: &Filter,
        mut f: impl FnMut(Feature<'_>),
    ) {
        let rocks = &self.rocks;
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        rocks.visit_rect_from(rect, k0, grow, |r| f(Feature::Rock(r)));
        self.craters.visit_rect(rect, fresh_only, |c| {
            f(Feature::Crater(c, None));
            if rocks.crater_has_rocks(c) {
                rocks.visit_crater_rect_from(c, rect, k0, grow, |r| f(Feature::Rock(r)));
            }
        });
    }
}
