//! Test vectors for the flight firmware: the rig, a pose prior, four frames and the
//! orbital map region, written as `vectors.rs` (constants, `f32` as exact bit patterns),
//! `frames.bin` (four frames, dataset order, packed), `map.bin` (north-up, packed) and
//! `map_windows.bin` (the map windows' CNN records, `orbfix::nn::window_cosine` layout).

use super::write_atomic;
use anyhow::{ensure, Context, Result};
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::flight_run::{self, FlightConfig, FlightInputs, FlightOutputs, NoClock, Scratch};
use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::nn::input::INPUT_LEN;
use orbfix::nn::model::{Arena, EMBED_LEN};
use orbfix::nn::window_cosine::{window_records_bytes, WINDOW_RECORD_BYTES};
use std::path::Path;

/// Everything the firmware embeds.
#[derive(Clone, Debug, PartialEq)]
pub struct Vectors {
    /// Camera rig.
    pub params: CameraParams,
    /// Pose prior (where the fix starts from; the map is centred on it).
    pub pose: RoverPose,
    /// True rover position the frames were rendered at, metres (east, north).
    pub truth_m: (f32, f32),
    /// Four frames, dataset order (front, right, rear, left), packed rows.
    pub frames: Vec<u8>,
    /// Map region, north-up, packed rows.
    pub map: Vec<u8>,
    /// Map width, pixels.
    pub map_w: usize,
    /// Map height, pixels.
    pub map_h: usize,
    /// Map georeference.
    pub map_geo: GeoRef,
    /// Side of the top-down grid (cells) the map-window embeddings were made for.
    pub grid_n: usize,
    /// Step of the map-window grid, pixels (the study's `grid_n / 4`, or the dense 4 m grid).
    pub window_step_px: usize,
    /// Records of the map windows: CNN embedding with its sums (computed on the ground with
    /// the core's network; layout in `orbfix::nn::window_cosine`).
    pub map_windows: Vec<u8>,
    /// How these vectors were made (for reports).
    pub source: String,
}

/// A small deterministic generator (SplitMix64).
struct SplitMix(u64);
impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// Value-noise texture: bilinear interpolation of a random lattice of `cell` pixels, two
/// octaves, mapped to grey levels 20..235 (never black, never saturated).
fn texture(w: usize, h: usize, cell: usize, rng: &mut SplitMix) -> Vec<u8> {
    let mut acc = vec![0f32; w * h];
    for (octave, amp) in [(cell, 0.7f32), (cell.div_ceil(4).max(1), 0.3)] {
        let gw = w / octave + 2;
        let gh = h / octave + 2;
        let lattice: Vec<f32> = (0..gw * gh)
            .map(|_| (rng.next() >> 40) as f32 / (1u64 << 24) as f32)
            .collect();
        for y in 0..h {
            let fy = y as f32 / octave as f32;
            let (y0, ty) = (fy as usize, fy.fract());
            for x in 0..w {
                let fx = x as f32 / octave as f32;
                let (x0, tx) = (fx as usize, fx.fract());
                let l = |i: usize, j: usize| lattice[j * gw + i];
                let top = l(x0, y0) * (1.0 - tx) + l(x0 + 1, y0) * tx;
                let bot = l(x0, y0 + 1) * (1.0 - tx) + l(x0 + 1, y0 + 1) * tx;
                acc[y * w + x] += amp * (top * (1.0 - ty) + bot * ty);
            }
        }
    }
    acc.into_iter()
        .map(|v| (20.0 + 215.0 * v.clamp(0.0, 1.0)).round() as u8)
        .collect()
}

/// CNN records (embedding and sums) of the windows of an `n x n` map for a `grid_n`
/// top-down grid.
fn embed_map(map: &[u8], n: usize, grid_n: usize, step: usize) -> Result<Vec<u8>> {
    let (cols, rows) = flight_run::map_window_grid_step(grid_n, step, n, n).with_context(|| {
        format!("the map ({n} px) is smaller than a {grid_n} px window, or the step is 0")
    })?;
    let view = ImageView::new(map, n, n).map_err(|e| anyhow::anyhow!("map: {e:?}"))?;
    let mut out = vec![0u8; window_records_bytes(cols * rows)];
    let mut window = vec![0u8; grid_n * grid_n];
    let mut arena = Box::new(Arena::new());
    let mut input = Box::new([0i8; INPUT_LEN]);
    flight_run::map_window_records(
        &view,
        grid_n,
        step,
        &mut window,
        &mut arena,
        &mut input,
        &mut out,
    )
    .map_err(|e| anyhow::anyhow!("cannot embed the map windows: {e:?}"))?;
    Ok(out)
}

