//! Settings of the fix ([`FixConfig`]): one value names the exact configuration an accuracy
//! or budget figure was produced with.

use super::stereo_depth::StereoConfig;
use super::FixError;
use crate::localize::MAX_CANDIDATES;
use crate::map_product::RefinePlane;
use crate::reproject::{GridSpec, RangeError, RangeOptions};

/// How the position inside the best coarse cells is found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RefineMode {
    /// Masked NCC refinement; kept when its score reaches [`RefineConfig::min_ncc`] inside
    /// the searched reach, otherwise the CNN's sub-cell peak (the default).
    Auto,
    /// Always the masked NCC refinement of the best CNN cell.
    Ncc,
    /// Only the CNN response's sub-cell peak (parabola on the window grid); no NCC.
    Cnn,
}

impl RefineMode {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            RefineMode::Auto => "auto",
            RefineMode::Ncc => "ncc",
            RefineMode::Cnn => "cnn",
        }
    }
}

/// One level of the NCC refinement: the template and map block-averaged by `factor`,
/// positions searched every level pixel within `reach_px` level pixels of the previous
/// level's best (of the CNN window for the first level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefineLevel {
    /// Block-averaging factor (top-down pixels per level pixel).
    pub factor: usize,
    /// Search reach, level pixels.
    pub reach_px: usize,
}

/// Settings of the refinement stage.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefineConfig {
    /// Which refinement runs.
    pub mode: RefineMode,
    /// Best coarse peaks (after suppression) refined, 1..=[`MAX_CANDIDATES`].
    pub peaks: usize,
    /// Box radius of the masked high-pass applied to the top-down image and the map before
    /// the NCC, metres (MARSAUTOLOCO-style local mean removal).
    pub highpass_m: f32,
    /// The two NCC levels, coarse then fine (the fine one's factor divides the coarse one's).
    pub levels: [RefineLevel; 2],
    /// Smallest NCC score for which [`RefineMode::Auto`] keeps the NCC position.
    pub min_ncc: f32,
    /// [`RefineConfig::min_ncc`] with the fix's own stereo depth
    /// ([`super::Depth::Stereo`]): the stereo top-down image has holes and far streaks that
    /// lower the NCC at the right position. Default [`MIN_NCC_STEREO`].
    pub min_ncc_stereo: f32,
    /// With the fix's own stereo depth ([`super::Depth::Stereo`]): a refined peak other
    /// than the CNN's best replaces it only when its NCC exceeds the best's by more than
    /// this (0: the highest NCC wins, as with the other depths; in `[0, 1]`). The NCC on a
    /// stereo top-down image is noisier than the CNN's ranking of its best peak. Default
    /// [`NCC_MARGIN_STEREO`].
    pub ncc_margin_stereo: f32,
    /// Rectify the high-passed images (`min(255, 2 |v - 128|)`): edge strength, which a
    /// change of sun azimuth does not invert, instead of signed shading.
    pub rectify: bool,
}

/// Stated error bounds, metres: what the report's `error_bound_m` says for a fix of each
/// path (calibrated so that at least 95 % of ok fixes lie within them; `docs/fix.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ErrorBounds {
    /// A fix refined by the NCC.
    pub ncc_m: f32,
    /// A fix from the CNN's sub-cell peak.
    pub cnn_m: f32,
}

/// The self-checks of a flight computer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfCheck {
    /// Recompute the map product's CRC-32 before use (the weight file's is always checked:
    /// 64 KiB). About 10 instructions per byte: 9.6 MB for a 300 m map.
    pub verify_map_crc: bool,
    /// Embed the top-down image twice and compare the embeddings' digests; a mismatch (a
    /// damaged weight, activation or scratch bit) is the status "self-check failed".
    pub redundant_embed: bool,
    /// Run the whole fix twice and compare the digests of everything it produced
    /// ([`super::output_digest`]); a mismatch is the status "self-check failed". Catches a
    /// transient upset of any scratch bit between any two stages (a flip in the top-down
    /// image after the reprojection, which both embeddings of `redundant_embed` would read
    /// alike, included), at twice the fix's time.
    pub redundant_run: bool,
}

/// Default [`FixConfig::accept_confidence_flat`]. On world seed 1 (development, 60 stops same
/// sun + 60 cross sun, flat-ground path), the flat-ground fixes more than 5 m off had
/// confidences up to 0.213; 0.30 keeps a margin above that. Held-out figures:
/// `docs/fix-results-lut.md`.
pub const ACCEPT_CONFIDENCE_FLAT: f32 = 0.30;

