//! The band matcher as it was before the column costs moved to four `u8` lanes per word
//! ([`super::swar`]): plain scalar loops over `u16` column sums, kept only for the tests,
//! which check that [`super::band::run`] gives exactly its output and counts.

use super::band::{check_inputs, BandReport, Output};
use super::expand::{expand_row, Passed, RowPlace};
use super::fill::fill_gaps;
use super::{StereoBuffer, StereoError, StereoRig, DISPARITY_FRAC_BITS, MAX_RADIUS};
use crate::image::ImageView;

const ONE_Q: u16 = 1 << DISPARITY_FRAC_BITS;
const RING_MAX: usize = 2 * MAX_RADIUS as usize + 2;

/// `u16` elements of the reference's word scratch (column costs `w d`, `d`, `5 w`).
pub(super) fn words_len(w: usize, d: usize) -> usize {
    w * d + d + 5 * w
}

/// The reference's word scratch for `rig`: the most any level in use needs, with the
/// union of all of its rows' disparities.
pub(super) fn ref_words_len(rig: &StereoRig) -> usize {
    let sc = rig.scales();
    sc.slots()
        .map(|l| {
            let g = sc.level(l);
            words_len(g.size().0, g.max_disparities())
        })
        .max()
        .unwrap_or(0)
}

