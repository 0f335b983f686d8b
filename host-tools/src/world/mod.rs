//! The procedural lunar world: a pure function of `(seed, x, y)`.
//!
//! Nothing is stored: any region is sampled lazily, so an 8 x 8 km world costs no memory.
//! World frame: `x` east, `y` north, `z` up, metres (`docs/frames.md`). The model, its
//! parameters and its measured cost are described in `docs/world.md`.
//!
//! Height = fractal gradient noise (rolling relief) + impact craters (power-law sizes, bowl,
//! raised rim, ejecta, degradation states) + boulders (power-law sizes, denser around fresh
//! craters). Albedo = regolith noise + bright halos and rays of fresh craters + brighter
//! boulders. Placement uses only integer hashes and exact `f64` arithmetic (`+ - * / sqrt
//! floor`), plus the `libm` crate (deterministic Rust) for the few `pow`/`exp` evaluated when a
//! world is built, so a world is bit-identical on every machine.
//!
//! Files: `config` (the model's parameters and errors), `noise`, `craters`, `rocks` (the
//! layers), `footprint` (point and footprint-filtered evaluation of the features that reach
//! a point), `grid` (sampled rasters), `zones` (training / test zones), `dem` (a real DEM
//! site instead of the procedural terrain); this file holds [`World`] and its sampling.

mod config;
mod craters;
pub mod dem;
mod footprint;
mod grid;
mod hash;
pub mod micro;
mod noise;
mod rocks;
pub mod zones;

pub use config::{WorldConfig, WorldError};
use craters::Rays;
pub use craters::{Crater, Degradation};
pub use grid::HeightGrid;
pub use rocks::Rock;

use craters::CraterField;
use footprint::{within, Acc, Feature, Filter, Item};
use grid::check_rect;
use noise::Fbm;
use rayon::prelude::*;
use rocks::RockField;

/// A procedural lunar terrain. Cheap to clone (a few small tables); `Send + Sync`.
#[derive(Clone, Debug)]
pub struct World {
    seed: u64,
    cfg: WorldConfig,
    relief: Fbm,
    albedo_regional: Fbm,
    albedo_fine: Fbm,
    craters: CraterField,
    rocks: RockField,
    /// A DEM + orthoimage drawn instead of the procedural terrain ([`World::from_geotiff`]).
    dem: Option<std::sync::Arc<dem::DemTerrain>>,
    /// Centimetre-scale roughness, clods and pebbles ([`World::micro`]).
    micro: std::sync::Arc<micro::MicroRelief>,
}

/// Noise layer numbers (distinct from the crater and rock layers).
const RELIEF_LAYER: u64 = 1;
const ALBEDO_REGIONAL_LAYER: u64 = 2;
const ALBEDO_FINE_LAYER: u64 = 3;

impl World {
    /// The world of `seed` with the default lunar configuration.
    pub fn new(seed: u64) -> Self {
        Self::build(seed, WorldConfig::default())
    }

    /// The world of `seed` with `cfg`. An invalid `cfg` (see [`WorldConfig::validate`]) is
    /// replaced by the default configuration, keeping only its `relief` flag; use
    /// [`World::try_with_config`] to get the error instead.
    pub fn with_config(seed: u64, cfg: WorldConfig) -> Self {
        match Self::try_with_config(seed, cfg.clone()) {
            Ok(w) => w,
            Err(_) => Self::build(
                seed,
                WorldConfig {
                    relief: cfg.relief,
                    ..WorldConfig::default()
                },
            ),
        }
    }

    /// The world of `seed` with `cfg`, or the reason `cfg` is invalid.
    pub fn try_with_config(seed: u64, cfg: WorldConfig) -> Result<Self, WorldError> {
        cfg.validate()?;
        Ok(Self::build(seed, cfg))
    }

    /// The default world of `seed` without relief: height 0 everywhere (no craters, rocks or
    /// noise in the height), but exactly the same albedo as [`World::new`]`(seed)`. For
    /// geometric checks of the reprojection (`--flat`).
    pub fn flat(seed: u64) -> Self {
        Self::build(
            seed,
            WorldConfig {
                relief: false,
                ..WorldConfig::default()
            },
        )
    }

    fn build(seed: u64, cfg: WorldConfig) -> Self {
        let relief = Fbm::new(
            seed,
            RELIEF_LAYER,
            cfg.noise_wavelength_m,
            cfg.noise_amplitude_m,
            cfg.noise_octaves,
            cfg.noise_hurst,
        );
        let half = 0.5 * cfg.albedo_regional_amplitude;
        let albedo_regional = Fbm::new(seed, ALBEDO_REGIONAL_LAYER, 250.0, half * 1.2, 2, 1.0);
        let albedo_fine = Fbm::new(
            seed,
            ALBEDO_FINE_LAYER,
            4.0,
            0.5 * cfg.albedo_fine_amplitude * 1.2,
            2,
            0.0,
        );
        let craters = CraterField::new(seed, &cfg);
        let rocks = RockField::new(seed, &cfg);
        Self {
            seed,
            cfg,
            relief,
            albedo_regional,
            albedo_fine,
            craters,
            rocks,
            dem: None,
            micro: std::sync::Arc::new(micro::MicroRelief::new(seed)),
        }
    }

    /// The micro-relief of the regolith (roughness, clods, pebbles), drawn by the renderer
    /// as the near-field texture of the ground views; `None` for a world without relief
    /// ([`World::flat`]) and for a DEM site, whose surface is the DEM's own.
    pub fn micro(&self) -> Option<&micro::MicroRelief> {
        if self.cfg.relief && self.dem.is_none() {
            Some(&self.micro)
        } else {
            None
        }
    }

