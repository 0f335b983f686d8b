//! Nested height grids sampled from the world: the geometry the renderer draws and the
//! composite height function that cast shadows are traced over.

use super::RenderOptions;
use super::Surface;
use crate::world::HeightGrid;
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
        self.locate(x, y).map(|(fx, fy)| self.interpolate(fx, fy))
    }

    /// `(x, y)` in node units (`(fx, fy)` with node `(c, r)` at `(c, r)`), or `None` outside
    /// the node lattice: the first half of [`Level::height`].
    #[inline]
    pub(crate) fn locate(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let g = &self.grid;
        let fx = (x - g.origin_x_m) / g.m_per_px - 0.5;
        let fy = (g.origin_y_m - y) / g.m_per_px - 0.5;
        if !(fx >= 0.0 && fy >= 0.0 && fx <= (g.nx - 1) as f64 && fy <= (g.ny - 1) as f64) {
            return None;
        }
        Some((fx, fy))
    }

    /// [`Level::height`] at four points, bit for bit, when all four lie on the node lattice
    /// (`None` otherwise, or without AVX2): four lanes of the same operations, the nodes
    /// gathered.
    #[inline]
    pub(crate) fn height4(&self, x: [f64; 4], y: [f64; 4]) -> Option<[f64; 4]> {
        #[cfg(target_arch = "x86_64")]
        {
            let g = &self.grid;
            // Node indices must fit 32-bit lanes.
            if std::arch::is_x86_feature_detected!("avx2")
                && g.nx >= 2
                && g.ny >= 2
                && g.nx
                    .checked_mul(g.ny)
                    .is_some_and(|n| n < i32::MAX as usize)
                && g.height_m.len() == g.nx * g.ny
            {
                // Safety: AVX2 is present; the grid's size was checked.
                return unsafe { simd::height4(g, x, y) };
            }
        }
        let _ = (x, y);
        None
    }

    /// The bilinear height at node coordinates from [`Level::locate`].
    #[inline]
    pub(crate) fn interpolate(&self, fx: f64, fy: f64) -> f64 {
        let g = &self.grid;
        let c = (fx as usize).min(g.nx.saturating_sub(2));
        let r = (fy as usize).min(g.ny.saturating_sub(2));
        let tx = fx - c as f64;
        let ty = fy - r as f64;
        let i = r * g.nx + c;
        let h = &g.height_m;
        let top = h[i] as f64 * (1.0 - tx) + h[i + 1] as f64 * tx;
        let bot = h[i + g.nx] as f64 * (1.0 - tx) + h[i + g.nx + 1] as f64 * tx;
        top * (1.0 - ty) + bot * ty
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

    /// Whether the node lattice covers the whole square with a quarter node to spare, so
    /// that [`Level::locate`] finds every point of the square (as levels built here do).
    pub(crate) fn covers_bounds(&self) -> bool {
        let g = &self.grid;
        let b = self.bounds;
        let (x0, x1) = (
            (b[0] - g.origin_x_m) / g.m_per_px - 0.5,
            (b[2] - g.origin_x_m) / g.m_per_px - 0.5,
        );
        let (y0, y1) = (
            (g.origin_y_m - b[3]) / g.m_per_px - 0.5,
            (g.origin_y_m - b[1]) / g.m_per_px - 0.5,
        );
        g.nx >= 2
            && g.ny >= 2
            && x0 >= 0.25
            && y0 >= 0.25
            && x1 <= g.nx as f64 - 1.25
            && y1 <= g.ny as f64 - 1.25
    }

    #[inline]
    fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.bounds[0] && y >= self.bounds[1] && x <= self.bounds[2] && y <= self.bounds[3]
    }
}

/// [`Level::height4`] with AVX2.
#[cfg(target_arch = "x86_64")]
mod simd {
    use crate::world::HeightGrid;
    use core::arch::x86_64::*;

