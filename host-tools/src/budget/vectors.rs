//! Test vectors for the flight firmware: one rover stop rendered from the procedural world
//! in the test zone (the same renderer and pipeline as `orbfix eval`), written as
//! `vectors.rs` (constants, `f32` as exact bit patterns, buffer sizes from
//! `orbfix::fix::fix_buffer_sizes`), `frames.bin` (four frames, rig order, packed),
//! `depths.bin` (their `u16` millimetre depth images, little-endian), `rights.bin` (the
//! right images of the stereo pairs, packed like the frames, when the fix computes depth
//! itself), `product.bin` (the map product) and `weights.bin` (the weight file the product
//! was made with and the fix runs: `orbfix budget --weights`). With a [`FusionCase`] and a
//! [`HeadingCase`] the vectors also carry the filter's start, leg and settings and the heading
//! search's estimate and steps, and the host runs the same work ([`FusionCase::host_run`],
//! [`Vectors::host_heading_search`]).

use crate::eval::pipeline::{
    make_queries, map_region, observe_raw, Condition, PipelineOptions, Query, Reprojection,
};
use crate::fix::{build_map_product_relief, FixDepth, FixOutcome, FixRunner, MapProductOptions};
use crate::fsutil::write_atomic;
use crate::world::World;
use anyhow::{Context, Result};
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::fix::protocol::{self, FusionStop};
use orbfix::fix::{self, FixConfig, FixReport, HeadingFix, HeadingSearch};
use orbfix::fusion::{Fusion, FusionConfig, OdometryLeg};
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
    /// The filter's work the firmware times after the fix, if any.
    pub fusion: Option<FusionCase>,
    /// The heading search the firmware runs after the fix, if any.
    pub heading: Option<HeadingCase>,
}

/// The filter's work at one stop as the budget measures it: a filter with `config` started
/// at `start_m`, predicted over `leg` to the stop, then updated with the stop's fix
/// ([`protocol::fusion_stop`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FusionCase {
    /// Filter settings.
    pub config: FusionConfig,
    /// Where the filter starts, metres (east, north).
    pub start_m: (f32, f32),
    /// The odometry leg driven to the stop.
    pub leg: OdometryLeg,
}

impl FusionCase {
    /// A case whose prediction lands `offset_m` from the stop's true position (as a
    /// dead-reckoned prior of a drive does), after a leg of `leg_m` metres along
    /// `heading_deg`.
    pub fn before_stop(
        config: FusionConfig,
        truth_m: (f64, f64),
        offset_m: (f64, f64),
        leg_m: f64,
        heading_deg: f64,
    ) -> Self {
        let h = heading_deg.to_radians();
        let start = (
            truth_m.0 + offset_m.0 - leg_m * h.sin(),
            truth_m.1 + offset_m.1 - leg_m * h.cos(),
        );
        Self {
            config,
            start_m: (start.0 as f32, start.1 as f32),
            leg: OdometryLeg {
                distance_m: leg_m as f32,
                heading_deg: heading_deg as f32,
            },
        }
    }

    /// The host's run of the same filter work on `fix`: the filter afterwards and what
    /// [`protocol::fusion_stop`] returned.
    pub fn host_run(&self, fix: &FixReport) -> Result<(Fusion, FusionStop)> {
        let mut f = Fusion::new(self.config, self.start_m.0, self.start_m.1)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let stop =
            protocol::fusion_stop(&mut f, &self.leg, fix).map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok((f, stop))
    }
}