    /// The seed this world was made from.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The configuration of this world.
    pub fn config(&self) -> &WorldConfig {
        &self.cfg
    }

    /// Terrain elevation at `(x, y)` metres, in metres. 0 for non-finite input.
    pub fn height_m(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y, true, false, &Filter::POINT).0
    }

    /// Normal albedo at `(x, y)` metres, in `0..=1`. `albedo_mean` for non-finite input.
    pub fn albedo(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y, false, true, &Filter::POINT).1
    }

    /// `(height_m, albedo)` at `(x, y)` metres: both for about the price of one.
    pub fn sample(&self, x: f64, y: f64) -> (f64, f64) {
        self.eval(x, y, true, true, &Filter::POINT)
    }

    /// Samples a north-up grid of `nx x ny` pixels of `m_per_px` metres whose north-west
    /// corner is `(origin_x_m, origin_y_m)`: pixel `(col, row)` is sampled at its centre
    /// `(origin_x_m + (col + 0.5) m_per_px, origin_y_m - (row + 0.5) m_per_px)`
    /// (`docs/frames.md`). Rows in parallel (rayon). Empty (`nx = ny = 0`) when `nx` or `ny`
    /// is 0 or the grid would exceed [`MAX_GRID_PIXELS`]; non-finite pixel centres get
    /// height 0 and `albedo_mean`. [`World::try_sample_grid`] reports such input as errors.
    pub fn sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> HeightGrid {
        self.grid_with(origin_x_m, origin_y_m, m_per_px, nx, ny, &Filter::POINT)
    }

    /// As [`World::sample_grid`], but each pixel's albedo is the mean over its square
    /// footprint of side `footprint_m` metres centred on the pixel centre (a box filter, as
    /// a sensor integrates its pixel, or a mesh node stands for its cell): a boulder or a
    /// ray narrower than the footprint adds its area-weighted brightness instead of all or
    /// nothing, so grids of different spacings agree in the mean and do not alias. Heights
    /// stay point samples, except that the boulders taken by their mean are left
    /// out of them (bumps between the nodes: a level of detail). `footprint_m <= 0` (or not
    /// finite) is [`World::sample_grid`].
    ///
    /// How (docs/world.md): a boulder adds `boost x covered fraction`, the overlap of the
    /// footprint with the boulder's disc (an equal-area square for boulders smaller than the
    /// footprint, a linear edge ramp of one footprint for larger ones); boulder size classes
    /// no wider than half the footprint (one footprint from 0.75 m on) add their expected value (density x mean area x mean
    /// boost, `rho^-3`-weighted around fresh craters) instead of being visited; fresh
    /// craters' albedo is averaged over up to 4 x 4 samples of the footprint
    /// ([`Crater::albedo_filtered`]).
    pub fn sample_grid_filtered(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        footprint_m: f64,
    ) -> HeightGrid {
        let filt = Filter::new(self, footprint_m);
        self.grid_with(origin_x_m, origin_y_m, m_per_px, nx, ny, &filt)
    }

    /// Albedo (normal albedo, 0..1) averaged over the `footprint_m`-wide square centred at
    /// `(x, y)` metres, as [`World::sample_grid_filtered`]; [`World::albedo`] for
    /// `footprint_m <= 0`.
    pub fn albedo_filtered(&self, x: f64, y: f64, footprint_m: f64) -> f64 {
        let filt = Filter::new(self, footprint_m);
        self.eval(x, y, false, true, &filt).1
    }

    fn grid_with(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
        filt: &Filter,
    ) -> HeightGrid {
        let (nx, ny) = match nx.checked_mul(ny) {
            Some(n) if n <= MAX_GRID_PIXELS => (nx, ny),
            _ => (0, 0),
        };
        let n = nx * ny;
        let mut grid = HeightGrid {
            origin_x_m,
            origin_y_m,
            m_per_px,
            nx,
            ny,
            height_m: vec![0.0; n],
            albedo: vec![0.0; n],
        };
        if n == 0 {
            return grid;
        }
        if let Some(d) = &self.dem {
            d.fill_grid(&mut grid, filt.fp);
            return grid;
        }
        let spec = GridSpec {
            ox: origin_x_m,
            oy: origin_y_m,
            m: m_per_px,
            nx,
            ny,
        };
        // Bands of whole tiles, about WINDOW pixels high, in parallel; each band in windows
        // of whole tiles about WINDOW pixels wide.
        let tile = spec.tile();
        let band = tile * (WINDOW / tile).max(1);
        grid.height_m
            .par_chunks_mut(nx * band)
            .zip(grid.albedo.par_chunks_mut(nx * band))
            .enumerate()
            .for_each(|(b, (hs, als))| {
                let rows = b * band..b * band + hs.len() / nx;
                // The band's base sums in whole rows (long vectorized runs).
                let xs: Vec<f64> = (0..nx)
                    .map(|c| origin_x_m + (c as f64 + 0.5) * m_per_px)
                    .collect();
                let mut bh = vec![0.0; rows.len() * nx];
                let mut ba = vec![0.0; rows.len() * nx];
                let mut tmp = vec![0.0; nx];
                for (k, r) in rows.clone().enumerate() {
                    let y = origin_y_m - (r as f64 + 0.5) * m_per_px;
                    let span = k * nx..(k + 1) * nx;
                    self.base_row(&xs, y, filt, &mut bh[span.clone()], &mut ba[span], &mut tmp);
                }
                let base = Base {
                    h: &bh,
                    a: &ba,
                    stride: nx,
                    c0: 0,
                    r0: rows.start,
                };
                let mut scratch = Scratch::default();
                let mut c0 = 0;
                while c0 < nx {
                    let c1 = (c0 + band).min(nx);
                    self.fill_window(
                        &spec,
                        filt,
                        c0..c1,
                        rows.clone(),
                        Some(base),
                        &mut scratch,
                        (&mut hs[c0..], &mut als[c0..], nx),
                    );
                    c0 = c1;
                }
            });
        grid
    }

    /// Pixels `cols x rows` of the grid that [`World::sample_grid_filtered`]`(origin_x_m,
    /// origin_y_m, m_per_px, nx, ny, footprint_m)` samples, with exactly its values, the rest
    /// of the grid not sampled: heights and albedo row-major, `cols.len()` wide. Empty when
    /// the window is empty or not inside the grid, or the grid exceeds [`MAX_GRID_PIXELS`].
    #[allow(clippy::too_many_arguments)]
    pub fn sample_grid_window(
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
        let ok = nx.checked_mul(ny).is_some_and(|n| n <= MAX_GRID_PIXELS)
            && cols.start < cols.end
            && rows.start < rows.end
            && cols.end <= nx
            && rows.end <= ny;
        if !ok {
            return (Vec::new(), Vec::new());
        }
        let w = cols.len();
        let n = w * rows.len();
        let (mut hs, mut als) = (vec![0f32; n], vec![0f32; n]);
        let filt = Filter::new(self, footprint_m);
        if let Some(d) = &self.dem {
            for (k, r) in rows.clone().enumerate() {
                let y = origin_y_m - (r as f64 + 0.5) * m_per_px;
                for (j, c) in cols.clone().enumerate() {
                    let x = origin_x_m + (c as f64 + 0.5) * m_per_px;
                    let (h, a) = d.sample(x, y, filt.fp);
                    hs[k * w + j] = h as f32;
                    als[k * w + j] = a as f32;
                }
            }
            return (hs, als);
        }
        let spec = GridSpec {
            ox: origin_x_m,
            oy: origin_y_m,
            m: m_per_px,
            nx,
            ny,
        };
        self.fill_window(
            &spec,
            &filt,
            cols,
            rows,
            None,
            &mut Scratch::default(),
            (&mut hs, &mut als, w),
        );
        (hs, als)
    }

    /// [`World::sample_grid`] with its input checked: finite origin, positive finite
    /// resolution, non-empty and at most [`MAX_GRID_PIXELS`] pixels.
    pub fn try_sample_grid(
        &self,
        origin_x_m: f64,
        origin_y_m: f64,
        m_per_px: f64,
        nx: usize,
        ny: usize,
    ) -> Result<HeightGrid, WorldError> {
        if !(origin_x_m.is_finite() && origin_y_m.is_finite()) {
            return Err(WorldError::BadQuery(format!(
                "grid origin ({origin_x_m}, {origin_y_m}) is not finite"
            )));
        }
        if !(m_per_px.is_finite() && m_per_px > 0.0) {
            return Err(WorldError::BadQuery(format!(
                "grid resolution {m_per_px} m/px must be positive and finite"
            )));
        }
        match nx.checked_mul(ny) {
            Some(n) if n > 0 && n <= MAX_GRID_PIXELS => {}
            _ => {
                return Err(WorldError::BadQuery(format!(
                    "grid of {nx} x {ny} pixels: need 1 ..= 2^28 pixels"
                )))
            }
        }
        Ok(self.sample_grid(origin_x_m, origin_y_m, m_per_px, nx, ny))
    }

    /// Every crater whose centre lies in `[x0, x1) x [y0, y1)` (metres) with diameter at
    /// least `d_min_m`, for statistics and overlays. The rectangle may span at most 10^8
    /// cells of the smallest wanted class.
    pub fn craters_in(
        &self,
        x0: f64,
        y0: f64,
        x1: f64,
        y1: f64,
        d_min_m: f64,
    ) -> Result<Vec<Crater>, WorldError> {
        let cell = self.cfg.ejecta_extent_radii * d_min_m.max(self.cfg.crater_d_min_m);
        check_rect(x0, y0, x1, y1, cell)?;
        if self.dem.is_some() {
            return Ok(Vec::new());
        }
        Ok(self.craters.in_rect(x0, y0, x1, y1, d_min_m))
    }

    /// Every background boulder (not those of fresh craters) whose centre lies in
    /// `[x0, x1) x [y0, y1)` metres. The rectangle may span at most 10^8 cells of the
    /// smallest class.
    pub fn rocks_in(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Result<Vec<Rock>, WorldError> {
        check_rect(x0, y0, x1, y1, 2.0 * self.cfg.rock_d_min_m)?;
        if self.dem.is_some() {
            return Ok(Vec::new());
        }
        Ok(self.rocks.in_rect(x0, y0, x1, y1))
    }

    /// Calls `f` for every boulder, background or of a fresh crater, whose footprint
    /// reaches into `rect` (`[x0, y0, x1, y1]` metres): the rocks of the height field, e.g.
    /// for the renderer to draw the near ones finer than its mesh. Nothing for a DEM site.
    pub fn visit_boulders(&self, rect: [f64; 4], mut f: impl FnMut(&Rock)) {
        if self.dem.is_some() || !self.cfg.relief {
            return;
        }
        self.features(rect, false, &Filter::POINT, |feat| {
            if let Feature::Rock(r) = feat {
                f(r);
            }
        });
    }

    /// The distance (metres) beyond which no crater reaches: the largest crater's ejecta.
    pub fn max_feature_reach_m(&self) -> f64 {
        self.craters.max_reach()
    }

    /// Calls `f` for every crater and boulder that reaches into `rect` (`[x0, y0, x1, y1]`
    /// metres), in the one fixed order in which their contributions are summed.
    /// With a footprint filter, `rect` must already be grown by half the footprint, and
    /// boulder classes below `filt.first_rock_class` are skipped (they enter by their mean).
    #[inline]
    fn features(
        &self,
        rect: [f64; 4],
        fresh_only: bool,
        filt: &Filter,
        mut f: impl FnMut(Feature<'_>),
    ) {
        let rocks = &self.rocks;
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        rocks.visit_rect_from(rect, k0, grow, |r| f(Feature::Rock(r)));
        self.craters.visit_rect(rect, fresh_only, |c| {
            f(Feature::Crater(c, None));
            if rocks.crater_has_rocks(c) {
                rocks.visit_crater_rect_from(c, rect, k0, grow, |r| f(Feature::Rock(r)));
            }
        });
    }

    /// The sum before features: noise relief and regolith albedo.
    #[inline]
    fn base<'f>(&self, x: f64, y: f64, relief: bool, want_a: bool, filt: &'f Filter) -> Acc<'f> {
        let mut a = 0.0;
        if want_a {
            a = self.cfg.albedo_mean + self.albedo_regional.at(x, y) + self.albedo_fine.at(x, y);
            if filt.rock_mean > 0.0 {
                a += filt.rock_mean;
            }
        }
        Acc {
            h: if relief { self.relief.at(x, y) } else { 0.0 },
            a,
            relief,
            want_a,
            boost: self.cfg.fresh_crater_albedo_boost,
            filt,
        }
    }

    /// [`World::base`] (relief per the configuration, albedo wanted) at `(xs[i], y)`, bit for
    /// bit: heights into `h`, albedo into `a` (`tmp`: scratch as long as `xs`).
    fn base_row(
        &self,
        xs: &[f64],
        y: f64,
        filt: &Filter,
        h: &mut [f64],
        a: &mut [f64],
        tmp: &mut [f64],
    ) {
        if self.cfg.relief {
            self.relief.row(xs, y, h);
        } else {
            h.fill(0.0);
        }
        self.albedo_regional.row(xs, y, a);
        self.albedo_fine.row(xs, y, tmp);
        let mean = self.cfg.albedo_mean;
        for (a, &f) in a.iter_mut().zip(tmp.iter()) {
            *a = mean + *a + f;
        }
        if filt.rock_mean > 0.0 {
            for a in a.iter_mut() {
                *a += filt.rock_mean;
            }
        }
    }

    /// An accumulator starting from precomputed base sums (see [`World::base_row`]).
    #[inline]
    fn acc_from<'f>(&self, h: f64, a: f64, filt: &'f Filter) -> Acc<'f> {
        Acc {
            h,
            a,
            relief: self.cfg.relief,
            want_a: true,
            boost: self.cfg.fresh_crater_albedo_boost,
            filt,
        }
    }

    #[inline]
    fn eval(&self, x: f64, y: f64, want_h: bool, want_a: bool, filt: &Filter) -> (f64, f64) {
        if let Some(d) = &self.dem {
            return d.sample(x, y, filt.fp);
        }
        if !(x.is_finite() && y.is_finite()) {
            return (0.0, self.cfg.albedo_mean);
        }
        let relief = want_h && self.cfg.relief;
        if !relief && !want_a {
            return (0.0, 0.0);
        }
        let mut acc = self.base(x, y, relief, want_a, filt);
        self.features(filt.grown([x, y, x, y]), !relief, filt, |f| {
            acc.add(f, x, y);
        });
        acc.finish()
    }

    /// Fills pixels `cols x rows` of the grid `g` (not empty, inside the grid) into `out`
    /// (heights, albedo, row stride; pixel `(c, r)` at `(r - rows.start) * stride + c -
    /// cols.start`), exactly as sampling the whole grid would: the grid's tiles (whole
    /// tiles of [`GridSpec::tile`] pixels from its north-west corner, partial ones at the
    /// east and south edges) each gather the craters (and, on fine grids, the boulders) that
    /// reach them, then every pixel sums its tile's features in the one fixed order, so a
    /// pixel's value does not depend on the window. Coarse grids gather the craters of the
    /// window's tiles at once and hand each tile the ones its own gathering would have
    /// visited (the same cell and distance tests, in the same order): most cells of small
    /// crater classes are then visited once, not once per tile.
    #[allow(clippy::too_many_arguments)]
    fn fill_window(
        &self,
        g: &GridSpec,
        filt: &Filter,
        cols: std::ops::Range<usize>,
        rows: std::ops::Range<usize>,
        base: Option<Base<'_>>,
        scratch: &mut Scratch,
        (hs, als, stride): (&mut [f32], &mut [f32], usize),
    ) {
        let tile = g.tile();
        let rocks_per_pixel = g.m > FINE_GRID_M_PER_PX;
        let w = cols.len();
        let Scratch {
            xs,
            ys,
            bh,
            ba,
            tmp,
            items,
            pre,
            acc_h,
            acc_a,
            rects,
        } = scratch;
        // Pixel centres of the window's tiles (columns from the first tile's start).
        let (t0, t1) = (cols.start / tile, (cols.end - 1) / tile + 1);
        let (b0, b1) = (rows.start / tile, (rows.end - 1) / tile + 1);
        let cs = t0 * tile;
        let ce = (t1 * tile).min(g.nx);
        xs.clear();
        xs.extend((cs..ce).map(|c| g.ox + (c as f64 + 0.5) * g.m));
        let rs = b0 * tile;
        let re = (b1 * tile).min(g.ny);
        ys.clear();
        ys.extend((rs..re).map(|r| g.oy - (r as f64 + 0.5) * g.m));
        // The sums before features, row by row (vectorized noise), unless given.
        let base = match base {
            Some(b) => b,
            None => {
                bh.clear();
                bh.resize(w * rows.len(), 0.0);
                ba.clear();
                ba.resize(w * rows.len(), 0.0);
                tmp.clear();
                tmp.resize(w, 0.0);
                let xw = &xs[cols.start - cs..cols.end - cs];
                for (k, r) in rows.clone().enumerate() {
                    let span = k * w..(k + 1) * w;
                    self.base_row(
                        xw,
                        ys[r - rs],
                        filt,
                        &mut bh[span.clone()],
                        &mut ba[span],
                        tmp,
                    );
                }
                Base {
                    h: bh,
                    a: ba,
                    stride: w,
                    c0: cols.start,
                    r0: rows.start,
                }
            }
        };
        // Each tile: its pixel centres, its gathering rectangle (None: pixels evaluated one
        // by one, as for a single-pixel or non-finite tile).
        let tile_rect = |t: usize, b: usize| {
            let xt = &xs[t * tile - cs..((t + 1) * tile).min(g.nx) - cs];
            let yt = &ys[b * tile - rs..((b + 1) * tile).min(g.ny) - rs];
            let (xa, xb, ya, yb) = (xt[0], xt[xt.len() - 1], yt[0], yt[yt.len() - 1]);
            let finite = xa.is_finite() && xb.is_finite() && ya.is_finite() && yb.is_finite();
            let single = xt.len() == 1 && yt.len() == 1;
            (finite && !single)
                .then(|| filt.grown([xa.min(xb), ya.min(yb), xa.max(xb), ya.max(yb)]))
        };
        let (nt, nb) = (t1 - t0, b1 - b0);
        // Binned when the tiles' rectangles run east and south in order (the usual grid:
        // finite, positive spacing), so that a crater finds its tiles by bisection.
        let ordered = g.m > 0.0
            && xs.iter().chain(ys.iter()).all(|v| v.is_finite())
            && xs.windows(2).all(|p| p[0] < p[1])
            && ys.windows(2).all(|p| p[0] > p[1]);
        let binned = rocks_per_pixel && nt * nb > 1 && ordered;
        if binned {
            // One gathering over the union of the tiles' rectangles; each crater is summed
            // into the pixels of the tiles whose own gathering visits it, as it is found.
            rects.clear();
            for b in b0..b1 {
                for t in t0..t1 {
                    rects.push(tile_rect(t, b));
                }
            }
            // Tile rectangles by column (west, east edges, both increasing) and by band row
            // (south, north edges, both decreasing); a tile's rectangle is its column's and
            // its row's (`tile_rect` grows each side alone).
            let col_x: Vec<(f64, f64)> = (t0..t1)
                .map(|t| {
                    let xa = xs[t * tile - cs];
                    let xb = xs[((t + 1) * tile).min(g.nx) - 1 - cs];
                    let r = filt.grown([xa, 0.0, xb, 0.0]);
                    (r[0], r[2])
                })
                .collect();
            let row_y: Vec<(f64, f64)> = (b0..b1)
                .map(|b| {
                    let ya = ys[b * tile - rs];
                    let yb = ys[((b + 1) * tile).min(g.ny) - 1 - rs];
                    let r = filt.grown([0.0, yb, 0.0, ya]);
                    (r[1], r[3])
                })
                .collect();
            let win = Window {
                cols: cols.clone(),
                rows: rows.clone(),
                tile,
                t0,
                b0,
                nx: g.nx,
                ny: g.ny,
                xs: &xs[..],
                cs,
                ys: &ys[..],
                rs,
                rects: &rects[..],
                col_x: &col_x,
                row_y: &row_y,
                pitch: tile as f64 * g.m,
            };
            self.splat_window(&win, filt, base, acc_h, acc_a);
            for b in b0..b1 {
                for t in t0..t1 {
                    let rect = rects[(b - b0) * nt + (t - t0)];
                    for r in (b * tile).max(rows.start)..((b + 1) * tile).min(rows.end) {
                        for c in (t * tile).max(cols.start)..((t + 1) * tile).min(cols.end) {
                            let q = (r - rows.start) * w + (c - cols.start);
                            let (h, a) = match rect {
                                Some(_) => (acc_h[q], acc_a[q].clamp(0.0, 1.0)),
                                None => self.eval(xs[c - cs], ys[r - rs], true, true, filt),
                            };
                            let k = (r - rows.start) * stride + (c - cols.start);
                            hs[k] = h as f32;
                            als[k] = a as f32;
                        }
                    }
                }
            }
            return;
        }
        for b in b0..b1 {
            let yt = &ys[b * tile - rs..((b + 1) * tile).min(g.ny) - rs];
            let r_lo = (b * tile).max(rows.start);
            let r_hi = ((b + 1) * tile).min(rows.end);
            for t in t0..t1 {
                let xt = &xs[t * tile - cs..((t + 1) * tile).min(g.nx) - cs];
                let c_lo = (t * tile).max(cols.start);
                let c_hi = ((t + 1) * tile).min(cols.end);
                let rect = tile_rect(t, b);
                if let Some(rect) = rect {
                    items.clear();
                    if rocks_per_pixel {
                        self.craters.visit_rect(rect, !self.cfg.relief, |c| {
                            items.push(Item::of(Feature::Crater(c, None)))
                        });
                    } else {
                        self.features(rect, !self.cfg.relief, filt, |f| items.push(Item::of(f)));
                    }
                    pre.clear();
                    pre.extend(items.iter().map(|it| filt.reach(it.as_feature())));
                }
                if let (Some(_), false) = (rect, rocks_per_pixel) {
                    // Fine tiles: feature by feature over the tile's pixels (each pixel
                    // still sums its features in their order); the height of a crater that
                    // is not fresh (its only term in a filtered sum) four pixels at a time.
                    let wt = c_hi - c_lo;
                    acc_h.clear();
                    acc_a.clear();
                    for r in r_lo..r_hi {
                        let kb = (r - base.r0) * base.stride + (c_lo - base.c0);
                        acc_h.extend_from_slice(&base.h[kb..kb + wt]);
                        acc_a.extend_from_slice(&base.a[kb..kb + wt]);
                    }
                    let xv = &xt[c_lo - t * tile..c_hi - t * tile];
                    let heights_only = self.cfg.relief && filt.fp > 0.0;
                    for (it, &p) in items.iter().zip(pre.iter()) {
                        let plain = match it {
                            Item::Crater(c, _)
                                if heights_only && (c.freshness <= 0.0 || c.freshness.is_nan()) =>
                            {
                                Some(c)
                            }
                            _ => None,
                        };
                        for r in r_lo..r_hi {
                            let y = yt[r - b * tile];
                            let q0 = (r - r_lo) * wt;
                            if let Some(c) = plain {
                                c.add_heights(xv, y, &mut acc_h[q0..q0 + wt]);
                                continue;
                            }
                            for (j, &x) in xv.iter().enumerate() {
                                // Features whose `add` would do nothing here are skipped.
                                if within(p, x, y) {
                                    let mut acc = self.acc_from(acc_h[q0 + j], acc_a[q0 + j], filt);
                                    acc.add(it.as_feature(), x, y);
                                    acc_h[q0 + j] = acc.h;
                                    acc_a[q0 + j] = acc.a;
                                }
                            }
                        }
                    }
                    for r in r_lo..r_hi {
                        for c in c_lo..c_hi {
                            let q = (r - r_lo) * wt + (c - c_lo);
                            let k = (r - rows.start) * stride + (c - cols.start);
                            hs[k] = acc_h[q] as f32;
                            als[k] = acc_a[q].clamp(0.0, 1.0) as f32;
                        }
                    }
                    continue;
                }
                for r in r_lo..r_hi {
                    let y = yt[r - b * tile];
                    for c in c_lo..c_hi {
                        let x = xt[c - t * tile];
                        let kb = (r - base.r0) * base.stride + (c - base.c0);
                        let (h, a) = match rect {
                            None => self.eval(x, y, true, true, filt),
                            // (Coarse tiles only: fine ones are summed above.) Features
                            // whose `add` would do nothing here are skipped.
                            Some(_) => self.sum_pixel_coarse(
                                x,
                                y,
                                (base.h[kb], base.a[kb]),
                                items
                                    .iter()
                                    .zip(pre.iter())
                                    .filter_map(|(it, &p)| match it {
                                        Item::Crater(c, rays) if within(p, x, y) => {
                                            Some((c, rays.as_ref()))
                                        }
                                        _ => None,
                                    }),
                                filt,
                            ),
                        };
                        let k = (r - rows.start) * stride + (c - cols.start);
                        hs[k] = h as f32;
                        als[k] = a as f32;
                    }
                }
            }
        }
    }

    /// Sums of a coarse grid's window (pixels of tiles with a gathering rectangle; the rest
    /// is the caller's) into `acc_h`, `acc_a` (row-major, window-wide): the same additions in
    /// the same order per pixel as [`World::sum_pixel_coarse`] over each tile's own gathering
    /// — base sums, the pixel's background boulders, then every crater its tile's gathering
    /// visits, in gathering order, each fresh crater's boulders right after it — but with
    /// the craters gathered once for the whole window and summed into the pixels they reach
    /// as they are found.
    fn splat_window(
        &self,
        win: &Window<'_>,
        filt: &Filter,
        base: Base<'_>,
        acc_h: &mut Vec<f64>,
        acc_a: &mut Vec<f64>,
    ) {
        let w = win.cols.len();
        let n = w * win.rows.len();
        acc_h.clear();
        acc_a.clear();
        acc_h.resize(n, 0.0);
        acc_a.resize(n, 0.0);
        let (nt, nb) = (win.col_x.len(), win.row_y.len());
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        let rocks = &self.rocks;
        let visits_rocks = k0 < rocks.class_count();
        let mut union: Option<[f64; 4]> = None;
        // Base sums and the pixels' own background boulders.
        for bi in 0..nb {
            let b = win.b0 + bi;
            for ti in 0..nt {
                let t = win.t0 + ti;
                let Some(r) = win.rects[bi * nt + ti] else {
                    continue;
                };
                union = Some(match union {
                    None => r,
                    Some(u) => [
                        u[0].min(r[0]),
                        u[1].min(r[1]),
                        u[2].max(r[2]),
                        u[3].max(r[3]),
                    ],
                });
                for r in (b * win.tile).max(win.rows.start)..((b + 1) * win.tile).min(win.rows.end)
                {
                    let y = win.ys[r - win.rs];
                    for c in
                        (t * win.tile).max(win.cols.start)..((t + 1) * win.tile).min(win.cols.end)
                    {
                        let x = win.xs[c - win.cs];
                        let q = (r - win.rows.start) * w + (c - win.cols.start);
                        let kb = (r - base.r0) * base.stride + (c - base.c0);
                        let mut acc = self.acc_from(base.h[kb], base.a[kb], filt);
                        if visits_rocks {
                            let point = filt.grown([x, y, x, y]);
                            rocks.visit_rect_from(point, k0, grow, |rk| {
                                acc.add(Feature::Rock(rk), x, y);
                            });
                        }
                        acc_h[q] = acc.h;
                        acc_a[q] = acc.a;
                    }
                }
            }
        }
        let Some(u) = union else {
            return;
        };
        // The cells each tile's gathering visits, per tile column / band and class.
        let nk = self.craters.class_count();
        let col_cells: Vec<(i64, i64)> = win
            .col_x
            .iter()
            .flat_map(|&(w, e)| (0..nk).map(move |k| (w, e, k)))
            .map(|(w, e, k)| self.craters.cell_range(k, w, e))
            .collect();
        let row_cells: Vec<(i64, i64)> = win
            .row_y
            .iter()
            .flat_map(|&(s, n)| (0..nk).map(move |k| (s, n, k)))
            .map(|(s, n, k)| self.craters.cell_range(k, s, n))
            .collect();
        let (x_first, y_first) = (win.col_x[0].0, win.row_y[0].1);
        // A crater adds nothing to a pixel farther than its reach (`add`'s first test),
        // and a crater that is not fresh nothing beyond its ejecta blanket (it has no
        // albedo terms or boulders): craters out of those distances of every pixel of the
        // window are skipped before they are drawn in full (the class's largest blanket
        // bounds the crater's, with a margin for rounding).
        let xw = &win.xs[win.cols.start - win.cs..win.cols.end - win.cs];
        let yw = &win.ys[win.rows.start - win.rs..win.rows.end - win.rs];
        // Squared distance to the nearest pixel centre along one axis (evenly spaced
        // centres: the nearest is within one of the rounded index), as `add` computes
        // `dx * dx`.
        let step = |at: &[f64]| {
            if at.len() >= 2 {
                (at[at.len() - 1] - at[0]) / (at.len() - 1) as f64
            } else {
                1.0
            }
        };
        let (sx, sy) = (step(xw), step(yw));
        let nearest2 = |v: f64, at: &[f64], step: f64| {
            // Rounded to the nearest index (`as` truncates; negatives clamp to 0 below).
            let i = (((v - at[0]) / step + 0.5) as i64).clamp(0, at.len() as i64 - 1) as usize;
            let mut d2 = f64::INFINITY;
            for &a in &at[i.saturating_sub(1)..(i + 2).min(at.len())] {
                let d = a - v;
                d2 = d2.min(d * d);
            }
            d2
        };
        let slack = filt.hf * core::f64::consts::SQRT_2;
        let keep = |k: usize, cx: f64, cy: f64, fresh: bool| {
            let reach = self.craters.class_reach(k) + if fresh { slack } else { 0.0 };
            let d2 = nearest2(cx, xw, sx) + nearest2(cy, yw, sy);
            d2 <= reach * reach * (1.0 + 1e-9)
        };
        self.craters
            .visit_rect_cells_if(u, !self.cfg.relief, keep, |k, ix, iy, c| {
                let reach = self.craters.class_reach(k);
                let (lx, hx) = (c.x_m - reach, c.x_m + reach);
                let (ly, hy) = (c.y_m - reach, c.y_m + reach);
                // Tiles whose rectangle meets the crater's reach square (a crater outside
                // it is not visited: its distance is at least `reach`): `partition_point`s,
                // searched from a guess on the tiles' pitch.
                let gx = |v: f64| ((v - x_first) / win.pitch).max(0.0) as usize;
                let gy = |v: f64| ((y_first - v) / win.pitch).max(0.0) as usize;
                let ta = partition_from(nt, gx(lx), |t| win.col_x[t].1 < lx);
                let tb = partition_from(nt, gx(hx), |t| win.col_x[t].0 <= hx);
                let ba = partition_from(nb, gy(hy), |b| win.row_y[b].0 > hy);
                let bb = partition_from(nb, gy(ly), |b| win.row_y[b].1 >= ly);
                let pre = filt.reach(Feature::Crater(c, None));
                // Drawn once for all the pixels (fresh craters only).
                let rays: Option<Rays> = (c.freshness > 0.0).then(|| c.rays());
                let fresh_rocks = rocks.crater_has_rocks(c);
                for bi in ba..bb {
                    let (iy0, iy1) = row_cells[bi * nk + k];
                    if iy < iy0 || iy > iy1 {
                        continue;
                    }
                    let b = win.b0 + bi;
                    for ti in ta..tb {
                        let (ix0, ix1) = col_cells[ti * nk + k];
                        if ix < ix0 || ix > ix1 {
                            continue;
                        }
                        let Some(rect) = win.rects[bi * nt + ti] else {
                            continue;
                        };
                        if !self.craters.reaches(rect, k, c) {
                            continue;
                        }

                        let t = win.t0 + ti;
                        let r_hi = ((b + 1) * win.tile).min(win.rows.end).min(win.ny);
                        for r in (b * win.tile).max(win.rows.start)..r_hi {
                            let y = win.ys[r - win.rs];
                            let c_hi = ((t + 1) * win.tile).min(win.cols.end).min(win.nx);
                            for col in (t * win.tile).max(win.cols.start)..c_hi {
                                let x = win.xs[col - win.cs];
                                // Where `add` would change nothing, it is skipped.
                                if !within(pre, x, y) {
                                    continue;
                                }
                                let q = (r - win.rows.start) * w + (col - win.cols.start);
                                let mut acc = self.acc_from(acc_h[q], acc_a[q], filt);
                                if acc.add(Feature::Crater(c, rays.as_ref()), x, y) && fresh_rocks {
                                    let point = filt.grown([x, y, x, y]);
                                    rocks.visit_crater_rect_from(c, point, k0, grow, |rk| {
                                        acc.add(Feature::Rock(rk), x, y);
                                    });
                                }
                                acc_h[q] = acc.h;
                                acc_a[q] = acc.a;
                            }
                        }
                    }
                }
            });
    }

    /// Height and albedo of one pixel of a coarse grid's tile: its base sums, its own
    /// background boulder look-up, then the tile's craters in their fixed order, each fresh
    /// crater's boulders (looked up by the pixel) right after it.
    #[inline]
    fn sum_pixel_coarse<'c>(
        &self,
        x: f64,
        y: f64,
        (base_h, base_a): (f64, f64),
        craters: impl Iterator<Item = (&'c Crater, Option<&'c Rays>)>,
        filt: &Filter,
    ) -> (f64, f64) {
        let mut acc = self.acc_from(base_h, base_a, filt);
        let point = filt.grown([x, y, x, y]);
        let (k0, grow) = (filt.first_rock_class, filt.grow);
        let rocks = &self.rocks;
        rocks.visit_rect_from(point, k0, grow, |rk| {
            acc.add(Feature::Rock(rk), x, y);
        });
        for (cr, rays) in craters {
            if acc.add(Feature::Crater(cr, rays), x, y) && rocks.crater_has_rocks(cr) {
                rocks.visit_crater_rect_from(cr, point, k0, grow, |rk| {
                    acc.add(Feature::Rock(rk), x, y);
                });
            }
        }
        acc.finish()
    }
}

