//! The fast gray mapping ([`GrayMap`]): linear radiance to gray level by a table.

/// Fast gray mapping: `255 * clamp(r, 0, 1) ^ (1 / gamma)` by a table over `sqrt(r)`
/// (4096 steps, linear interpolation; within 0.05 gray levels of [`RenderOptions::gray`]).
///
/// [`RenderOptions::gray`]: super::RenderOptions::gray
#[derive(Clone, Debug)]
pub struct GrayMap {
    table: Vec<f32>,
}

impl GrayMap {
    const N: usize = 4096;

    /// The table for `gamma`.
    pub fn new(gamma: f64) -> Self {
        let table = (0..=Self::N + 1)
            .map(|i| {
                let t = (i as f64 / Self::N as f64).min(1.0);
                (255.0 * (t * t).powf(1.0 / gamma)) as f32
            })
            .collect();
        Self { table }
    }

    /// Gray level (0..255, not rounded) of a linear radiance.
    #[inline]
    pub fn gray(&self, radiance: f64) -> f32 {
        self.gray_at(Self::position(radiance))
    }

    /// Table position (0..=4096) of a linear radiance: the first step of [`Self::gray`],
    /// free of lookups (vectorizes).
    #[inline(always)]
    pub(crate) fn position(radiance: f64) -> f64 {
        radiance.clamp(0.0, 1.0).sqrt() * Self::N as f64
    }

    /// Gray level at table position `t` from [`Self::position`]: the rest of [`Self::gray`].
    #[inline(always)]
    pub(crate) fn gray_at(&self, t: f64) -> f32 {
        let i = (t as usize).min(Self::N);
        let f = (t - i as f64) as f32;
        self.table[i] * (1.0 - f) + self.table[i + 1] * f
    }
}
