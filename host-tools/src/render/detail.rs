//! The near-field texture of the ground views: the world's micro-relief
//! ([`crate::world::micro`]: roughness, clods, pebbles) on a centimetre grid around the
//! rover, with cast shadows traced on that grid, so that the first metres of a view show
//! regolith grain, small angular rocks and shadows as sharp as the sun's half-degree disc
//! makes them, instead of the mesh's smooth shading.
//!
//! One texture is made per rover location and sun ([`DetailTexture::build`]) and shared by
//! every camera rendered there (the four views and their stereo partners). It is anchored to
//! the world lattice (texel centres at `(k + 0.5) cell`), so the same ground point has the
//! same texture in every camera. Per texel it keeps:
//! - `gx, gy`: the slope of the micro-relief (roughness + rocks), unitless, added to the
//!   mesh's interpolated normal by the rasterizer;
//! - `albedo_mul`: the albedo multiplier (soil grain, brighter rock; clods and pebbles too
//!   small for the grid by their covered area);
//! - `lit`: 0..1, the cast shadow of everything: the horizon sweep of `render::shadow` run
//!   on the texel grid over the mesh's height plus the micro-relief, each line first
//!   extended `shadow_reach_m` towards the sun over the coarse terrain.
//!
//! Mip levels (2 x 2 means) serve pixels whose ground footprint is larger than a texel; the
//! texture fades out over the last metre of its square, where the rasterizer's per-vertex
//! attributes take over.

use super::terrain::Terrain;
use super::{Sun, Surface};
use crate::world::micro::MicroRelief;
use rayon::prelude::*;

/// Number of mip levels kept (texel, 2, 4, 8 texels).
const MIPS: usize = 4;
/// Width of the fade at the square's edge, metres.
const FADE_M: f64 = 1.0;

/// One texel: micro-relief slope, albedo multiplier, lit fraction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Texel {
    /// Slope of the micro-relief towards east (dz/dx), unitless.
    pub gx: f32,
    /// Slope of the micro-relief towards north (dz/dy), unitless.
    pub gy: f32,
    /// Albedo multiplier (1 = the world's albedo).
    pub albedo_mul: f32,
    /// Lit fraction 0 (cast shadow) ..1.
    pub lit: f32,
}

impl Texel {
    #[inline]
    fn lerp(a: Texel, b: Texel, t: f32) -> Texel {
        Texel {
            gx: a.gx + (b.gx - a.gx) * t,
            gy: a.gy + (b.gy - a.gy) * t,
            albedo_mul: a.albedo_mul + (b.albedo_mul - a.albedo_mul) * t,
            lit: a.lit + (b.lit - a.lit) * t,
        }
    }
}

#[derive(Clone, Debug)]
struct Mip {
    /// Texel side, metres.
    m: f64,
    /// Texels per side.
    n: usize,
    /// Row-major, row 0 north.
    texels: Vec<Texel>,
}

/// What a pixel reads from the texture: the blended texel and the weight (0..1) with which
/// it replaces the mesh's own attributes (0 outside the square or for footprints larger
/// than the coarsest mip).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetailSample {
    /// The texel (trilinear).
    pub texel: Texel,
    /// Weight of the texture against the mesh's attributes.
    pub weight: f32,
}

/// The near-field texture around one rover location, for one sun.
#[derive(Clone, Debug)]
pub struct DetailTexture {
    /// West and north edges of the texel grid, metres.
    west: f64,
    north: f64,
    /// Centre of the square, metres.
    cx: f64,
    cy: f64,
    /// Half side of the square, metres.
    half: f64,
    mips: Vec<Mip>,
}

/// A square texel grid: `n x n` texels of side `m`, row 0 north, west and north edges in
/// metres.
#[derive(Clone, Copy, Debug)]
struct Grid {
    n: usize,
    west: f64,
    north: f64,
    m: f64,
}

impl Grid {
    /// World position of the (possibly fractional, possibly outside) texel `(c, r)`.
    #[inline]
    fn xy(&self, c: f64, r: f64) -> (f64, f64) {
        (
            self.west + (c + 0.5) * self.m,
            self.north - (r + 0.5) * self.m,
        )
    }
}

