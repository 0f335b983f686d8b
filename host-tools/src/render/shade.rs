//! Shading of a rasterized view: each covered pixel once, after the depth test
//! ([`super::raster`]), by per-row passes that the compiler vectorizes (AVX2 where the CPU
//! has it), each value the same f64 operations as a per-pixel computation.

use super::detail::DetailTexture;
use super::raster::Fragments;
use super::terrain::Terrain;
use super::{RenderOptions, Sun};
use orbfix::camera::Camera;

/// One image row's per-pixel geometry, computed for every pixel of the row (sky too, where
/// the values are never read) by branch-free loops the compiler vectorizes; each value is the
/// same sequence of f64 operations as a per-pixel computation, so the bits are the same.
struct RowGeometry {
    /// World offset from the camera centre, metres (x and y).
    dx: Vec<f64>,
    dy: Vec<f64>,
    /// Unit vector to the viewer, world frame.
    view: [Vec<f64>; 3],
    /// Ground footprint of the pixel across the line of sight, metres.
    across: Vec<f64>,
    /// The shaded surface's normal (not yet unit), albedo and lit fraction 0..1, filled for
    /// covered pixels by the per-pixel pass.
    normal: [Vec<f64>; 3],
    albedo: Vec<f64>,
    lit: Vec<f64>,
    /// Position in the gray table ([`super::GrayMap::position`]) of the pixel's radiance.
    position: Vec<f64>,
}

/// Camera-to-world rotation, centre and focal length of [`shade_pixels`]'s camera (f64).
struct ShadeCamera {
    /// Columns of world_to_cam (the rows of its transpose, camera to world).
    c0: [f64; 3],
    c1: [f64; 3],
    c2: [f64; 3],
    /// Focal length, pixels.
    f: f64,
}

impl RowGeometry {
    fn new(w: usize) -> Self {
        Self {
            dx: vec![0.0; w],
            dy: vec![0.0; w],
            view: [vec![0.0; w], vec![0.0; w], vec![0.0; w]],
            across: vec![0.0; w],
            normal: [vec![0.0; w], vec![0.0; w], vec![0.0; w]],
            albedo: vec![0.0; w],
            lit: vec![0.0; w],
            position: vec![0.0; w],
        }
    }

    /// Radiance of every pixel of the row from its normal, albedo, lit fraction and view
    /// direction, to its gray-table position (`w` pixels; sky pixels hold stale values
    /// whose results are never read).
    #[inline(always)]
    fn radiance_body(&mut self, w: usize, sdir: [f64; 3], opts: &RenderOptions) {
        let [n0, n1, n2] = &self.normal;
        let (n0, n1, n2) = (&n0[..w], &n1[..w], &n2[..w]);
        let [v0, v1, v2] = &self.view;
        let (v0, v1, v2) = (&v0[..w], &v1[..w], &v2[..w]);
        let albedo = &self.albedo[..w];
        let lit = &self.lit[..w];
        let position = &mut self.position[..w];
        for i in 0..w {
            let n = [n0[i], n1[i], n2[i]];
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-9);
            let n = [n[0] / l, n[1] / l, n[2] / l];
            let view = [v0[i], v1[i], v2[i]];
            position[i] = super::GrayMap::position(opts.radiance(albedo[i], n, sdir, view, lit[i]));
        }
    }

    /// [`Self::radiance_body`] compiled for AVX2 (wider lanes, the same operations per lane).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn radiance_avx2(&mut self, w: usize, sdir: [f64; 3], opts: &RenderOptions) {
        self.radiance_body(w, sdir, opts);
    }

    fn radiance(&mut self, w: usize, sdir: [f64; 3], opts: &RenderOptions, avx2: bool) {
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // Safety: `avx2` is true only where the CPU was detected to support AVX2.
            unsafe { self.radiance_avx2(w, sdir, opts) };
            return;
        }
        let _ = avx2;
        self.radiance_body(w, sdir, opts);
    }

    /// Fills the row from its `1 / z` (`inv_z`), the columns' normalized image x (`xs`) and
    /// the row's normalized image y (`yn`). All slices as long as the row.
    #[inline(always)]
    fn fill_body(&mut self, inv_z: &[f32], xs: &[f64], yn: f64, cam: &ShadeCamera) {
        let w = inv_z.len();
        let (c0, c1, c2, f) = (cam.c0, cam.c1, cam.c2, cam.f);
        let xs = &xs[..w];
        let dx = &mut self.dx[..w];
        let dy = &mut self.dy[..w];
        let [v0, v1, v2] = &mut self.view;
        let (v0, v1, v2) = (&mut v0[..w], &mut v1[..w], &mut v2[..w]);
        let across = &mut self.across[..w];
        for i in 0..w {
            let z = 1.0 / inv_z[i] as f64;
            let xn = xs[i];
            // Camera-frame point (xn z, yn z, z) to world offset from the centre:
            // world = R^T cam, R^T's rows are world_to_cam's columns.
            let pc = [xn * z, yn * z, z];
            let d = [
                c0[0] * pc[0] + c0[1] * pc[1] + c0[2] * pc[2],
                c1[0] * pc[0] + c1[1] * pc[1] + c1[2] * pc[2],
                c2[0] * pc[0] + c2[1] * pc[1] + c2[2] * pc[2],
            ];
            let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
            dx[i] = d[0];
            dy[i] = d[1];
            v0[i] = -d[0] / dist;
            v1[i] = -d[1] / dist;
            v2[i] = -d[2] / dist;
            across[i] = z / f;
        }
    }

    /// [`Self::fill_body`] compiled for AVX2 (wider lanes, the same operations per lane).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn fill_avx2(&mut self, inv_z: &[f32], xs: &[f64], yn: f64, cam: &ShadeCamera) {
        self.fill_body(inv_z, xs, yn, cam);
    }

    fn fill(&mut self, inv_z: &[f32], xs: &[f64], yn: f64, cam: &ShadeCamera, avx2: bool) {
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // Safety: `avx2` is true only where the CPU was detected to support AVX2.
            unsafe { self.fill_avx2(inv_z, xs, yn, cam) };
            return;
        }
        let _ = avx2;
        self.fill_body(inv_z, xs, yn, cam);
    }
}