    /// Requires `nx, ny >= 2`, `nx * ny < 2^31`, `height_m.len() == nx * ny`.
    #[target_feature(enable = "avx2")]
    pub(super) fn height4(g: &HeightGrid, x: [f64; 4], y: [f64; 4]) -> Option<[f64; 4]> {
        let set = _mm256_set1_pd;
        // Safety: 4-element arrays.
        let (xv, yv) = unsafe { (_mm256_loadu_pd(x.as_ptr()), _mm256_loadu_pd(y.as_ptr())) };
        let m = set(g.m_per_px);
        let fx = _mm256_sub_pd(
            _mm256_div_pd(_mm256_sub_pd(xv, set(g.origin_x_m)), m),
            set(0.5),
        );
        let fy = _mm256_sub_pd(
            _mm256_div_pd(_mm256_sub_pd(set(g.origin_y_m), yv), m),
            set(0.5),
        );
        let zero = _mm256_setzero_pd();
        let ok = _mm256_and_pd(
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(fx, zero),
                _mm256_cmp_pd::<_CMP_GE_OQ>(fy, zero),
            ),
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_LE_OQ>(fx, set((g.nx - 1) as f64)),
                _mm256_cmp_pd::<_CMP_LE_OQ>(fy, set((g.ny - 1) as f64)),
            ),
        );
        if _mm256_movemask_pd(ok) != 0xf {
            return None;
        }
        // c = trunc(fx) capped at nx - 2 (fx in [0, nx - 1] here), as `interpolate`.
        let c = _mm_min_epi32(_mm256_cvttpd_epi32(fx), _mm_set1_epi32(g.nx as i32 - 2));
        let r = _mm_min_epi32(_mm256_cvttpd_epi32(fy), _mm_set1_epi32(g.ny as i32 - 2));
        let tx = _mm256_sub_pd(fx, _mm256_cvtepi32_pd(c));
        let ty = _mm256_sub_pd(fy, _mm256_cvtepi32_pd(r));
        let i = _mm_add_epi32(_mm_mullo_epi32(r, _mm_set1_epi32(g.nx as i32)), c);
        let nx = _mm_set1_epi32(g.nx as i32);
        let p = g.height_m.as_ptr();
        // Safety: 0 <= c <= nx - 2 and 0 <= r <= ny - 2, so i + nx + 1 < nx * ny.
        let (h00, h01, h10, h11) = unsafe {
            (
                _mm256_cvtps_pd(_mm_i32gather_ps::<4>(p, i)),
                _mm256_cvtps_pd(_mm_i32gather_ps::<4>(
                    p,
                    _mm_add_epi32(i, _mm_set1_epi32(1)),
                )),
                _mm256_cvtps_pd(_mm_i32gather_ps::<4>(p, _mm_add_epi32(i, nx))),
                _mm256_cvtps_pd(_mm_i32gather_ps::<4>(
                    p,
                    _mm_add_epi32(_mm_add_epi32(i, nx), _mm_set1_epi32(1)),
                )),
            )
        };
        let one = set(1.0);
        let ux = _mm256_sub_pd(one, tx);
        let top = _mm256_add_pd(_mm256_mul_pd(h00, ux), _mm256_mul_pd(h01, tx));
        let bot = _mm256_add_pd(_mm256_mul_pd(h10, ux), _mm256_mul_pd(h11, tx));
        let v = _mm256_add_pd(
            _mm256_mul_pd(top, _mm256_sub_pd(one, ty)),
            _mm256_mul_pd(bot, ty),
        );
        let mut out = [0.0; 4];
        // Safety: 4-element array.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        Some(out)
    }
}

/// Nested levels, finest first; the composite height at a point is that of the finest
/// level covering it.
#[derive(Clone, Debug)]
pub struct Terrain {
    /// Levels, finest first.
    pub levels: Vec<Level>,
}

/// Samples `nx x ny` nodes at spacing `m` from NW corner `(ox, oy)`, in parallel row bands.
fn sample_block(world: &dyn Surface, ox: f64, oy: f64, m: f64, nx: usize, ny: usize) -> HeightGrid {
    let band = 32usize;
    let bands: Vec<HeightGrid> = (0..ny.div_ceil(band))
        .into_par_iter()
        .map(|b| {
            let rows = band.min(ny - b * band);
            world.sample_grid_filtered(ox, oy - (b * band) as f64 * m, m, nx, rows, m)
        })
        .collect();
    let mut height_m = Vec::with_capacity(nx * ny);
    let mut albedo = Vec::with_capacity(nx * ny);
    for g in bands {
        height_m.extend_from_slice(&g.height_m);
        albedo.extend_from_slice(&g.albedo);
    }
    HeightGrid {
        origin_x_m: ox,
        origin_y_m: oy,
        m_per_px: m,
        nx,
        ny,
        height_m,
        albedo,
    }
}

