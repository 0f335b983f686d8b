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
}

impl NodeAttrs {
    /// Normals and shadows of every node of `terrain`.
    pub fn compute(terrain: &Terrain, shadow: &ShadowField) -> Self {
        use rayon::prelude::*;
        let per: Vec<(Vec<[f32; 3]>, Vec<f32>)> = terrain
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
                (normal, lit)
            })
            .collect();
        let (normal, lit) = per.into_iter().unzip();
        Self { normal, lit }
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
/// interpolated perspective-correctly.
struct Fragments {
    inv_z: Vec<f32>,
    normal: Vec<[f32; 3]>,
    albedo: Vec<f32>,
    lit: Vec<f32>,
    /// Mesh level of the pixel's triangle.
    level: Vec<u8>,
    w: usize,
    h: usize,
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
        inv_z: vec![0f32; w * h],
        normal: vec![[0f32; 3]; w * h],
        albedo: vec![0f32; w * h],
        lit: vec![0f32; w * h],
        level: vec![0u8; w * h],
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
        verts.clear();
        verts.resize(nx * ny, Vtx::default());
        let normals = &attrs.normal[k];
        let lits = &attrs.lit[k];
        for rr in 0..ny {
            let y = g.origin_y_m - (rr as f64 + 0.5) * g.m_per_px;
            for c in 0..nx {
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
        for rr in 0..ny - 1 {
            let y_n = g.origin_y_m - (rr as f64 + 0.5) * m;
            let y_s = y_n - m;
            if y_n < own[1] - m || y_s > own[3] + m {
                continue;
            }
            for c in 0..nx - 1 {
                let x_w = g.origin_x_m + (c as f64 + 0.5) * m;
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
                for &q in &idx {
                    let p = verts[q];
                    behind |= p.z < NEAR_M;
                    u0 = u0.min(p.u);
                    u1 = u1.max(p.u);
                    v0 = v0.min(p.v);
                    v1 = v1.max(p.v);
                }
                if behind || u1 < 0.0 || v1 < 0.0 || u0 > w as f32 || v0 > h as f32 {
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
    let shade = shade_pixels(&frag, terrain, detail, cam, sun, opts);
    let mut range = vec![0f32; w * h];
    for j in 0..h {
        let dv = (j as f32 + 0.5 - cam.cy) / cam.focal_px;
        for i in 0..w {
            let k = j * w + i;
            if frag.inv_z[k] > 0.0 {
                let du = (i as f32 + 0.5 - cam.cx) / cam.focal_px;
                range[k] = (1.0 + du * du + dv * dv).sqrt() / frag.inv_z[k];
            }
        }
    }
    (shade, range)
}

/// Shades every covered pixel once (see [`render_view`]); gray levels 0..255, sky 0.
fn shade_pixels(
    frag: &Fragments,
    terrain: &Terrain,
    detail: Option<&DetailTexture>,
    cam: &Camera,
    sun: &Sun,
    opts: &RenderOptions,
) -> Vec<f32> {
    let (w, h) = (frag.w, frag.h);
    let mut shade = vec![0f32; w * h];
    let sdir = sun.direction();
    let gmap = super::GrayMap::new(opts.gamma);
    let rot = cam.world_to_cam;
    // Camera-to-world: the transpose of world_to_cam.
    let col = |j: usize| [rot[(0, j)] as f64, rot[(1, j)] as f64, rot[(2, j)] as f64];
    let (c0, c1, c2) = (col(0), col(1), col(2));
    let centre = [
        cam.centre.x as f64,
        cam.centre.y as f64,
        cam.centre.z as f64,
    ];
    let f = cam.focal_px as f64;
    let spacing: Vec<f64> = terrain.levels.iter().map(|l| l.m()).collect();
    for j in 0..h {
        let yn = (j as f64 + 0.5 - cam.cy as f64) / f;
        for i in 0..w {
            let k = j * w + i;
            let iz = frag.inv_z[k];
            if iz <= 0.0 {
                continue;
            }
            let z = 1.0 / iz as f64;
            let xn = (i as f64 + 0.5 - cam.cx as f64) / f;
            // Camera-frame point (xn z, yn z, z) to world offset from the centre:
            // world = R^T cam, R^T's rows are world_to_cam's columns.
            let pc = [xn * z, yn * z, z];
            let d = [
                c0[0] * pc[0] + c0[1] * pc[1] + c0[2] * pc[2],
                c1[0] * pc[0] + c1[1] * pc[1] + c1[2] * pc[2],
                c2[0] * pc[0] + c2[1] * pc[1] + c2[2] * pc[2],
            ];
            let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
            let view = [-d[0] / dist, -d[1] / dist, -d[2] / dist];
            let nb = frag.normal[k];
            let mut n = [nb[0] as f64, nb[1] as f64, nb[2] as f64];
            let mut albedo = frag.albedo[k] as f64;
            // Ground footprint of the pixel across the line of sight, metres.
            let across = z / f;
            // The mesh's shadow mask, sharpened: the 0.5 contour of its bilinear mask is
            // the edge, drawn one pixel wide instead of one lattice cell wide.
            let cell = spacing[frag.level[k] as usize];
            let gain = (cell / across).max(1.0);
            let mut lit = (0.5 + (frag.lit[k] as f64 - 0.5) * gain).clamp(0.0, 1.0);
            let (wx, wy) = (centre[0] + d[0], centre[1] + d[1]);
            let texture = match detail {
                Some(t) if t.covers(wx, wy) => {
                    // Stretched along the line of sight by 1 / cos e; the geometric mean of
                    // the two widths picks the mip.
                    let nl = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-9);
                    let cos_e = ((n[0] * view[0] + n[1] * view[1] + n[2] * view[2]) / nl).max(0.05);
                    t.sample(wx, wy, across / cos_e.sqrt())
                }
                _ => None,
            };
            if let Some(s) = texture {
                let wgt = s.weight as f64;
                let t = s.texel;
                n = [
                    n[0] - wgt * t.gx as f64 * n[2],
                    n[1] - wgt * t.gy as f64 * n[2],
                    n[2],
                ];
                albedo *= 1.0 + wgt * (t.albedo_mul as f64 - 1.0);
                lit += wgt * (t.lit as f64 - lit);
            }
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-9);
            let n = [n[0] / l, n[1] / l, n[2] / l];
            shade[k] = gmap.gray(opts.radiance(albedo, n, sdir, view, lit));
        }
    }
    shade
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
    let i0 = (min_u - 0.5).ceil().max(0.0);
    let i1 = (max_u - 0.5).floor().min(w as f32 - 1.0);
    let j0 = (min_v - 0.5).ceil().max(0.0);
    let j1 = (max_v - 0.5).floor().min(h as f32 - 1.0);
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
        let row = j * w;
        for i in i0..=i1 {
            let px = i as f32 + 0.5;
            let w0 = ((c.u - b.u) * (py - b.v) - (c.v - b.v) * (px - b.u)) * inv_area;
            let w1 = ((a.u - c.u) * (py - c.v) - (a.v - c.v) * (px - c.u)) * inv_area;
            let w2 = 1.0 - w0 - w1;
            if w0 < EPS || w1 < EPS || w2 < EPS {
                continue;
            }
            let iz = w0 * iza + w1 * izb + w2 * izc;
            let k = row + i;
            if iz > frag.inv_z[k] {
                frag.inv_z[k] = iz;
                let q = 1.0 / iz;
                let at = |t: usize| (w0 * pa[t] + w1 * pb[t] + w2 * pc[t]) * q;
                frag.normal[k] = [at(0), at(1), at(2)];
                frag.albedo[k] = at(3);
                frag.lit[k] = at(4);
                frag.level[k] = lvl;
            }
        }
    }
}
