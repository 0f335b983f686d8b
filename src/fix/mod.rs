//! The fix: one function, [`run`], from the rover's four frames (and depth, when it has
//! it) and the map product to a position with a stated error bound and a confidence.
//! This is the code that flies, that `orbfix eval` and `orbfix demo` evaluate and that
//! `orbfix budget` times on the Cortex-M7; every stage lives here once.
//!
//! Stages ([`Stage`], timed through a [`StageClock`]):
//! 1. **reprojection** (`lut_build` + `reproject`, and `stereo` with [`Depth::Stereo`]):
//!    the four frames into a north-up `n x n` top-down image and mask around the prior,
//!    with depth when the rover has it ([`Depth::Images`] from an external stereo engine:
//!    [`crate::reproject::reproject_range`], relief-faithful; or [`Depth::Stereo`]: the
//!    core's own stereo matcher on the pairs, band by band, each band placed at once,
//!    [`stereo_depth`]), else on
//!    flat ground through the integer lookup table built band by band
//!    ([`crate::reproject::Lut::build_rows`], [`LUT_BAND_ROWS`] rows per band);
//! 2. **`nn_embed`**: the CNN's 64 x 64 int8 input ([`crate::nn::input::prepare_input`])
//!    and its embedding with the given weights (CRC-checked first);
//! 3. **`nn_match`**: Q15 cosine against every window record of the map product (50 m
//!    windows every 4 m: 3969 over 300 m), the coarse response;
//! 4. **`refine`**: the best [`RefineConfig::peaks`] coarse peaks after non-maximum
//!    suppression ([`FixConfig::nms_radius_m`]), each refined by masked, high-passed NCC in
//!    two levels ([`refine`]) with a sub-pixel peak; [`RefineMode::Auto`] keeps the best NCC
//!    position (with stereo depth, the CNN's best peak unless another beats it by
//!    [`RefineConfig::ncc_margin_stereo`]) when its score reaches [`RefineConfig::min_ncc`]
//!    inside the reach, else the CNN's sub-cell peak (a parabola on the coarse response).
//!    The report names the path.
//!
//! Confidence (one definition, [`coarse::confidence`]): `(s1 - s2) / (s1 - mean)` on the
//! coarse response, `s1` the chosen window's score, `s2` the best score farther than the
//! suppression radius. Status: no data (too little of the top-down image, or nothing the
//! CNN can embed), self-check failed, on border (the chosen window touches the map's edge:
//! the truth may lie outside), ambiguous (confidence below
//! [`FixConfig::accept_confidence`], or on flat ground below the stricter
//! [`FixConfig::accept_confidence_flat`], or with the fix's own stereo below
//! [`FixConfig::accept_confidence_stereo`]), else ok. The error bound is the calibrated bound of
//! the path that produced the fix ([`ErrorBounds`]).

pub mod coarse;
mod config;
mod digest;
pub mod heading;
pub mod protocol;
pub mod refine;
pub mod relief;
mod report;
mod scratch;
mod stage;
pub mod stereo_depth;
mod top_down;

pub use config::{
    ErrorBounds, FixConfig, RefineConfig, RefineLevel, RefineMode, SelfCheck,
    ACCEPT_CONFIDENCE_FLAT, ACCEPT_CONFIDENCE_STEREO, MIN_NCC_STEREO, NCC_MARGIN_STEREO,
};
pub use digest::{fnv1a, fnv1a_start, output_digest};
pub use heading::{run_heading_search, HeadingFix, HeadingSearch, MAX_HEADINGS};
pub use report::{FixError, FixPath, FixReport, FixStatus, ReprojectionSummary, StageOps};
pub use scratch::{
    fix_buffer_sizes, FixBufferSizes, FixScratch, RefineLayout, LUT_BAND_ROWS, NN_WORK_WORDS,
};
pub use stage::{NoClock, Stage, StageClock};
pub use stereo_depth::{stereo_work_words, StereoConfig};
pub use top_down::{top_down, top_down_buffer_sizes, TopDownBufferSizes};

