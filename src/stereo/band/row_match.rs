//! The winner-take-all of one row: the aggregation window slides along the row's column
//! sums, each decided column keeps its first strict minimum, the runner-up and the
//! left-right check decide whether it stands, and a sub-pixel fit refines it.

use super::super::kernel::{
    column, decide, right_groups, slide, slide_min, unique, ColumnParams, LaneMin, EDGE, UNIQUE,
};
use super::super::{SubPixel, DISPARITY_FRAC_BITS};
use super::column_sums::lane;
use super::{BandReport, ONE_Q, RB_NONE};

/// Per-row settings of the winner-take-all.
pub(super) struct RowMatch {
    pub(super) w: usize,
    pub(super) r: usize,
    /// Words per column of the column sums.
    pub(super) stride: usize,
    /// First word of the row's groups in a column.
    pub(super) w0: usize,
    /// Groups of four disparities holding the row's range.
    pub(super) groups: usize,
    /// Disparity of the first group's index 0.
    pub(super) d0: usize,
    /// The row's range, indices relative to `d0`.
    pub(super) lo: usize,
    pub(super) hi: usize,
    pub(super) uniq: u32,
    pub(super) gap: u32,
    pub(super) lr: bool,
    pub(super) sub: SubPixel,
    /// Columns decided: every `step`-th (1..=4, `Scales::column_step`).
    pub(super) step: usize,
    /// The row's ground shear, Q8 pixels: added (rounded to Q4) to every disparity found,
    /// which are residuals until then ([`super::super::shear::add_shear`]).
    pub(super) shear_q8: i32,
}

/// Added to the row's aggregated costs of indices outside its range (and, for one pass, to
/// the runner-up's excluded indices): every aggregated cost is below it (at most
/// `(2r + 1)^2 2 cap` <= 28,350, [`lane`]), and a biased one stays below 2^16 while the
/// window slides (28,350 + 2^15 + 1,890 < 2^16), so a biased lane never wins a minimum
/// that an unbiased one takes part in. The right image's winners start at this cost, so a
/// biased lane never replaces one either.
pub(super) const BIAS: u32 = 0x8000;

/// Adds `v` to the lane of index `j` (relative to the row's first group) of the row's words.
#[inline(always)]
pub(super) fn lane_add(ap: &mut [u32], j: usize, v: u32) {
    let (i, s) = lane(j);
    if let Some(a) = ap.get_mut(i) {
        *a += v << s;
    }
}

/// The cost of index `j` (relative to the row's first group) in the row's words.
#[inline(always)]
pub(super) fn lane_cost(ap: &[u32], j: usize) -> u32 {
    let (i, s) = lane(j);
    ap.get(i).map_or(u32::MAX, |&v| (v >> s) & 0xffff)
}

/// The slide and lane minima of a column before the steady ones ([`match_row`]): `x == r`
/// (the first window, no slide) or right pixels partly outside the image.
#[inline(never)]
pub(super) fn first_columns(
    ap: &mut [u32],
    cs: *const u32,
    gw: usize,
    w0: usize,
    x: usize,
    r: usize,
    groups: usize,
) -> LaneMin {
    let ap_ptr = ap.as_mut_ptr();
    // Safety: as in [`match_row`] (checked once per row): columns `x + r` and `x - r - 1`
    // (`x > r`) of the column sums hold words `w0 .. w0 + 2 groups`; `ap` has `2 groups`
    // words and is not part of them.
    unsafe {
        if x > r {
            let ci = cs.add((x + r) * gw + w0);
            let co = cs.add((x - r - 1) * gw + w0);
            slide_min::<true>(ap_ptr, ci, co, groups)
        } else {
            slide_min::<false>(ap_ptr, cs, cs, groups)
        }
    }
}