/// Whether the CPU supports AVX2 (wider lanes for the shading's vectorized loops).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Shades every covered pixel once (see [`super::raster::render_view`]); gray levels 0..255, sky 0.
pub(super) fn shade_pixels(
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
    let f = cam.focal_px as f64;
    let scam = ShadeCamera {
        c0: col(0),
        c1: col(1),
        c2: col(2),
        f,
    };
    let centre = [cam.centre.x as f64, cam.centre.y as f64];
    let spacing: Vec<f64> = terrain.levels.iter().map(|l| l.m()).collect();
    // Normalized image x of each column.
    let xs: Vec<f64> = (0..w)
        .map(|i| (i as f64 + 0.5 - cam.cx as f64) / f)
        .collect();
    let avx2 = has_avx2();
    let mut geo = RowGeometry::new(w);
    // The row's `1 / z`, contiguous for the vectorized pass.
    let mut inv_z = vec![0f32; w];
    for j in 0..h {
        let yn = (j as f64 + 0.5 - cam.cy as f64) / f;
        let row = j * w..(j + 1) * w;
        let fr = &frag.px[row.clone()];
        for (o, p) in inv_z.iter_mut().zip(fr) {
            *o = p.inv_z;
        }
        if !inv_z.iter().any(|&iz| iz > 0.0) {
            continue;
        }
        geo.fill(&inv_z, &xs, yn, &scam, avx2);
        let out = &mut shade[row];
        for (i, p) in fr.iter().enumerate() {
            if p.inv_z <= 0.0 {
                continue;
            }
            let view = [geo.view[0][i], geo.view[1][i], geo.view[2][i]];
            let nb = p.normal;
            let mut n = [nb[0] as f64, nb[1] as f64, nb[2] as f64];
            let mut albedo = p.albedo as f64;
            // Ground footprint of the pixel across the line of sight, metres.
            let across = geo.across[i];
            // The mesh's shadow mask, sharpened: the 0.5 contour of its bilinear mask is
            // the edge, drawn one pixel wide instead of one lattice cell wide.
            let cell = spacing[p.level as usize];
            let gain = (cell / across).max(1.0);
            let mut lit = (0.5 + (p.lit as f64 - 0.5) * gain).clamp(0.0, 1.0);
            let (wx, wy) = (centre[0] + geo.dx[i], centre[1] + geo.dy[i]);
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
            geo.normal[0][i] = n[0];
            geo.normal[1][i] = n[1];
            geo.normal[2][i] = n[2];
            geo.albedo[i] = albedo;
            geo.lit[i] = lit;
        }
        geo.radiance(w, sdir, opts, avx2);
        for i in 0..w {
            if inv_z[i] > 0.0 {
                out[i] = gmap.gray_at(geo.position[i]);
            }
        }
    }
    shade
}
