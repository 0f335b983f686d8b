//! The whole fix as one call with per-stage hooks: the code the flight firmware times on
//! the target and the host re-runs for the bit-exactness check (`orbfix budget`).
//!
//! [`run`] takes the inputs (camera rig, pose prior, four frames and the orbital map region,
//! all borrowed: on the target they live in external memory), caller-provided [`Scratch`]
//! (sizes from [`scratch_sizes`]), and calls a [`StageClock`] around each stage so the
//! firmware can read its instruction counter there while the host passes [`NoClock`]. Both
//! get the same [`FlightOutputs`]; [`FlightOutputs::digest`] folds every output bit into one
//! 32-bit FNV-1a value.
//!
//! Stages ([`Stage`]):
//! 1. `lut_build`: the reprojection lookup table for the pose prior, built in bands of
//!    [`LUT_BAND_ROWS`] grid rows ([`Lut::build_rows`]) in the localizer's scratch;
//! 2. `reproject`: the four frames sampled through each band into the top-down image and
//!    mask ([`Lut::apply`]). Stages 1 and 2 alternate band by band; each stage's clock
//!    hooks are called once per band (the firmware adds the spans up).
//! 3. `localize`: masked NCC of the top-down image over the map region, coarse dense pass,
//!    fine re-scoring of the best peaks and sub-pixel refinement ([`localize()`]);
//! 4. `nn_embed`: the int8 siamese CNN ([`crate::nn`], shipped weights, CRC-checked)
//!    embeds the top-down image;
//! 5. `nn_match`: Q15 cosine of that embedding against the embeddings of the map windows
//!    (50 m windows on the CNN localization's dense 4 m grid, 3969 over 300 x 300 m, or the
//!    study's 441 every 12.5 m; see [`map_window_grid_step`]), which depend only on
//!    the map and are computed on the ground ([`map_window_records`]) and stored with it as
//!    [`crate::nn::window_cosine`] records (embedding plus its sum and sum of squares), so
//!    the flight side computes one int8 dot product per window
//!    ([`crate::nn::window_cosine::cosine_q15_window`], bit for bit
//!    [`crate::nn::model::cosine_q15`]).

use crate::camera::{CameraParams, RoverPose};
use crate::geo::GeoRef;
use crate::image::ImageView;
use crate::localize::{self, LocalizeConfig, LocalizeError};
use crate::matcher::ncc::Ncc;
use crate::matcher::OpCounts;
use crate::nn::input::{prepare_input, INPUT_LEN};
use crate::nn::model::{self as nn_model, Arena, EMBED_LEN};
use crate::nn::window_cosine::{
    cosine_q15_window, cosine_q15_windows, write_window_record, TemplateStats, WindowRecord,
    WINDOWS_PER_PASS, WINDOW_RECORD_BYTES,
};
use crate::nn::NnError;
use crate::reproject::{
    classify_frame, ApplyReport, BuildStats, Cell, FrameStatus, GridSpec, Lut, ReprojectError, Tap,
};

/// The stages of the fix, in run order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Reprojection lookup table for the pose prior (set-up floats, once per stop).
    LutBuild,
    /// Integer bilinear sampling of the four frames into the top-down image and mask.
    Reproject,
    /// Matcher over the map region (coarse dense NCC), fine re-scoring and refinement.
    Localize,
    /// CNN embedding of the top-down image (int8 network, weights checked first).
    NnEmbed,
    /// Cosine scores of the embedding against the map windows' embeddings.
    NnMatch,
}

impl Stage {
    /// Every stage, in run order.
    pub const ALL: [Stage; 5] = [
        Stage::LutBuild,
        Stage::Reproject,
        Stage::Localize,
        Stage::NnEmbed,
        Stage::NnMatch,
    ];

    /// Short lower-case name used in reports and the budget table.
    pub fn name(self) -> &'static str {
        match self {
            Stage::LutBuild => "lut_build",
            Stage::Reproject => "reproject",
            Stage::Localize => "localize",
            Stage::NnEmbed => "nn_embed",
            Stage::NnMatch => "nn_match",
        }
    }
}

