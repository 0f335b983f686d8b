//! The procedural lunar world: a pure function of `(seed, x, y)`.
//!
//! Nothing is stored: any region is sampled lazily, so an 8 x 8 km world costs no memory.
//! World frame: `x` east, `y` north, `z` up, metres (`docs/frames.md`).

/// A procedural lunar terrain.
#[derive(Clone, Debug)]
pub struct World {
    seed: u64,
}

impl World {
    /// The world of `seed`.
    pub fn new(seed: u64) -> Self {
        Self { seed }
    }

    /// The seed this world was made from.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Terrain elevation at `(x, y)`, metres.
    pub fn height_m(&self, x: f64, y: f64) -> f64 {
        // Placeholder relief until the crater model lands: two gentle sine swells.
        let s = (self.seed % 97) as f64;
        0.8 * ((x + s) / 23.0).sin() * ((y - s) / 31.0).cos()
    }

    /// Normal albedo at `(x, y)`, in 0..1.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        0.12 + 0.02 * ((x * 1.7).sin() + (y * 2.3).cos())
    }
}
