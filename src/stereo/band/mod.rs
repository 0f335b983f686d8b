//! The band matcher: running-sum SAD block matching of the rows of one view, streamed top
//! to bottom in bands (see the module docs of [`super`] for the pipeline).
//!
//! A [`StereoView`] holds one pair, the caller's scratch and where the stream stands: the
//! filtered rows, the column sums and the last three disparity rows stay in the scratch
//! between calls, so bands that follow each other cost no set-up rows, and the column sums
//! of each row hold only the groups of four disparities its own range needs (a group that
//! enters is summed over the window's rows once). The sums are exact, so a row's result
//! does not depend on where the stream started or how the rows are cut into bands.

mod column_sums;
mod rings;
mod row_match;

use super::expand::{expand_row, Passed, RowPlace};
use super::fill::fill_gaps;
use super::speckle::finish_row;
use super::{Side, StereoBuffer, StereoError, StereoRig, DISPARITY_FRAC_BITS, MAX_RADIUS};
use crate::image::ImageView;
use crate::reproject::{classify_frame, FrameStatus};
pub(crate) use column_sums::lane;
use column_sums::{add_row, out_cost, update_rows, Sums};
use rings::{RingTags, Rings};
use row_match::{match_row, RowMatch};

/// One pixel, Q4.
pub(crate) const ONE_Q: u16 = 1 << DISPARITY_FRAC_BITS;
const RING_MAX: usize = 2 * MAX_RADIUS as usize + 2;
/// A right pixel's winner index before any candidate.
const RB_NONE: u16 = u16::MAX;
/// "No row" in the stream's state.
const NONE: usize = usize::MAX;

/// Bytes of the byte scratch for a working width `w` and radius down `rv`: per image a ring
/// of 3 reduced rows and a ring of `2 rv + 2` filtered rows.
pub(crate) fn bytes_len(w: usize, rv: usize) -> usize {
    2 * w * (3 + 2 * rv + 2)
}

/// `u16` elements of the word scratch for a level width `w` and at most `groups` groups of
/// four disparities in a row: the right image's winners (costs and indices of the even and
/// of the odd right pixels, `4 ceil(w / 2)`), a ring of 3 disparity rows (`3 w`), then, on
/// `u32` words (one element of slack for the alignment), the column sums (`2 groups` words
/// per column) and the row's aggregated costs (`2 groups` words), in the lane layout of
/// [`lane`].
pub(crate) fn words_len(w: usize, groups: usize) -> usize {
    4 * w.div_ceil(2) + 3 * w + 4 * groups * (w + 1) + 1
}

/// What one call did (sums over calls with [`BandReport::add`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BandReport {
    /// Rows matched, at their level (output rows and the rows below them that the speckle
    /// test reads, each once per stream; sky rows are not matched).
    pub rows_matched: u64,
    /// Pixel-disparities of the winner-take-all (columns with a full window times each
    /// row's range): aggregation, winner search and the left-right bookkeeping.
    pub pixel_disparities: u64,
    /// Column-cost updates (one row in, one row out: two absolute differences each): each
    /// row's groups of four disparities times the columns, a group's set-up (its sums over
    /// the `2r + 1` rows of the window, when it enters) counted as `r + 1/2` updates.
    pub cost_updates: u64,
    /// Output pixels (working size) with a disparity.
    pub valid: u64,
    /// Rejected: winner on the range edge or window outside the right image.
    pub rejected_edge: u64,
    /// Rejected: not unique or textureless.
    pub rejected_unique: u64,
    /// Rejected by the left-right check.
    pub rejected_lr: u64,
    /// Rejected as speckle.
    pub rejected_speckle: u64,
}

impl BandReport {
    /// Adds another band's counts.
    pub fn add(&mut self, o: &BandReport) {
        self.rows_matched += o.rows_matched;
        self.pixel_disparities += o.pixel_disparities;
        self.cost_updates += o.cost_updates;
        self.valid += o.valid;
        self.rejected_edge += o.rejected_edge;
        self.rejected_unique += o.rejected_unique;
        self.rejected_lr += o.rejected_lr;
        self.rejected_speckle += o.rejected_speckle;
    }
}