impl Vectors {
    /// Deterministic synthetic vectors of `seed`: a value-noise orbital map of
    /// `map_size_m` square at `m_per_px` (the top-down grid's resolution) centred on the
    /// prior, and the four frames of the default rig (90 deg HFOV, 2 m, 15 deg down) at
    /// `width_px x height_px`, rendered over that map as flat ground
    /// ([`crate::reproject_ref::render_flat_ground`]) from a true position a few metres
    /// from the prior.
    pub fn synthetic(
        seed: u64,
        width_px: u32,
        height_px: u32,
        map_size_m: f32,
        m_per_px: f32,
        grid_n: usize,
    ) -> Result<Self> {
        let step = flight_run::study_window_step(grid_n);
        Self::synthetic_with_step(
            seed, width_px, height_px, map_size_m, m_per_px, grid_n, step,
        )
    }

    /// [`Self::synthetic`] with map windows every `window_step_px` pixels instead of the
    /// study's `grid_n / 4` (e.g. [`flight_run::dense_window_step`] for the dense 4 m grid).
    pub fn synthetic_with_step(
        seed: u64,
        width_px: u32,
        height_px: u32,
        map_size_m: f32,
        m_per_px: f32,
        grid_n: usize,
        window_step_px: usize,
    ) -> Result<Self> {
        ensure!(
            window_step_px > 0,
            "the map-window step must be at least 1 pixel"
        );
        let params = CameraParams {
            width_px,
            height_px,
            ..CameraParams::default()
        };
        params
            .validate()
            .map_err(|e| anyhow::anyhow!("bad camera size {width_px} x {height_px}: {e:?}"))?;
        ensure!(
            map_size_m.is_finite() && m_per_px.is_finite() && m_per_px > 0.0,
            "map size {map_size_m} m and resolution {m_per_px} m/px must be positive numbers"
        );
        let n = (map_size_m / m_per_px).round() as usize;
        ensure!(
            (8..=4096).contains(&n),
            "map of {map_size_m} m at {m_per_px} m/px is {n} px across; use 8..4096"
        );
        let mut rng = SplitMix(seed ^ 0x6F72_6266_6978);
        let pose = RoverPose::level(
            100.0 + (rng.next() % 1000) as f32 * 0.25,
            -50.0 + (rng.next() % 1000) as f32 * 0.25,
            0.0,
            (rng.next() % 360) as f32,
        );
        // The prior is off by up to +-10 m in each axis.
        let off = |r: u64| (r % 2001) as f32 * 0.01 - 10.0;
        let truth_m = (pose.x_m + off(rng.next()), pose.y_m + off(rng.next()));
        let map = texture(n, n, 12, &mut rng);
        let map_geo = GeoRef::centred(pose.x_m, pose.y_m, n, n, m_per_px)
            .map_err(|e| anyhow::anyhow!("bad map georeference: {e:?}"))?;
        let albedo = |x: f64, y: f64| {
            let (c, r) = (
                (x - map_geo.origin_x_m() as f64) / m_per_px as f64 - 0.5,
                (map_geo.origin_y_m() as f64 - y) / m_per_px as f64 - 0.5,
            );
            if !(c >= 0.0 && r >= 0.0 && c < (n - 1) as f64 && r < (n - 1) as f64) {
                return 128.0;
            }
            let (c0, r0) = (c as usize, r as usize);
            let (tc, tr) = (c - c0 as f64, r - r0 as f64);
            let p = |i: usize, j: usize| map[j * n + i] as f64;
            let top = p(c0, r0) * (1.0 - tc) + p(c0 + 1, r0) * tc;
            let bot = p(c0, r0 + 1) * (1.0 - tc) + p(c0 + 1, r0 + 1) * tc;
            top * (1.0 - tr) + bot * tr
        };
        let true_pose = RoverPose {
            x_m: truth_m.0,
            y_m: truth_m.1,
            ..pose
        };
        let views = crate::reproject_ref::render_flat_ground(&params, &true_pose, albedo)?;
        let mut frames = Vec::with_capacity(4 * (width_px * height_px) as usize);
        for v in &views {
            frames.extend_from_slice(v.as_raw());
        }
        let map_windows = embed_map(&map, n, grid_n, window_step_px)?;
        let window_count = map_windows.len() / WINDOW_RECORD_BYTES;
        Ok(Self {
            params,
            pose,
            truth_m,
            frames,
            map,
            map_w: n,
            map_h: n,
            map_geo,
            grid_n,
            window_step_px,
            map_windows,
            source: format!(
                "synthetic (seed {seed}): value-noise map {n} x {n} px at {m_per_px} m/px \
                 ({map_size_m} m), four {width_px} x {height_px} frames rendered over it as flat \
                 ground {:.2} m east and {:.2} m north of the prior; {} CNN map windows every \
                 {} m",
                truth_m.0 - pose.x_m,
                truth_m.1 - pose.y_m,
                window_count,
                window_step_px as f32 * m_per_px
            ),
        })
    }

    /// Pixels in one frame.
    pub fn frame_pixels(&self) -> usize {
        (self.params.width_px * self.params.height_px) as usize
    }

    /// A one-line description.
    pub fn describe(&self) -> String {
        self.source.clone()
    }

