//! Z-buffer rasterizer of the terrain mesh for one pinhole view.
//!
//! Each level's grid cells are split into two triangles; a level skips the cells lying
//! inside the next finer level (keeping one cell of overlap so there are no cracks).
//! Depth is tested on interpolated `1 / z`; the nearest surface's normal, albedo and lit
//! fraction are interpolated perspective-correctly per pixel, and each pixel is shaded once
//! afterwards, with the near-field texture ([`super::detail`]) where it reaches.

use super::detail::DetailTexture;
use super::shadow::ShadowField;
use super::terrain::Terrain;
use super::{RenderOptions, Sun};
use orbfix::camera::Camera;

/// Per-node attributes that do not depend on the view: normal, albedo, lit fraction.
#[derive(Clone, Debug)]
pub struct NodeAttrs {
    /// Per level, per node: unit normal.
    pub normal: Vec<Vec<[f32; 3]>>,
    /// Per level, per node: lit fraction 0..1.
    pub lit: Vec<Vec<f32>>,
    /// Per level, per block of [`BLOCK_CELLS`] x [`BLOCK_CELLS`] cells (row-major, see
    /// [`Blocks`]): lowest and highest node height of the block's nodes (its edges
    /// included), metres; `[-inf, inf]` where a height is not finite.
    pub block_z: Vec<Vec<[f32; 2]>>,
}

/// One level's normals, lit fractions and block height ranges (see [`NodeAttrs`]).
type LevelAttrs = (Vec<[f32; 3]>, Vec<f32>, Vec<[f32; 2]>);

/// Cells per side of a block culled against the view frustum as one.
pub const BLOCK_CELLS: usize = 16;

/// The blocks of a level's `(nx - 1) x (ny - 1)` cells.
#[derive(Clone, Copy)]
struct Blocks {
    nx: usize,
    ny: usize,
    /// Blocks per row and per column.
    bx: usize,
    by: usize,
}

impl Blocks {
    fn new(nx: usize, ny: usize) -> Self {
        let n = |k: usize| k.saturating_sub(1).div_ceil(BLOCK_CELLS);
        Self {
            nx,
            ny,
            bx: n(nx),
            by: n(ny),
        }
    }

    /// Block `(bc, br)`'s cells: columns `c0..c1`, rows `r0..r1` (its nodes: `c0..=c1`,
    /// `r0..=r1`).
    fn cells(&self, bc: usize, br: usize) -> (usize, usize, usize, usize) {
        let (c0, r0) = (bc * BLOCK_CELLS, br * BLOCK_CELLS);
        (
            c0,
            (c0 + BLOCK_CELLS).min(self.nx - 1),
            r0,
            (r0 + BLOCK_CELLS).min(self.ny - 1),
        )
    }

    /// Lowest and highest of `height` over the nodes of every block, row-major.
    fn z_range(&self, height: &[f32]) -> Vec<[f32; 2]> {
        let mut out = Vec::with_capacity(self.bx * self.by);
        for br in 0..self.by {
            for bc in 0..self.bx {
                let (c0, c1, r0, r1) = self.cells(bc, br);
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                let mut finite = true;
                for r in r0..=r1 {
                    for &z in &height[r * self.nx + c0..=r * self.nx + c1] {
                        finite &= z.is_finite();
                        lo = lo.min(z);
                        hi = hi.max(z);
                    }
                }
                out.push(if finite {
                    [lo, hi]
                } else {
                    [f32::NEG_INFINITY, f32::INFINITY]
                });
            }
        }
        out
    }
}

impl NodeAttrs {
    /// Normals and shadows of every node of `terrain`.
    pub fn compute(terrain: &Terrain, shadow: &ShadowField) -> Self {
        use rayon::prelude::*;
        let per: Vec<LevelAttrs> = terrain
            .levels
            .par_iter()
            .map(|l| {
                let (nx, ny) = (l.grid.nx, l.grid.ny);
                let mut normal = Vec::with_capacity(nx * ny);
                let mut lit = Vec::with_capacity(nx * ny);
                for r in 0..ny {
                    for c in 0..nx {
                        let n = l.normal(c, r);
                        normal.push([n[0] as f32, n[1] as f32, n[2] as f32]);
                        let (x, y) = l.node_xy(c, r);
                        lit.push(shadow.lit(x, y));
                    }
                }
                let block_z = if nx >= 2 && ny >= 2 {
                    Blocks::new(nx, ny).z_range(&l.grid.height_m)
                } else {
                    Vec::new()
                };
                (normal, lit, block_z)
            })
            .collect();
        let (mut normal, mut lit, mut block_z) = (Vec::new(), Vec::new(), Vec::new());
        for (n, l, z) in per {
            normal.push(n);
            lit.push(l);
            block_z.push(z);
        }
        Self {
            normal,
            lit,
            block_z,
        }
    }
}

