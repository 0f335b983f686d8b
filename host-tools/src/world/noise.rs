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
            let u = (x * o.cos - y * o.sin) * o.freq + o.off_x;
            let v = (x * o.sin + y * o.cos) * o.freq + o.off_y;
            sum += o.amp * gradient_noise(o.seed, u, v);
        }
        sum
    }
}