/// `(0..len).partition_point(pred)` for a predicate true on a prefix, searched from `guess`.
#[inline]
fn partition_from(len: usize, guess: usize, pred: impl Fn(usize) -> bool) -> usize {
    let mut i = guess.min(len);
    while i > 0 && !pred(i - 1) {
        i -= 1;
    }
    while i < len && pred(i) {
        i += 1;
    }
    i
}

/// A grid being sampled: north-west corner, metres per pixel, size.
#[derive(Clone, Copy, Debug)]
struct GridSpec {
    ox: f64,
    oy: f64,
    m: f64,
    nx: usize,
    ny: usize,
}

impl GridSpec {
    /// Side of the tiles that gather features, pixels.
    fn tile(&self) -> usize {
        if self.m > FINE_GRID_M_PER_PX {
            ((COARSE_TILE_MAX_M / self.m) as usize).clamp(2, TILE)
        } else {
            ((FINE_TILE_MAX_M / self.m) as usize).clamp(1, TILE)
        }
    }
}

/// The sums before features ([`World::base_row`]) of pixels `(c, r)` at `(r - r0) * stride +
/// c - c0`.
#[derive(Clone, Copy)]
struct Base<'a> {
    h: &'a [f64],
    a: &'a [f64],
    stride: usize,
    c0: usize,
    r0: usize,
}

