//! Grid sampling: whole north-up grids ([`World::sample_grid`],
//! [`World::sample_grid_filtered`], [`World::try_sample_grid`]), filled in parallel bands of
//! windows, and single windows of a grid ([`World::sample_grid_window`]) with exactly the
//! whole grid's values.

use super::base::Base;
use super::footprint::Filter;
use super::tiles::{GridSpec, Scratch};
use super::{HeightGrid, World, WorldError};
use rayon::prelude::*;

impl World {
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
    ///
    /// [`Crater::albedo_filtered`]: super::Crater::albedo_filtered
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
}

/// Side of the windows a grid is filled by, pixels (rounded down to whole tiles).
const WINDOW: usize = 16;

/// Largest grid `sample_grid` samples: 2^28 pixels (2 GiB of `f32` height and albedo).
pub const MAX_GRID_PIXELS: usize = 1 << 28;