    /// The core's inputs, borrowing these vectors.
    pub fn inputs(&self) -> Result<FlightInputs<'_>> {
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        let n = w * h;
        ensure!(
            self.frames.len() == 4 * n,
            "frames hold {} bytes, expected 4 x {w} x {h}",
            self.frames.len()
        );
        let view = |i: usize| {
            ImageView::new(&self.frames[i * n..(i + 1) * n], w, h)
                .map_err(|e| anyhow::anyhow!("frame {i}: {e:?}"))
        };
        Ok(FlightInputs {
            params: self.params,
            pose: self.pose,
            frames: [view(0)?, view(1)?, view(2)?, view(3)?],
            map: ImageView::new(&self.map, self.map_w, self.map_h)
                .map_err(|e| anyhow::anyhow!("map: {e:?}"))?,
            map_geo: self.map_geo,
            map_windows: &self.map_windows,
        })
    }

    /// The host's run of the core on these vectors with `cfg` (what the firmware must
    /// reproduce), in heap scratch of the sizes the core asks for.
    pub fn host_run(&self, cfg: &FlightConfig) -> Result<FlightOutputs> {
        let sz = flight_run::scratch_sizes(cfg, self.map_w, self.map_h)
            .map_err(|e| anyhow::anyhow!("bad flight configuration: {e:?}"))?;
        let mut top = vec![0u8; sz.top];
        let mut mask = vec![0u8; sz.top];
        let mut loc_bytes = vec![0u8; sz.loc_bytes];
        let mut loc_floats = vec![0f32; sz.loc_floats];
        let mut nn_arena = Box::new(Arena::new());
        let mut nn_input = Box::new([0i8; INPUT_LEN]);
        let mut nn_embedding = Box::new([0i8; EMBED_LEN]);
        let mut scratch = Scratch {
            top: &mut top,
            mask: &mut mask,
            loc_bytes: &mut loc_bytes,
            loc_floats: &mut loc_floats,
            nn_arena: &mut nn_arena,
            nn_input: &mut nn_input,
            nn_embedding: &mut nn_embedding,
        };
        flight_run::run(&self.inputs()?, cfg, &mut scratch, &mut NoClock)
            .map_err(|e| anyhow::anyhow!("the core rejected the test vectors: {e:?}"))
    }

    /// Writes `vectors.rs`, `frames.bin`, `map.bin` and `map_windows.bin` into `dir` (each
    /// atomically).
    /// `vectors.rs` also carries the scratch sizes of `cfg` for the firmware's static buffers.
    pub fn write(&self, dir: &Path, cfg: &FlightConfig) -> Result<()> {
        let sz = flight_run::scratch_sizes(cfg, self.map_w, self.map_h)
            .map_err(|e| anyhow::anyhow!("bad flight configuration: {e:?}"))?;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the vectors folder {}", dir.display()))?;
        let f = |v: f32| format!("f32::from_bits(0x{:08x})", v.to_bits());
        let p = &self.params;
        let q = &self.pose;
        let g = &self.map_geo;
        let src = format!(
            "// Written by `orbfix budget`: {}.\n\
             pub const WIDTH: usize = {};\npub const HEIGHT: usize = {};\n\
             pub const HFOV_DEG: f32 = {};\npub const CAM_HEIGHT_M: f32 = {};\n\
             pub const TILT_DEG: f32 = {};\n\
             /// x_m, y_m, ground_z_m, heading_deg, pitch_deg, roll_deg.\n\
             pub const POSE: [f32; 6] = [{}, {}, {}, {}, {}, {}];\n\
             pub const FRAMES_LEN: usize = {};\n\
             pub const MAP_W: usize = {};\npub const MAP_H: usize = {};\n\
             pub const MAP_LEN: usize = {};\n\
             /// origin_x_m (west edge), origin_y_m (north edge), m_per_px.\n\
             pub const MAP_GEO: [f32; 3] = [{}, {}, {}];\n\
             pub const GRID_N: usize = {};\npub const GRID_M_PER_PX: f32 = {};\n\
             pub const LOC_BYTES: usize = {};\npub const LOC_FLOATS: usize = {};\n\
             pub const MAP_WINDOWS_LEN: usize = {};\n",
            self.source,
            p.width_px,
            p.height_px,
            f(p.hfov_deg),
            f(p.height_m),
            f(p.tilt_deg),
            f(q.x_m),
            f(q.y_m),
            f(q.ground_z_m),
            f(q.heading_deg),
            f(q.pitch_deg),
            f(q.roll_deg),
            self.frames.len(),
            self.map_w,
            self.map_h,
            self.map.len(),
            f(g.origin_x_m()),
            f(g.origin_y_m()),
            f(g.m_per_px()),
            cfg.grid.n,
            f(cfg.grid.m_per_px),
            sz.loc_bytes,
            sz.loc_floats,
            self.map_windows.len(),
        );
        write_atomic(&dir.join("frames.bin"), &self.frames)?;
        write_atomic(&dir.join("map.bin"), &self.map)?;
        write_atomic(&dir.join("map_windows.bin"), &self.map_windows)?;
        write_atomic(&dir.join("vectors.rs"), src.as_bytes())?;
        Ok(())
    }
}