use crate::camera::{CameraParams, RoverPose};
use crate::image::ImageView;
use crate::localize::{Candidate, MAX_CANDIDATES};
use crate::map_product::{CrcCheck, MapProduct};
use crate::matcher::OpCounts;
use crate::nn::input::prepare_input;
use crate::nn::model::{embedding_macs, SiameseNet, EMBED_LEN};
use crate::nn::weights::crc32;
use crate::nn::NnError;
use crate::reproject::{
    classify_frame, reproject_range_relief, ApplyReport, Cell, DepthView, FrameStatus, Lut, Tap,
};

/// How the top-down image gets its geometry.
#[derive(Clone, Copy, Debug)]
pub enum Depth<'a> {
    /// No depth: flat ground under the rover (the lookup-table path).
    Flat,
    /// Depth images (`u16`, [`crate::reproject::RangeOptions::depth_scale_m`] per unit, 0 =
    /// no depth), one per frame, e.g. from an external stereo engine.
    Images([Option<DepthView<'a>>; 4]),
    /// The right images of the stereo pairs (the frames are the left images), one per
    /// frame: the fix computes depth itself (stage [`Stage::Stereo`], settings
    /// [`FixConfig::stereo`]). A view without a usable pair gets no depth.
    Stereo([Option<ImageView<'a>>; 4]),
}

/// Everything the fix reads. Frames, depth, the map product and the weights are borrowed
/// (external memory on the target).
#[derive(Clone, Copy, Debug)]
pub struct FixInputs<'a> {
    /// The camera rig.
    pub params: CameraParams,
    /// Pose prior: last known position (metres) and the known heading (degrees clockwise
    /// from north).
    pub pose: RoverPose,
    /// Frames in rig order (front, right, rear, left); `None` for a missing camera.
    pub frames: [Option<ImageView<'a>>; 4],
    /// Depth of the frames.
    pub depth: Depth<'a>,
    /// The map product's bytes ([`crate::map_product`]).
    pub map_product: &'a [u8],
    /// The weight file's bytes (`.ofw`, [`crate::nn::weights`]).
    pub weights: &'a [u8],
}

/// Runs the whole fix. See the module docs for the stages. Errors are for inputs the fix
/// cannot run on (sizes, settings, damaged files, short scratch); a fix that runs but
/// finds nothing usable is an `Ok` report with status [`FixStatus::NoData`].
///
/// With [`SelfCheck::redundant_run`] the whole fix runs twice on the same inputs and
/// scratch and the two runs' [`output_digest`]s (report, top-down image, mask, coarse
/// response, embedding) must agree; if they do not, the report is the prior's position with
/// status [`FixStatus::SelfCheckFailed`]. The second run re-reads and re-checks everything
/// (weights CRC, map CRC when [`SelfCheck::verify_map_crc`]); its ops are added to the
/// first's.
pub fn run<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    scratch: &mut FixScratch<'_>,
    clock: &mut C,
) -> Result<FixReport, FixError> {
    let first = run_once(inputs, cfg, scratch, clock)?;
    clock.after(Stage::Refine, scratch);
    if !cfg.self_check.redundant_run {
        return Ok(first);
    }
    let n = cfg.grid.n;
    let digest = output_digest(&first, scratch, n);
    let mut second = run_once(inputs, cfg, scratch, clock)?;
    clock.after(Stage::Refine, scratch);
    let agree = output_digest(&second, scratch, n) == digest;
    let (a, b) = (first.ops, second.ops);
    let ops = StageOps {
        lut_cells: a.lut_cells.saturating_add(b.lut_cells),
        reproject_px: a.reproject_px.saturating_add(b.reproject_px),
        embed_macs: a.embed_macs.saturating_add(b.embed_macs),
        match_elements: a.match_elements.saturating_add(b.match_elements),
        refine_macs: a.refine_macs.saturating_add(b.refine_macs),
        stereo_pixel_disparities: a
            .stereo_pixel_disparities
            .saturating_add(b.stereo_pixel_disparities),
        stereo_cost_updates: a.stereo_cost_updates.saturating_add(b.stereo_cost_updates),
        stereo_px: a.stereo_px.saturating_add(b.stereo_px),
        stereo_depth_px: a.stereo_depth_px.saturating_add(b.stereo_depth_px),
        relief_macs: a.relief_macs.saturating_add(b.relief_macs),
    };
    if !agree {
        second = FixReport::no_data(inputs.pose.x_m, inputs.pose.y_m, second.reprojection);
        second.status = FixStatus::SelfCheckFailed;
    }
    second.ops = ops;
    Ok(second)
}

/// One run of the fix (see [`run`]).
/// Column and row of window `idx` in a grid `cols` wide (`(0, 0)` for an empty grid).
fn window_cell(idx: usize, cols: usize) -> (usize, usize) {
    (
        idx.checked_rem(cols).unwrap_or(0),
        idx.checked_div(cols).unwrap_or(0),
    )
}

fn run_once<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    scratch: &mut FixScratch<'_>,
    clock: &mut C,
) -> Result<FixReport, FixError> {
    cfg.validate()?;
    let crc_check = if cfg.self_check.verify_map_crc {
        CrcCheck::Verify
    } else {
        CrcCheck::Skip
    };
    let product = MapProduct::parse(inputs.map_product, crc_check)?;
    let meta = *product.meta();
    let sizes = fix_buffer_sizes(cfg, &meta)?;
    if meta.weights_crc != weights_crc(inputs.weights) {
        return Err(FixError::MapMismatch {
            what: "the map product's records were made with other weights",
        });
    }
    let rel = (meta.geo.m_per_px() - cfg.grid.m_per_px).abs() / cfg.grid.m_per_px;
    if rel > 1e-3 {
        return Err(FixError::MapMismatch {
            what: "map resolution differs from the top-down grid",
        });
    }
    let map = product.map();
    let plane = product.plane();
    let (pc, pr) = meta.geo.to_pixel(inputs.pose.x_m, inputs.pose.y_m);
    if !(pc >= 0.0 && pr >= 0.0 && pc < map.width() as f32 && pr < map.height() as f32) {
        return Err(FixError::PriorOutsideMap);
    }
    let n = cfg.grid.n;
    let FixScratch {
        top,
        mask,
        work,
        response,
        refine_floats,
        nn_embedding,
        relief,
    } = scratch;
    let too_small = |buffer| FixError::ScratchTooSmall { buffer };
    let top = top.get_mut(..sizes.top).ok_or(too_small("top"))?;
    let mask = mask.get_mut(..sizes.mask).ok_or(too_small("mask"))?;
    let work = work.get_mut(..sizes.work_words).ok_or(too_small("work"))?;
    let response = response
        .get_mut(..sizes.response)
        .ok_or(too_small("response"))?;
    if refine_floats.len() < sizes.refine_floats {
        return Err(too_small("refine_floats"));
    }
    // The fault-injection hook ([`StageClock::after`]) over the live scratch.
    macro_rules! after {
        ($stage:expr) => {
            clock.after(
                $stage,
                &mut FixScratch {
                    top: &mut *top,
                    mask: &mut *mask,
                    work: &mut *work,
                    response: &mut *response,
                    refine_floats: &mut **refine_floats,
                    nn_embedding: &mut **nn_embedding,
                    relief: &mut **relief,
                },
            )
        };
    }

    // 1. Reprojection (the stage on its own: [`top_down::top_down`]).
    // The relief blocks, with depth and a product that has a relief plane.
    let relief_grid = match (&inputs.depth, product.relief()) {
        (Depth::Flat, _) | (_, None) => None,
        _ => scratch::relief_grid(cfg, &meta)?,
    };
    let relief_acc = match relief_grid {
        Some(g) => Some((
            g,
            relief
                .get_mut(..sizes.relief_words)
                .ok_or(too_small("relief"))?,
        )),
        None => None,
    };
    let (reprojection, mut ops) =
        top_down::top_down_relief(inputs, cfg, work, top, mask, relief_acc, clock)?;
    after!(Stage::Reproject);
    let mut report = FixReport::no_data(inputs.pose.x_m, inputs.pose.y_m, reprojection);
    let permille = reprojection
        .valid_cells
        .saturating_mul(1000)
        .checked_div(n.saturating_mul(n))
        .unwrap_or(0) as u32;
    report.coverage_permille = permille;
    if reprojection.valid_cells == 0 || permille < cfg.min_coverage_permille {
        report.ops = ops;
        return Ok(report);
    }

    // 2. Embedding (the weights are parsed and CRC-checked inside, out of line).
    // The arena and input live in the work area, free between the reprojection and the
    // refinement.
    clock.begin(Stage::NnEmbed);
    let embedded = self::scratch::nn_views(work).and_then(|(nn_arena, nn_input)| {
        embed_stage(
            inputs.weights,
            top,
            mask,
            n,
            nn_input,
            nn_arena,
            nn_embedding,
            cfg.self_check.redundant_embed,
        )
    });
    clock.end(Stage::NnEmbed);
    after!(Stage::NnEmbed);
    let (zp, self_check_ok) = match embedded {
        Ok(v) => v,
        Err(FixError::Nn(NnError::TooFewValid | NnError::FlatInput)) => {
            report.ops = ops;
            return Ok(report);
        }
        Err(e) => return Err(e),
    };
    ops.embed_macs = embedding_macs() * if cfg.self_check.redundant_embed { 2 } else { 1 };
    if !self_check_ok {
        report.status = FixStatus::SelfCheckFailed;
        report.ops = ops;
        return Ok(report);
    }

    // 3. Coarse response.
    clock.begin(Stage::NnMatch);
    let windows = coarse::cosine_response(nn_embedding, zp, product.records(), response)?;
    clock.end(Stage::NnMatch);
    after!(Stage::NnMatch);
    ops.match_elements = (windows * EMBED_LEN) as u64;
    let layout = *product.layout();
    let live = windows.min(response.len());
    let response = &mut response[..live];

    // 3b. Relief: the depth's heights against the map's elevation blocks, into the response.
    if let (Some(g), Some(plane)) = (relief_grid, product.relief()) {
        clock.begin(Stage::Relief);
        let words = relief.get_mut(..sizes.relief_words).unwrap_or_default();
        let t = crate::reproject::relief_template(
            &g,
            words,
            mask,
            n,
            u32::from(cfg.relief.min_fill_permille),
        )?;
        if t.valid >= usize::from(cfg.relief.min_blocks) && t.energy > 0 {
            let v = relief::compact(&t, words, plane.cols());
            let (vals, offs) = words
                .split_at_checked(g.blocks() * g.blocks())
                .unwrap_or_default();
            ops.relief_macs = relief::add_scores(
                &plane,
                vals.get(..v).unwrap_or_default(),
                offs.get(..v).unwrap_or_default(),
                layout.cols,
                layout.rows,
                cfg.relief.weight_q8(),
                response,
            );
            report.relief_blocks = v as u32;
        }
        clock.end(Stage::Relief);
    }
    let response = &*response;

    // 4. Peaks, refinement, confidence.
    clock.begin(Stage::Refine);
    let step = meta.step_px;
    let step_m = step as f32 * meta.geo.m_per_px();
    let radius_cells = cfg.nms_radius_m / step_m;
    let peaks = coarse::peaks(response, layout.cols, radius_cells, MAX_CANDIDATES);
    let Some(&(best_idx, best_score)) = peaks.first() else {
        clock.end(Stage::Refine);
        report.ops = ops;
        return Ok(report);
    };
    let cols = layout.cols;
    let half = n as f32 / 2.0;
    let centre = |col: f32, row: f32| meta.geo.to_world(col + half, row + half);
    // The CNN's own sub-cell peak of the best window.
    let cnn_pos = {
        let (c, r) = window_cell(best_idx, cols);
        let at = |x: usize, y: usize| {
            if x < cols && y < layout.rows {
                response.get(y * cols + x).map(|&v| v as f32)
            } else {
                None
            }
        };
        let (dx, dy) = crate::peak::peak_offset_2d(at, c, r);
        ((c as f32 + dx) * step as f32, (r as f32 + dy) * step as f32)
    };
    let mut refine_ops = OpCounts::default();
    let mut chosen = (best_idx, cnn_pos, best_score as f32 / 32768.0, FixPath::Cnn);
    let mut cands: heapless::Vec<Candidate, MAX_CANDIDATES> = heapless::Vec::new();
    if cfg.refine.mode != RefineMode::Cnn {
        let rl = RefineLayout::new(cfg, map.width(), map.height());
        let (hp, bytes) = work.split_at_mut(rl.hp_words.min(work.len()));
        // Safety: `u8` is valid for every bit pattern and has alignment 1, so the middle of
        // `align_to_mut` is the whole `u32` buffer viewed as bytes.
        let (_, bytes, _) = unsafe { bytes.align_to_mut::<u8>() };
        let (persist, phase) = bytes.split_at_mut(rl.persistent_bytes().min(bytes.len()));
        let top_v = ImageView::new(top, n, n).map_err(|_| too_small("top"))?;
        let mask_v = ImageView::new(mask, n, n).map_err(|_| too_small("mask"))?;
        let templates = refine::build_templates(
            cfg,
            &rl,
            &top_v,
            &mask_v,
            hp,
            persist,
            phase,
            &mut refine_ops,
        );
        match templates {
            Ok(t) => {
                // The CNN's best peak's refinement, and the best of the others.
                let (mut first, mut other): (Option<(usize, refine::Refined)>, _) = (None, None);
                for &(idx, coarse_q15) in peaks.iter().take(cfg.refine.peaks) {
                    let (c, r) = window_cell(idx, cols);
                    let w = (c * step, r * step);
                    let r = refine::refine_window(
                        cfg,
                        &rl,
                        &t,
                        &plane,
                        w,
                        phase,
                        refine_floats,
                        &mut refine_ops,
                    )?;
                    let (x_m, y_m) = centre(r.col, r.row);
                    let _ = cands.push(Candidate {
                        x_m,
                        y_m,
                        score: r.score,
                        refined: true,
                        coarse: coarse_q15 as f32 / 32768.0,
                    });
                    if first.is_none() {
                        first = Some((idx, r));
                    } else if other.is_none_or(|(_, b): (usize, refine::Refined)| r.score > b.score)
                    {
                        other = Some((idx, r));
                    }
                }
                // The highest NCC (the first on a tie), the CNN's best unless another beats
                // it by the margin.
                let margin = ncc_margin(cfg, &inputs.depth);
                let best = match (first, other) {
                    (Some(f), Some(o)) if o.1.score > f.1.score + margin => Some(o),
                    (Some(f), _) => Some(f),
                    (None, o) => o,
                };
                if let Some((idx, r)) = best {
                    let trusted = cfg.refine.mode == RefineMode::Ncc
                        || (r.score >= min_ncc(cfg, &inputs.depth) && !r.at_edge);
                    if trusted {
                        chosen = (idx, (r.col, r.row), r.score, FixPath::Ncc);
                    }
                }
            }
            // A top-down image without contrast after the high-pass: the CNN's peak stands.
            Err(FixError::Match(_)) => {}
            Err(e) => return Err(e),
        }
    }
    for &(idx, s) in peaks.iter().skip(cands.len()) {
        let (c, r) = window_cell(idx, cols);
        let (x_m, y_m) = centre((c * step) as f32, (r * step) as f32);
        let _ = cands.push(Candidate {
            x_m,
            y_m,
            score: s as f32 / 32768.0,
            refined: false,
            coarse: s as f32 / 32768.0,
        });
    }
    let (idx, (col, row), score, path) = chosen;
    let confidence = coarse::confidence(response, cols, idx, radius_cells);
    clock.end(Stage::Refine);
    ops.refine_macs = refine_ops.macs + refine_ops.downsample_px;

    let (x_m, y_m) = centre(col, row);
    let (c, r) = window_cell(idx, cols);
    let on_border = c == 0 || r == 0 || c + 1 == cols || r + 1 == layout.rows;
    report.x_m = x_m;
    report.y_m = y_m;
    report.score = score;
    report.confidence = confidence;
    report.path = path;
    report.best_window = idx as u32;
    report.cnn_best_window = best_idx as u32;
    report.cnn_best_q15 = best_score;
    report.windows = windows as u32;
    report.candidates = cands;
    report.error_bound_m = error_bound(cfg, path, score);
    report.status = if on_border {
        FixStatus::OnBorder
    } else if confidence < accept_threshold(cfg, &inputs.depth) {
        FixStatus::Ambiguous
    } else {
        FixStatus::Ok
    };
    report.ops = ops;
    Ok(report)
}

/// The confidence a fix needs to be reported ok: stricter on flat-ground reprojection and
/// with the fix's own stereo depth.
fn accept_threshold(cfg: &FixConfig, depth: &Depth<'_>) -> f32 {
    match depth {
        Depth::Flat => cfg.accept_confidence.max(cfg.accept_confidence_flat),
        Depth::Stereo(_) => cfg.accept_confidence.max(cfg.accept_confidence_stereo),
        Depth::Images(_) => cfg.accept_confidence,
    }
}

/// The stated error bound of a fix by `path` whose refinement scored `score`, metres. An NCC
/// position scored below the common [`RefineConfig::min_ncc`] (kept by the lower stereo
/// threshold, or by [`RefineMode::Ncc`]) is less sure than the fixes `ncc_m` was calibrated
/// on: it states the CNN's bound.
fn error_bound(cfg: &FixConfig, path: FixPath, score: f32) -> f32 {
    match path {
        FixPath::Ncc if score >= cfg.refine.min_ncc => cfg.bounds.ncc_m,
        FixPath::Ncc | FixPath::Cnn | FixPath::None => cfg.bounds.cnn_m,
    }
}

/// The NCC score the refinement needs to be kept ([`RefineMode::Auto`]): lower with the
/// fix's own stereo depth.
/// The NCC a refined peak other than the CNN's best needs above the best's to replace it:
/// [`RefineConfig::ncc_margin_stereo`] with the fix's own stereo depth, else 0.
fn ncc_margin(cfg: &FixConfig, depth: &Depth<'_>) -> f32 {
    match depth {
        Depth::Stereo(_) => cfg.refine.ncc_margin_stereo,
        Depth::Flat | Depth::Images(_) => 0.0,
    }
}

fn min_ncc(cfg: &FixConfig, depth: &Depth<'_>) -> f32 {
    match depth {
        Depth::Stereo(_) => cfg.refine.min_ncc_stereo,
        Depth::Flat | Depth::Images(_) => cfg.refine.min_ncc,
    }
}

/// CRC-32 of a weight file as the map product records it (the file's own trailer).
pub fn weights_crc(weights: &[u8]) -> u32 {
    match weights.len().checked_sub(4).and_then(|n| weights.get(n..)) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => crc32(weights),
    }
}

