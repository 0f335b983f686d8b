//! Stage `stereo` of the fix: depth from the rover's own stereo pairs
//! ([`super::Depth::Stereo`]), computed by the core's banded block matcher
//! ([`crate::stereo`]) band by band and placed into the top-down image as each band is done
//! ([`crate::reproject::RangeAccumulator::add_rows`]), so only one band of depth exists at a
//! time; each view's bands are one stream of the matcher (no row is matched twice). The
//! frames are reprojected at full resolution; each full-resolution pixel takes the depth of
//! the working-size pixel it lies in (`StereoParams::downsample`); rows the matcher took at
//! a coarser scale ([`crate::stereo::scale`]) come expanded to the working size, each
//! working row at its own distance (interpolated towards the next coarse row).
//!
//! Memory: inside the fix's work area after the range accumulator
//! ([`stereo_work_words`]): the matcher's byte and `u16` scratch for a working width of at
//! most [`StereoConfig::max_width_px`] and [`StereoConfig::max_disparities`] disparities, one
//! output band of [`StereoConfig::band_rows`] rows, and one expanded depth row.
//!
//! A view whose pair cannot give depth (no right image, a black or saturated image, a pair
//! whose sizes differ, a frame of the wrong size) gets no depth (recorded per view in
//! [`super::ReprojectionSummary::stereo`]) and the fix continues with the others; settings the
//! matcher refuses (a baseline of 0 or NaN, ...) are a [`FixError::Stereo`].

use super::{FixConfig, FixError, FixInputs, ReprojectionSummary, Stage, StageClock, StageOps};
use crate::camera::View;
use crate::image::ImageView;
use crate::reproject::{
    classify_frame, range_scratch_len, DepthBand, FrameStatus, RangeAccumulator, ReliefGrid,
};
use crate::stereo::{stereo_buffer_bound, StereoBuffer, StereoError, StereoParams, StereoRig};

/// Settings of the fix's own stereo stage.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StereoConfig {
    /// The matcher's settings (baseline, reduction, window, checks, ranges).
    pub matcher: StereoParams,
    /// Output rows (working size) per band, 1..=1024: the depth of one band is held at a
    /// time. A view's bands are one stream ([`crate::stereo::StereoView`]): the height
    /// only sets this buffer, not the work.
    pub band_rows: usize,
    /// Largest working width (frame width / `downsample`, pixels, 8..=4096) the scratch is
    /// sized for.
    pub max_width_px: usize,
    /// Most disparities of any row the scratch is sized for (1..=1024); a rig that needs
    /// more is refused with [`FixError::BadConfig`] `stereo.max_disparities`.
    pub max_disparities: usize,
}

impl Default for StereoConfig {
    /// The matcher's defaults, bands of 30 rows, 320 pixels wide (640 x 360 frames reduced
    /// by 2), up to 48 disparities (the default rig searches at most 32 in a row).
    fn default() -> Self {
        Self {
            matcher: StereoParams::default(),
            band_rows: 30,
            max_width_px: 320,
            max_disparities: 48,
        }
    }
}

impl StereoConfig {
    /// Checks the sizing settings (the matcher's are checked with the rig, when it runs).
    pub fn validate(&self) -> Result<(), FixError> {
        let bad = |field| Err(FixError::BadConfig { field });
        if !(1..=1024).contains(&self.band_rows) {
            return bad("stereo.band_rows");
        }
        if !(8..=4096).contains(&self.max_width_px) {
            return bad("stereo.max_width_px");
        }
        if !(1..=1024).contains(&self.max_disparities) {
            return bad("stereo.max_disparities");
        }
        if !(1..=4).contains(&self.matcher.downsample) {
            return bad("stereo.matcher.downsample");
        }
        Ok(())
    }
}

/// Word counts of the stereo stage's parts of the work area (each part starts on a word).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Parts {
    bytes: usize,
    words: usize,
    band: usize,
    row: usize,
}

impl Parts {
    fn new(s: &StereoConfig) -> Self {
        let b = stereo_buffer_bound(s.max_width_px, s.matcher.radius_rows_px, s.max_disparities);
        let full_width = s.max_width_px * usize::from(s.matcher.downsample.max(1));
        Self {
            bytes: b.bytes.div_ceil(4),
            words: b.words.div_ceil(2),
            band: (s.band_rows * s.max_width_px).div_ceil(2),
            row: full_width.div_ceil(2),
        }
    }

