//! Fractal gradient noise (Perlin-style) from integer lattice hashes. Only `+ - * /` and
//! `floor` on `f64`, so results are bit-identical on every IEEE-754 machine.

use super::hash::{floor_i64, lattice_hash, layer_key};

const S: f64 = core::f64::consts::FRAC_1_SQRT_2;
/// Eight unit gradients.
const GRADIENTS: [(f64, f64); 8] = [
    (1.0, 0.0),
    (-1.0, 0.0),
    (0.0, 1.0),
    (0.0, -1.0),
    (S, S),
    (-S, S),
    (S, -S),
    (-S, -S),
];

/// 2-D gradient noise at lattice-unit coordinates; roughly in `[-1, 1]`, zero mean, zero at
/// lattice points, C2-continuous (quintic fade).
#[inline]
pub(crate) fn gradient_noise(seed: u32, x: f64, y: f64) -> f64 {
    let xi = floor_i64(x);
    let yi = floor_i64(y);
    let fx = x - xi as f64;
    let fy = y - yi as f64;
    // Wrapping to i32 is fine: the lattice repeats only every 2^32 cells.
    let ix = xi as i32;
    let iy = yi as i32;
    let g = |dx: i32, dy: i32, px: f64, py: f64| {
        let h = lattice_hash(seed, ix.wrapping_add(dx), iy.wrapping_add(dy));
        let (gx, gy) = GRADIENTS[(h >> 29) as usize];
        gx * px + gy * py
    };
    let n00 = g(0, 0, fx, fy);
    let n10 = g(1, 0, fx - 1.0, fy);
    let n01 = g(0, 1, fx, fy - 1.0);
    let n11 = g(1, 1, fx - 1.0, fy - 1.0);
    let u = fade(fx);
    let v = fade(fy);
    let a = n00 + u * (n10 - n00);
    let b = n01 + u * (n11 - n01);
    // Max of |2-D Perlin| with unit gradients is sqrt(1/2); rescale to about [-1, 1].
    (a + v * (b - a)) * core::f64::consts::SQRT_2
}

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// One octave: a rotated, offset, scaled copy of the gradient noise.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Octave {
    seed: u32,
    /// Cycles per metre.
    freq: f64,
    /// Amplitude (metres of height, or albedo units).
    amp: f64,
    cos: f64,
    sin: f64,
    off_x: f64,
    off_y: f64,
}

/// A sum of octaves.
#[derive(Clone, Debug, Default)]
pub(crate) struct Fbm {
    octaves: Vec<Octave>,
}

impl Fbm {
    /// `n` octaves, the first of wavelength `wavelength_m` and amplitude `amplitude`, each next
    /// one half the wavelength and `2^-hurst` the amplitude. Each octave is rotated by a
    /// further `atan(3/4)` (about 36.9 deg, an exact rational rotation) to hide lattice axes.
    pub(crate) fn new(
        seed: u64,
        layer: u64,
        wavelength_m: f64,
        amplitude: f64,
        n: u32,
        hurst: f64,
    ) -> Self {
        let mut octaves = Vec::with_capacity(n as usize);
        let (mut c, mut s) = (1.0_f64, 0.0_f64);
        let gain = libm::pow(2.0, -hurst);
        let mut amp = amplitude;
        let mut wl = wavelength_m;
        for k in 0..n {
            let key = layer_key(seed, layer.wrapping_mul(64).wrapping_add(u64::from(k)));
            octaves.push(Octave {
                seed: key as u32,
                freq: 1.0 / wl,
                amp,
                cos: c,
                sin: s,
                // Offsets in [0, 4096) lattice units decorrelate the octaves' lattice origins.
                off_x: ((key >> 32) & 0xfff) as f64 + ((key >> 44) & 0xff) as f64 / 256.0,
                off_y: ((key >> 52) & 0xfff) as f64 + ((key >> 8) & 0xff) as f64 / 256.0,
            });
            // Rotate by (cos, sin) = (4/5, 3/5).
            let (nc, ns) = (c * 0.8 - s * 0.6, s * 0.8 + c * 0.6);
            c = nc;
            s = ns;
            amp *= gain;
            wl *= 0.5;
        }
        Self { octaves }
    }