/// Buffers reused from window to window.
#[derive(Default)]
struct Scratch {
    xs: Vec<f64>,
    ys: Vec<f64>,
    bh: Vec<f64>,
    ba: Vec<f64>,
    tmp: Vec<f64>,
    items: Vec<Item>,
    pre: Vec<[f64; 3]>,
    acc_h: Vec<f64>,
    acc_a: Vec<f64>,
    rects: Vec<Option<[f64; 4]>>,
}

/// A window of a coarse grid being filled by [`World::splat_window`]: its pixels, the grid's
/// tiles it overlaps (from tile column `t0` and band `b0`) with their pixel centres (`xs`
/// from column `cs`, `ys` from row `rs`) and gathering rectangles (`rects`, band-major;
/// `col_x` / `row_y`: their west-east and south-north edges per tile column / band), and the
/// tiles' pitch in metres.
struct Window<'a> {
    cols: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
    tile: usize,
    t0: usize,
    b0: usize,
    nx: usize,
    ny: usize,
    xs: &'a [f64],
    cs: usize,
    ys: &'a [f64],
    rs: usize,
    rects: &'a [Option<[f64; 4]>],
    col_x: &'a [(f64, f64)],
    row_y: &'a [(f64, f64)],
    pitch: f64,
}

/// Side of the windows a grid is filled by, pixels (rounded down to whole tiles).
const WINDOW: usize = 16;

/// Largest grid `sample_grid` samples: 2^28 pixels (2 GiB of `f32` height and albedo).
pub const MAX_GRID_PIXELS: usize = 1 << 28;

/// Largest side of the tiles `sample_grid` gathers features for, pixels.
const TILE: usize = 16;

/// Fine grids (at most this many metres per pixel) gather craters and boulders per tile;
/// coarser ones gather craters per tile and look boulders up per pixel.
const FINE_GRID_M_PER_PX: f64 = 1.0;

/// Largest ground side of a fine grid's tile, metres: a tile gathers every boulder cell it
/// touches (cells of 0.4 m and up).
const FINE_TILE_MAX_M: f64 = 4.0;

/// Largest ground side of a coarse grid's tile, metres (bounds the list of small craters
/// each pixel walks).
const COARSE_TILE_MAX_M: f64 = 8.0;
