//! Height and albedo at a point: [`World::height_m`], [`World::albedo`], [`World::sample`],
//! [`World::albedo_filtered`], and the evaluation they share (the sums before features, then
//! every feature that reaches the point, in the one fixed order).

use super::footprint::Filter;
use super::World;

impl World {
    /// Terrain elevation at `(x, y)` metres, in metres. 0 for non-finite input.
    pub fn height_m(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y, true, false, &Filter::POINT).0
    }

    /// Normal albedo at `(x, y)` metres, in `0..=1`. `albedo_mean` for non-finite input.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y, false, true, &Filter::POINT).1
    }

    /// `(height_m, albedo)` at `(x, y)` metres: both for about the price of one.
    pub fn sample(&self, x: f64, y: f64) -> (f64, f64) {
        self.eval(x, y, true, true, &Filter::POINT)
    }

    /// Albedo (normal albedo, 0..1) averaged over the `footprint_m`-wide square centred at
    /// `(x, y)` metres, as [`World::sample_grid_filtered`]; [`World::albedo`] for
    /// `footprint_m <= 0`.
    pub fn albedo_filtered(&self, x: f64, y: f64, footprint_m: f64) -> f64 {
        let filt = Filter::new(self, footprint_m);
        self.eval(x, y, false, true, &filt).1
    }

    #[inline]
    pub(super) fn eval(
        &self,
        x: f64,
        y: f64,
        want_h: bool,
        want_a: bool,
        filt: &Filter,
    ) -> (f64, f64) {
        if let Some(d) = &self.dem {
            return d.sample(x, y, filt.fp);
        }
        if !(x.is_finite() && y.is_finite()) {
            return (0.0, self.cfg.albedo_mean);
        }
        let relief = want_h && self.cfg.relief;
        if !relief && !want_a {
            return (0.0, 0.0);
        }
        let mut acc = self.base(x, y, relief, want_a, filt);
        self.features(filt.grown([x, y, x, y]), !relief, filt, |f| {
            acc.add(f, x, y);
        });
        acc.finish()
    }
}
