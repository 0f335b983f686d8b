//! The relief the range reprojection saw, on a coarse block grid: the mean height of the
//! points (a sparse sample of them, [`super::RangeAccumulator::with_relief`]) that fell in
//! each block of the top-down grid, for matching against an orbital elevation model
//! (sun-independent, unlike the gray levels).
//!
//! The blocks are `block_px x block_px` cells of the `n x n` top-down grid, `blocks` per
//! side, centred: block `(i, j)` (column `i`, row `j`, row 0 north) covers cells
//! `offset + i block_px ..` and `offset + j block_px ..` with `offset = (n - blocks
//! block_px) / 2`. With the map product's window step as the block side, block `(i, j)` of
//! the window at grid cell `(c, r)` is block `(c + i, r + j)` of the map's relief plane
//! ([`crate::map_product`]).
//!
//! Heights: Q7 metres (1/128 m) relative to the optical centre, up positive; only the
//! differences between blocks matter to the match (zero-mean normalized correlation).

use super::RangeError;

/// Fractional bits of the accumulated heights: Q7 metres.
pub const RELIEF_FRAC_BITS: u32 = 7;
/// Largest block side, cells (bounds the per-block sums: at most `64^2 * 255` samples of
/// at most `2^15` Q7 metres, below `2^31` for `block_px <= 16`; larger blocks saturate).
pub const MAX_BLOCK_PX: usize = 64;

/// The block grid of the relief over an `n x n` top-down grid. Checked by
/// [`ReliefGrid::new`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReliefGrid {
    shift: u32,
    blocks: usize,
    offset: usize,
}

impl ReliefGrid {
    /// Blocks of `block_px` cells (a power of two, 2 to [`MAX_BLOCK_PX`]) over an `n x n`
    /// grid holding at least 2 x 2 of them.
    pub fn new(n: usize, block_px: usize) -> Result<Self, RangeError> {
        if !block_px.is_power_of_two() || !(2..=MAX_BLOCK_PX).contains(&block_px) {
            return Err(RangeError::BadOption);
        }
        let blocks = n / block_px;
        if blocks < 2 {
            return Err(RangeError::BadOption);
        }
        Ok(Self {
            shift: block_px.trailing_zeros(),
            blocks,
            offset: (n - blocks * block_px) / 2,
        })
    }

    /// Block side, cells.
    pub fn block_px(&self) -> usize {
        1 << self.shift
    }

    /// Blocks per side.
    pub fn blocks(&self) -> usize {
        self.blocks
    }

    /// Cells from the grid's west (and north) edge to the first block.
    pub fn offset_px(&self) -> usize {
        self.offset
    }

    /// The block holding cell `(col, row)`, as an index into the accumulator, if any.
    #[inline(always)]
    pub(crate) fn block_of(&self, col: u32, row: u32) -> Option<usize> {
        let o = self.offset as u32;
        let bc = col.wrapping_sub(o) >> self.shift;
        let br = row.wrapping_sub(o) >> self.shift;
        let nb = self.blocks as u32;
        (bc < nb && br < nb).then(|| (br * nb + bc) as usize)
    }
}

/// `i32` words of the relief accumulator of `grid`: a height sum, then a sample count,
/// per block.
pub const fn relief_words(grid: &ReliefGrid) -> usize {
    2 * grid.blocks * grid.blocks
}

/// The accumulator inside the caller's words: sums (Q7 metres) and counts per block.
#[derive(Debug)]
pub(crate) struct ReliefCells<'s> {
    pub(crate) grid: ReliefGrid,
    pub(crate) sums: &'s mut [i32],
    pub(crate) counts: &'s mut [i32],
}

impl<'s> ReliefCells<'s> {
    /// Clears `words` ([`relief_words`] long) and views it as the accumulator.
    pub(crate) fn new(grid: ReliefGrid, words: &'s mut [i32]) -> Result<Self, RangeError> {
        let nb2 = grid.blocks * grid.blocks;
        if words.len() != 2 * nb2 {
            return Err(RangeError::ScratchSize {
                needed: 2 * nb2,
                got: words.len(),
            });
        }
        words.fill(0);
        let (sums, counts) = words
            .split_at_mut_checked(nb2)
            .ok_or(RangeError::BadOption)?;
        Ok(Self { grid, sums, counts })
    }

    /// Adds one point `h` (Q7 metres) to block `k`.
    #[inline(always)]
    pub(crate) fn add(&mut self, k: usize, h: i32) {
        if let (Some(s), Some(c)) = (self.sums.get_mut(k), self.counts.get_mut(k)) {
            *s = s.saturating_add(h);
            *c += 1;
        }
    }
}

