//! Impact craters: a power-law size-frequency distribution placed per grid cell per size
//! class, with bowl, raised rim, ejecta blanket, degradation state and bright rays.
//!
//! Size classes are octaves of diameter `[d, 2d)` (the last one cut at `crater_d_max_m`). A
//! class's grid cells are `ejecta_extent_radii * d_max_class` wide, so a crater influences
//! at most the 2 x 2 cells around a query point, and with the default exponent 2 every class
//! has the same expected count per cell. The count per cell is a Poisson draw from the hashed
//! cell, so the field is a pure function of `(seed, x, y)`.

mod field;

pub(crate) use field::{octave_bins, poisson_cdf, poisson_draw, CraterField, PowerLaw};

use super::hash::{mix64, Rng};
use serde::{Deserialize, Serialize};

/// Number of bright rays of a fresh crater.
pub const RAYS: usize = 5;

/// Degradation state of a crater.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Degradation {
    /// Sharp rim, full depth (~0.2 D), bright halo and rays, boulders around it.
    Fresh,
    /// Softened rim, shallower bowl.
    Mature,
    /// Nearly filled, rounded depression.
    Old,
}

/// One crater, as placed by the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crater {
    /// Centre, world east, metres.
    pub x_m: f64,
    /// Centre, world north, metres.
    pub y_m: f64,
    /// Rim-to-rim diameter, metres.
    pub diameter_m: f64,
    /// Depth of the bowl floor below the surrounding surface, metres (positive).
    pub depth_m: f64,
    /// Height of the rim crest above the surrounding surface before smoothing, metres.
    pub rim_m: f64,
    /// Width of the smooth-minimum that rounds the rim, metres (grows with degradation).
    pub smoothing_m: f64,
    /// Degradation, 0 (pristine) to 1 (nearly erased).
    pub degradation: f64,
    /// Degradation state (from `degradation` and the configured fractions).
    pub state: Degradation,
    /// Brightness of the fresh halo and rays, 0..1 (0 unless `Fresh`).
    pub freshness: f64,
    /// Outer edge of the ejecta blanket, in radii.
    pub ejecta_extent_radii: f64,
    /// Hash identifying the crater (seeds its rays and boulders).
    pub id: u64,
}

impl Crater {
    /// Radius, metres.
    pub fn radius_m(&self) -> f64 {
        0.5 * self.diameter_m
    }

    /// Height change (metres) at offset `(dx, dy)` metres from the centre, given
    /// `r2 = dx^2 + dy^2`. Zero beyond the ejecta blanket.
    #[inline]
    pub fn height_at(&self, r2: f64) -> f64 {
        let r = self.radius_m();
        let rho2 = r2 / (r * r);
        let e = self.ejecta_extent_radii;
        if rho2 >= e * e {
            return 0.0;
        }
        // Parabolic bowl from -depth at the centre to +rim at the rim (continued outside).
        let bowl = -self.depth_m + (self.depth_m + self.rim_m) * rho2;
        // Ejecta: rim * (rho^-3 - e^-3) / (1 - e^-3), capped inside the bowl where it only
        // has to stay above the bowl for the minimum below.
        let rc2 = if rho2 > 0.25 { rho2 } else { 0.25 };
        let inv3 = 1.0 / (rc2 * rc2.sqrt());
        let e3 = 1.0 / (e * e * e);
        let ejecta = self.rim_m * (inv3 - e3) / (1.0 - e3);
        smooth_min(bowl, ejecta, self.smoothing_m)
    }

    /// Albedo change at offset `(dx, dy)` metres, `r2 = dx^2 + dy^2` (fresh craters only:
    /// bright floor, halo and rays).
    #[inline]
    pub fn albedo_at(&self, dx: f64, dy: f64, r2: f64, boost: f64) -> f64 {
        if self.freshness <= 0.0 {
            return 0.0;
        }
        let r = self.radius_m();
        let rho2 = r2 / (r * r);
        let e = self.ejecta_extent_radii;
        if rho2 >= e * e {
            return 0.0;
        }
        let b = boost * self.freshness;
        if rho2 < 1.0 {
            return 0.7 * b;
        }
        let rho = rho2.sqrt();
        // Halo decaying like the ejecta, plus rays fading linearly to the blanket's edge.
        let halo = 1.0 / (rho2 * rho);
        let fade = (e - rho) / (e - 1.0);
        let inv_r = 1.0 / (rho * r);
        let (ux, uy) = (dx * inv_r, dy * inv_r);
        let mut ray: f64 = 0.0;
        for (k, (vx, vy)) in ray_directions(self.id).into_iter().enumerate() {
            let c = ux * vx + uy * vy;
            if c > 0.0 {
                // cos^32 (about +-12 deg wide), weights vary per ray.
                let mut p = c * c;
                p *= p;
                p *= p;
                p *= p;
                p *= p;
                let w = 0.6 + 0.1 * k as f64;
                if p * w > ray {
                    ray = p * w;
                }
            }
        }
        b * fade * (0.6 * halo + 0.8 * ray)
    }
}

