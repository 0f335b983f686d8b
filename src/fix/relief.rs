//! The relief stage: the relief the range reprojection saw ([`crate::reproject::ReliefGrid`]
//! blocks, heights of the points the depth gave) against the map product's relief plane
//! (the orbital elevation model on the same blocks) at every window of the coarse grid,
//! by zero-mean normalized correlation over the blocks the rover saw, added with a weight
//! to the CNN's coarse response. Heights do not change with the sun, the gray levels do:
//! where the CNN's ranking fails across suns, the relief usually still knows the place.
//!
//! All integer: heights Q7 metres (rover) and Q4 metres (map; the correlation is scale
//! free), sums in `i64`, the correlation Q15.

use crate::map_product::ReliefPlane;
use crate::nn::window_cosine::{isqrt_u64_bits, q15_quotient};
use crate::reproject::ReliefTemplate;

/// Settings of the relief stage ([`super::FixConfig::relief`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReliefConfig {
    /// Weight of the relief correlation in the coarse response, `[0, 4]`: each window's
    /// score becomes `cosine + weight * ncc` (both Q15). 0 turns the stage off.
    pub weight: f32,
    /// Fewest valid blocks the rover's relief needs for the stage to run (else the CNN's
    /// response stands alone).
    pub min_blocks: u16,
    /// Share of a block's cells that must be valid in the top-down mask for the block to
    /// count, per mille.
    pub min_fill_permille: u16,
}

impl Default for ReliefConfig {
    /// Weight 1 (measured on development seed 5, 100 cross-sun stops, truth depth: within
    /// 5 m 0.94 without the stage, 0.98 / 0.99 / 0.98 with weights 0.5 / 1 / 2), at least 24
    /// blocks, blocks 30 % filled.
    fn default() -> Self {
        Self {
            weight: 1.0,
            min_blocks: 24,
            min_fill_permille: 300,
        }
    }
}

impl ReliefConfig {
    /// The weight in Q8 (0..=1024).
    pub(crate) fn weight_q8(&self) -> i64 {
        (self.weight * 256.0 + 0.5) as i64
    }
}

/// Compacts the template in `words` (sums then validity, [`crate::reproject::relief_template`])
/// to its valid blocks: `words[..valid]` their zero-mean heights (Q7 m, clamped to `i16`),
/// `words[nb^2..nb^2 + valid]` their offsets in a relief plane of `plane_cols` columns.
/// Returns the number of valid blocks.
pub(crate) fn compact(t: &ReliefTemplate, words: &mut [i32], plane_cols: usize) -> usize {
    let nb = t.blocks;
    let nb2 = nb * nb;
    let (vals, marks) = words.split_at_mut(nb2.min(words.len()));
    let mut v = 0usize;
    for k in 0..nb2 {
        if marks.get(k).is_some_and(|&m| m != 0) {
            let h = vals.get(k).copied().unwrap_or(0);
            let off = k.checked_div(nb).unwrap_or(0) * plane_cols + k.checked_rem(nb).unwrap_or(0);
            // `v <= k`: the compact entry never overwrites an unread one.
            if let (Some(dv), Some(dm)) = (vals.get_mut(v), marks.get_mut(v)) {
                *dv = h.clamp(i32::from(i16::MIN), i32::from(i16::MAX));
                *dm = off as i32;
                v += 1;
            }
        }
    }
    v
}

/// Adds `weight_q8 / 256` times the relief correlation (Q15) of every window to
/// `response` (row-major over the `cols x rows` window grid): `vals[..v]` and `offs[..v]`
/// from [`compact`]. Returns the multiply-accumulates done.
pub(crate) fn add_scores(
    plane: &ReliefPlane<'_>,
    vals: &[i32],
    offs: &[i32],
    cols: usize,
    rows: usize,
    weight_q8: i64,
    response: &mut [i32],
) -> u64 {
    let v = vals.len().min(offs.len());
    let (Some(vals), Some(offs)) = (vals.get(..v), offs.get(..v)) else {
        return 0;
    };
    // At most 2^15 blocks keeps every sum of `|d| < 2^15` inside `i32` ([`Scores::run`]).
    if v == 0 || v > 1 << 15 || cols == 0 || rows == 0 || response.len() < cols * rows {
        return 0;
    }
    let energy: i64 = vals.iter().map(|&t| i64::from(t) * i64::from(t)).sum();
    let sq_t = (energy as u64).isqrt() as i64;
    if sq_t == 0 {
        return 0;
    }
    // Every block read, `base + o` with `base <= (rows - 1) pc + cols - 1`, lies in the
    // plane: checked once here (the layout guarantees it for a parsed product).
    let pc = plane.cols();
    let max_off = offs.iter().copied().max().unwrap_or(0);
    if offs.iter().any(|&o| o < 0) || (rows - 1) * pc + (cols - 1) + max_off as usize >= plane.len()
    {
        return 0;
    }
    let p = Scores {
        vals,
        offs,
        cols,
        rows,
        pc,
        sq_t,
        weight_q8,
    };
    #[cfg(target_endian = "little")]
    if let Some(h) = plane.as_i16() {
        // Safety: every index `k` passed is below `plane.len() == h.len()` (checked above).
        p.run(response, |k| i32::from(unsafe { *h.get_unchecked(k) }));
        return 3 * (v * cols * rows) as u64;
    }
    p.run(response, |k| i32::from(plane.at(k).unwrap_or(0)));
    3 * (v * cols * rows) as u64
}