/// Stage 1 with depth (kept out of line: its frame stays its own).
#[inline(never)]
fn reproject_depth(
    inputs: &FixInputs<'_>,
    depths: &[Option<DepthView<'_>>; 4],
    cfg: &FixConfig,
    work: &mut [u32],
    top: &mut [u8],
    mask: &mut [u8],
    relief: Option<(crate::reproject::ReliefGrid, &mut [i32])>,
) -> Result<crate::reproject::RangeReport, FixError> {
    Ok(reproject_range_relief(
        &inputs.frames,
        depths,
        &inputs.params,
        &inputs.pose,
        &cfg.grid,
        &cfg.range,
        work,
        top,
        mask,
        relief,
    )?)
}

/// Stage 2: parses the weights (CRC first), embeds the top-down image, and with
/// `redundant` embeds it again (weights parsed and checked again) and compares digests.
/// Returns the embedding's zero point and whether the self-check agreed. Out of line, so the
/// parsed network's parameter tables stay in this frame only.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn embed_stage(
    weights: &[u8],
    top: &[u8],
    mask: &[u8],
    n: usize,
    input: &mut [i8; crate::nn::input::INPUT_LEN],
    arena: &mut crate::nn::model::Arena,
    out: &mut [i8; EMBED_LEN],
    redundant: bool,
) -> Result<(i8, bool), FixError> {
    let net = SiameseNet::from_bytes(weights)?;
    let zp = i8::try_from(net.embedding_zero_point()).map_err(|_| NnError::BadGeometry)?;
    embed(&net, top, mask, n, input, arena, out)?;
    if !redundant {
        return Ok((zp, true));
    }
    let first = fnv1a(fnv1a_start(), &out.map(|v| v as u8));
    let again = SiameseNet::from_bytes(weights)
        .ok()
        .map(|net2| embed(&net2, top, mask, n, input, arena, out).is_ok())
        .unwrap_or(false);
    Ok((
        zp,
        again && first == fnv1a(fnv1a_start(), &out.map(|v| v as u8)),
    ))
}

