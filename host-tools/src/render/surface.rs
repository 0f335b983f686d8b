//! What the renderer draws: the [`Surface`] trait (a height field with an albedo texture,
//! sampled at points, on grids and on windows of grids) and its implementation for [`World`].

use crate::world::micro::MicroRelief;
use crate::world::{HeightGrid, Rock, World};

/// What the renderer draws: a height field with an albedo texture. [`World`] is one; tests
/// use their own (e.g. a flat plane with a bright marker).
pub trait Surface: Sync {
    /// Elevation at `(x, y)`, metres.
    fn height_m(&self, x: f64, y: f64) -> f64;
    /// Normal albedo at `(x, y)`, 0..1.
    fn albedo(&self, x: f64, y: f64) -> f64;
    /// Heights and albedo on a north-up grid (conventions of [`World::sample_grid`]).
    fn sample_grid(
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

    /// As [`Surface::sample_grid`], with each pixel's albedo averaged over its square
    /// footprint of side `footprint_m` metres (see [`World::sample_grid_filtered`]). The
    /// renderer asks for footprint = node spacing (mesh levels) or pixel size (orthographic
    /// renders). Default: point samples.
    fn sample_grid_filtered(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
    ) -> HeightGrid {
        let _ = footprint_m;
        self.sample_grid(origin_x_m, origin_y_m, m_per_px, nx, ny)
    }

    /// The surface's centimetre-scale micro-relief, drawn as the near-field texture of the
    /// ground views ([`detail`]). Default: none.
    ///
    /// [`detail`]: super::detail
    fn micro(&self) -> Option<&MicroRelief> {
        None
    }

    /// Calls `f` for every boulder of the height field whose footprint reaches into `rect`
    /// (`[x0, y0, x1, y1]` metres), so that the near-field texture can draw them finer than
    /// the mesh ([`detail`]). Default: none.
    ///
    /// [`detail`]: super::detail
    fn visit_boulders(&self, rect: [f64; 4], f: &mut dyn FnMut(&Rock)) {
        let _ = (rect, f);
    }

    /// Pixels `cols x rows` (inside the grid) of [`Surface::sample_grid_filtered`] with the
    /// same arguments, bit for bit: heights and albedo, row-major, `cols.len()` wide. The
    /// default samples the whole grid and copies the window; [`World`] samples only what
    /// the window needs.
    #[allow(clippy::too_many_arguments)]
    fn sample_grid_window(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
        cols: std::ops::Range<usize>,
        rows: std::ops::Range<usize>,
    ) -> (Vec<f32>, Vec<f32>) {
        let g = self.sample_grid_filtered(origin_x_m, origin_y_m, m_per_px, nx, ny, footprint_m);
        let (mut h, mut a) = (Vec::new(), Vec::new());
        if cols.end <= g.nx && rows.end <= g.ny {
            for r in rows {
                h.extend_from_slice(&g.height_m[r * g.nx + cols.start..r * g.nx + cols.end]);
                a.extend_from_slice(&g.albedo[r * g.nx + cols.start..r * g.nx + cols.end]);
            }
        }
        (h, a)
    }
}

impl Surface for World {
    fn height_m(&self, x: f64, y: f64) -> f64 {
        World::height_m(self, x, y)
    }
    fn albedo(&self, x: f64, y: f64) -> f64 {
        World::albedo(self, x, y)
    }
    fn sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> HeightGrid {
        World::sample_grid(self, origin_x_m, origin_y_m, m_per_px, nx, ny)
    }
    fn sample_grid_filtered(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
    ) -> HeightGrid {
        World::sample_grid_filtered(self, origin_x_m, origin_y_m, m_per_px, nx, ny, footprint_m)
    }
    fn micro(&self) -> Option<&MicroRelief> {
        World::micro(self)
    }
    fn visit_boulders(&self, rect: [f64; 4], f: &mut dyn FnMut(&Rock)) {
        World::visit_boulders(self, rect, f)
    }

    fn sample_grid_window(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
        cols: std::ops::Range<usize>,
        rows: std::ops::Range<usize>,
    ) -> (Vec<f32>, Vec<f32>) {
        World::sample_grid_window(
            self,
            origin_x_m,
            origin_y_m,
            m_per_px,
            nx,
            ny,
            footprint_m,
            cols,
            rows,
        )
    }
}