/// The per-window correlations of [`add_scores`] once its checks have passed.
struct Scores<'t> {
    vals: &'t [i32],
    offs: &'t [i32],
    cols: usize,
    rows: usize,
    pc: usize,
    sq_t: i64,
    weight_q8: i64,
}

impl Scores<'_> {
    #[inline(always)]
    fn run<F: Fn(usize) -> i32>(&self, response: &mut [i32], at: F) {
        let v = self.vals.len() as i64;
        for (r, out) in response
            .chunks_exact_mut(self.cols)
            .take(self.rows)
            .enumerate()
        {
            for (c, o) in out.iter_mut().enumerate() {
                let base = r * self.pc + c;
                // |d| <= 2^15 and at most 2^15 blocks: the sum fits `i32`, d^2 too.
                let (mut s, mut ss, mut st) = (0i32, 0i64, 0i64);
                for (&t, &off) in self.vals.iter().zip(self.offs) {
                    let d = at(base + off as usize);
                    s += d;
                    // Widened before the product: one `SMLAL` each on Armv7E-M.
                    ss += i64::from(d) * i64::from(d);
                    st += i64::from(t) * i64::from(d);
                }
                // Σ (d - mean)^2 = ss - s^2 / v; the template is zero-mean, so Σ t (d -
                // mean) = st.
                let s2 = i64::from(s) * i64::from(s);
                // s^2 / v by a 32-bit division where s^2 fits (heights of a few metres
                // always do): the same floor, without a 64-bit division call.
                let mean_sq = match (u32::try_from(s2), u32::try_from(v)) {
                    (Ok(a), Ok(b)) => a.checked_div(b).map_or(0, i64::from),
                    _ => s2.checked_div(v).unwrap_or(0),
                };
                let var = ss - mean_sq;
                // The floor of the square root, one bit per step (equal to `u64::isqrt`).
                let den = self.sq_t * isqrt_u64_bits(var.max(0) as u64) as i64;
                // Clamped: the square roots round down, so a perfect match can come out a
                // little above 1. The quotient bit by bit where the denominator fits `u32`
                // (the same truncated, clamped value as the 64-bit division).
                let ncc = match u32::try_from(den) {
                    Ok(d) => i64::from(q15_quotient(st << 15, d)),
                    Err(_) if den > 0 => (st << 15)
                        .checked_div(den)
                        .unwrap_or(0)
                        .clamp(-32_768, 32_768),
                    Err(_) => 0,
                };
                let add = (self.weight_q8 * ncc) >> 8;
                *o = o.saturating_add(add.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::GeoRef;
    use crate::map_product::{
        seal, write_header, CrcCheck, MapProduct, MapProductLayout, MapProductMeta, RefinePlane,
    };
    use crate::reproject::{relief_template, relief_words, ReliefGrid};

    #[test]
    fn the_true_window_scores_highest() {
        // 40 x 40 map, 16 px windows every 4 px: 7 x 7 windows, 4 blocks per window side,
        // a 10 x 10 relief plane with a bump pattern.
        let h =
            |i: usize, j: usize| ((i * i * 7 + j * j * 3 + i * j * 5 + i) % 17) as i16 * 16 - 128;
        let mut raw = [0u8; 110_000];
        let p = product(&mut raw, h);
        let plane = p.relief().unwrap();
        // The rover saw the blocks of window (3, 2), one block missing, in Q7 m (8x Q4)
        // plus an offset (its own datum).
        let g = ReliefGrid::new(16, 4).unwrap();
        let mut words = [0i32; 32];
        assert_eq!(relief_words(&g), 32);
        for k in 0..16 {
            let (i, j) = (k % 4, k / 4);
            words[k] = 8 * i32::from(h(3 + i, 2 + j)) + 5000;
            words[16 + k] = i32::from(k != 5);
        }
        let mask = [255u8; 256];
        let t = relief_template(&g, &mut words, &mask, 16, 0).unwrap();
        assert_eq!(t.valid, 15);
        let v = compact(&t, &mut words, plane.cols());
        assert_eq!(v, 15);
        let mut resp = [0i32; 49];
        let (vals, offs) = words.split_at(16);
        let macs = add_scores(&plane, &vals[..v], &offs[..v], 7, 7, 256, &mut resp);
        assert_eq!(macs, 49 * 45);
        let best = (0..49).max_by_key(|&i| resp[i]).unwrap();
        assert_eq!(best, 2 * 7 + 3);
        assert!(resp[best] > 32_000, "{}", resp[best]);
        assert!(resp.iter().all(|&r| r <= 32_768));
        // Weight 0.5 halves the scores added.
        let mut half = [0i32; 49];
        add_scores(&plane, &vals[..v], &offs[..v], 7, 7, 128, &mut half);
        assert!((half[best] - resp[best] / 2).abs() <= 1);
        // Every window's score is the plain 64-bit formula's (64-bit divisions, `u64::isqrt`).
        assert_eq!(resp, plain_scores(&plane, &vals[..v], &offs[..v], 7, 7));
        // Heights far beyond the realistic (s^2 and the denominator past `u32`): the 64-bit
        // paths, the same formula.
        let big: [i32; 15] = core::array::from_fn(|k| if k % 2 == 0 { 32_767 } else { -20_000 });
        let mut raw_big = [0u8; 110_000];
        let pb = product(&mut raw_big, |i, j| {
            if (i + 2 * j) % 3 == 0 {
                32_000
            } else {
                -31_000 + (i * 10 + j) as i16
            }
        });
        let bp = pb.relief().unwrap();
        let offs_big = &offs[..15];
        let mut got = [0i32; 49];
        add_scores(&bp, &big, offs_big, 7, 7, 256, &mut got);
        assert_eq!(got, plain_scores(&bp, &big, offs_big, 7, 7));
        assert!(got.iter().any(|&r| r != 0));
    }

    /// A 40 x 40 map product, 16 px windows every 4 px (7 x 7 windows, 4 blocks per window
    /// side), whose 10 x 10 relief plane holds `h(col, row)`, sealed in `raw`.
    fn product(raw: &mut [u8], h: impl Fn(usize, usize) -> i16) -> MapProduct<'_> {
        let meta = MapProductMeta {
            geo: GeoRef::new(0.0, 0.0, 0.25).unwrap(),
            width: 40,
            height: 40,
            window_px: 16,
            step_px: 4,
            weights_crc: 0,
            sun_deg: None,
            plane: RefinePlane::new(2, true).unwrap(),
            relief_block_px: 4,
        };
        let l = MapProductLayout::of(&meta).unwrap();
        let buf = &mut raw[..l.total];
        write_header(&meta, buf).unwrap();
        for j in 0..l.relief_rows {
            for i in 0..l.relief_cols {
                let at = l.relief_at + 2 * (j * l.relief_cols + i);
                buf[at..at + 2].copy_from_slice(&h(i, j).to_le_bytes());
            }
        }
        seal(buf).unwrap();
        MapProduct::parse(buf, CrcCheck::Verify).unwrap()
    }

    /// The scores [`add_scores`] adds at weight 1, by the plain 64-bit formula.
    fn plain_scores(
        plane: &ReliefPlane<'_>,
        vals: &[i32],
        offs: &[i32],
        cols: usize,
        rows: usize,
    ) -> [i32; 49] {
        let v = vals.len() as i64;
        let energy: i64 = vals.iter().map(|&t| i64::from(t) * i64::from(t)).sum();
        let sq_t = (energy as u64).isqrt() as i64;
        let mut out = [0i32; 49];
        for r in 0..rows {
            for c in 0..cols {
                let (mut s, mut ss, mut st) = (0i64, 0i64, 0i64);
                for (&t, &o) in vals.iter().zip(offs) {
                    let d = i64::from(plane.at(r * plane.cols() + c + o as usize).unwrap());
                    s += d;
                    ss += d * d;
                    st += i64::from(t) * d;
                }
                let var = ss - s * s / v;
                let den = sq_t * (var.max(0) as u64).isqrt() as i64;
                let ncc = if den > 0 {
                    ((st << 15) / den).clamp(-32_768, 32_768)
                } else {
                    0
                };
                out[r * cols + c] = ncc as i32;
            }
        }
        out
    }
}