/// What the band writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Output {
    /// Depth, millimetres.
    DepthMm,
    /// Disparity, Q4 pixels.
    DisparityQ4,
}

/// Checks the inputs of a band; returns the two frames.
pub(crate) fn check_inputs<'f, 'a>(
    rig: &StereoRig,
    left: &'f ImageView<'a>,
    right: Option<&'f ImageView<'a>>,
) -> Result<[&'f ImageView<'a>; 2], StereoError> {
    let right = right.ok_or(StereoError::MissingRight)?;
    let ls = (left.width(), left.height());
    let rs = (right.width(), right.height());
    if ls != rs {
        return Err(StereoError::PairSize {
            left: ls,
            right: rs,
        });
    }
    let expected = (rig.camera.width_px as usize, rig.camera.height_px as usize);
    if ls != expected {
        return Err(StereoError::FrameSize { expected, got: ls });
    }
    for (side, f) in [(Side::Left, left), (Side::Right, right)] {
        let status = classify_frame(f);
        if status != FrameStatus::Ok {
            return Err(StereoError::Frame { side, status });
        }
    }
    Ok([left, right])
}

/// Which column sums the scratch holds: those of row `row` ([`NONE`]: none) for groups
/// `g_lo..g_hi`, group `g` at words `2 (g - base)` of each column.
#[derive(Clone, Copy, Debug)]
struct SumsState {
    row: usize,
    g_lo: usize,
    g_hi: usize,
    base: usize,
}

/// Where a view's stream stands; the scratch holds the rows and sums it names.
#[derive(Clone, Copy, Debug)]
struct Stream {
    /// Level of the rows matched so far ([`NONE`]: nothing yet).
    level: usize,
    /// The next row (of the level's image) to match; rows `next - 3 .. next` are in the
    /// disparity ring where `disp_tag` says so.
    next: usize,
    rings: RingTags,
    disp_tag: [usize; 3],
    sums: SumsState,
}

impl Stream {
    const START: Self = Self {
        level: NONE,
        next: 0,
        rings: RingTags::EMPTY,
        disp_tag: [0; 3],
        sums: SumsState {
            row: NONE,
            g_lo: 0,
            g_hi: 0,
            base: 0,
        },
    };
}

/// One view's stereo pair matched row band by row band, top to bottom, in the caller's
/// scratch ([`StereoRig::view`]). Consecutive bands continue where the last one stopped;
/// any other band starts afresh (its set-up rows once more): the output is the same.
pub struct StereoView<'a> {
    rig: &'a StereoRig,
    frames: [&'a ImageView<'a>; 2],
    bytes: &'a mut [u8],
    words: &'a mut [u16],
    st: Stream,
}

/// How rows are finished: level width `w`, speckle support, output kind, depth constant
/// (working size) and the level (disparities are scaled by `2^level`, pixels expanded).
pub(super) struct Finish<'s> {
    w: usize,
    /// Neighbours (of 8) a disparity needs within 1 px (`StereoParams::min_support`).
    pub(super) support: u8,
    /// What the output holds.
    pub(super) mode: Output,
    /// Depth constant at the working size (`depth = depth_k / disparity`, Q4).
    pub(super) depth_k: u32,
    /// The slot ([`super::scale::SLOTS`]) of the rows.
    level: usize,
    /// Its working columns per column, as a shift.
    pub(super) shift: usize,
    /// Longest gap of a working row filled ([`super::fill::fill_gaps`]), pixels (0: off).
    gap: usize,
    /// The rig's levels (rows per level row, the flat-ground row scales).
    scales: &'s super::scale::Scales,
}

/// Working rows `rows` (all of level `level`) of a band whose output starts at working row
/// `y0`, `w` working pixels per row.
struct Band {
    level: usize,
    rows: core::ops::Range<usize>,
    y0: usize,
    w: usize,
}

