//! A column's verdict: the winner on the range edge, not unique, or a disparity, from the
//! lane minima and, when they do not decide, the exact runner-up.

use super::super::band::lane;
use super::super::swar::min2_u16x2;
use super::slide::LaneMin;

/// [`column`]'s verdict: the winner lies on its range's edge, or its window reaches
/// outside the right image.
pub(crate) const EDGE: u32 = u32::MAX;
/// [`column`]'s verdict: another lane's minimum, more than one index from the winner, is
/// below the uniqueness threshold.
pub(crate) const UNIQUE: u32 = u32::MAX - 1;

/// A row's settings for [`column`] (and the column's own `lim`), in the order the assembly
/// reads them.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct ColumnParams {
    /// Groups of the row (>= 1).
    pub(crate) n: u32,
    /// Bytes from a right pixel's cost to its index.
    pub(crate) off: u32,
    /// The row's range, indices from its first group.
    pub(crate) lo: u32,
    pub(crate) hi: u32,
    /// The largest index whose window lies inside the right image: `x - r - d0` (may be
    /// negative).
    pub(crate) lim: i32,
    /// `99 - uniqueness_pct` and `100 - uniqueness_pct` (>= 50).
    pub(crate) um1: u32,
    pub(crate) den: u32,
    /// The gap the runner-up needs, cost units.
    pub(crate) gap: u32,
}

/// The winner of a column's lane minima and the first uniqueness test: [`EDGE`] when the
/// winner (the first minimum: smallest cost, then smallest index) lies on the range's edge
/// (`j <= lo`, `j >= hi`) or past `lim`; [`UNIQUE`] when another lane's minimum more than
/// one index from it is below the threshold `t` ([`threshold`]); else the winner as `cost
/// << 16 | index`, for the exact runner-up.
#[inline(always)]
pub(crate) fn decide(m: &LaneMin, p: &ColumnParams) -> u32 {
    let keys = [
        (m.be << 16) | (m.ie & 0xffff),
        (m.be & 0xffff_0000) | (m.ie >> 16),
        (m.bd << 16) | (m.id & 0xffff),
        (m.bd & 0xffff_0000) | (m.id >> 16),
    ];
    let key = keys.iter().fold(u32::MAX, |a, &k| a.min(k));
    let (best, j) = (key >> 16, key & 0xffff);
    if j <= p.lo || j >= p.hi || j as i32 > p.lim {
        return EDGE;
    }
    let t = threshold(best, p);
    // A lane's index i is at or next to j when i - (j - 1) is 0, 1 or 2 (j >= 1).
    let jm1 = j - 1;
    if keys
        .iter()
        .any(|&k| (k & 0xffff).wrapping_sub(jm1) > 2 && (k >> 16) < t)
    {
        return UNIQUE;
    }
    key
}

/// The runner-up cost below which the winner `best` is not unique: `s (100 - u) < 100
/// best` or `s < best + gap`, i.e. `s` below the larger of `ceil(100 best / (100 - u))` and
/// `best + gap`, and never a biased lane's (`0x8000` or more).
#[inline(always)]
pub(crate) fn threshold(best: u32, p: &ColumnParams) -> u32 {
    ((100 * best + p.um1).checked_div(p.den))
        .unwrap_or(0)
        .max(best + p.gap)
        .min(0x8000)
}

/// The smallest cost of the row's words outside indices `j - 1 ..= j + 1` (relative to
/// the row's first group, `1 <= j`, `j + 1 < 4 groups`), and the costs of `j - 1` (low) and
/// `j + 1` (high); a smallest cost of `0x8000` or more means none. The three lanes are set
/// to `0xffff` (above every cost) in their words for the scan, and their words restored
/// after it.
#[inline(always)]
pub(crate) fn runner_up(ap: &mut [u32], j: usize) -> (u32, u32) {
    let ((i0, s0), (i1, s1), (i2, s2)) = (lane(j - 1), lane(j), lane(j + 1));
    let (Some(&w0), Some(&w2)) = (ap.get(i0), ap.get(i2)) else {
        return (0, 0);
    };
    let costs = ((w0 >> s0) & 0xffff) | (((w2 >> s2) & 0xffff) << 16);
    // Words may coincide: each is masked after the one before it, and restored in the
    // reverse order, so the first saved value (the original) is the last written.
    let mut saved = [0u32; 3];
    for ((i, sh), o) in [(i0, s0), (i1, s1), (i2, s2)].into_iter().zip(&mut saved) {
        if let Some(v) = ap.get_mut(i) {
            *o = *v;
            *v |= 0xffff << sh;
        }
    }
    let m = ap.iter().fold(u32::MAX, |m, &v| min2_u16x2(m, v));
    for (i, o) in [i2, i1, i0].into_iter().zip(saved.into_iter().rev()) {
        if let Some(v) = ap.get_mut(i) {
            *v = o;
        }
    }
    ((m & 0xffff).min(m >> 16), costs)
}

/// The exact uniqueness test of a winner `key` (`cost << 16 | index`) that passed
/// [`decide`]: [`UNIQUE`] when the runner-up more than one index away ([`runner_up`]) is
/// below the threshold ([`threshold`]), else `key` with the costs of its two neighbours
/// (index - 1 low, index + 1 high).
#[inline(never)]
pub(crate) fn unique(ap: &mut [u32], key: u32, p: &ColumnParams) -> (u32, u32) {
    let (best, j) = (key >> 16, (key & 0xffff) as usize);
    if j == 0 {
        return (UNIQUE, 0);
    }
    let (run, costs) = runner_up(ap, j);
    if run < threshold(best, p) {
        (UNIQUE, 0)
    } else {
        (key, costs)
    }
}