/// The right image's winners of a column before the steady ones, `base = x - d0`: the
/// groups whose four right pixels are all inside (`4k + 3 <= base`), then the inside lanes
/// of the next one at a time.
#[inline(never)]
pub(super) fn right_first_columns(
    ap: &[u32],
    rb: &mut [u16],
    half: usize,
    base: usize,
    groups: usize,
    lo: usize,
    hi: usize,
) {
    if rb.len() < 4 * half || ap.len() < 2 * groups {
        return;
    }
    let n = if base >= 3 {
        ((base - 3) / 4 + 1).min(groups)
    } else {
        0
    };
    if n > 0 {
        let b = base - 3;
        let rbp = rb.as_mut_ptr();
        // Safety: `ap` has `2 groups >= 2 n` words; for `k < n` the pixels `b - 4k ..= b -
        // 4k + 3` lie in `0..=base`, `base < w <= 2 half`, so their costs (`(p & 1) half +
        // (p >> 1)`, two at a time) and indices (`4 half` bytes further) lie inside `rb`.
        unsafe {
            let pe = rbp.add((b & 1) * half + (b >> 1));
            let pd = rbp.add(((b + 1) & 1) * half + ((b + 1) >> 1));
            right_groups(ap.as_ptr(), pe, pd, 4 * half, n);
        }
    }
    if n < groups {
        for j in (4 * n).max(lo)..=hi.min(base) {
            let a = lane_cost(ap, j);
            let xr = base - j;
            let p = (xr & 1) * half + (xr >> 1);
            if let Some(&c) = rb.get(p) {
                if a < u32::from(c) {
                    if let Some(c) = rb.get_mut(p) {
                        *c = a as u16;
                    }
                    if let Some(i) = rb.get_mut(p + 2 * half) {
                        *i = j as u16;
                    }
                }
            }
        }
    }
}

/// The sub-pixel disparity (Q4, at least 1) of a unique winner `key` (`cost << 16 |
/// index`, index from `d0`) whose neighbours' costs are `costs` (index - 1 low, index + 1
/// high).
#[inline(always)]
pub(super) fn sub_pixel(key: u32, costs: u32, d0: usize, sub: SubPixel) -> u16 {
    let (best, j) = (key >> 16, (key & 0xffff) as usize);
    let frac = sub.offset(
        (costs & 0xffff) as i32,
        best as i32,
        (costs >> 16) as i32,
        i32::from(ONE_Q),
    );
    let q = ((d0 + j) as i32 * i32::from(ONE_Q) + frac).max(1);
    q.min(i32::from(u16::MAX)) as u16
}

/// The right winners' pointers of a steady column ([`match_row`]): at the first one
/// (`last` is `None`) the costs of pixels `b` and `b + 1` (pixel `p` at element
/// `(p & 1) half + p / 2`), else `step` columns on from the last decided column's `(pe,
/// pd)`, pixels `b - step` and `b - step + 1`: for an even step both move `step / 2`
/// elements on in their arrays; for an odd one the parities swap, so pixel `b` is
/// `(step - 1) / 2` elements past the last pixel `b - step + 1` and pixel `b + 1` is
/// `(step + 1) / 2` past the last pixel `b - step`.
#[inline(always)]
pub(super) fn right_ptrs(
    rbp: *mut u16,
    half: usize,
    b: usize,
    step: usize,
    last: Option<(*mut u16, *mut u16)>,
) -> (*mut u16, *mut u16) {
    match last {
        None => (
            rbp.wrapping_add((b & 1) * half + (b >> 1)),
            rbp.wrapping_add(((b + 1) & 1) * half + ((b + 1) >> 1)),
        ),
        Some((pe, pd)) if step & 1 == 0 => (pe.wrapping_add(step / 2), pd.wrapping_add(step / 2)),
        Some((pe, pd)) => (pd.wrapping_add(step / 2), pe.wrapping_add(step / 2 + 1)),
    }
}

