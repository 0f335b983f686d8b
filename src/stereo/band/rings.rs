//! The row rings of a band: the reduced and the filtered rows of both images at one level,
//! made on demand and kept while the window needs them.

use crate::image::ImageView;

use super::RING_MAX;

/// Which rows the row rings hold (`row + 1`, 0: none).
#[derive(Clone, Copy, Debug)]
pub(super) struct RingTags {
    pub(super) ds: [usize; 3],
    pub(super) f: [usize; RING_MAX],
}

impl RingTags {
    pub(super) const EMPTY: Self = Self {
        ds: [0; 3],
        f: [0; RING_MAX],
    };
}

/// Row rings of both images at one level: reduced rows (3) and filtered rows (`2r + 2`).
pub(super) struct Rings<'b> {
    pub(super) ds: [&'b mut [u8]; 2],
    pub(super) filt: [&'b mut [u8]; 2],
    pub(super) tags: &'b mut RingTags,
    pub(super) w: usize,
    pub(super) h: usize,
    /// Reduction of the frames across and down.
    pub(super) k: (usize, usize),
    pub(super) ring: usize,
    pub(super) cap: u8,
    /// The ground shear's terms ([`super::super::shear::shear_at`]).
    pub(super) shear: (i32, i32),
}

impl<'b> Rings<'b> {
    /// The rings of a level of width `w` (level image height `h`, frames reduced by `k`
    /// across and down, `ring = 2 rv + 2` filtered rows) in `bytes` ([`super::bytes_len`] of the
    /// working width bounds every level's).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        bytes: &'b mut [u8],
        tags: &'b mut RingTags,
        w: usize,
        h: usize,
        k: (usize, usize),
        ring: usize,
        cap: u8,
        shear: (i32, i32),
    ) -> Self {
        // Lengths were checked by the caller; `min` keeps the splits free of panic paths.
        let (ds_l, rest) = bytes.split_at_mut((3 * w).min(bytes.len()));
        let (ds_r, rest) = rest.split_at_mut((3 * w).min(rest.len()));
        let (f_l, rest) = rest.split_at_mut((ring * w).min(rest.len()));
        let (f_r, _) = rest.split_at_mut((ring * w).min(rest.len()));
        Self {
            ds: [ds_l, ds_r],
            filt: [f_l, f_r],
            tags,
            w,
            h,
            k,
            ring,
            cap,
            shear,
        }
    }

    fn ensure_ds(&mut self, frames: [&ImageView<'_>; 2], q: usize) {
        let slot = q % 3;
        if self.tags.ds.get(slot) == Some(&(q + 1)) {
            return;
        }
        let w = self.w;
        for (buf, fr) in self.ds.iter_mut().zip(frames) {
            if let Some(o) = buf.get_mut(slot * w..slot * w + w) {
                super::super::downsample_row_by(fr, self.k.0, self.k.1, q, o);
            }
        }
        if let Some(t) = self.tags.ds.get_mut(slot) {
            *t = q + 1;
        }
    }

    /// Makes filtered row `k` (clamped to the image) present; returns its ring slot.
    pub(super) fn ensure(&mut self, frames: [&ImageView<'_>; 2], k: isize) -> usize {
        let last = self.h - 1;
        let k = (k.max(0) as usize).min(last);
        // `checked_rem`: no division-by-zero panic path in the flight build (ring >= 4).
        let slot = k.checked_rem(self.ring).unwrap_or(0);
        if self.tags.f.get(slot) == Some(&(k + 1)) {
            return slot;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(last));
        self.ensure_ds(frames, a);
        self.ensure_ds(frames, k);
        self.ensure_ds(frames, b);
        let w = self.w;
        for (i, (ds, f)) in self.ds.iter().zip(self.filt.iter_mut()).enumerate() {
            let row = |q: usize| ds.get((q % 3) * w..(q % 3) * w + w).unwrap_or(&[]);
            if let Some(o) = f.get_mut(slot * w..slot * w + w) {
                super::super::prefilter(row(a), row(k), row(b), self.cap, o);
                if i == 1 {
                    // The right image follows the ground down the window.
                    super::super::shear_row(o, super::super::shear::shear_at(self.shear, k));
                }
            }
        }
        if let Some(t) = self.tags.f.get_mut(slot) {
            *t = k + 1;
        }
        slot
    }

    pub(super) fn rows(&self, slot: usize) -> (&[u8], &[u8]) {
        let (a, b) = (slot * self.w, slot * self.w + self.w);
        let [l, r] = &self.filt;
        (l.get(a..b).unwrap_or(&[]), r.get(a..b).unwrap_or(&[]))
    }
}