/// Called around every stage (the firmware reads its instruction counter here).
pub trait StageClock {
    /// `stage` is about to start.
    fn begin(&mut self, stage: Stage);
    /// `stage` has finished.
    fn end(&mut self, stage: Stage);
}

/// A [`StageClock`] that does nothing (host runs).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl StageClock for NoClock {
    fn begin(&mut self, _stage: Stage) {}
    fn end(&mut self, _stage: Stage) {}
}

/// Why a fix could not be run.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlightError {
    /// Table build or frame sampling failed (camera, grid, frame sizes, buffers).
    Reproject(ReprojectError),
    /// Localization failed (coverage, resolution, prior outside the map, buffers).
    Localize(LocalizeError),
    /// The CNN failed (weights, too little valid top-down image, flat input).
    Nn(NnError),
    /// The shipped weight file did not validate (CRC, shapes).
    Weights,
    /// The map-window records are not a whole number of records, or none.
    BadMapEmbeddings,
    /// A scratch buffer is shorter than [`scratch_sizes`] asks.
    ScratchTooSmall,
}

impl From<NnError> for FlightError {
    fn from(e: NnError) -> Self {
        FlightError::Nn(e)
    }
}

impl From<ReprojectError> for FlightError {
    fn from(e: ReprojectError) -> Self {
        FlightError::Reproject(e)
    }
}

impl From<LocalizeError> for FlightError {
    fn from(e: LocalizeError) -> Self {
        FlightError::Localize(e)
    }
}

/// Everything the fix reads. Frames and the map are borrowed (external memory on target).
#[derive(Clone, Copy, Debug)]
pub struct FlightInputs<'a> {
    /// The camera rig.
    pub params: CameraParams,
    /// Pose prior: last known position (metres), heading (degrees clockwise from north).
    pub pose: RoverPose,
    /// Frames in dataset order (front, right, rear, left), `width_px x height_px` each,
    /// rows `width_px` bytes apart.
    pub frames: [ImageView<'a>; 4],
    /// Orbital map region around the prior, north-up, `grid.m_per_px` metres per pixel.
    pub map: ImageView<'a>,
    /// Georeference of `map` (north-west corner, metres per pixel).
    pub map_geo: GeoRef,
    /// Records of the map windows ([`map_window_records`]), `WINDOW_RECORD_BYTES` each
    /// (layout in [`crate::nn::window_cosine`]: sums, then the int8 embedding), row-major
    /// over the window grid (computed on the ground, stored with the map; 4-byte aligned
    /// start for word loads, though unaligned data works too).
    pub map_windows: &'a [u8],
}

/// Settings of the fix.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlightConfig {
    /// The top-down grid (default 200 x 200 cells of 0.25 m).
    pub grid: GridSpec,
    /// Coarse-to-fine localization settings.
    pub localize: LocalizeConfig,
}

/// Grid rows per band of the reprojection table: one band's cells (8 bytes each, 40,000
/// bytes for the 200-cell grid) and its overlap taps (at most one per cell) are resident
/// at a time, in the localizer's scratch (the stages run one after the other).
pub const LUT_BAND_ROWS: usize = 25;

/// Element counts of every scratch buffer of one fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScratchSizes {
    /// Cells of one band of the table (`LUT_BAND_ROWS * n` at most); they live in
    /// `loc_floats` during the table stages.
    pub band_cells: usize,
    /// Top-down image and mask, bytes each (`n * n`).
    pub top: usize,
    /// Localization byte scratch (also holds one band's overlap taps, 8 bytes each, one
    /// per band cell at most, so no tap is ever dropped).
    pub loc_bytes: usize,
    /// Localization `f32` scratch (response maps; also holds one band's cells).
    pub loc_floats: usize,
}

/// Scratch sizes of a fix with `cfg` over a `map_w x map_h` map region (pixels).
pub fn scratch_sizes(
    cfg: &FlightConfig,
    map_w: usize,
    map_h: usize,
) -> Result<ScratchSizes, FlightError> {
    cfg.grid.validate()?;
    let n = cfg.grid.n;
    let (loc_bytes, loc_floats) = localize::buffer_sizes(n, n, map_w, map_h, &cfg.localize)?;
    let band_cells = LUT_BAND_ROWS.min(n) * n;
    let cell = core::mem::size_of::<Cell>();
    let tap = core::mem::size_of::<Tap>();
    let float = core::mem::size_of::<f32>();
    Ok(ScratchSizes {
        band_cells,
        top: cfg.grid.cells(),
        // Taps need 4-byte alignment: up to 3 bytes of a byte buffer go to aligning.
        loc_bytes: loc_bytes.max(band_cells * tap + 3),
        loc_floats: loc_floats.max((band_cells * cell).div_ceil(float)),
    })
}

