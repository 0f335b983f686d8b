//! What the fix returns ([`FixReport`]) and why it may refuse to run ([`FixError`]).

use crate::localize::{Candidate, LocalizeError, MAX_CANDIDATES};
use crate::map_product::MapProductError;
use crate::matcher::MatchError;
use crate::nn::weights::WeightsError;
use crate::nn::NnError;
use crate::reproject::{FrameStatus, RangeError, ReprojectError};
use crate::stereo::StereoError;
use core::fmt;

/// The verdict on a fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixStatus {
    /// A fix: use it, with its error bound.
    Ok,
    /// Another place matches almost as well (confidence below the acceptance threshold).
    Ambiguous,
    /// Too little of the top-down image has data, or nothing the CNN can use (black,
    /// saturated or missing cameras): the position is the prior's.
    NoData,
    /// The best window touches the map's edge: the rover may be outside the map.
    OnBorder,
    /// The redundant run disagreed: a damaged bit in weights, map or memory; no fix.
    SelfCheckFailed,
}

impl FixStatus {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            FixStatus::Ok => "ok",
            FixStatus::Ambiguous => "ambiguous",
            FixStatus::NoData => "no-data",
            FixStatus::OnBorder => "on-border",
            FixStatus::SelfCheckFailed => "self-check-failed",
        }
    }

    /// Numeric code in the firmware's result protocol.
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// Which stage produced the position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixPath {
    /// No position (no data): the prior.
    None,
    /// The CNN's sub-cell peak on the coarse response.
    Cnn,
    /// The masked NCC refinement.
    Ncc,
}

impl FixPath {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            FixPath::None => "none",
            FixPath::Cnn => "cnn",
            FixPath::Ncc => "ncc",
        }
    }
}

/// What the reprojection did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReprojectionSummary {
    /// Depth path (`true`) or flat-ground table.
    pub range: bool,
    /// Per view (front, right, rear, left): sampled or why not.
    pub status: [FrameStatus; 4],
    /// Top-down cells with data.
    pub valid_cells: usize,
    /// With on-board stereo ([`super::Depth::Stereo`]): per view, why its pair gave no
    /// depth (`None`: it did, or the frame itself was unusable, see `status`); `None` for
    /// the other depth sources.
    pub stereo: Option<[Option<StereoError>; 4]>,
}

/// Work done per stage (the units of the budget's per-unit rates).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StageOps {
    /// Table cells built (flat path).
    pub lut_cells: u64,
    /// Frame pixels read (range path) or top-down cells sampled (flat path).
    pub reproject_px: u64,
    /// Multiply-accumulates of the embedding(s).
    pub embed_macs: u64,
    /// Embedding elements of the cosines (windows x embedding length).
    pub match_elements: u64,
    /// NCC multiply-accumulates and downsampled pixels of the refinement.
    pub refine_macs: u64,
    /// Stereo: pixel-disparities of the winner-take-all (columns x each row's disparities).
    pub stereo_pixel_disparities: u64,
    /// Stereo: column-cost updates (set-up rows of every band included).
    pub stereo_cost_updates: u64,
    /// Stereo: working-size pixels of the bands matched (four views, rows below the
    /// horizon).
    pub stereo_px: u64,
    /// Stereo: working-size pixels that got a depth.
    pub stereo_depth_px: u64,
    /// Relief: multiply-accumulates of the correlations (windows x 3 x blocks).
    pub relief_macs: u64,
}

/// The result of a fix.
#[derive(Clone, Debug, PartialEq)]
pub struct FixReport {
    /// Rover east, metres.
    pub x_m: f32,
    /// Rover north, metres.
    pub y_m: f32,
    /// Stated error bound of this fix, metres.
    pub error_bound_m: f32,
    /// Confidence, `[0, 1]` (module docs).
    pub confidence: f32,
    /// The verdict.
    pub status: FixStatus,
    /// Which stage produced the position.
    pub path: FixPath,
    /// Score of the position: NCC `[-1, 1]` (NCC path) or cosine (CNN path).
    pub score: f32,
    /// Index of the chosen map window (row-major over the map product's grid).
    pub best_window: u32,
    /// Index of the CNN's best window.
    pub cnn_best_window: u32,
    /// Its Q15 cosine.
    pub cnn_best_q15: i32,
    /// Map windows scored.
    pub windows: u32,
    /// Candidates, best coarse peak first: the refined ones, then unrefined peaks.
    pub candidates: heapless::Vec<Candidate, MAX_CANDIDATES>,
    /// What the reprojection did.
    pub reprojection: ReprojectionSummary,
    /// Valid share of the top-down image, per mille.
    pub coverage_permille: u32,
    /// Blocks of the rover's relief matched against the map's by the relief stage (0: the
    /// stage did not run: off, flat ground, no relief plane, or too few blocks).
    pub relief_blocks: u32,
    /// Work per stage.
    pub ops: StageOps,
}