/// A square level of spacing `m` around `(cx, cy)`. With `hole` (the finer level's square),
/// nodes more than 3 nodes inside the hole are not sampled (left at 0): nothing reads them,
/// since the finer level covers that area and only one cell of overlap is drawn.
fn sample_square(
    world: &dyn Surface,
    cx: f64,
    cy: f64,
    half: f64,
    m: f64,
    hole: Option<[f64; 4]>,
) -> Level {
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
    let mut grid = HeightGrid {
        origin_x_m: origin_x,
        origin_y_m: origin_y,
        m_per_px: m,
        nx,
        ny,
        height_m: vec![0.0; nx * ny],
        albedo: vec![0.0; nx * ny],
    };
    // Node index ranges [hc0, hc1) x [hr0, hr1) left unsampled.
    let (hc0, hc1, hr0, hr1) = match hole {
        Some(h) => {
            let col = |x: f64| ((x - origin_x) / m - 0.5).max(0.0);
            let row = |y: f64| ((origin_y - y) / m - 0.5).max(0.0);
            let hc0 = (col(h[0]).ceil() as usize + 3).min(nx);
            let hc1 = (col(h[2]).floor() as usize).saturating_sub(3).max(hc0);
            let hr0 = (row(h[3]).ceil() as usize + 3).min(ny);
            let hr1 = (row(h[1]).floor() as usize).saturating_sub(3).max(hr0);
            (hc0, hc1, hr0, hr1)
        }
        None => (0, 0, 0, 0),
    };
    let mut put = |c0: usize, r0: usize, w: usize, h: usize| {
        if w == 0 || h == 0 {
            return;
        }
        let b = sample_block(
            world,
            origin_x + c0 as f64 * m,
            origin_y - r0 as f64 * m,
            m,
            w,
            h,
        );
        for r in 0..h {
            let dst = (r0 + r) * nx + c0;
            grid.height_m[dst..dst + w].copy_from_slice(&b.height_m[r * w..(r + 1) * w]);
            grid.albedo[dst..dst + w].copy_from_slice(&b.albedo[r * w..(r + 1) * w]);
        }
    };
    if hc1 > hc0 && hr1 > hr0 {
        put(0, 0, nx, hr0); // north band
        put(0, hr0, hc0, hr1 - hr0); // west
        put(hc1, hr0, nx - hc1, hr1 - hr0); // east
        put(0, hr1, nx, ny - hr1); // south band
    } else {
        put(0, 0, nx, ny);
    }
    Level {
        grid,
        bounds: [cx - half, cy - half, cx + half, cy + half],
    }
}

impl Terrain {
    /// Levels around a rover at `(x_m, y_m)` for a camera of focal length `focal_px`:
    /// level 0 has `near_cell_m` cells out to where a cell projects to `lod_px_per_cell`
    /// pixels; each next level doubles cell size and extent, out to `max_range_m`.
    pub fn around(
        world: &dyn Surface,
        x_m: f64,
        y_m: f64,
        opts: &RenderOptions,
        focal_px: f64,
    ) -> Self {
        Self::around_cached(world, x_m, y_m, opts, focal_px, None)
    }