/// Cast shadows (1 lit, 0 shadow) of every texel: a horizon sweep like that of
/// [`super::shadow`], on the texel grid itself. With `a` the distance towards the sun and
/// `g = h - a tan e`, a texel is in shadow when a point nearer the sun on its sun line has
/// a larger `g`. The sweep runs line by line (columns, or rows when the sun is nearer north
/// or south) from the side of the sun; the running maximum of `g` along each sun line is
/// carried from one line to the next, read between two texels where the sun line crosses
/// the previous line (a shear, linear interpolation). Where the sun line leaves the grid,
/// its maximum comes from the mesh's terrain, traced `reach_m` towards the sun at the
/// terrain's own spacing.
fn cast_shadows(g: &Grid, height: &[f32], terrain: &Terrain, sun: &Sun, reach_m: f64) -> Vec<f32> {
    let n = g.n;
    let tan_e = sun.elevation_deg.to_radians().tan();
    let az = sun.azimuth_deg.to_radians();
    let (sx, sy) = (az.sin(), az.cos());
    let (cx, cy) = g.xy(0.5 * (n - 1) as f64, 0.5 * (n - 1) as f64);
    let key = |x: f64, y: f64, h: f64| h - ((x - cx) * sx + (y - cy) * sy) * tan_e;
    // Major axis: one step along it towards the sun moves the sun line `dv` texels across.
    let by_columns = sx.abs() >= sy.abs();
    let (du, dv) = if by_columns {
        (sx.signum(), -sy / sx.abs())
    } else {
        (-sy.signum(), sx / sy.abs())
    };
    // Texel (u, v) in major/minor terms -> (column, row), and its index.
    let cr = |u: f64, v: f64| if by_columns { (u, v) } else { (v, u) };
    let idx = |u: usize, v: usize| if by_columns { v * n + u } else { u * n + v };
    // Upstream maximum of `g` from a point off the grid: the terrain along the sun line.
    let outside = |x: f64, y: f64| -> f32 {
        let mut best = f64::NEG_INFINITY;
        let mut t = 0.0;
        while t <= reach_m {
            let (px, py) = (x + t * sx, y + t * sy);
            let step = match terrain.height(px, py) {
                Some((h, res)) => {
                    best = best.max(key(px, py, h));
                    res
                }
                None => reach_m / 64.0,
            };
            t += step.max(g.m);
        }
        best as f32
    };
    // Lines in sweep order: the sun-side line first.
    let order: Vec<usize> = if du > 0.0 {
        (0..n).rev().collect()
    } else {
        (0..n).collect()
    };
    // Whether the upstream point of minor index `v` falls off the grid (the same on every
    // line: the shear is constant).
    let off = |v: usize| !(0.0..=(n - 1) as f64).contains(&(v as f64 + dv));
    // Off-grid upstream values, computed in parallel up front: every texel of the first
    // line, and on the later lines the texels whose upstream point falls off the grid.
    let jobs: Vec<(usize, usize)> = order
        .iter()
        .enumerate()
        .flat_map(|(k, &u)| {
            (0..n)
                .filter(move |&v| k == 0 || off(v))
                .map(move |v| (u, v))
        })
        .collect();
    let ext: std::collections::HashMap<(usize, usize), f32> = jobs
        .par_iter()
        .map(|&(u, v)| {
            let (c, r) = cr(u as f64 + du, v as f64 + dv);
            let (x, y) = g.xy(c, r);
            ((u, v), outside(x, y))
        })
        .collect();
    let mut lit = vec![1f32; n * n];
    let mut prev = vec![f32::NEG_INFINITY; n];
    let mut cur = vec![f32::NEG_INFINITY; n];
    for (k, &u) in order.iter().enumerate() {
        for (v, out) in cur.iter_mut().enumerate() {
            let up = if k == 0 || off(v) {
                ext.get(&(u, v)).copied().unwrap_or(f32::NEG_INFINITY)
            } else {
                let w = v as f64 + dv;
                let v0 = (w as usize).min(n - 2);
                let t = (w - v0 as f64) as f32;
                prev[v0] + (prev[v0 + 1] - prev[v0]) * t
            };
            let (c, r) = cr(u as f64, v as f64);
            let (x, y) = g.xy(c, r);
            let i = idx(u, v);
            let here = key(x, y, height[i] as f64) as f32;
            if here < up - 1e-3 {
                lit[i] = 0.0;
            }
            *out = here.max(up);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    lit
}

/// Texel side (metres) for a camera of focal length `focal_px`: the ground footprint of a
/// pixel at 10 m, within 1..4 cm (3.1 cm at the default 640 x 360 views).
pub fn cell_for_focal(focal_px: f64) -> f64 {
    (10.0 / focal_px).clamp(0.01, 0.04)
}

impl DetailTexture {
    /// The texture of the square of half side `half_m` around `(cx, cy)` at texel side
    /// `cell_m`, over `terrain` (the mesh's levels: the heights under the micro-relief and
    /// the far terrain for the shadow sweep), for `sun`.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        surface: &dyn Surface,
        micro: &MicroRelief,
        terrain: &Terrain,
        cx: f64,
        cy: f64,
        half_m: f64,
        cell_m: f64,
        sun: &Sun,
        shadow_reach_m: f64,
    ) -> Self {
        let m = cell_m;
        // Texel columns k0..k0 + n (centres at (k + 0.5) m), a multiple of 2^(MIPS-1).
        let step = 1usize << (MIPS - 1);
        let n = (((2.0 * half_m / m).ceil() as usize).div_ceil(step) + 1) * step;
        let k0 = ((cx - 0.5 * n as f64 * m) / m).round();
        let j0 = ((cy + 0.5 * n as f64 * m) / m).round();
        let west = k0 * m;
        let north = j0 * m;
        // Octaves shorter than 2.5 texels would alias.
        let min_wl = 2.5 * m;
        // Rocks narrower than 1.5 texels are not drawn as relief: their covered area
        // brightens the texel instead.
        let r_geom = 0.75 * m;
        let band = 32usize;
        let l0 = terrain.levels.first();
        // Heights: the mesh's (bilinear) + roughness + rocks; micro part kept apart for the
        // slopes; albedo multiplier.
        let mut height = vec![0f32; n * n];
        let mut micro_h = vec![0f32; n * n];
        let mut albedo = vec![1f32; n * n];
        height
            .par_chunks_mut(band * n)
            .zip(micro_h.par_chunks_mut(band * n))
            .zip(albedo.par_chunks_mut(band * n))
            .enumerate()
            .for_each(|(b, ((hb, mb), ab))| {
                let rows = hb.len() / n;
                let r0 = b * band;
                let xs: Vec<f64> = (0..n).map(|c| west + (c as f64 + 0.5) * m).collect();
                let (mut soil_h, mut soil_g, mut tmp) = (vec![0f64; n], vec![0f64; n], Vec::new());
                for r in 0..rows {
                    let y = north - (r0 + r) as f64 * m - 0.5 * m;
                    micro.soil_row(&xs, y, min_wl, &mut soil_h, &mut soil_g, &mut tmp);
                    for (c, &x) in xs.iter().enumerate() {
                        let i = r * n + c;
                        let (mh, grain) = (soil_h[c], soil_g[c]);
                        mb[i] = mh as f32;
                        // The finest level first (it covers the texture at the default
                        // views), then the composite.
                        let base = l0
                            .and_then(|l| l.height(x, y))
                            .or_else(|| terrain.height(x, y).map(|t| t.0))
                            .unwrap_or(0.0);
                        hb[i] = (base + mh) as f32;
                        ab[i] = grain as f32;
                    }
                }
                let rect = [
                    west,
                    north - (r0 + rows) as f64 * m,
                    west + n as f64 * m,
                    north - r0 as f64 * m,
                ];
                // Pits reaching this band (those narrower than 2 texels are left out).
                micro.visit_pits(rect, |pit| {
                    if pit.radius_m < m {
                        return;
                    }
                    let e = pit.reach_m();
                    let c_lo = (((pit.x_m - e - west) / m).floor().max(0.0)) as usize;
                    let c_hi = (((pit.x_m + e - west) / m).ceil().max(0.0) as usize).min(n);
                    let r_lo =
                        ((((north - pit.y_m - e) / m).floor() - r0 as f64).max(0.0)) as usize;
                    let r_hi = ((((north - pit.y_m + e) / m).ceil() - r0 as f64).max(0.0) as usize)
                        .min(rows);
                    for r in r_lo..r_hi {
                        let y = north - (r0 + r) as f64 * m - 0.5 * m;
                        for c in c_lo..c_hi {
                            let x = west + (c as f64 + 0.5) * m;
                            let h = pit.height_at(x, y) as f32;
                            let i = r * n + c;
                            hb[i] += h;
                            mb[i] += h;
                        }
                    }
                });
                // Boulders of the height field: the mesh draws them bilinearly between its
                // nodes (a 0.2 m boulder is a spike on a 0.1 m mesh); the texture replaces
                // that by the boulder's own shape: `exact - bilinear of the node samples`.
                let grow = 0.5;
                let grown = [
                    rect[0] - grow,
                    rect[1] - grow,
                    rect[2] + grow,
                    rect[3] + grow,
                ];
                surface.visit_boulders(grown, &mut |b| {
                    let Some((_, mm)) = terrain.height(b.x_m, b.y_m) else {
                        return;
                    };
                    let rr = 0.5 * b.diameter_m;
                    let at = |x: f64, y: f64| {
                        let (dx, dy) = (x - b.x_m, y - b.y_m);
                        b.height_at(dx * dx + dy * dy)
                    };
                    // Mesh nodes at (k + 0.5) mm; the bilinear hull of the node samples
                    // reaches one node spacing beyond the boulder.
                    let e = rr + mm;
                    let c_lo = (((b.x_m - e - west) / m).floor().max(0.0)) as usize;
                    let c_hi = (((b.x_m + e - west) / m).ceil().max(0.0) as usize).min(n);
                    let r_lo = ((((north - b.y_m - e) / m).floor() - r0 as f64).max(0.0)) as usize;
                    let r_hi = ((((north - b.y_m + e) / m).ceil() - r0 as f64).max(0.0) as usize)
                        .min(rows);
                    for r in r_lo..r_hi {
                        let y = north - (r0 + r) as f64 * m - 0.5 * m;
                        let fy = y / mm - 0.5;
                        let (ky, ty) = (fy.floor(), fy - fy.floor());
                        let (y0, y1) = ((ky + 0.5) * mm, (ky + 1.5) * mm);
                        for c in c_lo..c_hi {
                            let x = west + (c as f64 + 0.5) * m;
                            let fx = x / mm - 0.5;
                            let (kx, tx) = (fx.floor(), fx - fx.floor());
                            let (x0, x1) = ((kx + 0.5) * mm, (kx + 1.5) * mm);
                            let mesh = (at(x0, y0) * (1.0 - tx) + at(x1, y0) * tx) * (1.0 - ty)
                                + (at(x0, y1) * (1.0 - tx) + at(x1, y1) * tx) * ty;
                            let d = (at(x, y) - mesh) as f32;
                            if d != 0.0 {
                                let i = r * n + c;
                                hb[i] += d;
                                mb[i] += d;
                            }
                        }
                    }
                });
                // Rocks reaching this band.
                micro.visit_rocks(rect, 0.0, |rock| {
                    if rock.radius_m < r_geom {
                        // Covered fraction of the texel under the centre (equal-area disc of
                        // the outline, about 0.55 r across).
                        let c = ((rock.x_m - west) / m).floor();
                        let r = ((north - rock.y_m) / m).floor() - r0 as f64;
                        if c >= 0.0 && r >= 0.0 && (c as usize) < n && (r as usize) < rows {
                            let i = r as usize * n + c as usize;
                            let a = core::f64::consts::PI * (0.55 * rock.radius_m).powi(2);
                            let frac = (a / (m * m)).min(1.0);
                            ab[i] *= (1.0 + frac * (rock.albedo_mul - 1.0)) as f32;
                        }
                        return;
                    }
                    let c_lo = (((rock.x_m - rock.radius_m - west) / m).floor().max(0.0)) as usize;
                    let c_hi =
                        (((rock.x_m + rock.radius_m - west) / m).ceil().max(0.0) as usize).min(n);
                    let r_lo = ((((north - rock.y_m - rock.radius_m) / m).floor() - r0 as f64)
                        .max(0.0)) as usize;
                    let r_hi = ((((north - rock.y_m + rock.radius_m) / m).ceil() - r0 as f64)
                        .max(0.0) as usize)
                        .min(rows);
                    for r in r_lo..r_hi {
                        let y = north - (r0 + r) as f64 * m - 0.5 * m;
                        for c in c_lo..c_hi {
                            let x = west + (c as f64 + 0.5) * m;
                            let h = rock.height_at(x, y);
                            if h > 0.0 {
                                let i = r * n + c;
                                hb[i] += h as f32;
                                mb[i] += h as f32;
                                ab[i] = rock.albedo_mul as f32;
                            }
                        }
                    }
                });
            });
        // Cast shadows on the texel grid, the lines extended over the mesh's terrain.
        let grid = Grid { n, west, north, m };
        let lit = if sun.elevation_deg >= 89.999 {
            vec![1f32; n * n]
        } else {
            cast_shadows(&grid, &height, terrain, sun, shadow_reach_m)
        };
        // Texels: slopes of the micro part by central differences, and the cast shadows.
        let mut texels = vec![Texel::default(); n * n];
        texels.par_chunks_mut(n).enumerate().for_each(|(r, row)| {
            let (ru, rd) = (r.saturating_sub(1), (r + 1).min(n - 1));
            for (c, t) in row.iter_mut().enumerate() {
                let (cl, cr) = (c.saturating_sub(1), (c + 1).min(n - 1));
                let gx = (micro_h[r * n + cr] - micro_h[r * n + cl])
                    / ((cr - cl).max(1) as f64 * m) as f32;
                // Row index grows southwards.
                let gy = (micro_h[ru * n + c] - micro_h[rd * n + c])
                    / ((rd - ru).max(1) as f64 * m) as f32;
                *t = Texel {
                    gx,
                    gy,
                    albedo_mul: albedo[r * n + c],
                    lit: lit[r * n + c],
                };
            }
        });
        let mut mips = vec![Mip { m, n, texels }];
        while mips.len() < MIPS {
            let prev = &mips[mips.len() - 1];
            let (pn, nn) = (prev.n, prev.n / 2);
            let mut t = vec![Texel::default(); nn * nn];
            for r in 0..nn {
                for c in 0..nn {
                    let q = |rr: usize, cc: usize| prev.texels[(2 * r + rr) * pn + 2 * c + cc];
                    let (a, b, cc_, d) = (q(0, 0), q(0, 1), q(1, 0), q(1, 1));
                    t[r * nn + c] = Texel {
                        gx: 0.25 * (a.gx + b.gx + cc_.gx + d.gx),
                        gy: 0.25 * (a.gy + b.gy + cc_.gy + d.gy),
                        albedo_mul: 0.25
                            * (a.albedo_mul + b.albedo_mul + cc_.albedo_mul + d.albedo_mul),
                        lit: 0.25 * (a.lit + b.lit + cc_.lit + d.lit),
                    };
                }
            }
            let mm = prev.m * 2.0;
            mips.push(Mip {
                m: mm,
                n: nn,
                texels: t,
            });
        }
        Self {
            west,
            north,
            cx,
            cy,
            half: half_m,
            mips,
        }
    }

    /// Texel side of the finest level, metres.
    pub fn cell_m(&self) -> f64 {
        self.mips[0].m
    }

    /// Bilinear texel of mip `k` at `(x, y)`, clamped to the grid.
    #[inline]
    fn bilinear(&self, k: usize, x: f64, y: f64) -> Texel {
        let mip = &self.mips[k];
        let n = mip.n;
        let fx = ((x - self.west) / mip.m - 0.5).clamp(0.0, (n - 1) as f64 - 1e-9);
        let fy = ((self.north - y) / mip.m - 0.5).clamp(0.0, (n - 1) as f64 - 1e-9);
        let (c, r) = (fx as usize, fy as usize);
        let (tx, ty) = ((fx - c as f64) as f32, (fy - r as f64) as f32);
        let i = r * n + c;
        let t = &mip.texels;
        let top = Texel::lerp(t[i], t[i + 1], tx);
        let bot = Texel::lerp(t[i + n], t[i + n + 1], tx);
        Texel::lerp(top, bot, ty)
    }

    /// Whether ground point `(x, y)` (metres) lies where the texture has any weight.
    #[inline]
    pub fn covers(&self, x: f64, y: f64) -> bool {
        (x - self.cx).abs().max((y - self.cy).abs()) < self.half
    }

    /// The texture at ground point `(x, y)` for a pixel whose ground footprint is
    /// `footprint_m` wide: trilinear between the two mips around the footprint, weighted
    /// down over the last [`FADE_M`] of the square and for footprints beyond the coarsest
    /// mip. `None` where the weight is 0.
    #[inline]
    pub fn sample(&self, x: f64, y: f64, footprint_m: f64) -> Option<DetailSample> {
        let d = (x - self.cx).abs().max((y - self.cy).abs());
        let edge = ((self.half - d) / FADE_M).min(1.0);
        if edge.is_nan() || edge <= 0.0 {
            return None;
        }
        let lod = ((footprint_m / self.mips[0].m) as f32).max(1.0).log2();
        let top = (MIPS - 1) as f32;
        // Beyond the coarsest mip, fade out over one more octave.
        let coarse = (1.0 - (lod - top)).clamp(0.0, 1.0);
        let weight = edge as f32 * coarse;
        if weight <= 0.0 {
            return None;
        }
        let lod = lod.min(top);
        let k = (lod as usize).min(MIPS - 1);
        let t = lod - k as f32;
        let a = self.bilinear(k, x, y);
        let texel = if k + 1 < MIPS && t > 0.0 {
            Texel::lerp(a, self.bilinear(k + 1, x, y), t)
        } else {
            a
        };
        Some(DetailSample { texel, weight })
    }
}
