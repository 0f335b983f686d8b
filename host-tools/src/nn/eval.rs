//! Localization evaluation of a matcher on the 441-window protocol of the 2018 study:
//! a 300 x 300 m search region, 50 m windows at a 12.5 m stride (21 x 21), the true
//! position on a window centre somewhere in the region. Reports recall@1/5/10 of 441,
//! median and p95 error of the best window, and pair AUC (true window vs the 440 others).

use super::data::{
    random_aug, random_sun, render_ortho, rover_input, sample_in, Sun, Zone, SAT_SIDE, WINDOW_M,
};
use super::float_model::{batch_tensor, FloatNet};
use crate::world::World;
use anyhow::Result;
use orbfix::nn::input::{prepare_input, INPUT_LEN};
use orbfix::nn::model::{cosine_q15, Arena, SiameseNet, EMBED_LEN};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

/// Windows per side of the search region.
pub const GRID: usize = 21;
/// Window stride, metres.
pub const STRIDE_M: f64 = 12.5;

/// A matcher under evaluation: scores the rover input against every window.
pub enum Scorer<'a> {
    /// Float candle model (cosine of L2-normalized embeddings).
    Float(&'a FloatNet),
    /// Int8 core network (Q15 cosine).
    Int8(&'a SiameseNet<'a>),
    /// Masked normalized cross-correlation of the prepared 64 px inputs (classical baseline;
    /// invalid rover pixels are 0 and drop out).
    MaskedNcc,
}

/// Metrics of one evaluation.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    /// Locations evaluated.
    pub n: usize,
    /// Fraction with the true window ranked first.
    pub recall_at_1: f64,
    /// ... within the best 5.
    pub recall_at_5: f64,
    /// ... within the best 10.
    pub recall_at_10: f64,
    /// Median distance from the best window's centre to the truth, metres.
    pub median_error_m: f64,
    /// 95th percentile of that distance, metres.
    pub p95_error_m: f64,
    /// Probability that the true window outscores a wrong one.
    pub pair_auc: f64,
}

/// One test location: rover input and the 441 window inputs, true window index.
pub struct Case {
    /// Rover side.
    pub rover: [i8; INPUT_LEN],
    /// Windows, row-major from the north-west.
    pub windows: Vec<[i8; INPUT_LEN]>,
    /// Index of the window centred on the truth.
    pub truth: usize,
}

/// Builds `n` cases from `zone` (deterministic for `seed`); `cross_sun` draws the rover's
/// sun independently of the map's, else both share one.
pub fn cases(world: &World, zone: &Zone, n: usize, seed: u64, cross_sun: bool) -> Vec<Case> {
    (0..n)
        .into_par_iter()
        .filter_map(|i| {
            let mut rng = StdRng::seed_from_u64(seed.wrapping_mul(31).wrapping_add(i as u64));
            let (x, y) = sample_in(zone, &mut rng, 200.0);
            let map_sun: Sun = random_sun(&mut rng);
            let view_sun = if cross_sun {
                random_sun(&mut rng)
            } else {
                map_sun
            };
            let aug = random_aug(&mut rng, 0.0);
            let rover = rover_input(world, x, y, view_sun, &aug, &mut rng)?;
            // Truth at window (tu, tv) of the grid.
            let (tu, tv) = (rng.random_range(0..GRID), rng.random_range(0..GRID));
            let half = (GRID / 2) as f64;
            let cx = x - (tu as f64 - half) * STRIDE_M;
            let cy = y + (tv as f64 - half) * STRIDE_M;
            let mpp = WINDOW_M / SAT_SIDE as f64;
            let step = (STRIDE_M / mpp).round() as usize;
            let side = SAT_SIDE + step * (GRID - 1);
            let region = render_ortho(world, cx, cy, side, mpp, map_sun);
            let mut windows = Vec::with_capacity(GRID * GRID);
            let mut crop = vec![0u8; SAT_SIDE * SAT_SIDE];
            for v in 0..GRID {
                for u in 0..GRID {
                    for r in 0..SAT_SIDE {
                        let s = (v * step + r) * side + u * step;
                        crop[r * SAT_SIDE..(r + 1) * SAT_SIDE]
                            .copy_from_slice(&region[s..s + SAT_SIDE]);
                    }
                    let mut w = [0i8; INPUT_LEN];
                    // A flat window stays all-zero: it scores 0 against anything.
                    let _ = prepare_input(&crop, None, SAT_SIDE, &mut w);
                    windows.push(w);
                }
            }
            Some(Case {
                rover,
                windows,
                truth: tv * GRID + tu,
            })
        })
        .collect()
}