fn embed(
    net: &SiameseNet<'_>,
    top: &[u8],
    mask: &[u8],
    n: usize,
    input: &mut [i8; crate::nn::input::INPUT_LEN],
    arena: &mut crate::nn::model::Arena,
    out: &mut [i8; EMBED_LEN],
) -> Result<(), NnError> {
    prepare_input(top, Some(mask), n, input)?;
    net.embed(input, arena, out)
}

/// Stage 1 on flat ground: the table built band by band in `work` (cells, then overlap
/// taps), each band sampled into its rows of `top` and `mask`.
#[inline(never)]
fn reproject_flat<C: StageClock>(
    inputs: &FixInputs<'_>,
    cfg: &FixConfig,
    work: &mut [u32],
    top: &mut [u8],
    mask: &mut [u8],
    clock: &mut C,
    ops: &mut StageOps,
) -> Result<ReprojectionSummary, FixError> {
    let n = cfg.grid.n;
    let band_cells = LUT_BAND_ROWS.min(n) * n;
    let cell_words = band_cells * core::mem::size_of::<Cell>() / 4 + 2;
    let (cw, tw) = work.split_at_mut(cell_words.min(work.len()));
    // Safety: `Cell` and `Tap` are `repr(C)` structs of integers without padding, valid for
    // every bit pattern, as is `u32`; `align_to_mut` handles the alignment, so viewing the
    // word buffers as cells and taps never creates an invalid value.
    let (_, cells, _) = unsafe { cw.align_to_mut::<Cell>() };
    // Safety: as above.
    let (_, taps, _) = unsafe { tw.align_to_mut::<Tap>() };
    let too_small = FixError::ScratchTooSmall { buffer: "work" };
    let cells = cells.get_mut(..band_cells).ok_or(too_small)?;
    let taps = taps.get_mut(..band_cells).ok_or(too_small)?;
    let stride = inputs.params.width_px as usize;
    clock.begin(Stage::Reproject);
    let status = inputs
        .frames
        .map(|f| f.as_ref().map_or(FrameStatus::Missing, classify_frame));
    clock.end(Stage::Reproject);
    let mut report = ApplyReport {
        status,
        valid_cells: 0,
        lost_cells: 0,
    };
    let mut row = 0usize;
    while row < n {
        let end = (row + LUT_BAND_ROWS).min(n);
        let band = (end - row) * n;
        let (Some(bc), Some(bt), Some(bm)) = (
            cells.get_mut(..band),
            top.get_mut(row * n..end * n),
            mask.get_mut(row * n..end * n),
        ) else {
            return Err(too_small);
        };
        clock.begin(Stage::LutBuild);
        let lut = Lut::build_rows(
            bc,
            taps,
            &inputs.params,
            &inputs.pose,
            &cfg.grid,
            stride,
            row..end,
        )?;
        clock.end(Stage::LutBuild);
        clock.begin(Stage::Reproject);
        let a = lut.apply_with_status(&inputs.frames, &status, bt, bm)?;
        clock.end(Stage::Reproject);
        report.valid_cells += a.valid_cells;
        report.lost_cells += a.lost_cells;
        row = end;
    }
    ops.reproject_px = (n * n) as u64;
    ops.lut_cells = (n * n) as u64;
    Ok(ReprojectionSummary {
        range: false,
        status: report.status,
        valid_cells: report.valid_cells,
        stereo: None,
    })
}

#[cfg(test)]
mod tests;