impl Crater {
    /// Albedo change averaged over the `footprint_m` x `footprint_m` square centred at
    /// offset `(dx, dy)` metres from the centre (fresh craters only), analytically: the
    /// bright floor's edge is a linear ramp one footprint wide (area-weighted where the
    /// footprint straddles the rim), and each ray lobe (`cos^32`, a Gaussian of angular
    /// variance 1/32) is widened by the footprint's angular width `w = footprint / r` seen
    /// from the centre (variance + `w^2 / 12`, the box's) at equal integral, so a ray
    /// narrower than a pixel adds its area-weighted brightness instead of all or nothing.
    /// The halo (`rho^-3`) is smooth and taken at the footprint centre. `footprint_m <= 0`:
    /// the point value [`Crater::albedo_at`].
    // Not inlined: it is called for few (fresh) craters, and inlining it into the per-feature
    // sum bloats that hot function's frame for every boulder and crater.
    pub fn albedo_filtered(&self, dx: f64, dy: f64, boost: f64, footprint_m: f64) -> f64 {
        self.albedo_filtered_with(dx, dy, boost, footprint_m, None)
    }

    /// The directions of this crater's rays (what [`Crater::albedo_filtered`] draws from
    /// its id each time), to pass to it when it is evaluated at many points.
    pub(crate) fn rays(&self) -> Rays {
        ray_directions(self.id)
    }

    /// [`Crater::albedo_filtered`] with the crater's [`Crater::rays`] given (or drawn when
    /// `None`): the same value.
    #[inline(never)]
    pub(crate) fn albedo_filtered_with(
        &self,
        dx: f64,
        dy: f64,
        boost: f64,
        footprint_m: f64,
        rays: Option<&Rays>,
    ) -> f64 {
        let r2 = dx * dx + dy * dy;
        if self.freshness <= 0.0 {
            return 0.0;
        }
        if footprint_m.is_nan() || footprint_m <= 0.0 {
            return self.albedo_at(dx, dy, r2, boost);
        }
        let rc = self.radius_m();
        let e = self.ejecta_extent_radii;
        let r = r2.sqrt();
        let b = boost * self.freshness;
        // Fraction of the footprint inside the rim (the floor, 0.7 b).
        let t_floor = (0.5 + (rc - r) / footprint_m).clamp(0.0, 1.0);
        if t_floor >= 1.0 {
            return 0.7 * b;
        }
        // Outside the rim: halo and rays at rho >= 1, fading to 0 at the blanket's edge.
        let rho = (r / rc).max(1.0);
        if rho >= e {
            return t_floor * 0.7 * b;
        }
        let halo = 1.0 / (rho * rho * rho);
        let fade = (e - rho) / (e - 1.0);
        let (ux, uy) = if r > 1e-12 {
            (dx / r, dy / r)
        } else {
            (1.0, 0.0)
        };
        let w = footprint_m / (rho * rc);
        let var = 1.0 / 32.0 + w * w / 12.0;
        let amp = (1.0 / (32.0 * var)).sqrt();
        let inv_var = 1.0 / var;
        // The brightest ray, `max_k w_k exp(-q_k)`, found on the logarithms: one `exp`.
        let mut best = f64::NEG_INFINITY;
        let dirs = match rays {
            Some(r) => *r,
            None => ray_directions(self.id),
        };
        for (k, (vx, vy)) in dirs.into_iter().enumerate() {
            let c = ux * vx + uy * vy;
            if c > 0.0 {
                let l = LN_RAY_WEIGHT[k] - (1.0 - c) * inv_var;
                if l > best {
                    best = l;
                }
            }
        }
        let ray = if best > -30.0 {
            amp * libm::exp(best)
        } else {
            0.0
        };
        t_floor * 0.7 * b + (1.0 - t_floor) * b * fade * (0.6 * halo + 0.8 * ray)
    }
}