fn ncc(a: &[i8], b: &[i8]) -> f32 {
    let (mut d, mut na, mut nb) = (0i64, 0i64, 0i64);
    for (&x, &y) in a.iter().zip(b) {
        if x != 0 {
            d += x as i64 * y as i64;
            na += x as i64 * x as i64;
            nb += y as i64 * y as i64;
        }
    }
    if na == 0 || nb == 0 {
        0.0
    } else {
        d as f32 / ((na as f32).sqrt() * (nb as f32).sqrt())
    }
}

/// Scores of every window of `case` (higher is better).
pub fn scores(scorer: &Scorer<'_>, case: &Case) -> Result<Vec<f32>> {
    Ok(match scorer {
        Scorer::MaskedNcc => case
            .windows
            .par_iter()
            .map(|w| ncc(&case.rover, w))
            .collect(),
        Scorer::Float(net) => {
            let r = net.embed(&batch_tensor(&[&case.rover])?)?;
            let mut out = Vec::with_capacity(case.windows.len());
            for chunk in case.windows.chunks(64) {
                let refs: Vec<&[i8; INPUT_LEN]> = chunk.iter().collect();
                let e = net.embed(&batch_tensor(&refs)?)?;
                out.extend(e.matmul(&r.t()?)?.flatten_all()?.to_vec1::<f32>()?);
            }
            out
        }
        Scorer::Int8(net) => {
            let zp = net.embedding_zero_point();
            let mut arena = Box::new(Arena::new());
            let mut er = [0i8; EMBED_LEN];
            net.embed(&case.rover, &mut arena, &mut er)
                .map_err(|e| anyhow::anyhow!("int8 embedding failed: {e}"))?;
            case.windows
                .par_iter()
                .map_init(
                    || Box::new(Arena::new()),
                    |arena, w| {
                        let mut ew = [0i8; EMBED_LEN];
                        net.embed(w, arena, &mut ew)
                            .map(|_| cosine_q15(&er, &ew, zp) as f32 / 32768.0)
                            .map_err(|e| anyhow::anyhow!("int8 embedding failed: {e}"))
                    },
                )
                .collect::<Result<Vec<f32>>>()?
        }
    })
}

/// Evaluates `scorer` on `cases`.
pub fn evaluate(scorer: &Scorer<'_>, cases: &[Case]) -> Result<Metrics> {
    let (mut r1, mut r5, mut r10) = (0usize, 0usize, 0usize);
    let mut errors = Vec::new();
    let (mut wins, mut pairs) = (0f64, 0f64);
    for case in cases {
        let s = scores(scorer, case)?;
        let t = s[case.truth];
        let better = s.iter().filter(|&&v| v > t).count();
        let ties = s.iter().filter(|&&v| v == t).count() - 1;
        // Rank with ties counted pessimistically.
        let rank = better + ties;
        r1 += (rank < 1) as usize;
        r5 += (rank < 5) as usize;
        r10 += (rank < 10) as usize;
        let best = s
            .iter()
            .enumerate()
            .fold((0, f32::MIN), |b, (i, &v)| if v > b.1 { (i, v) } else { b })
            .0;
        let (du, dv) = (
            (best % GRID) as f64 - (case.truth % GRID) as f64,
            (best / GRID) as f64 - (case.truth / GRID) as f64,
        );
        errors.push(du.hypot(dv) * STRIDE_M);
        for (i, &v) in s.iter().enumerate() {
            if i != case.truth {
                pairs += 1.0;
                wins += if t > v {
                    1.0
                } else if t == v {
                    0.5
                } else {
                    0.0
                };
            }
        }
    }
    let n = cases.len();
    errors.sort_by(|a, b| a.total_cmp(b));
    let pct = |p: f64| -> f64 {
        if errors.is_empty() {
            f64::NAN
        } else {
            errors[((errors.len() - 1) as f64 * p).round() as usize]
        }
    };
    let d = n.max(1) as f64;
    Ok(Metrics {
        n,
        recall_at_1: r1 as f64 / d,
        recall_at_5: r5 as f64 / d,
        recall_at_10: r10 as f64 / d,
        median_error_m: pct(0.5),
        p95_error_m: pct(0.95),
        pair_auc: if pairs > 0.0 { wins / pairs } else { f64::NAN },
    })
}
