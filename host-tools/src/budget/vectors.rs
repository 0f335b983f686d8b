//! Test vectors for the flight firmware: one rover stop rendered from the procedural world
//! in the test zone (the same renderer and pipeline as `orbfix eval`), written as
//! `vectors.rs` (constants, `f32` as exact bit patterns, buffer sizes from
//! `orbfix::fix::fix_buffer_sizes`), `frames.bin` (four frames, rig order, packed),
//! `depths.bin` (their `u16` millimetre depth images, little-endian), `rights.bin` (the
//! right images of the stereo pairs, packed like the frames, when the fix computes depth
//! itself), `product.bin` (the map product) and `weights.bin` (the weight file the product
//! was made with and the fix runs: `orbfix budget --weights`).

use crate::eval::pipeline::{
    make_queries, map_region, observe_raw, Condition, PipelineOptions, Query, Reprojection,
};
use crate::fix::{build_map_product, FixDepth, FixOutcome, FixRunner, MapProductOptions};
use crate::fsutil::write_atomic;
use crate::world::World;
use anyhow::{Context, Result};
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::fix::{self, FixConfig};
use orbfix::map_product::{CrcCheck, MapProduct};
use std::path::Path;

/// Everything the firmware embeds for one stop.
#[derive(Clone, Debug)]
pub struct Vectors {
    /// Camera rig.
    pub params: CameraParams,
    /// Pose prior (position the fix starts from; the map is centred on it; heading known).
    pub pose: RoverPose,
    /// True rover position the frames were rendered at, metres (east, north).
    pub truth_m: (f64, f64),
    /// Four frames, rig order (front, right, rear, left), packed rows.
    pub frames: Vec<u8>,
    /// Their depth images, `u16` millimetres, packed, or `None` (flat-ground path, or the
    /// stereo pairs).
    pub depths: Option<[Vec<u16>; 4]>,
    /// The right images of the stereo pairs, packed like `frames` (the fix computes depth
    /// itself), or `None`.
    pub rights: Option<Vec<u8>>,
    /// Stereo baseline, metres (with `rights`).
    pub baseline_m: f32,
    /// The map product.
    pub product: Vec<u8>,
    /// The weight file (`.ofw`) the product's records were made with.
    pub weights: Vec<u8>,
    /// How these vectors were made (for reports).
    pub source: String,
}

impl Vectors {
    /// Stop `index` of the budget's stops: the `index`-th generated query of world `seed`'s
    /// test zone (same sun), rendered with `opts`, its map product made with `weights`.
    pub fn world_stop(
        seed: u64,
        index: usize,
        opts: &PipelineOptions,
        weights: &[u8],
    ) -> Result<Self> {
        let world = World::new(seed);
        let q: Query = *make_queries(seed, index + 1, Condition::SameSun)
            .get(index)
            .context("no such stop")?;
        let obs = observe_raw(&world, q.x_m, q.y_m, q.heading_deg, q.sun_rover, opts)?;
        let map = map_region(
            &world,
            q.prior_x_m,
            q.prior_y_m,
            opts.map_px,
            opts.grid.m_per_px as f64,
            q.sun_map,
            &opts.render,
        )?;
        // The firmware's configuration: the default fix on this grid (firmware/src/main.rs).
        let fix_cfg = orbfix::fix::FixConfig {
            grid: opts.grid,
            ..orbfix::fix::FixConfig::default()
        };
        let product = build_map_product(
            &map,
            weights,
            &MapProductOptions::for_fix(
                &fix_cfg,
                Some((q.sun_map.elevation_deg as f32, q.sun_map.azimuth_deg as f32)),
            )?,
        )?;
        let windows = MapProduct::parse(&product, CrcCheck::Verify)
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .layout()
            .windows();
        let mut pose = obs.pose;
        pose.x_m = q.prior_x_m as f32;
        pose.y_m = q.prior_y_m as f32;
        let frames = obs
            .views
            .iter()
            .flat_map(|v| v.as_raw().iter().copied())
            .collect();
        let rights = obs
            .rights
            .as_ref()
            .map(|r| r.iter().flat_map(|v| v.as_raw().iter().copied()).collect());
        let stereo = rights.is_some();
        Ok(Self {
            params: obs.params,
            pose,
            truth_m: (q.x_m, q.y_m),
            frames,
            depths: if stereo { None } else { obs.depths },
            rights,
            baseline_m: opts.stereo_params().baseline_m,
            product,
            weights: weights.to_vec(),
            source: format!(
                "world seed {seed}, test-zone stop {index} at ({:.1}, {:.1}) m, heading {:.1} deg, prior {:.1} m off; {} x {} frames{}; map {} x {} px at {} m/px with {} CNN window records",
                q.x_m,
                q.y_m,
                q.heading_deg,
                ((q.prior_x_m - q.x_m).powi(2) + (q.prior_y_m - q.y_m).powi(2)).sqrt(),
                obs.params.width_px,
                obs.params.height_px,
                match opts.reprojection {
                    Reprojection::Range => " with depth",
                    Reprojection::Stereo => " with their stereo partners (the fix computes depth)",
                    Reprojection::Lut => ", flat ground",
                },
                opts.map_px,
                opts.map_px,
                opts.grid.m_per_px,
                windows,
            ),
        })
    }