impl<'a> StereoView<'a> {
    /// Checks the pair and the scratch sizes ([`StereoRig::buffer_sizes`]).
    pub(crate) fn new(
        rig: &'a StereoRig,
        left: &'a ImageView<'a>,
        right: Option<&'a ImageView<'a>>,
        bytes: &'a mut [u8],
        words: &'a mut [u16],
    ) -> Result<Self, StereoError> {
        let frames = check_inputs(rig, left, right)?;
        let sizes = rig.buffer_sizes();
        for (buffer, needed, got) in [
            (StereoBuffer::Bytes, sizes.bytes, bytes.len()),
            (StereoBuffer::Words, sizes.words, words.len()),
        ] {
            if got < needed {
                return Err(StereoError::BufferSize {
                    buffer,
                    needed,
                    got,
                });
            }
        }
        Ok(Self {
            rig,
            frames,
            bytes,
            words,
            st: Stream::START,
        })
    }

    /// Depth of output rows `y0..y1` (working size) into `out` (at least `(y1 - y0) *
    /// width` elements, row-major, `u16` millimetres along the optical axis, 0 = no data;
    /// rows that only see sky are 0). A band that starts where the last one stopped costs
    /// no set-up rows; the result of a row is the same however the image is cut.
    pub fn depth_rows(
        &mut self,
        y0: usize,
        y1: usize,
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        self.rows(y0, y1, out, Output::DepthMm)
    }

    /// As [`StereoView::depth_rows`], writing disparities instead: Q4 pixels at the
    /// working size ([`DISPARITY_FRAC_BITS`]), 0 = no data.
    pub fn disparity_rows(
        &mut self,
        y0: usize,
        y1: usize,
        out: &mut [u16],
    ) -> Result<BandReport, StereoError> {
        self.rows(y0, y1, out, Output::DisparityQ4)
    }

    /// Rows `y0..y1` of the working-size output into `out` (`(y1 - y0) * width`,
    /// row-major): the rows of each level ([`super::scale`]) matched at that level and
    /// expanded.
    pub(crate) fn rows(
        &mut self,
        y0: usize,
        y1: usize,
        out: &mut [u16],
        mode: Output,
    ) -> Result<BandReport, StereoError> {
        let (w, h) = (self.rig.width, self.rig.height);
        if y0 >= y1 || y1 > h {
            return Err(StereoError::Rows { y0, y1, height: h });
        }
        if out.len() < (y1 - y0) * w {
            return Err(StereoError::BufferSize {
                buffer: StereoBuffer::Output,
                needed: (y1 - y0) * w,
                got: out.len(),
            });
        }
        let out = out.get_mut(..(y1 - y0) * w).unwrap_or(&mut []);
        out.fill(0);
        let mut rep = BandReport::default();
        let sc = &self.rig.scales;
        // Runs of rows of one level.
        let mut ya = y0.max(sc.first_active());
        while ya < y1 {
            let l = sc.level_of_row(ya);
            let mut yb = ya + 1;
            while yb < y1 && sc.level_of_row(yb) == l {
                yb += 1;
            }
            let band = Band {
                level: l,
                rows: ya..yb,
                y0,
                w,
            };
            self.level_rows(&band, out, mode, &mut rep)?;
            ya = yb;
        }
        Ok(rep)
    }