    fn total(&self) -> usize {
        self.bytes + self.words + self.band + self.row
    }
}

/// `u32` words of the work area the stereo stage needs after the range accumulator.
pub fn stereo_work_words(s: &StereoConfig) -> usize {
    Parts::new(s).total()
}

/// Whether a matcher error concerns one view's pair (the view gets no depth) rather than
/// the settings (the fix cannot run).
fn per_view(e: &StereoError) -> bool {
    matches!(
        e,
        StereoError::MissingRight
            | StereoError::Frame { .. }
            | StereoError::PairSize { .. }
            | StereoError::FrameSize { .. }
    )
}

/// Whether a view's rig fits the fix's stereo scratch: its widest row in `max_disparities`
/// (whole groups of four), its byte and `u16` scratch in `bytes` and `words` elements.
fn fits(
    rig: &StereoRig,
    max_disparities: usize,
    bytes: usize,
    words: usize,
) -> Result<(), StereoError> {
    let need = rig.buffer_sizes();
    let checks = [
        (
            StereoBuffer::Words,
            need.max_disparities,
            4 * max_disparities.div_ceil(4),
        ),
        (StereoBuffer::Bytes, need.bytes, bytes),
        (StereoBuffer::Words, need.words, words),
    ];
    for (buffer, needed, got) in checks {
        if needed > got {
            return Err(StereoError::BufferSize {
                buffer,
                needed,
                got,
            });
        }
    }
    Ok(())
}

/// Replaces `rig` with the rig of `view` at the pose's pitch and roll, if it has one that
/// fits the scratch (`bytes`, `words` elements); else leaves `rig` as it was and says why.
/// Not inlined: the new rig is built in this frame, not the caller's.
#[inline(never)]
fn view_rig(
    rig: &mut StereoRig,
    inputs: &FixInputs<'_>,
    sc: &StereoConfig,
    view: View,
    bytes: usize,
    words: usize,
) -> Result<(), StereoError> {
    let v = StereoRig::for_view(&inputs.params, &sc.matcher, &inputs.pose, view)?;
    fits(&v, sc.max_disparities, bytes, words)?;
    *rig = v;
    Ok(())
}

