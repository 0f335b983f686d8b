//! Integer hashing and a small counter-based generator: the only source of randomness in the
//! world, so placement is bit-identical on every machine.

/// SplitMix64 finaliser: a bijective 64-bit mixer.
#[inline]
pub(crate) const fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Key of a layer (craters of one size class, rocks, noise octave, ...) of the world `seed`.
#[inline]
pub(crate) const fn layer_key(seed: u64, layer: u64) -> u64 {
    mix64(seed ^ mix64(layer.wrapping_add(0x6a09_e667_f3bc_c909)))
}

/// Hash of the grid cell `(ix, iy)` of a layer (one mixing round: this is on the hot path).
#[inline]
pub(crate) const fn cell_hash(key: u64, ix: i64, iy: i64) -> u64 {
    mix64(
        key ^ (ix as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ (iy as u64)
                .wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
                .rotate_left(29),
    )
}

/// 32-bit hash of a lattice point, for gradient noise (cheap: called 4 times per octave).
#[inline]
pub(crate) const fn lattice_hash(seed: u32, ix: i32, iy: i32) -> u32 {
    let mut h =
        (ix as u32).wrapping_mul(0x8da6_b343) ^ (iy as u32).wrapping_mul(0xd816_3841) ^ seed;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^ (h >> 15)
}

/// SplitMix64 stream: a deterministic sequence of draws from one hash.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rng {
    state: u64,
}

impl Rng {
    #[inline]
    pub(crate) const fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    #[inline]
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`, 53 bits, exact.
    #[inline]
    pub(crate) fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Index of the grid cell of size `cell` holding coordinate `v` (saturating for huge or
/// non-finite `v`; callers reject non-finite input first).
#[inline]
pub(crate) fn cell_of(v: f64, cell: f64) -> i64 {
    floor_i64(v / cell)
}

/// `floor(v)` as an integer, exact for `|v| < 2^63` (saturating beyond, 0 for NaN). Inline
/// integer arithmetic: without SSE4.1, `f64::floor` is a library call.
#[inline]
pub(crate) fn floor_i64(v: f64) -> i64 {
    let i = v as i64;
    if (i as f64) > v {
        i.wrapping_sub(1)
    } else {
        i
    }
}