    /// Sum of the octaves at world `(x, y)` metres.
    #[inline]
    pub(crate) fn at(&self, x: f64, y: f64) -> f64 {
        let mut sum = 0.0;
        for o in &self.octaves {
            sum += o.amp * o.noise(x, y);
        }
        sum
    }

    /// [`Fbm::at`] at `(xs[i], y)` for every `i`, into `out[i]` (`out` as long as `xs`), bit
    /// for bit: the same operations in the same order per sample, four samples at a time
    /// where the CPU has AVX2.
    pub(crate) fn row(&self, xs: &[f64], y: f64, out: &mut [f64]) {
        let n = xs.len().min(out.len());
        let (xs, out) = (&xs[..n], &mut out[..n]);
        out.fill(0.0);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            for o in &self.octaves {
                // Safety: AVX2 is present (checked above).
                unsafe { simd::octave_row(o, xs, y, out) };
            }
            return;
        }
        for o in &self.octaves {
            for (s, &x) in out.iter_mut().zip(xs) {
                *s += o.amp * o.noise(x, y);
            }
        }
    }
}

impl Octave {
    /// This octave's noise (before its amplitude) at world `(x, y)` metres.
    #[inline]
    fn noise(&self, x: f64, y: f64) -> f64 {
        let u = (x * self.cos - y * self.sin) * self.freq + self.off_x;
        let v = (x * self.sin + y * self.cos) * self.freq + self.off_y;
        gradient_noise(self.seed, u, v)
    }
}