impl FixReport {
    /// A report with no fix: the prior's position, status no data.
    pub fn no_data(x_m: f32, y_m: f32, reprojection: ReprojectionSummary) -> Self {
        Self {
            x_m,
            y_m,
            error_bound_m: f32::INFINITY,
            confidence: 0.0,
            status: FixStatus::NoData,
            path: FixPath::None,
            score: 0.0,
            best_window: 0,
            cnn_best_window: 0,
            cnn_best_q15: 0,
            windows: 0,
            candidates: heapless::Vec::new(),
            reprojection,
            coverage_permille: 0,
            relief_blocks: 0,
            ops: StageOps::default(),
        }
    }

    /// Whether the fix may be used (status ok).
    pub fn accepted(&self) -> bool {
        self.status == FixStatus::Ok
    }
}

/// Why a fix could not be run.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixError {
    /// A setting is out of range.
    BadConfig {
        /// The setting.
        field: &'static str,
    },
    /// The map product was refused.
    MapProduct(MapProductError),
    /// The map product does not fit these settings or weights.
    MapMismatch {
        /// What differs.
        what: &'static str,
    },
    /// The weight file was refused.
    Weights(WeightsError),
    /// The prior position lies outside the map product.
    PriorOutsideMap,
    /// Reprojection set-up or frame sizes.
    Reproject(ReprojectError),
    /// Range reprojection set-up or depth sizes.
    Range(RangeError),
    /// The stereo matcher refused its settings (e.g. a baseline of 0 or NaN).
    Stereo(StereoError),
    /// A matcher or downsampling set-up error.
    Match(MatchError),
    /// A network error other than an unusable input.
    Nn(NnError),
    /// A scratch buffer is shorter than [`super::fix_buffer_sizes`] says.
    ScratchTooSmall {
        /// Which buffer.
        buffer: &'static str,
    },
}

impl fmt::Display for FixError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BadConfig { field } => write!(f, "the fix setting '{field}' is out of range"),
            Self::MapProduct(e) => write!(f, "{e}"),
            Self::MapMismatch { what } => write!(
                f,
                "the map product does not fit this fix ({what}); rebuild it with `orbfix map` for these settings and weights"
            ),
            Self::Weights(e) => write!(f, "the weight file was refused: {e}"),
            Self::PriorOutsideMap => write!(
                f,
                "the prior position lies outside the map product: use a map around the prior"
            ),
            Self::Reproject(e) => write!(f, "reprojection failed: {e}"),
            Self::Range(e) => write!(f, "range reprojection failed: {e}"),
            Self::Stereo(e) => write!(f, "on-board stereo cannot run: {e}"),
            Self::Match(e) => write!(f, "matching failed: {e}"),
            Self::Nn(e) => write!(f, "the network failed: {e}"),
            Self::ScratchTooSmall { buffer } => write!(
                f,
                "the fix's '{buffer}' buffer is smaller than fix_buffer_sizes says"
            ),
        }
    }
}

impl core::error::Error for FixError {}

impl From<MapProductError> for FixError {
    fn from(e: MapProductError) -> Self {
        Self::MapProduct(e)
    }
}
impl From<WeightsError> for FixError {
    fn from(e: WeightsError) -> Self {
        Self::Weights(e)
    }
}
impl From<ReprojectError> for FixError {
    fn from(e: ReprojectError) -> Self {
        Self::Reproject(e)
    }
}
impl From<RangeError> for FixError {
    fn from(e: RangeError) -> Self {
        Self::Range(e)
    }
}
impl From<StereoError> for FixError {
    fn from(e: StereoError) -> Self {
        Self::Stereo(e)
    }
}
impl From<MatchError> for FixError {
    fn from(e: MatchError) -> Self {
        Self::Match(e)
    }
}
impl From<NnError> for FixError {
    fn from(e: NnError) -> Self {
        Self::Nn(e)
    }
}
impl From<LocalizeError> for FixError {
    fn from(e: LocalizeError) -> Self {
        match e {
            LocalizeError::Match(m) => Self::Match(m),
            _ => Self::BadConfig {
                field: "refine.levels",
            },
        }
    }
}