#[derive(Clone, Copy, Default)]
struct Vtx {
    u: f32,
    v: f32,
    /// Camera depth, metres (<= 0: behind).
    z: f32,
    /// Unit normal, world frame.
    n: [f32; 3],
    /// Albedo.
    a: f32,
    /// Lit fraction.
    lit: f32,
}

const NEAR_M: f32 = 0.05;

/// What a pixel keeps of the nearest surface until it is shaded: the mesh's attributes,
/// interpolated perspective-correctly. One 32-byte record per pixel, so a depth-test win
/// writes one cache line.
#[derive(Clone, Copy, Default)]
#[repr(C, align(32))]
pub(super) struct Frag {
    /// `1 / z`, 1/metres (0: sky).
    pub(super) inv_z: f32,
    /// The surface's normal (interpolated, not unit), world frame.
    pub(super) normal: [f32; 3],
    /// Albedo (reflectance factor).
    pub(super) albedo: f32,
    /// Lit fraction, 0..1.
    pub(super) lit: f32,
    /// Mesh level of the pixel's triangle.
    pub(super) level: u8,
}

/// The image's fragments, row-major.
pub(super) struct Fragments {
    pub(super) px: Vec<Frag>,
    /// Width, pixels.
    pub(super) w: usize,
    /// Height, pixels.
    pub(super) h: usize,
}

