//! Runs the core's fix on owned images with owned scratch.

use super::OwnedScratch;
use orbfix::camera::{CameraParams, RoverPose};
use orbfix::fix::{
    self, Depth, FixConfig, FixInputs, FixReport, FixScratch, HeadingFix, HeadingSearch, NoClock,
};
use orbfix::image::ImageView;
use orbfix::map_product::{CrcCheck, MapProduct};
use orbfix::reproject::DepthView;
use std::time::Instant;

/// Everything one fix produced, with the images it was made from.
#[derive(Clone, Debug)]
pub struct FixOutcome {
    /// The core's report.
    pub report: FixReport,
    /// The top-down image (`n * n`).
    pub top: Vec<u8>,
    /// Its mask.
    pub mask: Vec<u8>,
    /// The coarse response (Q15 cosines over the map product's window grid).
    pub response: Vec<i32>,
    /// Window grid `(cols, rows, step_px)` of the response.
    pub grid: (usize, usize, usize),
    /// Digest of every output ([`fix::output_digest`]).
    pub digest: u32,
    /// Wall time of the fix, seconds (one core).
    pub seconds: f64,
}

/// The depth a fix gets ([`FixRunner::run_with`]).
#[derive(Clone, Copy, Debug)]
pub enum FixDepth<'a> {
    /// None: flat ground.
    Flat,
    /// Depth images (`u16` millimetres, frame size), e.g. the renderer's truth.
    Images(&'a [Vec<u16>; 4]),
    /// The right images of the stereo pairs: the fix computes depth itself.
    Stereo([Option<ImageView<'a>>; 4]),
}

impl<'a> FixDepth<'a> {
    /// Depth images when given, else flat ground.
    pub fn from_images(depths: Option<&'a [Vec<u16>; 4]>) -> Self {
        match depths {
            Some(d) => Self::Images(d),
            None => Self::Flat,
        }
    }
}

/// A fix configuration with its weights: runs [`orbfix::fix::run`].
#[derive(Clone, Debug)]
pub struct FixRunner {
    /// The weight file's bytes.
    pub weights: Vec<u8>,
    /// The configuration (named in every report).
    pub cfg: FixConfig,
}

impl FixRunner {
    /// The shipped weights with `cfg`.
    pub fn shipped(cfg: FixConfig) -> Self {
        Self {
            weights: orbfix::nn::model::SHIPPED_WEIGHTS.to_vec(),
            cfg,
        }
    }

    /// Runs the fix on `frames` (front, right, rear, left; `None` = missing) with optional
    /// `depths` (same order; `None` = flat ground) against `product`.
    pub fn run(
        &self,
        params: &CameraParams,
        pose: &RoverPose,
        frames: [Option<ImageView<'_>>; 4],
        depths: Option<&[Vec<u16>; 4]>,
        product: &[u8],
    ) -> anyhow::Result<FixOutcome> {
        self.run_with(params, pose, frames, FixDepth::from_images(depths), product)
    }

    /// As [`FixRunner::run`] with any depth source, the stereo pairs included.
    pub fn run_with(
        &self,
        params: &CameraParams,
        pose: &RoverPose,
        frames: [Option<ImageView<'_>>; 4],
        depth: FixDepth<'_>,
        product: &[u8],
    ) -> anyhow::Result<FixOutcome> {
        let n = self.cfg.grid.n;
        let (report, mut out) =
            self.with_scratch(params, pose, frames, depth, product, |inputs, scratch| {
                let report = fix::run(inputs, &self.cfg, scratch, &mut NoClock)?;
                let digest = fix::output_digest(&report, scratch, n);
                Ok((report, digest))
            })?;
        let (report, digest) = report;
        out.report = report;
        out.digest = digest;
        Ok(out)
    }

    /// Runs the core's heading search ([`orbfix::fix::run_heading_search`]) around
    /// `pose.heading_deg`; the images of the outcome are those of the last heading tried
    /// (the core's scratch), its report the best heading's.
    pub fn run_heading_search(
        &self,
        params: &CameraParams,
        pose: &RoverPose,
        frames: [Option<ImageView<'_>>; 4],
        depths: Option<&[Vec<u16>; 4]>,
        product: &[u8],
        search: &HeadingSearch,
    ) -> anyhow::Result<(HeadingFix, FixOutcome)> {
        let depth = FixDepth::from_images(depths);
        self.run_heading_search_with(params, pose, frames, depth, product, search)
    }

    /// As [`FixRunner::run_heading_search`] with any depth source; the outcome's digest is
    /// [`fix::output_digest`] of the best report over the scratch the search left.
    pub fn run_heading_search_with(
        &self,
        params: &CameraParams,
        pose: &RoverPose,
        frames: [Option<ImageView<'_>>; 4],
        depth: FixDepth<'_>,
        product: &[u8],
        search: &HeadingSearch,
    ) -> anyhow::Result<(HeadingFix, FixOutcome)> {
        let n = self.cfg.grid.n;
        // Boxed: the search result holds a report per heading; by value it took this
        // frame past 4 KiB (a stack probe, scripts/stack-probe-check.py).
        let ((hf, digest), mut out) =
            self.with_scratch(params, pose, frames, depth, product, |inputs, scratch| {
                let hf = Box::new(heading_search(inputs, &self.cfg, search, scratch)?);
                let digest = fix::output_digest(&hf.report, scratch, n);
                Ok((hf, digest))
            })?;
        out.report = hf.report.clone();
        out.digest = digest;
        Ok((*hf, out))
    }

    /// Sets up the inputs and owned scratch, times `f` on them and returns its result with
    /// the images left in the scratch (report and digest left empty for the caller).
    fn with_scratch<R>(
        &self,
        params: &CameraParams,
        pose: &RoverPose,
        frames: [Option<ImageView<'_>>; 4],
        depth: FixDepth<'_>,
        product: &[u8],
        f: impl FnOnce(&FixInputs<'_>, &mut FixScratch<'_>) -> Result<R, fix::FixError>,
    ) -> anyhow::Result<(R, FixOutcome)> {
        let depths = match depth {
            FixDepth::Images(d) => Some(d),
            _ => None,
        };
        let parsed =
            MapProduct::parse(product, CrcCheck::Skip).map_err(|e| anyhow::anyhow!("{e}"))?;
        let (meta, l) = (*parsed.meta(), parsed.layout().to_owned());
        let sizes = fix::fix_buffer_sizes(&self.cfg, &meta).map_err(|e| anyhow::anyhow!("{e}"))?;
        let (w, h) = (params.width_px as usize, params.height_px as usize);
        let mut dviews: [Option<DepthView<'_>>; 4] = [None; 4];
        if let Some(ds) = depths {
            for (dv, d) in dviews.iter_mut().zip(ds) {
                *dv = Some(
                    DepthView::new(d, w, h)
                        .map_err(|e| anyhow::anyhow!("depth image is not {w} x {h}: {e}"))?,
                );
            }
        }
        let inputs = FixInputs {
            params: *params,
            pose: *pose,
            frames,
            depth: match depth {
                FixDepth::Images(_) => Depth::Images(dviews),
                FixDepth::Stereo(rights) => Depth::Stereo(rights),
                FixDepth::Flat => Depth::Flat,
            },
            map_product: product,
            weights: &self.weights,
        };
        let mut bufs = OwnedScratch::new(&sizes);
        let mut scratch = bufs.scratch();
        let t0 = Instant::now();
        let result = f(&inputs, &mut scratch).map_err(|e| anyhow::anyhow!("{e}"))?;
        let seconds = t0.elapsed().as_secs_f64();
        let report = FixReport::no_data(pose.x_m, pose.y_m, empty_summary());
        Ok((
            result,
            FixOutcome {
                report,
                top: bufs.top,
                mask: bufs.mask,
                response: bufs.response,
                grid: (l.cols, l.rows, meta.step_px),
                digest: 0,
                seconds,
            },
        ))
    }
}

/// The core's heading search, out of line: inlined into its caller (with the digest after
/// it) the frame grows past the stack-probe check's 4 KiB (scripts/stack-probe-check.py).
#[inline(never)]
fn heading_search(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    search: &HeadingSearch,
    scratch: &mut FixScratch<'_>,
) -> Result<HeadingFix, fix::FixError> {
    fix::run_heading_search(inputs, cfg, search, scratch, &mut NoClock)
}

fn empty_summary() -> orbfix::fix::ReprojectionSummary {
    orbfix::fix::ReprojectionSummary {
        range: false,
        status: [orbfix::reproject::FrameStatus::Missing; 4],
        valid_cells: 0,
        stereo: None,
    }
}