/// Default [`FixConfig::accept_confidence_stereo`]. On world seed 1 (development, 100 stops
/// same sun + 100 cross sun, the fix's own stereo depth, `out/calib-stereo-seed1`), the
/// 40 stereo fixes more than 5 m off (26 cross sun, 14 same sun) had confidences up to
/// 0.190, and 4 of them reached the common 0.15; 0.25 keeps a margin above that. Held-out
/// figures: `docs/fix-results-stereo.md`.
pub const ACCEPT_CONFIDENCE_STEREO: f32 = 0.25;

/// Default [`RefineConfig::min_ncc_stereo`]. On world seed 5 (development, 100 stops per sun,
/// the fix's own stereo depth with the relief stage; `orbfix eval --seed 5 --queries 100
/// --matcher fix,fix-mn0.2,fix-mn0.1 --depth stereo`), lowering the kept NCC from 0.3 moved
/// the share within 1 m from 0.91 to 0.95 same sun and from 0.75 to 0.84 (0.2) and 0.88 (0.1)
/// cross sun, within 5 m cross sun 0.88 -> 0.91, with no wrong-confident fix and every ok
/// fix within its bound. Held-out figures: `docs/fix-results-stereo.md`.
pub const MIN_NCC_STEREO: f32 = 0.1;

/// Default [`RefineConfig::ncc_margin_stereo`]. On the development seeds 5 and 6 (100
/// cross-sun stops each, the fix's own stereo depth; `orbfix eval --seed S --queries 100
/// --matcher fix,fix-nm0.05 --condition cross-sun --depth stereo`), keeping the CNN's best
/// peak unless another refined peak beats its NCC by 0.05 moved the share within 1 m from
/// 0.87 / 0.90 to 0.87 / 0.94 and within 5 m from 0.92 / 0.93 to 0.91 / 0.97, with no
/// wrong-confident fix and the same bound coverage (four of the ten seed-6 misses had the
/// right peak first, beaten by a wrong one by 0.03-0.04 of NCC). Held-out figures:
/// `docs/fix-results-stereo.md`.
pub const NCC_MARGIN_STEREO: f32 = 0.05;

/// Every setting of the fix.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixConfig {
    /// The top-down grid (200 x 200 cells of 0.25 m; must match the map product's window side
    /// and resolution).
    pub grid: GridSpec,
    /// Settings of the range (depth) reprojection.
    pub range: RangeOptions,
    /// Minimum valid share of the top-down image, per mille; below it the fix has no data.
    pub min_coverage_permille: u32,
    /// Non-maximum suppression radius between coarse peaks, metres (the study's 12.5 m
    /// stride).
    pub nms_radius_m: f32,
    /// The refinement.
    pub refine: RefineConfig,
    /// Confidence below which a fix is reported ambiguous.
    pub accept_confidence: f32,
    /// Confidence below which a fix made on flat-ground reprojection ([`super::Depth::Flat`])
    /// is reported ambiguous (the larger of this and [`FixConfig::accept_confidence`]
    /// applies). Stricter: on relief the flat top-down image is smeared, and its wrong fixes
    /// reach confidences that the depth paths only reach when right. Calibrated on world
    /// seed 1 (`docs/fix-results-lut.md`).
    pub accept_confidence_flat: f32,
    /// Confidence below which a fix made with the fix's own stereo depth
    /// ([`super::Depth::Stereo`]) is reported ambiguous (the larger of this and
    /// [`FixConfig::accept_confidence`] applies). Stricter than with depth images: the
    /// stereo top-down image has holes and far-field smear, and its wrong fixes reach
    /// confidences that truth depth only reaches when right. Calibrated on world seed 1
    /// (`docs/fix-results-stereo.md`).
    pub accept_confidence_stereo: f32,
    /// Stated error bounds.
    pub bounds: ErrorBounds,
    /// Self-checks.
    pub self_check: SelfCheck,
    /// The fix's own stereo stage (used with [`super::Depth::Stereo`]).
    pub stereo: StereoConfig,
    /// The relief stage (with depth, and a map product with a relief plane).
    pub relief: super::relief::ReliefConfig,
}

impl Default for FixConfig {
    fn default() -> Self {
        Self {
            grid: GridSpec::default(),
            // Rows near the mast read every 4th pixel at most (half a cell apart on flat
            // ground): the range path's per-pixel work drops by about 3x for the same fix.
            range: RangeOptions {
                max_column_stride: 4,
                ..RangeOptions::default()
            },
            min_coverage_permille: 50,
            nms_radius_m: 12.5,
            refine: RefineConfig {
                mode: RefineMode::Auto,
                peaks: 3,
                highpass_m: 2.0,
                levels: [
                    RefineLevel {
                        factor: 4,
                        reach_px: 5,
                    },
                    RefineLevel {
                        factor: 2,
                        reach_px: 2,
                    },
                ],
                min_ncc: 0.3,
                min_ncc_stereo: MIN_NCC_STEREO,
                ncc_margin_stereo: NCC_MARGIN_STEREO,
                rectify: true,
            },
            accept_confidence: 0.15,
            accept_confidence_flat: ACCEPT_CONFIDENCE_FLAT,
            accept_confidence_stereo: ACCEPT_CONFIDENCE_STEREO,
            bounds: ErrorBounds {
                ncc_m: 0.5,
                cnn_m: 2.0,
            },
            self_check: SelfCheck {
                verify_map_crc: false,
                redundant_embed: false,
                redundant_run: false,
            },
            stereo: StereoConfig::default(),
            relief: super::relief::ReliefConfig::default(),
        }
    }
}