/// Renders one view: gray levels (0..255 floats, sky 0) and range (metres, sky 0).
///
/// The mesh is rasterized first (depth test on `1 / z`, attributes interpolated per pixel),
/// then every pixel is shaded once: the mesh's normal plus the micro-relief slope of
/// `detail` (where it reaches), albedo times the texture's multiplier, and the texture's
/// cast shadow, or outside it the mesh's shadow mask sharpened to the pixel's footprint
/// (edges as sharp as the lattice allows, not a blur one lattice cell wide).
pub fn render_view(
    terrain: &Terrain,
    attrs: &NodeAttrs,
    detail: Option<&DetailTexture>,
    cam: &Camera,
    sun: &Sun,
    opts: &RenderOptions,
) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    let mut frag = Fragments {
        px: vec![Frag::default(); w * h],
        w,
        h,
    };
    let rot = cam.world_to_cam;
    let (ccx, ccy, ccz) = (
        cam.centre.x as f64,
        cam.centre.y as f64,
        cam.centre.z as f64,
    );
    let r = |i: usize, j: usize| rot[(i, j)] as f64;
    let rows = [
        [r(0, 0), r(0, 1), r(0, 2)],
        [r(1, 0), r(1, 1), r(1, 2)],
        [r(2, 0), r(2, 1), r(2, 2)],
    ];
    let f = cam.focal_px as f64;
    let (pcx, pcy) = (cam.cx as f64, cam.cy as f64);
    let mut verts: Vec<Vtx> = Vec::new();
    for (k, level) in terrain.levels.iter().enumerate() {
        let g = &level.grid;
        let (nx, ny) = (g.nx, g.ny);
        if nx < 2 || ny < 2 {
            continue;
        }
        verts.clear();
        verts.resize(nx * ny, Vtx::default());
        let normals = &attrs.normal[k];
        let lits = &attrs.lit[k];
        // Hole: cells wholly inside the finer level, shrunk by one cell of this level.
        let hole = if k > 0 {
            let b = terrain.levels[k - 1].bounds;
            let m = g.m_per_px;
            Some([b[0] + m, b[1] + m, b[2] - m, b[3] - m])
        } else {
            None
        };
        let own = level.bounds;
        let m = g.m_per_px;
        let lvl = k.min(255) as u8;
        // Cell edges as the cell loop computes them (each monotonic in its index).
        let x_w = |c: usize| g.origin_x_m + (c as f64 + 0.5) * m;
        let y_n = |rr: usize| g.origin_y_m - (rr as f64 + 0.5) * m;
        // Whether the cell loop would skip cells by their position alone: outside the
        // level's square (`x_e`, `y_s`: the east and south edges) or inside the hole.
        let outside = |x_w: f64, x_e: f64, y_s: f64, y_n: f64| {
            x_e < own[0] - m || x_w > own[2] + m || y_n < own[1] - m || y_s > own[3] + m
        };
        let in_hole = |x_w: f64, x_e: f64, y_s: f64, y_n: f64| match hole {
            Some(hb) => x_w >= hb[0] && x_e <= hb[2] && y_s >= hb[1] && y_n <= hb[3],
            None => false,
        };
        // Blocks whose every cell the cell loop would skip (below): wholly outside the
        // level's square, inside the hole, or with every node behind the near plane or on
        // the far side of one of the image's edges. Only the other blocks' nodes are
        // projected (a node on a block's edge once per block, the same value each time).
        let blocks = Blocks::new(nx, ny);
        let block_z = &attrs.block_z[k];
        let mut drawn = vec![false; blocks.bx * blocks.by];
        for br in 0..blocks.by {
            for bc in 0..blocks.bx {
                let (c0, c1, r0, r1) = blocks.cells(bc, br);
                // The extreme cell edges of the block's cells: every cell's west edge is
                // at least `bw`, its east edge at most `be`, and so on.
                let (bw, be) = (x_w(c0), x_w(c1 - 1) + m);
                let (bn, bs) = (y_n(r0), y_n(r1 - 1) - m);
                if outside(bw, be, bs, bn) || in_hole(bw, be, bs, bn) {
                    continue;
                }
                let [z0, z1] = block_z[br * blocks.bx + bc];
                if frustum_excludes(
                    [x_w(c0), x_w(c1)],
                    [y_n(r1), y_n(r0)],
                    [z0, z1],
                    [ccx, ccy, ccz],
                    &rows,
                    [f, pcx, pcy],
                    [w as f64, h as f64],
                ) {
                    continue;
                }
                drawn[br * blocks.bx + bc] = true;
                for rr in r0..=r1 {
                    let y = g.origin_y_m - (rr as f64 + 0.5) * g.m_per_px;
                    for c in c0..=c1 {
                        let i = rr * nx + c;
                        let x = g.origin_x_m + (c as f64 + 0.5) * g.m_per_px;
                        let zw = g.height_m[i] as f64;
                        let d = [x - ccx, y - ccy, zw - ccz];
                        let cz = rows[2][0] * d[0] + rows[2][1] * d[1] + rows[2][2] * d[2];
                        if cz < NEAR_M as f64 {
                            verts[i].z = cz as f32;
                            continue;
                        }
                        let cxx = rows[0][0] * d[0] + rows[0][1] * d[1] + rows[0][2] * d[2];
                        let cyy = rows[1][0] * d[0] + rows[1][1] * d[1] + rows[1][2] * d[2];
                        verts[i] = Vtx {
                            u: (f * cxx / cz + pcx) as f32,
                            v: (f * cyy / cz + pcy) as f32,
                            z: cz as f32,
                            n: normals[i],
                            a: g.albedo[i],
                            lit: lits[i],
                        };
                    }
                }
            }
        }
        // The cells in their original order (ties of the depth test go to the first drawn),
        // the culled blocks' left out.
        for rr in 0..ny - 1 {
            let y_n = y_n(rr);
            let y_s = y_n - m;
            if y_n < own[1] - m || y_s > own[3] + m {
                continue;
            }
            let br = rr / BLOCK_CELLS;
            for c in 0..nx - 1 {
                if !drawn[br * blocks.bx + c / BLOCK_CELLS] {
                    continue;
                }
                let x_w = x_w(c);
                let x_e = x_w + m;
                if x_e < own[0] - m || x_w > own[2] + m {
                    continue;
                }
                if let Some(hb) = hole {
                    if x_w >= hb[0] && x_e <= hb[2] && y_s >= hb[1] && y_n <= hb[3] {
                        continue;
                    }
                }
                let i = rr * nx + c;
                let idx = [i, i + 1, i + nx, i + nx + 1];
                // Cells behind the near plane or wholly outside the image: skip.
                let (mut u0, mut u1, mut v0, mut v1) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
                let mut behind = false;
                let mut nan = false;
                for &q in &idx {
                    let p = verts[q];
                    behind |= p.z < NEAR_M;
                    nan |= p.u.is_nan() | p.v.is_nan();
                    u0 = u0.min(p.u);
                    u1 = u1.max(p.u);
                    v0 = v0.min(p.v);
                    v1 = v1.max(p.v);
                }
                if behind || u1 < 0.0 || v1 < 0.0 || u0 > w as f32 || v0 > h as f32 {
                    continue;
                }
                // No pixel centre inside the cell's box: none inside either triangle's box
                // (which lies inside the cell's), so both would draw nothing.
                if !nan && (ceil(u0 - 0.5) > floor(u1 - 0.5) || ceil(v0 - 0.5) > floor(v1 - 0.5)) {
                    continue;
                }
                let a = verts[i];
                let b = verts[i + 1];
                let cc = verts[i + nx];
                let d = verts[i + nx + 1];
                tri(&mut frag, lvl, a, b, cc);
                tri(&mut frag, lvl, b, d, cc);
            }
        }
    }
    let shade = super::shade::shade_pixels(&frag, terrain, detail, cam, sun, opts);
    let mut range = vec![0f32; w * h];
    // Normalized image x of each column (f32).
    let dus: Vec<f32> = (0..w)
        .map(|i| (i as f32 + 0.5 - cam.cx) / cam.focal_px)
        .collect();
    for (j, (out, row)) in range
        .chunks_exact_mut(w)
        .zip(frag.px.chunks_exact(w))
        .enumerate()
    {
        let dv = (j as f32 + 0.5 - cam.cy) / cam.focal_px;
        // Branch-free: sky pixels compute a value and keep 0.
        for ((o, p), &du) in out.iter_mut().zip(row).zip(&dus) {
            let iz = p.inv_z;
            let r = (1.0 + du * du + dv * dv).sqrt() / iz;
            *o = if iz > 0.0 { r } else { 0.0 };
        }
    }
    (shade, range)
}

