//! The procedural lunar world: a pure function of `(seed, x, y)`.
//!
//! Nothing is stored: any region is sampled lazily, so an 8 x 8 km world costs no memory.
//! World frame: `x` east, `y` north, `z` up, metres (`docs/frames.md`).

/// A procedural lunar terrain.
#[derive(Clone, Debug)]
pub struct World {
    seed: u64,
    flat: bool,
}

pub mod zones;

/// Heights and albedo of a north-up grid of world points (`World::sample_grid`).
///
/// Row-major, row 0 north; node `(col, row)` is at
/// `x = origin_x_m + (col + 0.5) m_per_px`, `y = origin_y_m - (row + 0.5) m_per_px`.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightGrid {
    /// West edge, metres.
    pub origin_x_m: f64,
    /// North edge, metres.
    pub origin_y_m: f64,
    /// Node spacing, metres.
    pub m_per_px: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// Elevation per node, metres.
    pub height_m: Vec<f32>,
    /// Normal albedo per node, 0..1.
    pub albedo: Vec<f32>,
}

impl World {
    /// The world of `seed`.
    pub fn new(seed: u64) -> Self {
        Self { seed, flat: false }
    }

    /// The world of `seed` with zero relief and the same albedo texture.
    pub fn flat(seed: u64) -> Self {
        Self { seed, flat: true }
    }

    /// Samples heights and albedo on a north-up grid (see [`HeightGrid`]).
    pub fn sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> HeightGrid {
        let mut height_m = Vec::with_capacity(nx * ny);
        let mut albedo = Vec::with_capacity(nx * ny);
        for r in 0..ny {
            let y = origin_y_m - (r as f64 + 0.5) * m_per_px;
            for c in 0..nx {
                let x = origin_x_m + (c as f64 + 0.5) * m_per_px;
                height_m.push(self.height_m(x, y) as f32);
                albedo.push(self.albedo(x, y) as f32);
            }
        }
        HeightGrid {
            origin_x_m,
            origin_y_m,
            m_per_px,
            nx,
            ny,
            height_m,
            albedo,
        }
    }

    /// The seed this world was made from.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Terrain elevation at `(x, y)`, metres.
    pub fn height_m(&self, x: f64, y: f64) -> f64 {
        if self.flat {
            return 0.0;
        }
        // Placeholder relief until the crater model lands: two gentle sine swells.
        let s = (self.seed % 97) as f64;
        0.8 * ((x + s) / 23.0).sin() * ((y - s) / 31.0).cos()
    }

    /// Normal albedo at `(x, y)`, in 0..1.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        0.12 + 0.02 * ((x * 1.7).sin() + (y * 2.3).cos())
    }
}