/// A relief template made from the accumulator ([`relief_template`]): per block, in the
/// accumulator's words, the zero-mean height (Q7 metres) where the block is valid and 0
/// elsewhere (sum words), and 1 / 0 for valid / not (count words).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReliefTemplate {
    /// Blocks per side.
    pub blocks: usize,
    /// Valid blocks.
    pub valid: usize,
    /// Sum of the squared zero-mean heights, Q14 square metres.
    pub energy: u64,
}

/// Turns the accumulator `words` of `grid` into the template: a block is valid when it
/// has samples and at least `min_fill_permille` of its cells are valid in `mask` (the
/// top-down mask, `n x n`, nonzero = valid); its height is the mean of its samples, minus
/// the mean over the valid blocks. Errors when the sizes disagree.
pub fn relief_template(
    grid: &ReliefGrid,
    words: &mut [i32],
    mask: &[u8],
    n: usize,
    min_fill_permille: u32,
) -> Result<ReliefTemplate, RangeError> {
    let nb = grid.blocks;
    let nb2 = nb * nb;
    let b = grid.block_px();
    if words.len() != 2 * nb2 {
        return Err(RangeError::ScratchSize {
            needed: 2 * nb2,
            got: words.len(),
        });
    }
    if mask.len() != n * n || grid.offset + nb * b > n {
        return Err(RangeError::BadOption);
    }
    let (sums, counts) = words
        .split_at_mut_checked(nb2)
        .ok_or(RangeError::BadOption)?;
    let need = (min_fill_permille.min(1000) as usize * b * b).div_ceil(1000);
    let (mut valid, mut total) = (0usize, 0i64);
    for (k, (s, c)) in sums.iter_mut().zip(counts.iter_mut()).enumerate() {
        let (bi, bj) = (
            k.checked_rem(nb).unwrap_or(0),
            k.checked_div(nb).unwrap_or(0),
        );
        let (x0, y0) = (grid.offset + bi * b, grid.offset + bj * b);
        let filled: usize = (y0..y0 + b)
            .map(|y| {
                mask.get(y * n + x0..y * n + x0 + b)
                    .map_or(0, |r| r.iter().filter(|&&m| m != 0).count())
            })
            .sum();
        let cnt = *c;
        if cnt > 0 && filled >= need.max(1) {
            // Rounded mean (toward negative infinity for the half, as `div_euclid`).
            *s = (*s + cnt / 2).checked_div_euclid(cnt).unwrap_or(0);
            *c = 1;
            valid += 1;
            total += i64::from(*s);
        } else {
            *s = 0;
            *c = 0;
        }
    }
    let mean = if valid > 0 {
        (total + valid as i64 / 2)
            .checked_div_euclid(valid as i64)
            .unwrap_or(0) as i32
    } else {
        0
    };
    let mut energy = 0u64;
    for (s, &c) in sums.iter_mut().zip(counts.iter()) {
        if c != 0 {
            *s -= mean;
            energy += (i64::from(*s) * i64::from(*s)) as u64;
        }
    }
    Ok(ReliefTemplate {
        blocks: nb,
        valid,
        energy,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_centred_and_checked() {
        let g = ReliefGrid::new(200, 16).unwrap();
        assert_eq!((g.blocks(), g.offset_px(), g.block_px()), (12, 4, 16));
        assert_eq!(g.block_of(3, 100), None);
        assert_eq!(g.block_of(4, 4), Some(0));
        assert_eq!(g.block_of(195, 195), Some(143));
        assert_eq!(g.block_of(196, 4), None);
        assert!(ReliefGrid::new(200, 12).is_err());
        assert!(ReliefGrid::new(200, 128).is_err());
        assert!(ReliefGrid::new(20, 16).is_err());
    }

    #[test]
    fn template_is_zero_mean_over_filled_blocks() {
        let g = ReliefGrid::new(8, 4).unwrap();
        let mut w = [0i32; 8];
        let mut acc = ReliefCells::new(g, &mut w).unwrap();
        // Block 0: two samples 100, 300 (mean 200); block 1: one sample 0; block 2: 50 but
        // its cells are not in the mask; block 3: nothing.
        acc.add(0, 100);
        acc.add(0, 300);
        acc.add(1, 0);
        acc.add(2, 50);
        let mut mask = [255u8; 64];
        for y in 4..8 {
            for x in 0..4 {
                mask[y * 8 + x] = 0;
            }
        }
        let t = relief_template(&g, &mut w, &mask, 8, 500).unwrap();
        assert_eq!(t.valid, 2);
        assert_eq!(&w[..4], &[100, -100, 0, 0]);
        assert_eq!(&w[4..], &[1, 1, 0, 0]);
        assert_eq!(t.energy, 20_000);
        assert!(relief_template(&g, &mut w[..6], &mask, 8, 500).is_err());
    }
}
