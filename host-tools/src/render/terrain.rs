//! Nested height grids sampled from the world: the geometry the renderer draws and the
//! composite height function that cast shadows are traced over.

use super::RenderOptions;
use crate::world::{HeightGrid, World};
use orbfix::geo::GeoRef;
use rayon::prelude::*;

/// One square level: a world grid (with a one-node apron for normals) and the square of
/// the world it is meant to cover.
#[derive(Clone, Debug)]
pub struct Level {
    /// Heights and albedo at the nodes (node `(c, r)` at `origin + (c + 0.5, -(r + 0.5)) * m`).
    pub grid: HeightGrid,
    /// Covered square: west, south, east, north edges, metres.
    pub bounds: [f64; 4],
}

impl Level {
    /// Node spacing, metres.
    pub fn m(&self) -> f64 {
        self.grid.m_per_px
    }

    /// World position of node `(c, r)`.
    #[inline]
    pub fn node_xy(&self, c: usize, r: usize) -> (f64, f64) {
        let g = &self.grid;
        (
            g.origin_x_m + (c as f64 + 0.5) * g.m_per_px,
            g.origin_y_m - (r as f64 + 0.5) * g.m_per_px,
        )
    }

    /// Bilinear height at `(x, y)`, or `None` outside the node lattice.
    #[inline]
    pub fn height(&self, x: f64, y: f64) -> Option<f64> {
        let g = &self.grid;
        let fx = (x - g.origin_x_m) / g.m_per_px - 0.5;
        let fy = (g.origin_y_m - y) / g.m_per_px - 0.5;
        if !(fx >= 0.0 && fy >= 0.0 && fx <= (g.nx - 1) as f64 && fy <= (g.ny - 1) as f64) {
            return None;
        }
        let c = (fx as usize).min(g.nx.saturating_sub(2));
        let r = (fy as usize).min(g.ny.saturating_sub(2));
        let tx = fx - c as f64;
        let ty = fy - r as f64;
        let i = r * g.nx + c;
        let h = &g.height_m;
        let top = h[i] as f64 * (1.0 - tx) + h[i + 1] as f64 * tx;
        let bot = h[i + g.nx] as f64 * (1.0 - tx) + h[i + g.nx + 1] as f64 * tx;
        Some(top * (1.0 - ty) + bot * ty)
    }

    /// Unit normal at node `(c, r)` by central differences (one-sided at the edges).
    #[inline]
    pub fn normal(&self, c: usize, r: usize) -> [f64; 3] {
        let g = &self.grid;
        let h = |c: usize, r: usize| g.height_m[r * g.nx + c] as f64;
        let (c0, c1) = (c.saturating_sub(1), (c + 1).min(g.nx - 1));
        let (r0, r1) = (r.saturating_sub(1), (r + 1).min(g.ny - 1));
        let dx = (h(c1, r) - h(c0, r)) / (((c1 - c0).max(1)) as f64 * g.m_per_px);
        // Row index grows southwards: dh/dy = (h(north) - h(south)) / distance.
        let dy = (h(c, r0) - h(c, r1)) / (((r1 - r0).max(1)) as f64 * g.m_per_px);
        let n = [-dx, -dy, 1.0];
        let l = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
        [n[0] / l, n[1] / l, n[2] / l]
    }

    fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.bounds[0] && y >= self.bounds[1] && x <= self.bounds[2] && y <= self.bounds[3]
    }
}

/// Nested levels, finest first; the composite height at a point is that of the finest
/// level covering it.
#[derive(Clone, Debug)]
pub struct Terrain {
    /// Levels, finest first.
    pub levels: Vec<Level>,
}