/// Caller-provided working memory of one fix (static buffers on the target).
/// The reprojection table has no buffer of its own: its bands live in `loc_floats` (cells)
/// and `loc_bytes` (overlap taps) before the localizer needs them.
pub struct Scratch<'a> {
    /// Top-down image, at least [`ScratchSizes::top`] bytes.
    pub top: &'a mut [u8],
    /// Validity mask, at least [`ScratchSizes::top`] bytes.
    pub mask: &'a mut [u8],
    /// Localization bytes, at least [`ScratchSizes::loc_bytes`].
    pub loc_bytes: &'a mut [u8],
    /// Localization floats, at least [`ScratchSizes::loc_floats`].
    pub loc_floats: &'a mut [f32],
    /// The CNN's activations and convolution scratch.
    pub nn_arena: &'a mut Arena,
    /// The CNN's int8 input.
    pub nn_input: &'a mut [i8; INPUT_LEN],
    /// The top-down image's embedding.
    pub nn_embedding: &'a mut [i8; EMBED_LEN],
}

/// The fix part of the outputs (metres, scores as the matcher gives them).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixSummary {
    /// Rover east, metres.
    pub x_m: f32,
    /// Rover north, metres.
    pub y_m: f32,
    /// Fine-level NCC score of the fix, `[-1, 1]`.
    pub score: f32,
    /// Peak distinctiveness, `[0, 1]`.
    pub confidence: f32,
    /// Best coarse score.
    pub peak_score: f32,
    /// Second coarse peak after suppression.
    pub second_score: f32,
    /// The peak is on the border of the search region (a failure).
    pub on_border: bool,
    /// Number of candidates.
    pub candidates: u32,
}

/// What the fix produced (bit for bit the same on host and target).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlightOutputs {
    /// Table statistics.
    pub lut: BuildStats,
    /// What the sampling did per frame.
    pub apply: ApplyReport,
    /// FNV-1a of the top-down image (`n * n` bytes, row-major).
    pub top_hash: u32,
    /// FNV-1a of the validity mask.
    pub mask_hash: u32,
    /// FNV-1a of the coarse response map (`f32` bits, little-endian, row-major).
    pub response_hash: u32,
    /// Positions in the coarse response map.
    pub response_len: u32,
    /// FNV-1a of the candidates (x, y, score bits and refined flag, best first).
    pub candidates_hash: u32,
    /// The fix.
    pub fix: FixSummary,
    /// Operations of coarse and fine passes together.
    pub ops: OpCounts,
    /// FNV-1a of the top-down image's int8 embedding.
    pub embedding_hash: u32,
    /// FNV-1a of the cosine scores (Q15, `i32` little-endian) of all map windows.
    pub nn_scores_hash: u32,
    /// Map windows scored by the CNN.
    pub nn_windows: u32,
    /// Best window (row-major index) and its Q15 cosine.
    pub nn_best: (u32, i32),
}

const FNV_OFFSET: u32 = 0x811c_9dc5;
const FNV_PRIME: u32 = 0x0100_0193;

/// FNV-1a (32-bit) of `bytes`, continuing from `h` (start with [`fnv1a_start`]).
pub fn fnv1a(mut h: u32, bytes: &[u8]) -> u32 {
    for &b in bytes {
        h = (h ^ b as u32).wrapping_mul(FNV_PRIME);
    }
    h
}

/// The FNV-1a start value.
pub const fn fnv1a_start() -> u32 {
    FNV_OFFSET
}

fn fnv_u32s(mut h: u32, words: &[u32]) -> u32 {
    for w in words {
        h = fnv1a(h, &w.to_le_bytes());
    }
    h
}