/// Margin of [`frustum_excludes`]'s side tests, pixels.
const FRUSTUM_MARGIN_PX: f64 = 2.0;

/// Whether every node of a block projects where the cell loop skips its cells: the block's
/// world box (`xs`, `ys`: west/east and south/north node positions, `zs`: lowest and
/// highest height, metres) lies wholly before the near plane, or wholly beyond one of the
/// image's edges by [`FRUSTUM_MARGIN_PX`]. The camera maps world `p` to camera
/// `rows * (p - centre)`; `cam` is the focal length and principal point, `size` the image's
/// width and height, pixels.
///
/// Each test is a half-space linear in the world point (the image's edge at `u = -M`, for
/// instance, is `f x + (cx + M) z < 0`), so it holds over the box if it holds at its eight
/// corners; a node in front of the near plane inside it then projects at `u < -M`, which
/// the f64 projection's rounding (relative 1e-16) cannot bring to 0. A node behind the near
/// plane makes its cells skipped anyway. Non-finite heights never exclude.
fn frustum_excludes(
    xs: [f64; 2],
    ys: [f64; 2],
    zs: [f32; 2],
    centre: [f64; 3],
    rows: &[[f64; 3]; 3],
    cam: [f64; 3],
    size: [f64; 2],
) -> bool {
    if !(zs[0].is_finite() && zs[1].is_finite()) {
        return false;
    }
    let [f, pcx, pcy] = cam;
    let mg = FRUSTUM_MARGIN_PX;
    // Per test, whether it holds at every corner so far.
    let (mut near, mut left, mut right, mut top, mut bottom) = (true, true, true, true, true);
    for x in xs {
        for y in ys {
            for z in zs {
                let d = [x - centre[0], y - centre[1], z as f64 - centre[2]];
                let cam = |r: &[f64; 3]| r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
                let (cx, cy, cz) = (cam(&rows[0]), cam(&rows[1]), cam(&rows[2]));
                near &= cz < NEAR_M as f64 * 0.5;
                left &= f * cx + (pcx + mg) * cz < 0.0;
                right &= f * cx + (pcx - size[0] - mg) * cz > 0.0;
                top &= f * cy + (pcy + mg) * cz < 0.0;
                bottom &= f * cy + (pcy - size[1] - mg) * cz > 0.0;
            }
        }
    }
    near || left || right || top || bottom
}