impl Crater {
    /// For pixel centres `xs` on the row `y`: `h[i] += height_at(r2)` where the pixel lies
    /// inside the ejecta blanket (`r2 < (extent * radius)^2`), exactly as a footprint-filtered
    /// sum adds the height of a crater that is not fresh (its only term), four pixels at a
    /// time where the CPU has AVX2 (the same operations per pixel).
    pub(crate) fn add_heights(&self, xs: &[f64], y: f64, h: &mut [f64]) {
        let n = xs.len().min(h.len());
        let mut i = 0;
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            while i + 4 <= n {
                // Safety: AVX2 is present (checked above); i + 4 <= n.
                unsafe { simd::add_heights4(self, &xs[i..i + 4], y, &mut h[i..i + 4]) };
                i += 4;
            }
        }
        let em = self.ejecta_extent_radii * self.radius_m();
        for k in i..n {
            let (dx, dy) = (xs[k] - self.x_m, y - self.y_m);
            let r2 = dx * dx + dy * dy;
            if r2 < em * em {
                h[k] += self.height_at(r2);
            }
        }
    }
}

/// [`Crater::add_heights`] four pixels at a time with AVX2: [`Crater::height_at`]'s operations
/// lane by lane, selects for its branches.
#[cfg(target_arch = "x86_64")]
mod simd {
    use super::Crater;
    use core::arch::x86_64::*;

    #[target_feature(enable = "avx2")]
    pub(super) fn add_heights4(c: &Crater, xs: &[f64], y: f64, h: &mut [f64]) {
        assert!(xs.len() >= 4 && h.len() >= 4);
        // Safety: 4 elements each (asserted).
        let (x, h0) = unsafe { (_mm256_loadu_pd(xs.as_ptr()), _mm256_loadu_pd(h.as_ptr())) };
        let set = _mm256_set1_pd;
        let dx = _mm256_sub_pd(x, set(c.x_m));
        let dy = set(y - c.y_m);
        let r2 = _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy));
        let em = c.ejecta_extent_radii * c.radius_m();
        let inside = _mm256_cmp_pd::<_CMP_LT_OQ>(r2, set(em * em));
        if _mm256_movemask_pd(inside) == 0 {
            return;
        }
        // height_at(r2)
        let r = c.radius_m();
        let rho2 = _mm256_div_pd(r2, set(r * r));
        let e = c.ejecta_extent_radii;
        let beyond = _mm256_cmp_pd::<_CMP_GE_OQ>(rho2, set(e * e));
        let bowl = _mm256_add_pd(
            set(-c.depth_m),
            _mm256_mul_pd(set(c.depth_m + c.rim_m), rho2),
        );
        let rc2 = _mm256_blendv_pd(
            set(0.25),
            rho2,
            _mm256_cmp_pd::<_CMP_GT_OQ>(rho2, set(0.25)),
        );
        let inv3 = _mm256_div_pd(set(1.0), _mm256_mul_pd(rc2, _mm256_sqrt_pd(rc2)));
        let e3 = 1.0 / (e * e * e);
        let ejecta = _mm256_div_pd(
            _mm256_mul_pd(set(c.rim_m), _mm256_sub_pd(inv3, set(e3))),
            set(1.0 - e3),
        );
        // smooth_min(bowl, ejecta, smoothing)
        let (a, b, k) = (bowl, ejecta, c.smoothing_m);
        let m = _mm256_blendv_pd(b, a, _mm256_cmp_pd::<_CMP_LT_OQ>(a, b));
        let sm = if k <= 0.0 {
            m
        } else {
            let d = _mm256_andnot_pd(set(-0.0), _mm256_sub_pd(a, b));
            let far = _mm256_cmp_pd::<_CMP_GE_OQ>(d, set(k));
            let hh = _mm256_div_pd(_mm256_sub_pd(set(k), d), set(k));
            let soft = _mm256_sub_pd(
                m,
                _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(hh, hh), set(k)), set(0.25)),
            );
            _mm256_blendv_pd(soft, m, far)
        };
        let val = _mm256_blendv_pd(sm, set(0.0), beyond);
        let out = _mm256_blendv_pd(h0, _mm256_add_pd(h0, val), inside);
        // Safety: 4 elements (asserted).
        unsafe { _mm256_storeu_pd(h.as_mut_ptr(), out) };
    }
}