/// The heading search the budget measures: `search` around `estimate_deg`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingCase {
    /// Headings tried.
    pub search: HeadingSearch,
    /// The heading estimate given to the search, degrees clockwise from north.
    pub estimate_deg: f32,
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
        let heights = |x: f64, y: f64| world.height_m(x, y);
        let product = build_map_product_relief(
            &map,
            weights,
            &MapProductOptions::for_fix(
                &fix_cfg,
                Some((q.sun_map.elevation_deg as f32, q.sun_map.azimuth_deg as f32)),
            )?,
            Some(&heights),
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
            fusion: None,
            heading: None,
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
        let (frames, rights) = self.views()?;
        runner.run_with(
            &self.params,
            &self.pose,
            frames,
            self.depth(rights),
            &self.product,
        )
    }

    /// The host's run of the heading search of `self.heading` on these vectors: the search's
    /// result and the digest the firmware reports with it; `None` without a heading case.
    pub fn host_heading_search(&self, runner: &FixRunner) -> Result<Option<(HeadingFix, u32)>> {
        let Some(hc) = self.heading else {
            return Ok(None);
        };
        let (frames, rights) = self.views()?;
        let mut pose = self.pose;
        pose.heading_deg = hc.estimate_deg;
        let (hf, out) = runner.run_heading_search_with(
            &self.params,
            &pose,
            frames,
            self.depth(rights),
            &self.product,
            &hc.search,
        )?;
        Ok(Some((hf, out.digest)))
    }

    /// The four frames and the right images of the stereo pairs (all `None` without).
    #[allow(clippy::type_complexity)]
    fn views(
        &self,
    ) -> Result<(
        [Option<orbfix::image::ImageView<'_>>; 4],
        [Option<orbfix::image::ImageView<'_>>; 4],
    )> {
        let n = self.frame_pixels();
        let (w, h) = (
            self.params.width_px as usize,
            self.params.height_px as usize,
        );
        let mut frames: [Option<orbfix::image::ImageView<'_>>; 4] = [None; 4];
        for (i, f) in frames.iter_mut().enumerate() {
            let px = self
                .frames
                .get(i * n..(i + 1) * n)
                .context("the frames are shorter than four frames")?;
            *f = Some(
                orbfix::image::ImageView::new(px, w, h)
                    .map_err(|e| anyhow::anyhow!("bad frame: {e}"))?,
            );
        }
        let mut rights: [Option<orbfix::image::ImageView<'_>>; 4] = [None; 4];
        if let Some(r) = &self.rights {
            for (i, f) in rights.iter_mut().enumerate() {
                let px = r
                    .get(i * n..(i + 1) * n)
                    .context("the right frames are shorter than four frames")?;
                *f = Some(
                    orbfix::image::ImageView::new(px, w, h)
                        .map_err(|e| anyhow::anyhow!("bad right frame: {e}"))?,
                );
            }
        }
        Ok((frames, rights))
    }

    /// The depth source of these vectors, with the right images from [`Vectors::views`].
    fn depth<'a>(&'a self, rights: [Option<orbfix::image::ImageView<'a>>; 4]) -> FixDepth<'a> {
        if self.rights.is_some() {
            FixDepth::Stereo(rights)
        } else {
            match &self.depths {
                Some(d) => FixDepth::Images(d),
                None => FixDepth::Flat,
            }
        }
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
        // Without a fusion case the firmware skips it; the constants still need values.
        let fc = self.fusion.unwrap_or(FusionCase {
            config: FusionConfig::default(),
            start_m: (q.x_m, q.y_m),
            leg: OdometryLeg {
                distance_m: 0.0,
                heading_deg: 0.0,
            },
        });
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
             pub const RELIEF_WORDS: usize = {};\n\
             pub const HAS_STEREO: bool = {};\npub const RIGHTS_LEN: usize = {};\n\
             pub const STEREO_BASELINE_M: f32 = {};\n\
             /// The filter's work after the fix (protocol::fusion_stop): settings as f32 bits\n\
             /// (protocol::fusion_config_words), start x, y m; leg distance m, heading deg.\n\
             pub const FUSION: bool = {};\npub const FUSION_CFG: [u32; {}] = {:?};\n\
             pub const FUSION_START: [f32; 2] = [{}, {}];\n\
             pub const FUSION_LEG: [f32; 2] = [{}, {}];\n\
             /// The heading search after the fix: steps each side (0: none), step, estimate.\n\
             pub const HEADING_STEPS: usize = {};\npub const HEADING_STEP_DEG: f32 = {};\n\
             pub const HEADING_ESTIMATE_DEG: f32 = {};\n",
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
            sz.relief_words,
            self.rights.is_some(),
            right_bytes.len(),
            f(self.baseline_m),
            self.fusion.is_some(),
            protocol::FUSION_CONFIG_WORDS,
            protocol::fusion_config_words(&fc.config),
            f(fc.start_m.0),
            f(fc.start_m.1),
            f(fc.leg.distance_m),
            f(fc.leg.heading_deg),
            self.heading.map_or(0, |h| h.search.steps_each_side()),
            f(self.heading.map_or(1.0, |h| h.search.step_deg())),
            f(self.heading.map_or(q.heading_deg, |h| h.estimate_deg)),
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