    /// As [`Terrain::around`], taking coarse levels (node spacing >= [`CACHE_MIN_M`]) from
    /// `cache` (tiles of the same world lattice, so results are bit-identical).
    pub fn around_cached(
        world: &dyn Surface,
        x_m: f64,
        y_m: f64,
        opts: &RenderOptions,
        focal_px: f64,
        cache: Option<&TileCache>,
    ) -> Self {
        let m0 = opts.near_cell_m;
        // Keep level 0 at least 4 m and at most 512 cells across.
        let half0 = (focal_px * m0 / opts.lod_px_per_cell).clamp(4.0, 256.0 * m0);
        let mut levels = Vec::new();
        let (mut half, mut m) = (half0, m0);
        loop {
            let hole = levels.last().map(|l: &Level| l.bounds);
            let level = match cache {
                Some(c) if m >= CACHE_MIN_M => c.square(world, x_m, y_m, half, m, hole),
                _ => sample_square(world, x_m, y_m, half, m, hole),
            };
            levels.push(level);
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
    pub fn region(
        world: &dyn Surface,
        geo: &GeoRef,
        w: u32,
        h: u32,
        reach_m: f64,
        cache: Option<&TileCache>,
    ) -> Self {
        let m = geo.m_per_px() as f64;
        let ox = geo.origin_x_m() as f64;
        let oy = geo.origin_y_m() as f64;
        let (nx, ny) = (w as usize + 2, h as usize + 2);
        // Sample by bands of rows in parallel.
        let band = 64usize;
        let bands: Vec<HeightGrid> = (0..ny.div_ceil(band))
            .into_par_iter()
            .map(|b| {
                let rows = band.min(ny - b * band);
                world.sample_grid_filtered(ox - m, oy + m - (b * band) as f64 * m, m, nx, rows, m)
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
        // Coarse surround for shadows cast from outside: about 128 nodes across, never finer
        // than 2 px; the raster itself is not re-sampled.
        // Spacing 0.1 m x 2^k so that the surround's tiles are shared through a cache.
        let need = (2.0 * half / 128.0).max(2.0 * m);
        let mut m1 = 0.1;
        while m1 < need {
            m1 *= 2.0;
        }
        let own;
        let cache = match cache {
            Some(c) => c,
            None => {
                own = TileCache::new(1 << 20);
                &own
            }
        };
        let l1 = if m1 >= CACHE_MIN_M {
            cache.square(world, cx, cy, half, m1, Some(bounds))
        } else {
            sample_square(world, cx, cy, half, m1, Some(bounds))
        };
        Self {
            levels: vec![l0, l1],
        }
    }

    /// Whether every level's square lies inside the next one's (as [`Terrain::around`] and
    /// [`Terrain::region`] build them): then the levels containing a point are a suffix.
    pub(crate) fn nested(&self) -> bool {
        self.levels.windows(2).all(|w| {
            let (a, b) = (w[0].bounds, w[1].bounds);
            b[0] <= a[0] && b[1] <= a[1] && b[2] >= a[2] && b[3] >= a[3]
        })
    }

    /// The first level whose square contains `(x, y)` (`levels.len()`: none), for
    /// [`Terrain::nested`] terrains only, searched from `hint` (and left there): points met
    /// one after the other along a line mostly stay in one level.
    #[inline]
    pub(crate) fn first_containing(&self, x: f64, y: f64, hint: &mut usize) -> usize {
        let n = self.levels.len();
        // Containment is monotone in the level index (nested squares); past the last level
        // counts as containing.
        let inside = |j: usize| self.levels[j].contains(x, y);
        let mut j = (*hint).min(n);
        if j == n || inside(j) {
            while j > 0 && inside(j - 1) {
                j -= 1;
            }
        } else {
            while j < n && !inside(j) {
                j += 1;
            }
        }
        *hint = j;
        j
    }

    /// [`Terrain::height`]'s level and node coordinates at `(x, y)`: the first level from
    /// `first` on whose square contains the point and whose node lattice covers it (`first`:
    /// 0, or [`Terrain::first_containing`] of a nested terrain).
    #[inline]
    pub(crate) fn locate_from(&self, x: f64, y: f64, first: usize) -> Option<(usize, f64, f64)> {
        for (k, l) in self.levels.iter().enumerate().skip(first) {
            if l.contains(x, y) {
                if let Some((fx, fy)) = l.locate(x, y) {
                    return Some((k, fx, fy));
                }
            }
        }
        None
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

/// Finest node spacing whose levels a [`TileCache`] keeps, metres. Finer levels
/// are cheap to sample (the world's grid sampler) and rarely shared between locations.
pub const CACHE_MIN_M: f64 = 0.75;

/// Nodes per side of the lattice tiles whose frame cached nodes are computed in (node
/// `(c, r)` of tile `(tx, ty)` at `(tx * 64 * m + (c + 0.5) m, (ty + 1) * 64 * m - (r + 0.5) m)`,
/// sampled as part of that 64 x 64 grid).
const TILE_N: usize = 64;

/// Nodes per side of the blocks the cache fills and keeps: a tile is sampled block by block
/// as its blocks are needed (the same values as sampling the whole tile).
const BLOCK_N: usize = 16;

type TileKey = (u64, i64, i64);
type TileData = std::sync::Arc<(Vec<f32>, Vec<f32>)>;

/// Heights and albedo of world-lattice blocks (16 x 16 nodes of 64 x 64 tiles) of coarse
/// levels, shared by the renders of many locations of one world (e.g. a dataset run): far
/// terrain is sampled once instead of once per location. Use one cache per world.
/// Thread-safe; when it holds more than its node budget it is emptied.
pub struct TileCache {
    tiles: std::sync::RwLock<std::collections::HashMap<TileKey, TileData>>,
    max_tiles: usize,
}

impl TileCache {
    /// A cache holding at most about `max_nodes` nodes (8 bytes each).
    pub fn new(max_nodes: usize) -> Self {
        Self {
            tiles: Default::default(),
            max_tiles: (max_nodes / (BLOCK_N * BLOCK_N)).max(256),
        }
    }

    /// Block `(bx, by)` (node columns `bx * 16..`, northing indices `by * 16..`; row 0 is the
    /// northernmost, index `by * 16 + 15`) of the level of spacing `m`.
    fn tile(&self, world: &dyn Surface, m: f64, bx: i64, by: i64) -> TileData {
        let key = (m.to_bits(), bx, by);
        if let Ok(map) = self.tiles.read() {
            if let Some(t) = map.get(&key) {
                return t.clone();
            }
        }
        // The block's tile (tx, ty): node columns tx*N.., node rows (northing index)
        // ty*N.. (row 0 of the tile is the northernmost, index ty*N + N - 1).
        let (n, b) = (TILE_N as i64, BLOCK_N as i64);
        let (tx, ty) = ((bx * b).div_euclid(n), (by * b).div_euclid(n));
        let c0 = (bx * b - tx * n) as usize;
        let r0 = ((ty + 1) * n - (by + 1) * b) as usize;
        let (h, a) = world.sample_grid_window(
            (tx * n) as f64 * m,
            ((ty + 1) * n) as f64 * m,
            m,
            TILE_N,
            TILE_N,
            m,
            c0..c0 + BLOCK_N,
            r0..r0 + BLOCK_N,
        );
        let t = std::sync::Arc::new((h, a));
        if let Ok(mut map) = self.tiles.write() {
            if map.len() >= self.max_tiles {
                map.clear();
            }
            map.insert(key, t.clone());
        }
        t
    }

    /// The level square of [`sample_square`], assembled from blocks; blocks wholly inside
    /// `hole` (shrunk by 3 nodes) are not fetched (left at 0, never read).
    fn square(
        &self,
        world: &dyn Surface,
        cx: f64,
        cy: f64,
        half: f64,
        m: f64,
        hole: Option<[f64; 4]>,
    ) -> Level {
        let c0 = ((cx - half) / m).floor() as i64 - 1;
        let c1 = ((cx + half) / m).ceil() as i64 + 1;
        let r0 = ((cy + half) / m).ceil() as i64 + 1; // north edge, in nodes
        let r1 = ((cy - half) / m).floor() as i64 - 1;
        let nx = (c1 - c0) as usize;
        let ny = (r0 - r1) as usize;
        let n = BLOCK_N as i64;
        let mut height_m = vec![0f32; nx * ny];
        let mut albedo = vec![0f32; nx * ny];
        // Node (c, r) of the level: column gx = c0 + c, northing index gy = r0 - 1 - r.
        let tys: Vec<i64> = (r1.div_euclid(n)..=(r0 - 1).div_euclid(n)).collect();
        let txs: Vec<i64> = (c0.div_euclid(n)..=(c1 - 1).div_euclid(n)).collect();
        // Hole in global node indices: columns [hx0, hx1), northing [hy0, hy1).
        let (hx0, hx1, hy0, hy1) = match hole {
            Some(h) => (
                (h[0] / m).ceil() as i64 + 3,
                (h[2] / m).floor() as i64 - 3,
                (h[1] / m).ceil() as i64 + 3,
                (h[3] / m).floor() as i64 - 3,
            ),
            None => (0, 0, 0, 0),
        };
        let inside_hole = |tx: i64, ty: i64| {
            tx * n >= hx0 && (tx + 1) * n <= hx1 && ty * n >= hy0 && (ty + 1) * n <= hy1
        };
        let pairs: Vec<(i64, i64)> = tys
            .iter()
            .flat_map(|&ty| txs.iter().map(move |&tx| (tx, ty)))
            .filter(|&(tx, ty)| !inside_hole(tx, ty))
            .collect();
        let tiles: Vec<_> = pairs
            .par_iter()
            .map(|&(tx, ty)| ((tx, ty), self.tile(world, m, tx, ty)))
            .collect();
        for ((tx, ty), t) in tiles {
            let gx0 = (tx * n).max(c0);
            let gx1 = ((tx + 1) * n).min(c1);
            let gy0 = (ty * n).max(r1);
            let gy1 = ((ty + 1) * n).min(r0);
            for gy in gy0..gy1 {
                let r = (r0 - 1 - gy) as usize;
                let tr = ((ty + 1) * n - 1 - gy) as usize;
                let tc0 = (gx0 - tx * n) as usize;
                let w = (gx1 - gx0) as usize;
                let dst = r * nx + (gx0 - c0) as usize;
                let src = tr * BLOCK_N + tc0;
                height_m[dst..dst + w].copy_from_slice(&t.0[src..src + w]);
                albedo[dst..dst + w].copy_from_slice(&t.1[src..src + w]);
            }
        }
        Level {
            grid: HeightGrid {
                origin_x_m: c0 as f64 * m,
                origin_y_m: r0 as f64 * m,
                m_per_px: m,
                nx,
                ny,
                height_m,
                albedo,
            },
            bounds: [cx - half, cy - half, cx + half, cy + half],
        }
    }
}