/// Status code of a frame in reports: 0 ok, 1 missing, 2 black, 3 saturated.
pub fn status_code(s: FrameStatus) -> u8 {
    match s {
        FrameStatus::Ok => 0,
        FrameStatus::Missing => 1,
        FrameStatus::Black => 2,
        FrameStatus::Saturated => 3,
    }
}

impl FlightOutputs {
    /// One 32-bit FNV-1a over every output field (little-endian).
    pub fn digest(&self) -> u32 {
        let l = &self.lut;
        let a = &self.apply;
        let f = &self.fix;
        let s = |v: usize| v as u32;
        let mut h = fnv_u32s(
            fnv1a_start(),
            &[
                s(l.valid_cells),
                s(l.blended_cells),
                s(l.dropped_taps),
                s(l.cells_per_view[0]),
                s(l.cells_per_view[1]),
                s(l.cells_per_view[2]),
                s(l.cells_per_view[3]),
                s(a.valid_cells),
                s(a.lost_cells),
            ],
        );
        for st in a.status {
            h = fnv1a(h, &[status_code(st)]);
        }
        h = fnv_u32s(
            h,
            &[
                self.top_hash,
                self.mask_hash,
                self.response_hash,
                self.response_len,
                self.candidates_hash,
                f.x_m.to_bits(),
                f.y_m.to_bits(),
                f.score.to_bits(),
                f.confidence.to_bits(),
                f.peak_score.to_bits(),
                f.second_score.to_bits(),
                f.on_border as u32,
                f.candidates,
            ],
        );
        for v in [self.ops.macs, self.ops.windows, self.ops.downsample_px] {
            h = fnv1a(h, &v.to_le_bytes());
        }
        fnv_u32s(
            h,
            &[
                self.embedding_hash,
                self.nn_scores_hash,
                self.nn_windows,
                self.nn_best.0,
                self.nn_best.1 as u32,
            ],
        )
    }
}

/// Stages 1 and 2: builds the table band by band ([`LUT_BAND_ROWS`] rows) with its cells in
/// `floats` and its overlap taps in `bytes`, and samples the frames through each band into
/// its rows of `top` and `mask`. Returns the summed statistics of the bands (equal to a
/// whole table's: every band has room for a tap per cell, so none is dropped) and the
/// merged apply report.
#[allow(clippy::too_many_arguments)]
fn build_and_apply_banded<C: StageClock>(
    inputs: &FlightInputs<'_>,
    cfg: &FlightConfig,
    sizes: &ScratchSizes,
    floats: &mut [f32],
    bytes: &mut [u8],
    top: &mut [u8],
    mask: &mut [u8],
    clock: &mut C,
) -> Result<(BuildStats, ApplyReport), FlightError> {
    let n = cfg.grid.n;
    // Safety: `Cell` and `Tap` are `repr(C)` structs of integers without padding (8 bytes
    // each), valid for every bit pattern, and `f32` / `u8` are too, so viewing the buffers'
    // aligned middles as cells and taps (and the localizer later writing them as floats and
    // bytes again) never creates an invalid value; `align_to_mut` handles the alignment.
    let (_, cells, _) = unsafe { floats.align_to_mut::<Cell>() };
    // Safety: as above.
    let (_, extra, _) = unsafe { bytes.align_to_mut::<Tap>() };
    let cells = cells
        .get_mut(..sizes.band_cells)
        .ok_or(FlightError::ScratchTooSmall)?;
    let extra = extra
        .get_mut(..sizes.band_cells)
        .ok_or(FlightError::ScratchTooSmall)?;
    let stride = inputs.params.width_px as usize;
    let [f0, f1, f2, f3] = inputs.frames;
    let frames = [Some(f0), Some(f1), Some(f2), Some(f3)];
    // Classified once (sparse 32 x 32 probes per frame), not once per band; part of the
    // `reproject` stage.
    clock.begin(Stage::Reproject);
    let status = frames.map(|f| f.as_ref().map_or(FrameStatus::Missing, classify_frame));
    clock.end(Stage::Reproject);
    let mut stats = BuildStats::default();
    let mut report = ApplyReport {
        status: [FrameStatus::Missing; 4],
        valid_cells: 0,
        lost_cells: 0,
    };
    let mut row = 0usize;
    while row < n {
        let end = (row + LUT_BAND_ROWS).min(n);
        let band = (end - row) * n;
        let (Some(band_cells), Some(band_top), Some(band_mask)) = (
            cells.get_mut(..band),
            top.get_mut(row * n..end * n),
            mask.get_mut(row * n..end * n),
        ) else {
            return Err(FlightError::ScratchTooSmall);
        };
        clock.begin(Stage::LutBuild);
        let lut = Lut::build_rows(
            band_cells,
            extra,
            &inputs.params,
            &inputs.pose,
            &cfg.grid,
            stride,
            row..end,
        )?;
        clock.end(Stage::LutBuild);
        clock.begin(Stage::Reproject);
        let a = lut.apply_with_status(&frames, &status, band_top, band_mask)?;
        clock.end(Stage::Reproject);
        let s = lut.stats();
        stats.valid_cells += s.valid_cells;
        stats.blended_cells += s.blended_cells;
        stats.dropped_taps += s.dropped_taps;
        for (t, v) in stats.cells_per_view.iter_mut().zip(s.cells_per_view) {
            *t += v;
        }
        report.status = a.status;
        report.valid_cells += a.valid_cells;
        report.lost_cells += a.lost_cells;
        row = end;
    }
    Ok((stats, report))
}