/// Stage 1 with on-board stereo: depth band by band (stage `stereo`), each band placed at
/// once (stage `reproject`), then the top-down image (`work`: the accumulator's [`range_scratch_len`]
/// words, then [`stereo_work_words`]).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub(super) fn reproject_stereo<C: StageClock>(
    inputs: &FixInputs<'_>,
    rights: &[Option<ImageView<'_>>; 4],
    cfg: &FixConfig,
    work: &mut [u32],
    top: &mut [u8],
    mask: &mut [u8],
    relief: Option<(ReliefGrid, &mut [i32])>,
    clock: &mut C,
    ops: &mut StageOps,
) -> Result<ReprojectionSummary, FixError> {
    let too_small = FixError::ScratchTooSmall { buffer: "work" };
    let sc = &cfg.stereo;
    clock.begin(Stage::Stereo);
    let rig = StereoRig::new(&inputs.params, &sc.matcher);
    clock.end(Stage::Stereo);
    let mut rig = rig.map_err(FixError::Stereo)?;
    let need = rig.buffer_sizes();
    let (w, h) = rig.output_size();
    // The scratch holds whole groups of four disparities per column.
    if need.max_disparities > 4 * sc.max_disparities.div_ceil(4) {
        return Err(FixError::BadConfig {
            field: "stereo.max_disparities",
        });
    }
    if w > sc.max_width_px {
        return Err(FixError::BadConfig {
            field: "stereo.max_width_px",
        });
    }
    let n = cfg.grid.n;
    let parts = Parts::new(sc);
    let (acc_w, rest) = work.split_at_mut(range_scratch_len(n).min(work.len()));
    let (bytes_w, rest) = rest.split_at_mut(parts.bytes.min(rest.len()));
    let (words_w, rest) = rest.split_at_mut(parts.words.min(rest.len()));
    let (band_w, rest) = rest.split_at_mut(parts.band.min(rest.len()));
    let row_w = rest.get_mut(..parts.row).ok_or(too_small)?;
    // Safety: `u8` and `u16` are valid for every bit pattern and their alignment divides
    // `u32`'s, so `align_to_mut` views each whole word buffer as bytes or half-words (empty
    // prefix and suffix).
    let (_, bytes, _) = unsafe { bytes_w.align_to_mut::<u8>() };
    // Safety: as above.
    let (_, words, _) = unsafe { words_w.align_to_mut::<u16>() };
    // Safety: as above.
    let (_, band, _) = unsafe { band_w.align_to_mut::<u16>() };
    // Safety: as above.
    let (_, row_buf, _) = unsafe { row_w.align_to_mut::<u16>() };
    if bytes.len() < need.bytes || words.len() < need.words || band.len() < sc.band_rows * w {
        return Err(too_small);
    }

    clock.begin(Stage::Reproject);
    let acc = RangeAccumulator::new(
        &inputs.params,
        &inputs.pose,
        &cfg.grid,
        &cfg.range,
        acc_w,
        mask,
    )
    .and_then(|a| match relief {
        Some((g, words)) => a.with_relief(g, words),
        None => Ok(a),
    });
    clock.end(Stage::Reproject);
    let mut acc = acc?;
    let k = usize::from(sc.matcher.downsample);
    let mut errors: [Option<StereoError>; 4] = [None; 4];
    for (((left, right), view), err) in inputs
        .frames
        .iter()
        .zip(rights)
        .zip(View::ALL)
        .zip(errors.iter_mut())
    {
        let Some(left) = left else {
            acc.set_view_status(view, FrameStatus::Missing, false);
            continue;
        };
        let status = classify_frame(left);
        if status != FrameStatus::Ok {
            acc.set_view_status(view, status, false);
            continue;
        }
        acc.set_view_status(view, FrameStatus::Ok, false);
        // One stream per view: the pair is checked once, and each band continues where
        // the last one stopped. The view's row ranges follow the rover's pitch and roll.
        clock.begin(Stage::Stereo);
        // The view's rig replaces the last one in place (one rig in this frame); a pose
        // the rig cannot take, or ranges wider than the scratch holds (a steep attitude),
        // cost this view its depth, not the fix.
        let posed = view_rig(&mut rig, inputs, sc, view, bytes.len(), words.len());
        let stream = posed.and_then(|()| rig.view(left, right.as_ref(), bytes, words));
        clock.end(Stage::Stereo);
        let mut stream = match stream {
            Ok(s) => s,
            Err(e) if per_view(&e) || posed.is_err() => {
                *err = Some(e);
                acc.set_view_status(view, FrameStatus::Ok, true);
                continue;
            }
            Err(e) => return Err(FixError::Stereo(e)),
        };
        let mut y0 = rig.ranges().first_active();
        while y0 < h {
            let y1 = (y0 + sc.band_rows).min(h);
            let out = band.get_mut(..(y1 - y0) * w).ok_or(too_small)?;
            clock.begin(Stage::Stereo);
            let r = stream.depth_rows(y0, y1, out);
            clock.end(Stage::Stereo);
            let rep = r.map_err(FixError::Stereo)?;
            ops.stereo_pixel_disparities += rep.pixel_disparities;
            ops.stereo_cost_updates += rep.cost_updates;
            ops.stereo_depth_px += rep.valid;
            ops.stereo_px += ((y1 - y0) * w) as u64;
            let depth = DepthBand {
                data: out,
                width: w,
                first_row: y0,
                factor: k,
            };
            clock.begin(Stage::Reproject);
            let placed = acc.add_rows(view, left, y0 * k..y1 * k, &depth, row_buf);
            clock.end(Stage::Reproject);
            placed?;
            y0 = y1;
        }
    }
    clock.begin(Stage::Reproject);
    let r = acc.finish(top);
    clock.end(Stage::Reproject);
    let r = r?;
    ops.reproject_px = r.pixels_read;
    Ok(ReprojectionSummary {
        range: true,
        status: r.status,
        valid_cells: r.valid_cells,
        stereo: Some(errors),
    })
}