fn sample_square(world: &World, cx: f64, cy: f64, half: f64, m: f64) -> Level {
    // Nodes snapped to the world lattice of spacing `m` (node centres at (k + 0.5) m),
    // one apron node beyond the square on each side.
    let c0 = ((cx - half) / m).floor() - 1.0;
    let c1 = ((cx + half) / m).ceil() + 1.0;
    let r0 = ((cy + half) / m).ceil() + 1.0; // north
    let r1 = ((cy - half) / m).floor() - 1.0;
    let nx = (c1 - c0) as usize;
    let ny = (r0 - r1) as usize;
    let origin_x = c0 * m;
    let origin_y = r0 * m;
    // Sample in parallel bands of rows, each band a world grid call.
    let band = 32usize;
    let bands: Vec<HeightGrid> = (0..ny.div_ceil(band))
        .into_par_iter()
        .map(|b| {
            let rows = band.min(ny - b * band);
            world.sample_grid(origin_x, origin_y - (b * band) as f64 * m, m, nx, rows)
        })
        .collect();
    let mut height_m = Vec::with_capacity(nx * ny);
    let mut albedo = Vec::with_capacity(nx * ny);
    for g in bands {
        height_m.extend_from_slice(&g.height_m);
        albedo.extend_from_slice(&g.albedo);
    }
    Level {
        grid: HeightGrid {
            origin_x_m: origin_x,
            origin_y_m: origin_y,
            m_per_px: m,
            nx,
            ny,
            height_m,
            albedo,
        },
        bounds: [cx - half, cy - half, cx + half, cy + half],
    }
}

impl Terrain {
    /// Levels around a rover at `(x_m, y_m)` for a camera of focal length `focal_px`:
    /// level 0 has `near_cell_m` cells out to where a cell projects to `lod_px_per_cell`
    /// pixels; each next level doubles cell size and extent, out to `max_range_m`.
    pub fn around(world: &World, x_m: f64, y_m: f64, opts: &RenderOptions, focal_px: f64) -> Self {
        let m0 = opts.near_cell_m;
        // Keep level 0 at least 4 m and at most 512 cells across.
        let half0 = (focal_px * m0 / opts.lod_px_per_cell).clamp(4.0, 256.0 * m0);
        let mut levels = Vec::new();
        let (mut half, mut m) = (half0, m0);
        loop {
            levels.push(sample_square(world, x_m, y_m, half, m));
            if half >= opts.max_range_m || levels.len() >= 24 {
                break;
            }
            half *= 2.0;
            m *= 2.0;
        }
        Self { levels }
    }

    /// Levels for an orthographic render of the raster `geo` (`w x h` pixels): level 0 has
    /// one node per pixel centre (plus an apron); level 1, coarser, reaches `reach_m` beyond
    /// it so that shadows cast from outside the raster are traced.
    pub fn region(world: &World, geo: &GeoRef, w: u32, h: u32, reach_m: f64) -> Self {
        let m = geo.m_per_px as f64;
        let ox = geo.origin_x_m as f64;
        let oy = geo.origin_y_m as f64;
        let (nx, ny) = (w as usize + 2, h as usize + 2);
        // Sample by bands of rows in parallel.
        let band = 64usize;
        let bands: Vec<HeightGrid> = (0..ny.div_ceil(band))
            .into_par_iter()
            .map(|b| {
                let rows = band.min(ny - b * band);
                world.sample_grid(ox - m, oy + m - (b * band) as f64 * m, m, nx, rows)
            })
            .collect();
        let mut height_m = Vec::with_capacity(nx * ny);
        let mut albedo = Vec::with_capacity(nx * ny);
        for g in bands {
            height_m.extend_from_slice(&g.height_m);
            albedo.extend_from_slice(&g.albedo);
        }
        let bounds = [ox, oy - h as f64 * m, ox + w as f64 * m, oy];
        let l0 = Level {
            grid: HeightGrid {
                origin_x_m: ox - m,
                origin_y_m: oy + m,
                m_per_px: m,
                nx,
                ny,
                height_m,
                albedo,
            },
            bounds,
        };
        let cx = 0.5 * (bounds[0] + bounds[2]);
        let cy = 0.5 * (bounds[1] + bounds[3]);
        let half = 0.5 * (bounds[2] - bounds[0]).max(bounds[3] - bounds[1]) + reach_m;
        // Coarse surround: about 512 nodes across, never finer than 2 px.
        let m1 = (2.0 * half / 512.0).max(2.0 * m);
        let l1 = sample_square(world, cx, cy, half, m1);
        Self {
            levels: vec![l0, l1],
        }
    }

    /// Composite height (metres) at `(x, y)` and the node spacing it comes from, or `None`
    /// outside every level.
    #[inline]
    pub fn height(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        for l in &self.levels {
            if l.contains(x, y) {
                if let Some(h) = l.height(x, y) {
                    return Some((h, l.m()));
                }
            }
        }
        None
    }
}