/// Runs the whole fix on `inputs` with `cfg` in `scratch`, calling `clock` around every
/// stage. The prior is `inputs.pose` (position and heading).
pub fn run<C: StageClock>(
    inputs: &FlightInputs<'_>,
    cfg: &FlightConfig,
    scratch: &mut Scratch<'_>,
    clock: &mut C,
) -> Result<FlightOutputs, FlightError> {
    let sizes = scratch_sizes(cfg, inputs.map.width(), inputs.map.height())?;
    let n = cfg.grid.n;
    let top = scratch
        .top
        .get_mut(..sizes.top)
        .ok_or(FlightError::ScratchTooSmall)?;
    let mask = scratch
        .mask
        .get_mut(..sizes.top)
        .ok_or(FlightError::ScratchTooSmall)?;
    let (lut_stats, apply) = build_and_apply_banded(
        inputs,
        cfg,
        &sizes,
        scratch.loc_floats,
        scratch.loc_bytes,
        top,
        mask,
        clock,
    )?;

    clock.begin(Stage::Localize);
    let template = ImageView::new(top, n, n).map_err(|_| FlightError::ScratchTooSmall)?;
    let weight = ImageView::new(mask, n, n).map_err(|_| FlightError::ScratchTooSmall)?;
    let fix = localize::localize(
        &Ncc::default(),
        &template,
        &weight,
        cfg.grid.m_per_px,
        &inputs.map,
        &inputs.map_geo,
        inputs.pose.x_m,
        inputs.pose.y_m,
        &cfg.localize,
        scratch.loc_bytes,
        scratch.loc_floats,
    )?;
    clock.end(Stage::Localize);

    clock.begin(Stage::NnEmbed);
    let net = nn_model::shipped().map_err(|_| FlightError::Weights)?;
    prepare_input(template.data(), Some(weight.data()), n, scratch.nn_input)?;
    net.embed(scratch.nn_input, scratch.nn_arena, scratch.nn_embedding)?;
    clock.end(Stage::NnEmbed);

    clock.begin(Stage::NnMatch);
    // The weight check keeps zero points in int8 range; anything else is a bad weight file.
    let zp = i8::try_from(net.embedding_zero_point()).map_err(|_| FlightError::Weights)?;
    if inputs.map_windows.is_empty() || inputs.map_windows.len() % WINDOW_RECORD_BYTES != 0 {
        return Err(FlightError::BadMapEmbeddings);
    }
    // The rover's side of every cosine, once per fix.
    let template_stats = TemplateStats::new(scratch.nn_embedding, zp);
    let mut nn_scores_hash = fnv1a_start();
    let mut nn_best = (0u32, i32::MIN);
    let mut nn_windows = 0u32;
    let mut take = |c: i32| {
        nn_scores_hash = fnv1a(nn_scores_hash, &c.to_le_bytes());
        if c > nn_best.1 {
            nn_best = (nn_windows, c);
        }
        nn_windows += 1;
    };
    // WINDOWS_PER_PASS windows per pass (the rover's embedding is read once for them),
    // then the rest one by one.
    const PASS: usize = WINDOWS_PER_PASS;
    let groups = inputs.map_windows.chunks_exact(PASS * WINDOW_RECORD_BYTES);
    let rest = groups.remainder();
    for g in groups {
        let mut ws = [WindowRecord::EMPTY; PASS];
        for (w, r) in ws.iter_mut().zip(g.chunks_exact(WINDOW_RECORD_BYTES)) {
            *w = WindowRecord::parse(r)?;
        }
        for c in cosine_q15_windows(scratch.nn_embedding, &template_stats, &ws) {
            take(c);
        }
    }
    for r in rest.chunks_exact(WINDOW_RECORD_BYTES) {
        let w = WindowRecord::parse(r)?;
        take(cosine_q15_window(scratch.nn_embedding, &template_stats, &w));
    }
    clock.end(Stage::NnMatch);

    let response_len = fix.coarse_grid.cols() * fix.coarse_grid.rows();
    let mut response_hash = fnv1a_start();
    for v in scratch.loc_floats.iter().take(response_len) {
        response_hash = fnv1a(response_hash, &v.to_bits().to_le_bytes());
    }
    let mut candidates_hash = fnv1a_start();
    for c in &fix.candidates {
        candidates_hash = fnv_u32s(
            candidates_hash,
            &[
                c.x_m.to_bits(),
                c.y_m.to_bits(),
                c.score.to_bits(),
                c.refined as u32,
            ],
        );
    }
    let mut ops = fix.ops_coarse;
    ops.add(&fix.ops_fine);
    Ok(FlightOutputs {
        lut: lut_stats,
        apply,
        top_hash: fnv1a(fnv1a_start(), template.data()),
        mask_hash: fnv1a(fnv1a_start(), weight.data()),
        response_hash,
        response_len: response_len as u32,
        candidates_hash,
        fix: FixSummary {
            x_m: fix.x_m,
            y_m: fix.y_m,
            score: fix.score,
            confidence: fix.confidence,
            peak_score: fix.peak_score,
            second_score: fix.second_score,
            on_border: fix.on_border,
            candidates: fix.candidates.len() as u32,
        },
        ops,
        embedding_hash: fnv1a(
            fnv1a_start(),
            // int8 as their two's-complement bytes.
            &scratch.nn_embedding.map(|v| v as u8),
        ),
        nn_scores_hash,
        nn_windows,
        nn_best,
    })
}