/// Four samples at a time with AVX2: the operations of [`gradient_noise`] and [`Fbm::at`]
/// lane by lane (IEEE-754 `+ - * floor` give the same bits in any lane; no fused
/// multiply-add), integer hashing in 32-bit lanes.
#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{gradient_noise, Octave, GRADIENTS};
    use core::arch::x86_64::*;

    /// [`super::super::hash::lattice_hash`] in four lanes, from `(ix * 0x8da6_b343) ^ (iy *
    /// 0xd816_3841) ^ seed` already formed.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn finish_hash(h: __m128i) -> __m128i {
        let h = _mm_xor_si128(h, _mm_srli_epi32::<15>(h));
        let h = _mm_mullo_epi32(h, _mm_set1_epi32(0x2c1b_3c6d_u32 as i32));
        let h = _mm_xor_si128(h, _mm_srli_epi32::<12>(h));
        let h = _mm_mullo_epi32(h, _mm_set1_epi32(0x297a_2d39_u32 as i32));
        _mm_xor_si128(h, _mm_srli_epi32::<15>(h))
    }

    /// A gradient table as two halves (entries 0..4 and 4..8), each four `f64` viewed as eight
    /// `f32` lanes for `vpermps`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn halves(t: [f64; 8]) -> (__m256, __m256) {
        (
            _mm256_castpd_ps(_mm256_setr_pd(t[0], t[1], t[2], t[3])),
            _mm256_castpd_ps(_mm256_setr_pd(t[4], t[5], t[6], t[7])),
        )
    }

    /// The two gradient tables, `x` and `y` components.
    #[derive(Clone, Copy)]
    struct Tables {
        gx: (__m256, __m256),
        gy: (__m256, __m256),
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn tables() -> Tables {
        Tables {
            gx: halves(GRADIENTS.map(|g| g.0)),
            gy: halves(GRADIENTS.map(|g| g.1)),
        }
    }

    /// The gradient `GRADIENTS[h >> 29]` (exact table values, picked by permutes and a
    /// blend), `x` and `y` components.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn gradient(t: &Tables, h: __m128i) -> (__m256d, __m256d) {
        let k = _mm256_cvtepu32_epi64(_mm_srli_epi32::<29>(h));
        // 32-bit lane indices (2j, 2j + 1) of entry j = k & 3 within a half.
        let j2 = _mm256_slli_epi64::<1>(_mm256_and_si256(k, _mm256_set1_epi64x(3)));
        let idx = _mm256_or_si256(
            j2,
            _mm256_slli_epi64::<32>(_mm256_or_si256(j2, _mm256_set1_epi64x(1))),
        );
        // Bit 2 of k (which half) in each lane's sign bit.
        let hi = _mm256_castsi256_pd(_mm256_slli_epi64::<61>(k));
        let pick = |(a, b): (__m256, __m256)| {
            _mm256_blendv_pd(
                _mm256_castps_pd(_mm256_permutevar8x32_ps(a, idx)),
                _mm256_castps_pd(_mm256_permutevar8x32_ps(b, idx)),
                hi,
            )
        };
        (pick(t.gx), pick(t.gy))
    }

    /// `gx * px + gy * py`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn dot((gx, gy): (__m256d, __m256d), px: __m256d, py: __m256d) -> __m256d {
        _mm256_add_pd(_mm256_mul_pd(gx, px), _mm256_mul_pd(gy, py))
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn fade(t: __m256d) -> __m256d {
        let t3 = _mm256_mul_pd(_mm256_mul_pd(t, t), t);
        let inner = _mm256_add_pd(
            _mm256_mul_pd(
                t,
                _mm256_sub_pd(_mm256_mul_pd(t, _mm256_set1_pd(6.0)), _mm256_set1_pd(15.0)),
            ),
            _mm256_set1_pd(10.0),
        );
        _mm256_mul_pd(t3, inner)
    }

    /// Adds `o.amp * noise` at `(xs[i], y)` to `out[i]`.
    #[target_feature(enable = "avx2")]
    pub(super) fn octave_row(o: &Octave, xs: &[f64], y: f64, out: &mut [f64]) {
        let n = xs.len().min(out.len());
        let cos = _mm256_set1_pd(o.cos);
        let sin = _mm256_set1_pd(o.sin);
        let ysin = _mm256_set1_pd(y * o.sin);
        let ycos = _mm256_set1_pd(y * o.cos);
        let freq = _mm256_set1_pd(o.freq);
        let offx = _mm256_set1_pd(o.off_x);
        let offy = _mm256_set1_pd(o.off_y);
        let amp = _mm256_set1_pd(o.amp);
        let one = _mm256_set1_pd(1.0);
        // Lattice indices must fit an i32 exactly (the scalar code wraps larger ones).
        let lo = _mm256_set1_pd(-2_147_483_648.0);
        let hi = _mm256_set1_pd(2_147_483_647.0);
        let seed = _mm_set1_epi32(o.seed as i32);
        let cx = _mm_set1_epi32(0x8da6_b343_u32 as i32);
        let cy = _mm_set1_epi32(0xd816_3841_u32 as i32);
        let one_i = _mm_set1_epi32(1);
        let t = tables();
        // Corner gradients of the cells of the last four samples (`have`: computed yet).
        let zero = _mm256_setzero_pd();
        let (mut g00, mut g10, mut g01, mut g11) =
            ((zero, zero), (zero, zero), (zero, zero), (zero, zero));
        let mut last_ix = _mm_set1_epi32(0);
        let mut last_iy = _mm_set1_epi32(0);
        let mut have = false;
        let mut i = 0;
        while i < n {
            // The last step pads its lanes with the last sample (computed, not stored).
            let full = i + 4 <= n;
            let x = if full {
                // Safety: i + 4 <= n <= xs.len().
                unsafe { _mm256_loadu_pd(xs.as_ptr().add(i)) }
            } else {
                let mut p = [xs[n - 1]; 4];
                p[..n - i].copy_from_slice(&xs[i..n]);
                // Safety: 4-element array.
                unsafe { _mm256_loadu_pd(p.as_ptr()) }
            };
            let u = _mm256_add_pd(
                _mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(x, cos), ysin), freq),
                offx,
            );
            let v = _mm256_add_pd(
                _mm256_mul_pd(_mm256_add_pd(_mm256_mul_pd(x, sin), ycos), freq),
                offy,
            );
            let flx = _mm256_floor_pd(u);
            let fly = _mm256_floor_pd(v);
            let ok = _mm256_and_pd(
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(flx, lo),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(flx, hi),
                ),
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(fly, lo),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(fly, hi),
                ),
            );
            let g = if _mm256_movemask_pd(ok) == 0xf {
                let fx = _mm256_sub_pd(u, flx);
                let fy = _mm256_sub_pd(v, fly);
                let ix = _mm256_cvttpd_epi32(flx);
                let iy = _mm256_cvttpd_epi32(fly);
                // Every lane in the lattice cell it was in last time: same corner gradients
                // (frequent on fine grids, where a cell spans many samples).
                let same =
                    _mm_and_si128(_mm_cmpeq_epi32(ix, last_ix), _mm_cmpeq_epi32(iy, last_iy));
                if !have || _mm_movemask_epi8(same) != 0xffff {
                    let hx0 = _mm_mullo_epi32(ix, cx);
                    let hx1 = _mm_mullo_epi32(_mm_add_epi32(ix, one_i), cx);
                    let hy0 = _mm_xor_si128(_mm_mullo_epi32(iy, cy), seed);
                    let hy1 = _mm_xor_si128(_mm_mullo_epi32(_mm_add_epi32(iy, one_i), cy), seed);
                    g00 = gradient(&t, finish_hash(_mm_xor_si128(hx0, hy0)));
                    g10 = gradient(&t, finish_hash(_mm_xor_si128(hx1, hy0)));
                    g01 = gradient(&t, finish_hash(_mm_xor_si128(hx0, hy1)));
                    g11 = gradient(&t, finish_hash(_mm_xor_si128(hx1, hy1)));
                    last_ix = ix;
                    last_iy = iy;
                    have = true;
                }
                let fx1 = _mm256_sub_pd(fx, one);
                let fy1 = _mm256_sub_pd(fy, one);
                let n00 = dot(g00, fx, fy);
                let n10 = dot(g10, fx1, fy);
                let n01 = dot(g01, fx, fy1);
                let n11 = dot(g11, fx1, fy1);
                let fu = fade(fx);
                let fv = fade(fy);
                let a = _mm256_add_pd(n00, _mm256_mul_pd(fu, _mm256_sub_pd(n10, n00)));
                let b = _mm256_add_pd(n01, _mm256_mul_pd(fu, _mm256_sub_pd(n11, n01)));
                _mm256_mul_pd(
                    _mm256_add_pd(a, _mm256_mul_pd(fv, _mm256_sub_pd(b, a))),
                    _mm256_set1_pd(core::f64::consts::SQRT_2),
                )
            } else {
                // Out of the i32 lattice (or not finite): the scalar code, lane by lane.
                let mut u4 = [0.0; 4];
                let mut v4 = [0.0; 4];
                // Safety: 4-element arrays.
                unsafe {
                    _mm256_storeu_pd(u4.as_mut_ptr(), u);
                    _mm256_storeu_pd(v4.as_mut_ptr(), v);
                }
                let g4 = [0, 1, 2, 3].map(|k| gradient_noise(o.seed, u4[k], v4[k]));
                // Safety: 4-element array.
                unsafe { _mm256_loadu_pd(g4.as_ptr()) }
            };
            if full {
                // Safety: i + 4 <= n <= out.len().
                unsafe {
                    let s = _mm256_loadu_pd(out.as_ptr().add(i));
                    _mm256_storeu_pd(
                        out.as_mut_ptr().add(i),
                        _mm256_add_pd(s, _mm256_mul_pd(amp, g)),
                    );
                }
            } else {
                let mut q = [0.0; 4];
                q[..n - i].copy_from_slice(&out[i..n]);
                // Safety: 4-element array.
                unsafe {
                    let s = _mm256_loadu_pd(q.as_ptr());
                    _mm256_storeu_pd(q.as_mut_ptr(), _mm256_add_pd(s, _mm256_mul_pd(amp, g)));
                }
                out[i..n].copy_from_slice(&q[..n - i]);
            }
            i += 4;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Fbm;

    #[test]
    fn rows_are_the_point_values_bit_for_bit() {
        let f = Fbm::new(77, 1, 800.0, 3.0, 8, 0.9);
        let g = Fbm::new(5, 3, 4.0, 0.01, 2, 0.0);
        for (x0, y, dx, n) in [
            (-1234.56, 987.65, 0.1, 37),
            (0.05, -0.05, 0.013, 64),
            (4.0e6, -3.3e6, 17.3, 23),
            (-2.0e11, 1.0e11, 3.0e9, 9),
            (1.0, f64::NAN, 1.0, 5),
        ] {
            let xs: Vec<f64> = (0..n).map(|i| x0 + i as f64 * dx).collect();
            for fbm in [&f, &g] {
                let mut out = vec![7.0; n];
                fbm.row(&xs, y, &mut out);
                for (i, &x) in xs.iter().enumerate() {
                    assert_eq!(out[i].to_bits(), fbm.at(x, y).to_bits(), "x {x} y {y}");
                }
            }
        }
    }
}
