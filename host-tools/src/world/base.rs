//! The sums before features: the noise relief and the regolith albedo (plus the mean of the
//! boulders a footprint filter takes by their mean), at a point or along a row of pixels, and
//! the accumulators that start from them.

use super::footprint::{Acc, Filter};
use super::World;

impl World {
    /// The sum before features: noise relief and regolith albedo.
    #[inline]
    pub(super) fn base<'f>(
        &self,
        x: f64,
        y: f64,
        relief: bool,
        want_a: bool,
        filt: &'f Filter,
    ) -> Acc<'f> {
        let mut a = 0.0;
        if want_a {
            a = self.cfg.albedo_mean + self.albedo_regional.at(x, y) + self.albedo_fine.at(x, y);
            if filt.rock_mean > 0.0 {
                a += filt.rock_mean;
            }
        }
        Acc {
            h: if relief { self.relief.at(x, y) } else { 0.0 },
            a,
            relief,
            want_a,
            boost: self.cfg.fresh_crater_albedo_boost,
            filt,
        }
    }

    /// [`World::base`] (relief per the configuration, albedo wanted) at `(xs[i], y)`, bit for
    /// bit: heights into `h`, albedo into `a` (`tmp`: scratch as long as `xs`).
    pub(super) fn base_row(
        &self,
        xs: &[f64],
        y: f64,
        filt: &Filter,
        h: &mut [f64],
        a: &mut [f64],
        tmp: &mut [f64],
    ) {
        if self.cfg.relief {
            self.relief.row(xs, y, h);
        } else {
            h.fill(0.0);
        }
        self.albedo_regional.row(xs, y, a);
        self.albedo_fine.row(xs, y, tmp);
        let mean = self.cfg.albedo_mean;
        for (a, &f) in a.iter_mut().zip(tmp.iter()) {
            *a = mean + *a + f;
        }
        if filt.rock_mean > 0.0 {
            for a in a.iter_mut() {
                *a += filt.rock_mean;
            }
        }
    }

    /// An accumulator starting from precomputed base sums (see [`World::base_row`]).
    #[inline]
    pub(super) fn acc_from<'f>(&self, h: f64, a: f64, filt: &'f Filter) -> Acc<'f> {
        Acc {
            h,
            a,
            relief: self.cfg.relief,
            want_a: true,
            boost: self.cfg.fresh_crater_albedo_boost,
            filt,
        }
    }
}

/// The sums before features ([`World::base_row`]) of pixels `(c, r)` at `(r - r0) * stride +
/// c - c0`.
#[derive(Clone, Copy)]
pub(super) struct Base<'a> {
    pub(super) h: &'a [f64],
    pub(super) a: &'a [f64],
    pub(super) stride: usize,
    pub(super) c0: usize,
    pub(super) r0: usize,
}