/// Step (pixels) of the study's window grid for `n x n` windows: `n / 4` (12.5 m for 50 m
/// windows).
pub const fn study_window_step(n: usize) -> usize {
    if n >= 4 {
        n / 4
    } else {
        1
    }
}

/// Step (pixels) of the dense CNN grid: 4 m at `m_per_px` metres per pixel (16 px at
/// 0.25 m/px: 63 x 63 = 3969 windows of 50 m over a 300 m map), at least 1.
pub fn dense_window_step(m_per_px: f32) -> usize {
    let s = 4.0 / m_per_px;
    if s.is_finite() && s >= 1.0 {
        (s + 0.5) as usize
    } else {
        1
    }
}

/// Window grid over a `map_w x map_h` map: `n x n` windows (the top-down grid's size)
/// every `step` pixels, top-left corners at multiples of `step`. Returns `(cols, rows)`,
/// or `None` if the map is smaller than a window or `n` or `step` is 0.
pub fn map_window_grid_step(
    n: usize,
    step: usize,
    map_w: usize,
    map_h: usize,
) -> Option<(usize, usize)> {
    if n == 0 || step == 0 || map_w < n || map_h < n {
        return None;
    }
    Some(((map_w - n) / step + 1, (map_h - n) / step + 1))
}

/// Top-left corners (map pixels) of the study's window grid over a `map_w x map_h` map:
/// `n x n` windows (the top-down grid's size) every [`study_window_step`] pixels (12.5 m for
/// 50 m windows). Returns `(cols, rows, step)`.
pub fn map_window_grid(n: usize, map_w: usize, map_h: usize) -> Option<(usize, usize, usize)> {
    let step = study_window_step(n);
    let (cols, rows) = map_window_grid_step(n, step, map_w, map_h)?;
    Some((cols, rows, step))
}

