//! The per-column loops of the band matcher ([`super::band`]): the column sums' update by
//! one row in and one row out and their set-up, the window slide with the lane minima, and
//! the right image's winners.
//!
//! All run over the groups of four disparities of a row, two `u16` lanes per word (the
//! layout of `band::lane`). With the `armv7em-dsp` feature on Arm (Cortex-M4/M7, the flight
//! firmware) each is one assembly loop that keeps all its state in registers (`USUB16` and
//! `SEL` for the lane minima); elsewhere the portable loops below, which give the same
//! result for every input (the host tests run the matcher built on them against the scalar
//! reference, and the QEMU budget checks the firmware's output against the host's to the
//! bit).

mod column;
mod right;
mod slide;
mod update;
mod verdict;

pub(crate) use column::column;
pub(crate) use right::right_groups;
pub(crate) use slide::{slide, slide_min, LaneMin};
pub(crate) use update::{add_groups, update_columns, UpdateCols};
pub(crate) use verdict::{decide, unique, ColumnParams, EDGE, UNIQUE};

#[cfg(test)]
mod tests {
    use super::super::band::lane;
    use super::update::update_groups;
    use super::verdict::runner_up;
    use super::*;

    #[test]
    fn runner_up_skips_the_winner_and_its_neighbours_and_restores_the_words() {
        // Four groups of pseudo-random lane costs; every winner index in range.
        let mut seed = 0x2545_f491u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % 2000
        };
        for _ in 0..50 {
            let ap0: [u32; 8] = core::array::from_fn(|_| next() | (next() << 16));
            let cost = |j: usize| {
                let (i, s) = lane(j);
                (ap0[i] >> s) & 0xffff
            };
            for j in 1..15 {
                let mut ap = ap0;
                let (run, costs) = runner_up(&mut ap, j);
                let want = (0..16)
                    .filter(|&i: &usize| i.abs_diff(j) > 1)
                    .map(cost)
                    .min()
                    .unwrap_or(u32::MAX);
                assert_eq!(run, want, "index {j}");
                assert_eq!(costs, cost(j - 1) | (cost(j + 1) << 16), "index {j}");
                assert_eq!(ap, ap0, "index {j}: words restored");
            }
        }
    }

    #[test]
    fn lane_minima_keep_the_first_smallest_of_each_lane() {
        // Three groups; lane costs chosen with ties across groups.
        let mut ap = [
            10u32 | 5 << 16,
            7 | 9 << 16,
            3 | 5 << 16,
            7 | 2 << 16,
            3 | 6 << 16,
            1 | 2 << 16,
        ];
        let z = [0u32; 6];
        // Safety: three groups of two words each, no overlap.
        let m = unsafe { slide_min::<true>(ap.as_mut_ptr(), z.as_ptr(), z.as_ptr(), 3) };
        // e words: low lane indices 3, 7, 11 (costs 10, 3, 3): 3 at 7; high 1, 5, 9 (5, 5,
        // 6): 5 at 1. d words: low 2, 6, 10 (7, 7, 1): 1 at 10; high 0, 4, 8 (9, 2, 2): 2 at 4.
        assert_eq!(
            m,
            LaneMin {
                be: 3 | 5 << 16,
                ie: 7 | 1 << 16,
                bd: 1 | 2 << 16,
                id: 10 | 4 << 16
            }
        );
        // The slide adds `ci` and removes `co` lane by lane.
        let ci = [1u32 | 1 << 16; 6];
        let co = [1u32; 6];
        let before = ap;
        // Safety: as above.
        unsafe { slide_min::<true>(ap.as_mut_ptr(), ci.as_ptr(), co.as_ptr(), 3) };
        for (a, b) in ap.iter().zip(before) {
            assert_eq!(*a, b + (1 << 16));
        }
    }

    #[test]
    fn right_winners_take_strict_improvements() {
        // Pixels 0..8: even costs, odd costs, then their indices (16 bytes further).
        let mut rb = [0xffffu16; 16];
        let ap = [5u32 | 6 << 16, 7 | 8 << 16];
        // b = 4: e -> pixels 4 (low, index 3) and 6 (high, index 1), d -> 5 (index 2), 7
        // (index 0).
        let off = 16;
        // Safety: pixel 4 is even entry 2, pixel 5 odd entry 2 (two elements each, inside).
        unsafe {
            let p = rb.as_mut_ptr();
            right_groups(ap.as_ptr(), p.add(2), p.add(4 + 2), off, 1);
        }
        assert_eq!(&rb[2..4], &[5, 6]);
        assert_eq!(&rb[6..8], &[7, 8]);
        assert_eq!(&rb[8 + 2..8 + 4], &[3, 1]);
        assert_eq!(&rb[8 + 6..8 + 8], &[2, 0]);
        // An equal cost does not replace; a smaller one does.
        let ap2 = [5u32 | 1 << 16, 9 | 8 << 16];
        // Safety: as above.
        unsafe {
            let p = rb.as_mut_ptr();
            right_groups(ap2.as_ptr(), p.add(2), p.add(4 + 2), off, 1);
        }
        assert_eq!(&rb[2..4], &[5, 1]);
        assert_eq!(&rb[8 + 2..8 + 4], &[3, 1]);
        assert_eq!(&rb[6..8], &[7, 8]);
    }

    #[test]
    fn column_sums_take_a_row_in_and_a_row_out() {
        // Two groups; right bytes of the new row 10..18, of the old row 20..28.
        let new: [u8; 8] = [1, 2, 3, 4, 5, 6, 7, 8];
        let old: [u8; 8] = [9, 9, 9, 9, 0, 0, 0, 0];
        let mut cs = [100u32 | 100 << 16; 4];
        let (a4, b4) = (5u32 * 0x0101_0101, 3u32 * 0x0101_0101);
        // Safety: group 0 reads bytes 4..8, group 1 bytes 0..4; four words.
        unsafe {
            update_groups(
                cs.as_mut_ptr(),
                new.as_ptr().add(4),
                old.as_ptr().add(4),
                a4,
                b4,
                2,
            );
        }
        // Group 0: new |5 - (5, 6, 7, 8)| = (0, 1, 2, 3), old |3 - 0| = 3: word 0 takes
        // bytes 0 and 2 (+0 -3, +2 -3), word 1 bytes 1 and 3 (+1 -3, +3 -3).
        assert_eq!(cs[0], 97 | 99 << 16);
        assert_eq!(cs[1], 98 | 100 << 16);
        // Group 1: new |5 - (1, 2, 3, 4)| = (4, 3, 2, 1), old |3 - 9| = 6.
        assert_eq!(cs[2], 98 | 96 << 16);
        assert_eq!(cs[3], 97 | 95 << 16);
        let mut z = [0u32; 4];
        // Safety: as above.
        unsafe { add_groups(z.as_mut_ptr(), new.as_ptr().add(4), a4, 2) };
        assert_eq!(z, [2 << 16, 1 | 3 << 16, 4 | 2 << 16, 3 | 1 << 16]);
    }
}