    /// Matches (or takes from the stream) the rows of `band.level` that hold working rows
    /// `band.rows`, with the rows the speckle test reads around them, and writes them,
    /// expanded, into the band's output.
    fn level_rows(
        &mut self,
        band: &Band,
        out: &mut [u16],
        mode: Output,
        rep: &mut BandReport,
    ) -> Result<(), StereoError> {
        let l = band.level;
        let rig = self.rig;
        let geo = rig.scales.level(l);
        let (w, h) = geo.size();
        if band.rows.is_empty() || w == 0 || h == 0 {
            return Ok(());
        }
        let p = &rig.params;
        let r = usize::from(p.radius_px);
        let rv = rig.scales.radius_rows(l);
        let m = rig.scales.rows_per(l);
        // Level rows holding the band's rows; rows `c0..end` must be matched.
        // `checked_div`: no panic path (`m >= 1`).
        let div = |y: usize| y.checked_div(m).unwrap_or(0);
        let (qa, qb) = (div(band.rows.start), div(band.rows.end - 1) + 1);
        let c0 = qa.saturating_sub(1).max(rig.scales.first_active_of(l));
        let end = (qb + 1).min(h);
        // Continue the stream when it holds (or is about to match) exactly what is needed.
        let st = &mut self.st;
        if !(st.level == l && c0 <= st.next && st.next <= c0 + 3) {
            *st = Stream {
                level: l,
                next: c0,
                ..Stream::START
            };
        }
        let fin = Finish {
            w,
            support: p.min_support,
            mode,
            depth_k: rig.depth_k,
            level: l,
            shift: rig.scales.col_shift(l),
            gap: usize::from(p.gap_fill_px),
            scales: &rig.scales,
        };
        let Stream {
            next,
            rings: tags,
            disp_tag,
            sums,
            ..
        } = st;
        let mut rings = Rings::new(
            self.bytes,
            tags,
            w,
            h,
            rig.scales.reduction(l, usize::from(p.downsample)),
            2 * rv + 2,
            p.prefilter_cap,
            geo.shear_terms(),
        );
        // The word scratch of this level: right winners, disparity ring, column sums (a
        // stride of the level's most groups per row), the row's words.
        let stride = 2 * rig.scales.max_groups(l);
        let words = &mut *self.words;
        let (rb, rest) = words.split_at_mut((4 * w.div_ceil(2)).min(words.len()));
        let (disp, rest) = rest.split_at_mut((3 * w).min(rest.len()));
        // Safety: `u16` and `u32` are plain integers valid for every bit pattern, and
        // `align_to_mut` gives the aligned middle part as whole `u32` words (its prefix and
        // suffix, at most one `u16` each, stay unused: `words_len` has one element of slack).
        let (_, wide, _) = unsafe { rest.align_to_mut::<u32>() };
        let (colsum, rest) = wide.split_at_mut((w * stride).min(wide.len()));
        let (aggw, _) = rest.split_at_mut(stride.min(rest.len()));
        let area = ((2 * r + 1) * (2 * rv + 1)) as u32;
        let oc = out_cost(p.prefilter_cap);
        let mut q_fin = qa;
        loop {
            // Finish every row whose neighbours are matched (or cannot be).
            while q_fin < qb && q_fin < *next && (q_fin + 1 < *next || q_fin + 1 >= h) {
                finish(disp_tag, disp, q_fin, band, &fin, out, rep);
                q_fin += 1;
            }
            if *next >= end {
                break;
            }
            let q = *next;
            *next += 1;
            let Some((dlo, dhi)) = geo.row(q) else {
                sums.row = NONE;
                continue;
            };
            let (ga, gb) = (dlo / 4, dhi / 4 + 1);
            if gb - ga > stride / 2 {
                return Err(StereoError::TooSmall);
            }
            sums_to_row(
                sums,
                &mut rings,
                self.frames,
                colsum,
                stride,
                q,
                (ga, gb),
                rv,
                oc,
                rep,
            );
            let m = RowMatch {
                w,
                r,
                stride,
                w0: 2 * (ga - sums.base),
                groups: gb - ga,
                d0: 4 * ga,
                lo: dlo - 4 * ga,
                hi: dhi - 4 * ga,
                uniq: u32::from(p.uniqueness_pct),
                gap: area * u32::from(p.min_gap_per_px),
                lr: p.lr_check,
                sub: p.subpixel,
                step: rig.scales.column_step(l, q),
                shear_q8: geo.shear_q8(q),
            };
            if let Some(drow) = disp.get_mut((q % 3) * w..(q % 3) * w + w) {
                match_row(&m, colsum, aggw, rb, drow, rep);
                if let Some(t) = disp_tag.get_mut(q % 3) {
                    *t = q + 1;
                }
                rep.rows_matched += 1;
            }
        }
        Ok(())
    }
}