    /// Pixels of one frame.
    pub fn frame_pixels(&self) -> usize {
        (self.params.width_px * self.params.height_px) as usize
    }

    /// The host's run of the fix on these vectors (same code, same inputs as the firmware).
    pub fn host_run(&self, runner: &FixRunner) -> Result<FixOutcome> {
        let n = self.frame_pixels();
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        let mut frames: [Option<orbfix::image::ImageView<'_>>; 4] = [None; 4];
        for (i, f) in frames.iter_mut().enumerate() {
            *f = Some(
                orbfix::image::ImageView::new(&self.frames[i * n..(i + 1) * n], w, h)
                    .map_err(|e| anyhow::anyhow!("bad frame: {e}"))?,
            );
        }
        let mut rights: [Option<orbfix::image::ImageView<'_>>; 4] = [None; 4];
        let depth = match &self.rights {
            Some(r) => {
                for (i, f) in rights.iter_mut().enumerate() {
                    let px = r
                        .get(i * n..(i + 1) * n)
                        .context("the right frames are shorter than four frames")?;
                    *f = Some(
                        orbfix::image::ImageView::new(px, w, h)
                            .map_err(|e| anyhow::anyhow!("bad right frame: {e}"))?,
                    );
                }
                FixDepth::Stereo(rights)
            }
            None => match &self.depths {
                Some(d) => FixDepth::Images(d),
                None => FixDepth::Flat,
            },
        };
        runner.run_with(&self.params, &self.pose, frames, depth, &self.product)
    }

    /// Writes `vectors.rs`, `frames.bin`, `depths.bin` and `product.bin` into `dir` (each
    /// atomically); `vectors.rs` carries the buffer sizes of `cfg` for the firmware's
    /// static buffers.
    pub fn write(&self, dir: &Path, cfg: &FixConfig) -> Result<()> {
        let meta = *MapProduct::parse(&self.product, CrcCheck::Verify)
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .meta();
        let sz = fix::fix_buffer_sizes(cfg, &meta).map_err(|e| anyhow::anyhow!("{e}"))?;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the vectors folder {}", dir.display()))?;
        let f = |v: f32| format!("f32::from_bits(0x{:08x})", v.to_bits());
        let p = &self.params;
        let q = &self.pose;
        let depth_bytes: Vec<u8> = match &self.depths {
            Some(d) => d.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
            None => vec![0u8; 2 * 4 * self.frame_pixels()],
        };
        // Without stereo pairs: one frame of zeros, so the firmware's include has a file.
        let right_bytes: Vec<u8> = match &self.rights {
            Some(r) => r.clone(),
            None => vec![0u8; self.frame_pixels()],
        };
        let src = format!(
            "// Written by `orbfix budget`: {}.\n\
             pub const WIDTH: usize = {};\npub const HEIGHT: usize = {};\n\
             pub const HFOV_DEG: f32 = {};\npub const CAM_HEIGHT_M: f32 = {};\n\
             pub const TILT_DEG: f32 = {};\n\
             /// x_m, y_m, ground_z_m, heading_deg, pitch_deg, roll_deg.\n\
             pub const POSE: [f32; 6] = [{}, {}, {}, {}, {}, {}];\n\
             pub const FRAMES_LEN: usize = {};\npub const DEPTHS_BYTES: usize = {};\n\
             pub const HAS_DEPTH: bool = {};\npub const PRODUCT_LEN: usize = {};\n\
             pub const GRID_N: usize = {};\npub const GRID_M_PER_PX: f32 = {};\n\
             pub const TOP: usize = {};\npub const MASK: usize = {};\n\
             pub const WORK_WORDS: usize = {};\npub const RESPONSE: usize = {};\n\
             pub const REFINE_FLOATS: usize = {};\npub const WEIGHTS_LEN: usize = {};\n\
             pub const HAS_STEREO: bool = {};\npub const RIGHTS_LEN: usize = {};\n\
             pub const STEREO_BASELINE_M: f32 = {};\n",
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
            depth_bytes.len(),
            self.depths.is_some(),
            self.product.len(),
            cfg.grid.n,
            f(cfg.grid.m_per_px),
            sz.top,
            sz.mask,
            sz.work_words,
            sz.response,
            sz.refine_floats,
            self.weights.len(),
            self.rights.is_some(),
            right_bytes.len(),
            f(self.baseline_m),
        );
        write_atomic(&dir.join("frames.bin"), &self.frames)?;
        write_atomic(&dir.join("depths.bin"), &depth_bytes)?;
        write_atomic(&dir.join("rights.bin"), &right_bytes)?;
        write_atomic(&dir.join("product.bin"), &self.product)?;
        write_atomic(&dir.join("weights.bin"), &self.weights)?;
        write_atomic(&dir.join("vectors.rs"), src.as_bytes())?;
        Ok(())
    }
}