#[inline]
fn tri(frag: &mut Fragments, lvl: u8, a: Vtx, b: Vtx, c: Vtx) {
    if a.z < NEAR_M || b.z < NEAR_M || c.z < NEAR_M {
        return;
    }
    let (w, h) = (frag.w, frag.h);
    let min_u = a.u.min(b.u).min(c.u);
    let max_u = a.u.max(b.u).max(c.u);
    let min_v = a.v.min(b.v).min(c.v);
    let max_v = a.v.max(b.v).max(c.v);
    // Pixel centres (i + 0.5) inside the box.
    let i0 = ceil(min_u - 0.5).max(0.0);
    let i1 = floor(max_u - 0.5).min(w as f32 - 1.0);
    let j0 = ceil(min_v - 0.5).max(0.0);
    let j1 = floor(max_v - 0.5).min(h as f32 - 1.0);
    if !(i0 <= i1 && j0 <= j1) {
        return;
    }
    let area = (b.u - a.u) * (c.v - a.v) - (b.v - a.v) * (c.u - a.u);
    if area.abs() < 1e-9 {
        return;
    }
    let inv_area = 1.0 / area;
    let (iza, izb, izc) = (1.0 / a.z, 1.0 / b.z, 1.0 / c.z);
    // Attributes over z, for perspective-correct interpolation.
    let attr = |v: &Vtx, iz: f32| [v.n[0] * iz, v.n[1] * iz, v.n[2] * iz, v.a * iz, v.lit * iz];
    let (pa, pb, pc) = (attr(&a, iza), attr(&b, izb), attr(&c, izc));
    let (i0, i1, j0, j1) = (i0 as usize, i1 as usize, j0 as usize, j1 as usize);
    const EPS: f32 = -1e-5;
    for j in j0..=j1 {
        let py = j as f32 + 0.5;
        // Barycentric weights of pixel column `i` on this row, as computed below.
        let e0 = |i: usize| {
            let px = i as f32 + 0.5;
            ((c.u - b.u) * (py - b.v) - (c.v - b.v) * (px - b.u)) * inv_area
        };
        let e1 = |i: usize| {
            let px = i as f32 + 0.5;
            ((a.u - c.u) * (py - c.v) - (a.v - c.v) * (px - c.u)) * inv_area
        };
        // Wide rows: the columns where the first two weights pass (an interval of the box,
        // see `passing`); the loop still tests all three at each of them.
        let (i0, i1) = if i1 - i0 >= WIDE_ROW_PX {
            match passing(i0, i1, |i| e0(i) >= EPS)
                .and_then(|(l, r)| passing(l, r, |i| e1(i) >= EPS))
            {
                Some(s) => s,
                None => continue,
            }
        } else {
            (i0, i1)
        };
        // The row's span of the box; `i1 < w`, `j1 < h`, so it lies inside the image.
        let span = &mut frag.px[j * w + i0..j * w + i1 + 1];
        for (p, i) in span.iter_mut().zip(i0..=i1) {
            let (w0, w1) = (e0(i), e1(i));
            let w2 = 1.0 - w0 - w1;
            if (w0 < EPS) | (w1 < EPS) | (w2 < EPS) {
                continue;
            }
            let iz = w0 * iza + w1 * izb + w2 * izc;
            if iz > p.inv_z {
                let q = 1.0 / iz;
                let at = |t: usize| (w0 * pa[t] + w1 * pb[t] + w2 * pc[t]) * q;
                *p = Frag {
                    inv_z: iz,
                    normal: [at(0), at(1), at(2)],
                    albedo: at(3),
                    lit: at(4),
                    level: lvl,
                };
            }
        }
    }
}

/// Rows of a triangle's box at least this wide (pixels, less one) are narrowed by
/// [`passing`] before the per-pixel tests; narrower ones are scanned whole.
const WIDE_ROW_PX: usize = 6;

/// The columns of `lo..=hi` where `pass` holds, for a `pass` monotonic in the column (false
/// then true, or true then false): `None` if none. A barycentric weight as rasterized is
/// such a function on a row (`((A - B (px - u)) * s`: every rounding is monotonic), so
/// `w >= EPS` is, and the columns outside fail the test the scan would make (the weights
/// are finite: the vertices are, and the area is at least 1e-9).
#[inline]
fn passing(lo: usize, hi: usize, pass: impl Fn(usize) -> bool) -> Option<(usize, usize)> {
    match (pass(lo), pass(hi)) {
        (true, true) => Some((lo, hi)),
        (false, false) => None,
        // The last passing column.
        (true, false) => Some((lo, last_alike(lo, hi, true, &pass))),
        // The first passing column: one after the last failing one.
        (false, true) => Some((last_alike(lo, hi, false, &pass) + 1, hi)),
    }
}

/// The last column of `a..b` whose `pass` equals `at_a` (`pass(a) == at_a`,
/// `pass(b) != at_a`, monotonic between), by bisection.
#[inline]
fn last_alike(mut a: usize, mut b: usize, at_a: bool, pass: &impl Fn(usize) -> bool) -> usize {
    while b - a > 1 {
        let m = a + (b - a) / 2;
        if pass(m) == at_a {
            a = m;
        } else {
            b = m;
        }
    }
    a
}

/// `x.ceil()`, bit for bit up to the sign of a zero result (callers clamp at 0 or compare),
/// without the library call baseline x86-64 makes for it.
#[inline]
fn ceil(x: f32) -> f32 {
    // Below 2^23 in magnitude the truncation is exact in i32 and back; beyond, every f32
    // is an integer (and NaN goes to the library).
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t < x {
            t + 1.0
        } else {
            t
        }
    } else {
        x.ceil()
    }
}

/// `x.floor()`, bit for bit up to the sign of a zero result, as [`ceil`].
#[inline]
fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x.floor()
    }
}