/// Winner-take-all of one row from the column sums into `disp` (Q4, 0 = none): `aggw`
/// holds the row's aggregated costs (the whole groups of four holding its range, the lane
/// layout of [`lane`], indices outside the range biased by [`BIAS`]), `rb` the right
/// image's winners ([`right_groups`]).
///
/// Per column, one pass over the row's words slides the aggregation window one column on
/// and keeps, per lane, its first strict minimum ([`min_u16x2`]): every lane sees its
/// indices in increasing order, so of the four lanes the smaller cost, on a tie the smaller
/// index, is the first minimum of the whole range, what a scan in index order keeping
/// strict improvements finds. A second pass gives every right pixel its candidate of this
/// column; a right pixel sees its candidates in increasing index (one per column), so
/// keeping strict improvements is the first of its smallest costs too. The runner-up more
/// than one index from the winner is first bounded by the other lanes' minima (enough to
/// reject most textureless windows) and only computed exactly when that does not decide
/// ([`unique`]; on Armv7E-M inside the column's assembly block).
/// Indices are below 2^15 (at most the working width, [`super::super::StereoRig::new`]), so [`RB_NONE`]
/// is never one.
// A function of its own (called once per row): its loops get the registers to
// themselves instead of spilling in the band loop.
#[inline(never)]
pub(super) fn match_row(
    m: &RowMatch,
    colsum: &[u32],
    aggw: &mut [u32],
    rb: &mut [u16],
    disp: &mut [u16],
    rep: &mut BandReport,
) {
    disp.fill(0);
    let groups = m.groups;
    let (w0, nw) = (m.w0, 2 * groups);
    let (w, r, gw) = (m.w, m.r, m.stride);
    let half = w.div_ceil(2);
    let (lo, hi) = (m.lo, m.hi);
    // Everything the column loop reads or writes through pointers, checked once per row.
    if gw == 0
        || groups == 0
        || lo > hi
        || hi >= 4 * groups
        || w0 + nw > gw
        || colsum.len() < w * gw
        || aggw.len() < nw
        || rb.len() < 4 * half
        || disp.len() < w
        || w < 2 * r + 1
    {
        return;
    }
    let ap = aggw.get_mut(..nw).unwrap_or(&mut []);
    ap.fill(0);
    for c in colsum.chunks_exact(gw).take(2 * r + 1) {
        for (a, &v) in ap.iter_mut().zip(c.get(w0..w0 + nw).unwrap_or(&[])) {
            *a += v;
        }
    }
    for j in (0..lo).chain(hi + 1..4 * groups) {
        lane_add(ap, j, BIAS);
    }
    if m.lr {
        let (c, i) = rb.split_at_mut((2 * half).min(rb.len()));
        c.fill(BIAS as u16);
        i.iter_mut().take(2 * half).for_each(|v| *v = RB_NONE);
    }
    let dmin = m.d0;
    let lr_on = m.lr;
    let cs = colsum.as_ptr();
    let rbp = rb.as_mut_ptr();
    // From column `x_full` on, every group's right pixels lie inside the image; from
    // `x_steady` on (also past the first column, which has no slide) each column is one
    // [`column`] call.
    let x_full = dmin + 4 * groups - 1;
    let x_steady = x_full.max(r + 1);
    // The right winners' pointers of the last decided steady column.
    let mut last: Option<(*mut u16, *mut u16)> = None;
    let mut prm = ColumnParams {
        n: groups as u32,
        off: (4 * half) as u32,
        lo: lo as u32,
        hi: hi as u32,
        lim: 0,
        um1: 99 - m.uniq,
        den: 100 - m.uniq,
        gap: m.gap,
    };
    let (mut edge, mut uniq) = (0u64, 0u64);
    let step = m.step.max(1);
    // The decided columns `x` (`x - r` a multiple of `step`); after each, the window
    // slides over the `step - 1` columns that are not decided in one call.
    let mut x = r;
    // Column `x + r`'s and column `x - r - 1`'s words of the row's groups (the latter before
    // `colsum` at `x = r`: not read there), moved on with `x`.
    let mut ci = cs.wrapping_add(2 * r * gw + w0);
    let mut co = cs.wrapping_add(w0).wrapping_sub(gw);
    while x < w - r {
        let ap_ptr = ap.as_mut_ptr();
        // The largest index whose window lies inside the right image (x >= d + r).
        prm.lim = (x - r) as i32 - dmin as i32;
        // The verdict and, for a unique winner, its neighbours' costs.
        let (res, costs) = if lr_on && x >= x_steady {
            // Every group's right pixels inside: pixels `b - 4k ..= b - 4k + 3`, `b = x -
            // dmin - 3`.
            // The decided columns are `step` apart.
            let (pe, pd) = right_ptrs(rbp, half, x - dmin - 3, step, last);
            last = Some((pe, pd));
            // Safety: checked above for the row: columns `x + r < w` and `x - r - 1`
            // (`x > r`; `ci`, `co`) of `colsum` (at least `w gw` words) hold words `w0 .. w0 + nw <=
            // gw`; `ap` has `nw` words and is not part of `colsum`; `pe`, `pd` point at the
            // costs of pixels `b` and `b + 1` (`(p & 1) half + (p >> 1)`), and for `k <
            // groups` the pixels `b - 4k ..= b - 4k + 3` lie in `0..=x - dmin` (x >= x_full)
            // and below `w <= 2 half`, so their costs (two at a time) and indices (`2 half`
            // elements, `4 half` bytes further) lie inside `rb`'s `4 half` elements.
            unsafe { column(ap_ptr, ci, co, pe, pd, &prm) }
        } else {
            let acc = first_columns(ap, cs, gw, w0, x, r, groups);
            if lr_on && x >= dmin {
                right_first_columns(ap, rb, half, x - dmin, groups, lo, hi);
            }
            match decide(&acc, &prm) {
                key @ (EDGE | UNIQUE) => (key, 0),
                key => unique(ap, key, &prm),
            }
        };
        match res {
            EDGE => edge += 1,
            UNIQUE => uniq += 1,
            key => {
                if let Some(o) = disp.get_mut(x) {
                    *o = sub_pixel(key, costs, dmin, m.sub);
                }
            }
        }
        // The columns up to the next decided one (not past the row's last): the window
        // slides on.
        let n = (step - 1).min(w - r - 1 - x);
        if n > 0 {
            // Safety: checked above for the row: columns `x + 1 + r ..= x + n + r < w` and
            // `x - r ..= x + n - r - 1` (from `ci`, `co` one column on) of `colsum` (at least `w gw` words) hold words `w0 ..
            // w0 + nw <= gw`; `ap` has `nw` words and is not part of `colsum`.
            unsafe {
                slide(
                    ap_ptr,
                    ci.wrapping_add(gw),
                    co.wrapping_add(gw),
                    groups,
                    gw,
                    n,
                );
            }
        }
        x += n + 1;
        ci = ci.wrapping_add((n + 1) * gw);
        co = co.wrapping_add((n + 1) * gw);
    }
    rep.pixel_disparities += ((w - 2 * r) * (hi + 1 - lo)) as u64;
    rep.rejected_edge += edge;
    rep.rejected_unique += uniq;
    // Residuals to disparities ([`super::super::shear::add_shear`]), at the decided columns.
    let g4 = super::super::shear::shear_q4(m.shear_q8);
    let shifted = |v: u16| super::super::shear::sheared(v, g4);
    if lr_on {
        let mut lr = 0u64;
        // Only the decided columns (`x - r` a multiple of `step`) can hold a disparity yet.
        let mut x = r;
        while let Some(o) = disp.get_mut(x).filter(|_| x < w - r) {
            let v = *o;
            x += step;
            if v == 0 {
                continue;
            }
            let dl = usize::from((v + ONE_Q / 2) >> DISPARITY_FRAC_BITS);
            // A right pixel no candidate reached has disparity 0.
            let ok = (x - step)
                .checked_sub(dl)
                .and_then(|xr| rb.get(2 * half + (xr & 1) * half + (xr >> 1)))
                .is_some_and(|&j| {
                    let dr = match j {
                        RB_NONE => 0,
                        j => dmin + usize::from(j),
                    };
                    dr.abs_diff(dl) <= 1
                });
            if !ok {
                *o = 0;
                lr += 1;
            } else if g4 != 0 {
                *o = shifted(v);
            }
        }
        rep.rejected_lr += lr;
    } else if g4 != 0 {
        let mut x = r;
        while let Some(o) = disp.get_mut(x).filter(|_| x < w - r) {
            if *o != 0 {
                *o = shifted(*o);
            }
            x += step;
        }
    }
    // The blend of two decided columns moves with them: the shear could be added to the
    // decided columns alone.
    if step > 1 {
        super::super::fill::fill_between(disp, r, w - r, step);
    }
}