/// Row rings of both images: reduced rows (3) and filtered rows (`2r + 2`), tagged with
/// `row + 1` (0: empty).
struct Rings<'b> {
    ds: [&'b mut [u8]; 2],
    filt: [&'b mut [u8]; 2],
    ds_tag: [usize; 3],
    f_tag: [usize; RING_MAX],
    w: usize,
    h: usize,
    k: (usize, usize),
    ring: usize,
    cap: u8,
    /// The ground shear's terms ([`super::shear::shear_at`]).
    shear: (i32, i32),
}

impl Rings<'_> {
    fn ensure_ds(&mut self, frames: [&ImageView<'_>; 2], q: usize) {
        let slot = q % 3;
        if self.ds_tag.get(slot) == Some(&(q + 1)) {
            return;
        }
        let w = self.w;
        for (buf, fr) in self.ds.iter_mut().zip(frames) {
            if let Some(o) = buf.get_mut(slot * w..slot * w + w) {
                super::downsample_row_by(fr, self.k.0, self.k.1, q, o);
            }
        }
        if let Some(t) = self.ds_tag.get_mut(slot) {
            *t = q + 1;
        }
    }

    /// Makes filtered row `k` (clamped to the image) present; returns its ring slot.
    fn ensure(&mut self, frames: [&ImageView<'_>; 2], k: isize) -> usize {
        let last = self.h - 1;
        let k = (k.max(0) as usize).min(last);
        // `checked_rem`: no division-by-zero panic path in the flight build (ring >= 4).
        let slot = k.checked_rem(self.ring).unwrap_or(0);
        if self.f_tag.get(slot) == Some(&(k + 1)) {
            return slot;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(last));
        self.ensure_ds(frames, a);
        self.ensure_ds(frames, k);
        self.ensure_ds(frames, b);
        let w = self.w;
        for (i, (ds, f)) in self.ds.iter().zip(self.filt.iter_mut()).enumerate() {
            let row = |q: usize| ds.get((q % 3) * w..(q % 3) * w + w).unwrap_or(&[]);
            if let Some(o) = f.get_mut(slot * w..slot * w + w) {
                super::prefilter(row(a), row(k), row(b), self.cap, o);
                if i == 1 {
                    // The right image follows the ground down the window.
                    super::shear_row(o, super::shear::shear_at(self.shear, k));
                }
            }
        }
        if let Some(t) = self.f_tag.get_mut(slot) {
            *t = k + 1;
        }
        slot
    }

    fn rows(&self, slot: usize) -> (&[u8], &[u8]) {
        let (a, b) = (slot * self.w, slot * self.w + self.w);
        let [l, r] = &self.filt;
        (l.get(a..b).unwrap_or(&[]), r.get(a..b).unwrap_or(&[]))
    }
}

/// Cost of a column whose right pixel is outside the image (the largest difference).
fn out_cost(cap: u8) -> u16 {
    2 * u16::from(cap)
}

#[inline(always)]
fn absdiff(a: u8, b: u8) -> u16 {
    u16::from(a.abs_diff(b))
}

/// Number of disparities `dmin + j` (`j < dn`) with the right pixel `x - d` inside.
#[inline(always)]
fn inside(x: usize, dmin: usize, dn: usize) -> usize {
    if x < dmin {
        0
    } else {
        (x - dmin + 1).min(dn)
    }
}

/// Adds one filtered row pair's costs to the column sums (`dn` per column).
fn add_row(colsum: &mut [u16], dn: usize, dmin: usize, l: &[u8], r: &[u8], oc: u16) {
    for (x, (col, &lp)) in colsum.chunks_exact_mut(dn.max(1)).zip(l).enumerate() {
        let nv = inside(x, dmin, dn);
        let (cin, cout) = col.split_at_mut(nv.min(col.len()));
        if nv > 0 {
            let hi = x + 1 - dmin;
            if let Some(rs) = r.get(hi - nv..hi) {
                for (c, &rp) in cin.iter_mut().zip(rs.iter().rev()) {
                    *c += absdiff(lp, rp);
                }
            }
        }
        for c in cout {
            *c += oc;
        }
    }
}

/// One row in (`ln`, `rn`), one row out (`lo`, `ro`) of the column sums. Columns whose
/// right pixel is outside add and remove the same constant: unchanged.
#[allow(clippy::too_many_arguments)]
fn update_rows(
    colsum: &mut [u16],
    dn: usize,
    dmin: usize,
    ln: &[u8],
    rn: &[u8],
    lo: &[u8],
    ro: &[u8],
) {
    for (x, (col, (&a, &b))) in colsum
        .chunks_exact_mut(dn.max(1))
        .zip(ln.iter().zip(lo))
        .enumerate()
    {
        let nv = inside(x, dmin, dn);
        if nv == 0 {
            continue;
        }
        let hi = x + 1 - dmin;
        let (Some(rsn), Some(rso)) = (rn.get(hi - nv..hi), ro.get(hi - nv..hi)) else {
            continue;
        };
        for ((c, &pn), &po) in col.iter_mut().zip(rsn.iter().rev()).zip(rso.iter().rev()) {
            // The sum holds the outgoing cost: add first, then subtract, never below 0
            // nor above (2r + 1) 2 cap + 2 cap.
            *c = *c + absdiff(a, pn) - absdiff(b, po);
        }
    }
}

/// Per-row settings of the winner-take-all.
struct RowMatch {
    w: usize,
    r: usize,
    dn: usize,
    dmin: usize,
    /// Row range, as indices into the band's disparities.
    jl: usize,
    jh: usize,
    uniq: u32,
    gap: u32,
    lr: bool,
    sub: super::SubPixel,
    step: usize,
    /// The row's ground shear, Q8 pixels, added (Q4) to the disparities found.
    shear_q8: i32,
}

/// Winner-take-all of one row from the column sums into `disp` (Q4, 0 = none).
fn match_row(
    m: &RowMatch,
    colsum: &[u16],
    agg: &mut [u16],
    rbc: &mut [u16],
    rbd: &mut [u16],
    disp: &mut [u16],
    rep: &mut BandReport,
) {
    disp.fill(0);
    let len = m.jh + 1 - m.jl;
    let Some(agg) = agg.get_mut(..len) else {
        return;
    };
    let col = |x: usize| {
        colsum
            .get(x * m.dn + m.jl..x * m.dn + m.jh + 1)
            .unwrap_or(&[])
    };
    agg.fill(0);
    for x in 0..=2 * m.r {
        for (a, &c) in agg.iter_mut().zip(col(x)) {
            *a += c;
        }
    }
    if m.lr {
        rbc.fill(u16::MAX);
        rbd.fill(0);
    }
    let d0 = m.dmin + m.jl;
    let (mut edge, mut uniq) = (0u64, 0u64);
    for x in m.r..m.w - m.r {
        if x > m.r {
            for ((a, &ci), &co) in agg.iter_mut().zip(col(x + m.r)).zip(col(x - m.r - 1)) {
                *a = *a + ci - co;
            }
        }
        if (x - m.r) % m.step.max(1) != 0 {
            continue;
        }
        let (mut best, mut bi) = (u16::MAX, 0usize);
        for (i, &c) in agg.iter().enumerate() {
            if c < best {
                best = c;
                bi = i;
            }
        }
        if m.lr {
            // The right pixel x - d sees this cost at its own disparity d.
            let n = inside(x, d0, len);
            let hi = (x + 1).saturating_sub(d0);
            if let (true, Some(bc), Some(bd)) = (
                n > 0,
                rbc.get_mut(hi.saturating_sub(n)..hi),
                rbd.get_mut(hi.saturating_sub(n)..hi),
            ) {
                let ds = (d0..d0 + n).map(|d| d as u16);
                for (((c, cd), &a), d) in bc
                    .iter_mut()
                    .rev()
                    .zip(bd.iter_mut().rev())
                    .zip(agg.iter())
                    .zip(ds)
                {
                    if a < *c {
                        *c = a;
                        *cd = d;
                    }
                }
            }
        }
        let d = d0 + bi;
        if bi == 0 || bi + 1 >= len || x < d + m.r {
            edge += 1;
            continue;
        }
        let mut second = u16::MAX;
        for (i, &c) in agg.iter().enumerate() {
            if (i + 1 < bi || i > bi + 1) && c < second {
                second = c;
            }
        }
        if second != u16::MAX {
            let (b, s) = (u32::from(best), u32::from(second));
            if s * (100 - m.uniq) < b * 100 || s < b + m.gap {
                uniq += 1;
                continue;
            }
        }
        let (Some(&l), Some(&r)) = (agg.get(bi - 1), agg.get(bi + 1)) else {
            continue;
        };
        let off = m.sub.offset(
            i32::from(l),
            i32::from(best),
            i32::from(r),
            i32::from(ONE_Q),
        );
        let q = (d as i32 * i32::from(ONE_Q) + off).max(1);
        if let Some(o) = disp.get_mut(x) {
            *o = q.min(i32::from(u16::MAX)) as u16;
        }
    }
    rep.pixel_disparities += ((m.w - 2 * m.r) * len) as u64;
    rep.rejected_edge += edge;
    rep.rejected_unique += uniq;
    if m.lr {
        let mut lr = 0u64;
        for (x, o) in disp.iter_mut().enumerate() {
            if *o == 0 {
                continue;
            }
            let dl = usize::from((*o + ONE_Q / 2) >> DISPARITY_FRAC_BITS);
            let ok = x
                .checked_sub(dl)
                .and_then(|xr| rbd.get(xr))
                .is_some_and(|&dr| usize::from(dr).abs_diff(dl) <= 1);
            if !ok {
                *o = 0;
                lr += 1;
            }
        }
        rep.rejected_lr += lr;
    }
    // Residuals to disparities, before the blend (as the band matcher: its decided columns).
    super::shear::add_shear(disp, m.shear_q8);
    if m.step > 1 {
        // Columns between decided ones: the linear blend of the two decided columns on
        // either side when both agree within 1 px (rounded half up).
        let (lo, hi, n) = (m.r, m.w - m.r, m.step);
        for x in lo..hi {
            let k = (x - lo) % n;
            if k == 0 {
                continue;
            }
            let a = disp.get(x - k).copied().unwrap_or(0);
            let b = if x - k + n < hi {
                disp.get(x - k + n).copied().unwrap_or(0)
            } else {
                0
            };
            let near = a != 0 && b != 0 && a.abs_diff(b) <= ONE_Q;
            let v = (u64::from(a) * (n - k) as u64 + u64::from(b) * k as u64 + (n / 2) as u64)
                / n as u64;
            if let Some(o) = disp.get_mut(x) {
                *o = if near { v as u16 } else { 0 };
            }
        }
    }
}

/// Speckle filter and output of a level row from the disparity rows above, at and below,
/// into `out` at the level's width (disparities at the working size, Q4).
#[allow(clippy::too_many_arguments)]
fn finish_row(
    above: Option<&[u16]>,
    cur: &[u16],
    below: Option<&[u16]>,
    support: u8,
    mode: Output,
    depth_k: u32,
    level: usize,
    out: &mut [u16],
    rep: &mut BandReport,
) -> u64 {
    let w = cur.len();
    let near = |a: u16, b: u16| b != 0 && a.abs_diff(b) <= ONE_Q;
    let count = |row: Option<&[u16]>, x: usize, d: u16, skip_mid: bool| -> u32 {
        let Some(row) = row else { return 0 };
        let lo = x.saturating_sub(1);
        let hi = (x + 2).min(w);
        row.get(lo..hi).map_or(0, |s| {
            s.iter()
                .enumerate()
                .filter(|&(i, &v)| !(skip_mid && lo + i == x) && near(d, v))
                .count() as u32
        })
    };
    let (mut valid, mut speck) = (0u64, 0u64);
    for (x, (o, &d)) in out.iter_mut().zip(cur).enumerate() {
        *o = 0;
        if d == 0 {
            continue;
        }
        if support > 0 {
            let n = count(above, x, d, false)
                + count(Some(cur), x, d, true)
                + count(below, x, d, false);
            if n < u32::from(support) {
                speck += 1;
                continue;
            }
        }
        let dw = u32::from(d) * (1 << level);
        let v = match mode {
            Output::DisparityQ4 => dw.min(65_535) as u16,
            Output::DepthMm => {
                let z = (depth_k + dw / 2).checked_div(dw).unwrap_or(0);
                if z == 0 || z > u32::from(u16::MAX) {
                    continue;
                }
                z as u16
            }
        };
        *o = v;
        valid += 1;
    }
    rep.rejected_speckle += speck;
    valid
}

/// Rows `y0..y1` of the working-size output into `out` (`(y1 - y0) * width`, row-major).
#[allow(clippy::too_many_arguments)]
pub(super) fn run(
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
    let frames = check_inputs(rig, left, right)?;
    let (w, h) = (rig.width, rig.height);
    if y0 >= y1 || y1 > h {
        return Err(StereoError::Rows { y0, y1, height: h });
    }
    let sizes = rig.buffer_sizes();
    for (buffer, needed, got) in [
        (StereoBuffer::Bytes, sizes.bytes, bytes.len()),
        (StereoBuffer::Words, ref_words_len(rig), words.len()),
        (StereoBuffer::Output, (y1 - y0) * w, out.len()),
    ] {
        if got < needed {
            return Err(StereoError::BufferSize {
                buffer,
                needed,
                got,
            });
        }
    }
    let out = out.get_mut(..(y1 - y0) * w).unwrap_or(&mut []);
    out.fill(0);
    let mut rep = BandReport::default();
    // Every row at its level: coarse row `y >> l` of level `l`, expanded.
    let sc = rig.scales();
    let mut row_out = [0u16; 4096];
    // Rows above the first matched one only see sky (as the band's stream).
    let mut y = y0.max(sc.first_active());
    while y < y1 {
        let l = sc.level_of_row(y);
        let mut yb = y + 1;
        while yb < y1 && sc.level_of_row(yb) == l {
            yb += 1;
        }
        let m = sc.rows_per(l);
        let (qa, qb) = (y / m, (yb - 1) / m + 1);
        let wl = sc.level(l).size().0;
        let sh = sc.col_shift(l);
        let mut level_rows =
            |q: usize, vals: &[u16], above: Option<&[u16]>, cur: &[u16], below: Option<&[u16]>| {
                for yy in (q * m).max(y)..((q + 1) * m).min(yb) {
                    let o = &mut out[(yy - y0) * w..(yy - y0 + 1) * w];
                    if m == 1 {
                        for (x, &v) in vals.iter().enumerate() {
                            for c in 0..1usize << sh {
                                o[(x << sh) + c] = v;
                            }
                        }
                        continue;
                    }
                    // Rows of a coarse level row: the shared expansion (not what is tested).
                    let place = RowPlace {
                        level: sh,
                        rows: m,
                        offset: yy - q * m,
                        flat_q15: sc.row_scale_q15(l, q, yy, false),
                    };
                    let nb = if 2 * (yy - q * m) + 1 < m {
                        above
                    } else {
                        below
                    };
                    expand_row(cur, nb, Passed::Row(vals, 1), o, &place, mode, rig.depth_k);
                }
            };
        run_level(
            rig,
            l,
            frames,
            qa,
            qb,
            bytes,
            words,
            mode,
            &mut rep,
            &mut row_out[..wl],
            &mut level_rows,
        )?;
        y = yb;
    }
    // Short gaps of every working row ([`super::fill::fill_gaps`]).
    for row in out.chunks_exact_mut(w.max(1)) {
        fill_gaps(row, usize::from(rig.params.gap_fill_px), mode, rig.depth_k);
    }
    // Working-size pixels with data (a disparity or depth is never 0).
    rep.valid = out.iter().filter(|&&v| v != 0).count() as u64;
    Ok(rep)
}

/// Receives a finished level row: its number, its finished values (level width), and the
/// raw disparities of the row above, the row itself and the row below.
type EmitRow<'e> = dyn FnMut(usize, &[u16], Option<&[u16]>, &[u16], Option<&[u16]>) + 'e;

/// Level `l`'s rows `qa..qb` (its own rows), each finished into `row_out` and handed to
/// `emit` with its row number; `rep.valid` counts working-size pixels (as `emit` expands).
#[allow(clippy::too_many_arguments)]
fn run_level(
    rig: &StereoRig,
    l: usize,
    frames: [&ImageView<'_>; 2],
    qa: usize,
    qb: usize,
    bytes: &mut [u8],
    words: &mut [u16],
    mode: Output,
    rep: &mut BandReport,
    row_out: &mut [u16],
    emit: &mut EmitRow<'_>,
) -> Result<(), StereoError> {
    let geo = rig.scales().level(l);
    let (w, h) = geo.size();
    let p = &rig.params;
    let r = usize::from(p.radius_px);
    let rv = rig.scales().radius_rows(l);
    let ring = 2 * rv + 2;
    let (ds_l, rest) = bytes.split_at_mut(3 * w);
    let (ds_r, rest) = rest.split_at_mut(3 * w);
    let (f_l, rest) = rest.split_at_mut(ring * w);
    let (f_r, _) = rest.split_at_mut(ring * w);
    let mut rings = Rings {
        ds: [ds_l, ds_r],
        filt: [f_l, f_r],
        ds_tag: [0; 3],
        f_tag: [0; RING_MAX],
        w,
        h,
        k: rig.scales().reduction(l, usize::from(p.downsample)),
        ring,
        cap: p.prefilter_cap,
        shear: geo.shear_terms(),
    };
    let first = (0..h).find(|&v| geo.row(v).is_some()).unwrap_or(h);
    let c0 = qa.saturating_sub(1).max(first);
    let c1 = (qb + 1).min(h);
    if c0 >= c1 {
        return Ok(());
    }
    let Some((dmin, dmax)) = geo.union(c0, c1) else {
        return Ok(());
    };
    let dn = dmax + 1 - dmin;
    if dn > geo.max_disparities() {
        return Err(StereoError::TooSmall);
    }
    let (colsum, rest) = words.split_at_mut(w * dn);
    let (agg, rest) = rest.split_at_mut(dn);
    let (rbc, rest) = rest.split_at_mut(w);
    let (rbd, rest) = rest.split_at_mut(w);
    let (disp, _) = rest.split_at_mut(3 * w);
    let mut disp_tag = [0usize; 3];
    let oc = out_cost(p.prefilter_cap);
    let ri = rv as isize;

    colsum.fill(0);
    for k in c0 as isize - ri..=c0 as isize + ri {
        let s = rings.ensure(frames, k);
        let (lr, rr) = rings.rows(s);
        add_row(colsum, dn, dmin, lr, rr, oc);
    }
    rep.cost_updates += ((2 * rv + 1) * w * dn) as u64 / 2;
    let area = ((2 * r + 1) * (2 * rv + 1)) as u32;
    let mut fin = |q: usize, disp: &[u16], tag: &[usize; 3], rep: &mut BandReport| {
        let row = |y: Option<usize>| -> Option<&[u16]> {
            let y = y?;
            if tag[y % 3] != y + 1 {
                return None;
            }
            Some(&disp[(y % 3) * w..(y % 3) * w + w])
        };
        let Some(cur) = row(Some(q)) else {
            return;
        };
        let (above, below) = (row(q.checked_sub(1)), row(Some(q + 1)));
        let valid = finish_row(
            above,
            cur,
            below,
            p.min_support,
            mode,
            rig.depth_k,
            rig.scales().col_shift(l),
            row_out,
            rep,
        );
        // `valid` counts level pixels; the caller counts the expanded output.
        let _ = valid;
        emit(q, row_out, above, cur, below);
    };
    for y in c0..c1 {
        if y > c0 {
            let so = rings.ensure(frames, y as isize - ri - 1);
            let sn = rings.ensure(frames, y as isize + ri);
            let (lo, ro) = rings.rows(so);
            let (ln, rn) = rings.rows(sn);
            update_rows(colsum, dn, dmin, ln, rn, lo, ro);
            rep.cost_updates += (w * dn) as u64;
        }
        if let Some((lo, hi)) = geo.row(y) {
            let m = RowMatch {
                w,
                r,
                dn,
                dmin,
                jl: lo.saturating_sub(dmin),
                jh: hi.saturating_sub(dmin).min(dn - 1),
                uniq: u32::from(p.uniqueness_pct),
                gap: area * u32::from(p.min_gap_per_px),
                lr: p.lr_check,
                sub: p.subpixel,
                step: rig.scales().column_step(l, y),
                shear_q8: geo.shear_q8(y),
            };
            let drow = &mut disp[(y % 3) * w..(y % 3) * w + w];
            match_row(&m, colsum, agg, rbc, rbd, drow, rep);
            disp_tag[y % 3] = y + 1;
            rep.rows_matched += 1;
        }
        if y >= 1 && (qa..qb).contains(&(y - 1)) {
            fin(y - 1, disp, &disp_tag, rep);
        }
    }
    if (qa..qb).contains(&(c1 - 1)) {
        fin(c1 - 1, disp, &disp_tag, rep);
    }
    Ok(())
}

#[cfg(test)]
mod tests;