impl FixConfig {
    /// Checks every setting; the error names the first bad one.
    pub fn validate(&self) -> Result<(), FixError> {
        self.grid.validate()?;
        self.stereo.validate()?;
        let bad = |field| Err(FixError::BadConfig { field });
        match self.range.validate() {
            Ok(()) => {}
            Err(RangeError::BadDepthScale) => return bad("range.depth_scale_m or range.max_depth_m"),
            Err(_) => {
                return bad("range (min_height_m <= max_height_m, fill_min_neighbours <= 8, max_column_stride 1..=16)")
            }
        }
        let r = &self.refine;
        if r.peaks == 0 || r.peaks > MAX_CANDIDATES {
            return bad("refine.peaks");
        }
        if !(r.highpass_m.is_finite() && r.highpass_m > 0.0 && r.highpass_m <= 25.0) {
            return bad("refine.highpass_m");
        }
        let [a, b] = r.levels;
        let n = self.grid.n;
        if a.factor == 0 || b.factor == 0 || a.factor % b.factor != 0 || a.factor > 16 {
            return bad("refine.levels.factor");
        }
        if n % a.factor != 0 || n / a.factor < 8 {
            return bad("refine.levels.factor");
        }
        if a.reach_px == 0 || a.reach_px > 32 || b.reach_px == 0 || b.reach_px > 32 {
            return bad("refine.levels.reach_px");
        }
        if !(r.min_ncc.is_finite() && (-1.0..=1.0).contains(&r.min_ncc)) {
            return bad("refine.min_ncc");
        }
        if !(r.min_ncc_stereo.is_finite() && (-1.0..=1.0).contains(&r.min_ncc_stereo)) {
            return bad("refine.min_ncc_stereo");
        }
        if !(r.ncc_margin_stereo.is_finite() && (0.0..=1.0).contains(&r.ncc_margin_stereo)) {
            return bad("refine.ncc_margin_stereo");
        }
        if !(self.nms_radius_m.is_finite() && self.nms_radius_m >= 0.0) {
            return bad("nms_radius_m");
        }
        if self.min_coverage_permille > 1000 {
            return bad("min_coverage_permille");
        }
        if !(self.accept_confidence.is_finite() && (0.0..=1.0).contains(&self.accept_confidence)) {
            return bad("accept_confidence");
        }
        if !(self.accept_confidence_flat.is_finite()
            && (0.0..=1.0).contains(&self.accept_confidence_flat))
        {
            return bad("accept_confidence_flat");
        }
        if !(self.accept_confidence_stereo.is_finite()
            && (0.0..=1.0).contains(&self.accept_confidence_stereo))
        {
            return bad("accept_confidence_stereo");
        }
        let rl = &self.relief;
        if !(rl.weight.is_finite() && (0.0..=4.0).contains(&rl.weight)) {
            return bad("relief.weight");
        }
        if rl.min_fill_permille > 1000 {
            return bad("relief.min_fill_permille");
        }
        let ok_bound = |v: f32| v.is_finite() && v > 0.0;
        if !(ok_bound(self.bounds.ncc_m) && ok_bound(self.bounds.cnn_m)) {
            return bad("bounds");
        }
        Ok(())
    }

    /// Map pixels around a coarse window the refinement reads on each side (the reach of
    /// both levels plus the high-pass box).
    pub fn refine_margin_px(&self) -> usize {
        let [a, b] = self.refine.levels;
        a.reach_px * a.factor + b.reach_px * b.factor + a.factor + self.highpass_radius_px()
    }

    /// The refinement plane a map product must carry for this configuration (the high-pass
    /// radius and rectification of the refinement).
    pub fn refine_plane(&self) -> Result<RefinePlane, FixError> {
        RefinePlane::new(self.highpass_radius_px(), self.refine.rectify).map_err(|_| {
            FixError::BadConfig {
                field: "refine.highpass_m",
            }
        })
    }

    /// Box radius of the high-pass, top-down pixels (at least 1).
    pub fn highpass_radius_px(&self) -> usize {
        let r = self.refine.highpass_m / self.grid.m_per_px;
        if r.is_finite() && r >= 1.0 {
            (r + 0.5) as usize
        } else {
            1
        }
    }
}