/// Computes the records of every map window of [`map_window_grid_step`]`(n, step, ..)`
/// into `out` (`cols * rows` records of [`WINDOW_RECORD_BYTES`], row-major; layout in
/// [`crate::nn::window_cosine`]), with `window` (`n * n` bytes) as the copy buffer. Done on
/// the ground once per map, with the same network code as the flight stage. Returns the
/// number of windows.
pub fn map_window_records(
    map: &ImageView<'_>,
    n: usize,
    step: usize,
    window: &mut [u8],
    arena: &mut Arena,
    input: &mut [i8; INPUT_LEN],
    out: &mut [u8],
) -> Result<usize, FlightError> {
    let (cols, rows) = map_window_grid_step(n, step, map.width(), map.height())
        .ok_or(FlightError::BadMapEmbeddings)?;
    let net = nn_model::shipped().map_err(|_| FlightError::Weights)?;
    let window = window
        .get_mut(..n * n)
        .ok_or(FlightError::ScratchTooSmall)?;
    let mut emb = [0i8; EMBED_LEN];
    let mut chunks = out.chunks_exact_mut(WINDOW_RECORD_BYTES);
    for r in 0..rows {
        for c in 0..cols {
            let sub = map
                .sub(c * step, r * step, n, n)
                .ok_or(FlightError::BadMapEmbeddings)?;
            for (y, dst) in window.chunks_exact_mut(n).enumerate() {
                let row = sub.row(y).ok_or(FlightError::BadMapEmbeddings)?;
                dst.copy_from_slice(row);
            }
            prepare_input(window, None, n, input)?;
            net.embed(input, arena, &mut emb)?;
            write_window_record(&emb, chunks.next().ok_or(FlightError::ScratchTooSmall)?)?;
        }
    }
    Ok(cols * rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_names_are_distinct_and_ordered() {
        assert_eq!(Stage::ALL.len(), 5);
        for (i, a) in Stage::ALL.iter().enumerate() {
            assert_eq!(*a as usize, i);
            for b in &Stage::ALL[i + 1..] {
                assert_ne!(a.name(), b.name());
            }
        }
    }

    #[test]
    fn fnv_matches_reference_values() {
        // FNV-1a 32-bit test vectors.
        assert_eq!(fnv1a(fnv1a_start(), b""), 0x811c_9dc5);
        assert_eq!(fnv1a(fnv1a_start(), b"a"), 0xe40c_292c);
        assert_eq!(fnv1a(fnv1a_start(), b"foobar"), 0xbf9c_f968);
    }

    #[test]
    fn window_grids_of_the_study_and_the_dense_cnn() {
        assert_eq!(map_window_grid(200, 1200, 1200), Some((21, 21, 50)));
        assert_eq!(dense_window_step(0.25), 16);
        assert_eq!(map_window_grid_step(200, 16, 1200, 1200), Some((63, 63)));
        assert_eq!(map_window_grid_step(200, 0, 1200, 1200), None);
        assert_eq!(map_window_grid_step(200, 16, 199, 1200), None);
        assert_eq!(dense_window_step(f32::NAN), 1);
    }

    #[test]
    fn scratch_sizes_follow_the_grid_and_map() {
        let cfg = FlightConfig::default();
        let s = scratch_sizes(&cfg, 1200, 1200).unwrap();
        assert_eq!(s.band_cells, LUT_BAND_ROWS * 200);
        assert!(s.loc_floats * 4 >= s.band_cells * 8);
        assert!(s.loc_bytes >= s.band_cells * 8 + 3);
        assert_eq!(s.top, 200 * 200);
        let small = scratch_sizes(&cfg, 400, 400).unwrap();
        assert!(small.loc_floats < s.loc_floats);
        let bad = FlightConfig {
            grid: GridSpec::new(0, 0.25),
            ..cfg
        };
        assert!(matches!(
            scratch_sizes(&bad, 1200, 1200),
            Err(FlightError::Reproject(ReprojectError::BadGridSize))
        ));
    }
}