/// `ln(0.6 + 0.1 k)`: the logarithms of the rays' weights in [`Crater::albedo_at`].
const LN_RAY_WEIGHT: [f64; RAYS] = [
    -0.510_825_623_765_990_7,
    -0.356_674_943_938_732_45,
    -0.223_143_551_314_209_7,
    -0.105_360_515_657_826_28,
    0.0,
];

/// Unit directions of a crater's rays.
pub(crate) type Rays = [(f64, f64); RAYS];

/// Unit directions of a crater's rays, from its id (exact arithmetic only).
fn ray_directions(id: u64) -> Rays {
    let mut rng = Rng::new(id);
    let mut out = [(1.0, 0.0); RAYS];
    for d in out.iter_mut() {
        // Rejection-free: any non-zero vector, normalised.
        let v = rng.next_u64();
        let x = (v as u32) as f64 / 4_294_967_296.0 - 0.5;
        let y = ((v >> 32) as u32) as f64 / 4_294_967_296.0 - 0.5;
        let n2 = x * x + y * y;
        if n2 > 1e-6 {
            let inv = 1.0 / n2.sqrt();
            *d = (x * inv, y * inv);
        }
    }
    out
}

/// Diameter and degradation draws of crater `i` of the cell with hash `h`.
#[inline]
pub(super) fn shape_of(h: u64, i: u64) -> u64 {
    mix64(h ^ (i + 1).wrapping_mul(0xd1b5_4a32_d192_ed03))
}

/// The top 53 bits of `h` as a uniform draw in `[0, 1)`.
#[inline]
pub(crate) fn unit_f64(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Squared distance (m^2) from `(cx, cy)` to the rectangle `[x0, y0, x1, y1]`; for a
/// point rectangle exactly `(x - cx)^2 + (y - cy)^2`.
#[inline]
pub(crate) fn rect_dist2(rect: [f64; 4], cx: f64, cy: f64) -> f64 {
    let [x0, y0, x1, y1] = rect;
    let dx = if cx < x0 {
        x0 - cx
    } else if cx > x1 {
        cx - x1
    } else {
        0.0
    };
    let dy = if cy < y0 {
        y0 - cy
    } else if cy > y1 {
        cy - y1
    } else {
        0.0
    };
    dx * dx + dy * dy
}

/// Polynomial smooth minimum of width `k` (Quilez); `min(a, b)` when `k <= 0`.
#[inline]
fn smooth_min(a: f64, b: f64, k: f64) -> f64 {
    let m = if a < b { a } else { b };
    if k <= 0.0 {
        return m;
    }
    let d = (a - b).abs();
    if d >= k {
        return m;
    }
    let h = (k - d) / k;
    m - h * h * k * 0.25
}

#[cfg(test)]
mod tests {
    use super::{Crater, Degradation};

    #[test]
    fn four_at_a_time_heights_are_the_point_heights() {
        for (d, smoothing, depth, rim) in [
            (3.0, 0.05, 0.6, 0.12),
            (40.0, 0.0, 2.0, 0.4),
            (1.3, 2.0, 0.1, 0.01),
        ] {
            let c = Crater {
                x_m: 10.3,
                y_m: -4.1,
                diameter_m: d,
                depth_m: depth,
                rim_m: rim,
                smoothing_m: smoothing,
                degradation: 0.5,
                state: Degradation::Mature,
                freshness: 0.0,
                ejecta_extent_radii: 2.5,
                id: 7,
            };
            for row in 0..40 {
                let y = -4.1 + (row as f64 - 20.0) * 0.07 * d;
                let xs: Vec<f64> = (0..23)
                    .map(|i| 10.3 + (i as f64 - 11.3) * 0.11 * d)
                    .collect();
                let mut h: Vec<f64> = (0..23).map(|i| i as f64 * 0.25 - 2.0).collect();
                let mut want = h.clone();
                c.add_heights(&xs, y, &mut h);
                let e = c.ejecta_extent_radii * c.radius_m();
                for (w, &x) in want.iter_mut().zip(&xs) {
                    let (dx, dy) = (x - c.x_m, y - c.y_m);
                    let r2 = dx * dx + dy * dy;
                    if r2 < e * e {
                        *w += c.height_at(r2);
                    }
                }
                for (a, b) in h.iter().zip(&want) {
                    assert_eq!(a.to_bits(), b.to_bits(), "d {d} row {row}");
                }
            }
        }
    }
}