/// Brings the column sums to row `q` for groups `ga..gb`: groups the sums of row `q - 1`
/// hold are updated by one row in and one row out, the others set up over the window's
/// `2 rv + 1` rows; the groups kept move to the front of each column when the window would
/// run past the stride.
#[allow(clippy::too_many_arguments)]
fn sums_to_row(
    st: &mut SumsState,
    rings: &mut Rings<'_>,
    frames: [&ImageView<'_>; 2],
    colsum: &mut [u32],
    stride: usize,
    q: usize,
    (ga, gb): (usize, usize),
    rv: usize,
    oc: u16,
    rep: &mut BandReport,
) {
    let w = rings.w;
    let ri = rv as isize;
    // Groups kept from row q - 1.
    let (ka, kb) = if st.row != NONE && st.row + 1 == q {
        (ga.max(st.g_lo), gb.min(st.g_hi))
    } else {
        (ga, ga)
    };
    let (ka, kb) = if ka < kb { (ka, kb) } else { (ga, ga) };
    // Rebase when a group would lie before the base or past the stride.
    if ga < st.base || 2 * (gb - st.base) > stride {
        let (from, to, len) = (2 * (ka - st.base.min(ka)), 2 * (ka - ga), 2 * (kb - ka));
        for col in colsum.chunks_exact_mut(stride.max(1)).take(w) {
            move_words(col, from, to, len);
        }
        st.base = ga;
    }
    let sums = |g0: usize, g1: usize| Sums {
        stride,
        n: g1 - g0,
        dmin: 4 * g0,
    };
    let base = st.base;
    if kb > ka {
        let so = rings.ensure(frames, q as isize - ri - 1);
        let sn = rings.ensure(frames, q as isize + ri);
        let (lo, ro) = rings.rows(so);
        let (ln, rn) = rings.rows(sn);
        let cs = colsum.get_mut(2 * (ka - base)..).unwrap_or(&mut []);
        update_rows(cs, sums(ka, kb), ln, rn, lo, ro);
        rep.cost_updates += (w * 4 * (kb - ka)) as u64;
    }
    // New groups: below the kept ones and above them.
    for (g0, g1) in [(ga, ka), (kb, gb)] {
        if g1 <= g0 {
            continue;
        }
        let (off, n) = (2 * (g0 - base), 2 * (g1 - g0));
        for col in colsum.chunks_exact_mut(stride.max(1)).take(w) {
            if let Some(c) = col.get_mut(off..off + n) {
                c.fill(0);
            }
        }
        for k in q as isize - ri..=q as isize + ri {
            let sl = rings.ensure(frames, k);
            let (lr, rr) = rings.rows(sl);
            add_row(
                colsum.get_mut(off..).unwrap_or(&mut []),
                sums(g0, g1),
                lr,
                rr,
                oc,
            );
        }
        rep.cost_updates += ((2 * rv + 1) * w * 2 * n) as u64 / 2;
    }
    st.row = q;
    st.g_lo = ga;
    st.g_hi = gb;
}

/// Moves `len` words of `col` from `from` to `to` (the ranges may overlap; nothing moves
/// when either lies outside).
fn move_words(col: &mut [u32], from: usize, to: usize, len: usize) {
    if from + len > col.len() || to + len > col.len() || from == to {
        return;
    }
    if to < from {
        for i in 0..len {
            if let Some(&v) = col.get(from + i) {
                if let Some(d) = col.get_mut(to + i) {
                    *d = v;
                }
            }
        }
    } else {
        for i in (0..len).rev() {
            if let Some(&v) = col.get(from + i) {
                if let Some(d) = col.get_mut(to + i) {
                    *d = v;
                }
            }
        }
    }
}

/// Finishes level row `q` from the disparity ring (rows not matched are "no data") into
/// the band's working rows it covers.
fn finish(
    tag: &[usize; 3],
    disp: &[u16],
    q: usize,
    band: &Band,
    fin: &Finish,
    out: &mut [u16],
    rep: &mut BandReport,
) {
    let w = fin.w;
    let row = |y: Option<usize>| -> Option<&[u16]> {
        let y = y?;
        if tag.get(y % 3) != Some(&(y + 1)) {
            return None;
        }
        disp.get((y % 3) * w..(y % 3) * w + w)
    };
    let Some(cur) = row(Some(q)) else {
        return;
    };
    let l = fin.level;
    let m = fin.scales.rows_per(l);
    // The working rows of level row `q` inside the band's rows.
    let ya = (q * m).max(band.rows.start);
    let yb = ((q + 1) * m).min(band.rows.end);
    if ya >= yb || ya < band.y0 {
        return;
    }
    let bw = band.w;
    let first = (ya - band.y0) * bw;
    let Some(o) = out.get_mut(first..first + bw) else {
        return;
    };
    let above = row(q.checked_sub(1));
    let below = row(Some(q + 1));
    let valid = finish_row(above, cur, below, fin, o, rep);
    if m <= 1 {
        // Working-size pixels with data: each level pixel covers 2^l across.
        rep.valid += valid << fin.shift;
    } else {
        expand_rows(cur, above, below, q, m, first, ya, yb, bw, fin, out, rep);
    }
    // Short gaps of the finished working rows (`StereoParams::gap_fill_px`).
    for row in out
        .get_mut(first..first + (yb - ya) * bw)
        .unwrap_or(&mut [])
        .chunks_exact_mut(bw.max(1))
    {
        rep.valid += fill_gaps(row, fin.gap, fin.mode, fin.depth_k);
    }
}

/// Working rows `ya..yb` (the first at `first` in `out`, `bw` apart) of level row `q` (`m`
/// working rows per level row) from its disparities `cur` and its neighbours'
/// ([`super::expand`]): the later rows first (the first row, finished, tells which pixels
/// passed), then the first in place.
#[allow(clippy::too_many_arguments)]
fn expand_rows(
    cur: &[u16],
    above: Option<&[u16]>,
    below: Option<&[u16]>,
    q: usize,
    m: usize,
    first: usize,
    ya: usize,
    yb: usize,
    bw: usize,
    fin: &Finish,
    out: &mut [u16],
    rep: &mut BandReport,
) {
    let place = |y: usize| RowPlace {
        level: fin.shift,
        rows: m,
        offset: y - q * m,
        flat_q15: fin.scales.row_scale_q15(fin.level, q, y, false),
    };
    let side = |y: usize| {
        if 2 * (y - q * m) + 1 < m {
            above
        } else {
            below
        }
    };
    let (head, tail) = out.split_at_mut((first + bw).min(out.len()));
    let first_row = head.get_mut(first..).unwrap_or(&mut []);
    let mut written = 0;
    for (i, dst) in tail
        .chunks_exact_mut(bw.max(1))
        .take(yb - ya - 1)
        .enumerate()
    {
        let y = ya + 1 + i;
        let passed = Passed::Row(first_row, 1 << fin.shift);
        written += expand_row(cur, side(y), passed, dst, &place(y), fin.mode, fin.depth_k);
    }
    written += expand_row(
        cur,
        side(ya),
        Passed::InPlace,
        first_row,
        &place(ya),
        fin.mode,
        fin.depth_k,
    );
    rep.valid += written;
}

/// Rows `y0..y1` of the working-size output into `out` (`(y1 - y0) * width`, row-major),
/// on a fresh stream.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run(
    rig: &StereoRig,
    left: &ImageView<'_>,
    right: Option<&ImageView<'_>>,
    y0: usize,
    y1: usize,
    bytes: &mut [u8],
    words: &mut [u16],
    out: &mut [u16],
    mode: Output,
) -> Result<BandReport, StereoError> {
    StereoView::new(rig, left, right, bytes, words)?.rows(y0, y1, out, mode)
}
