//! Metrics of an evaluation: recall@k, error percentiles, ROC / AUC and the best-threshold
//! error rate of match / non-match pair classification.

use serde::Serialize;

/// Share of queries whose true-window rank (0 = best) is below `k`.
pub fn recall_at(ranks: &[usize], k: usize) -> f64 {
    if ranks.is_empty() {
        return 0.0;
    }
    ranks.iter().filter(|&&r| r < k).count() as f64 / ranks.len() as f64
}

/// The `q`-quantile (`0..=1`) of `values` (linear interpolation); `NaN` when empty.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (i, f) = (pos.floor() as usize, pos - pos.floor());
    if i + 1 < v.len() {
        v[i] * (1.0 - f) + v[i + 1] * f
    } else {
        v[i]
    }
}

/// Match / non-match classification quality of pair scores (higher score = "match").
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PairStats {
    /// Area under the ROC curve (probability a matching pair outscores a non-matching one).
    pub auc: f64,
    /// Lowest classification error over all thresholds (share of pairs wrong, 50/50 pairs).
    pub error_rate: f64,
    /// Score threshold reaching `error_rate` (pairs scoring at least this are "match").
    pub threshold: f64,
    /// Matching pairs.
    pub positives: usize,
    /// Non-matching pairs.
    pub negatives: usize,
}

/// ROC curve points `(false positive rate, true positive rate)` from the strictest threshold
/// to the loosest.
pub fn roc(pos: &[f64], neg: &[f64]) -> Vec<(f64, f64)> {
    let mut all: Vec<(f64, bool)> = pos
        .iter()
        .map(|&s| (s, true))
        .chain(neg.iter().map(|&s| (s, false)))
        .collect();
    all.sort_by(|a, b| b.0.total_cmp(&a.0));
    let (np, nn) = (pos.len().max(1) as f64, neg.len().max(1) as f64);
    let (mut tp, mut fp) = (0usize, 0usize);
    let mut pts = vec![(0.0, 0.0)];
    let mut i = 0;
    while i < all.len() {
        let s = all[i].0;
        while i < all.len() && all[i].0 == s {
            if all[i].1 {
                tp += 1;
            } else {
                fp += 1;
            }
            i += 1;
        }
        pts.push((fp as f64 / nn, tp as f64 / np));
    }
    pts
}

/// AUC and best-threshold error of pair scores.
pub fn pair_stats(pos: &[f64], neg: &[f64]) -> PairStats {
    // AUC by the Mann-Whitney statistic (ties count half).
    let mut wins = 0.0;
    for &p in pos {
        for &n in neg {
            wins += if p > n {
                1.0
            } else if p == n {
                0.5
            } else {
                0.0
            };
        }
    }
    let total = (pos.len() * neg.len()).max(1) as f64;
    let auc = wins / total;
    // Threshold sweep: classify "match" when score >= t.
    let mut ts: Vec<f64> = pos.iter().chain(neg).copied().collect();
    ts.sort_by(f64::total_cmp);
    ts.push(f64::INFINITY);
    let n = (pos.len() + neg.len()).max(1) as f64;
    let (mut best_err, mut best_t) = (f64::INFINITY, f64::NAN);
    for &t in &ts {
        let fn_ = pos.iter().filter(|&&p| p < t).count();
        let fp = neg.iter().filter(|&&q| q >= t).count();
        let e = (fn_ + fp) as f64 / n;
        if e < best_err {
            best_err = e;
            best_t = t;
        }
    }
    PairStats {
        auc,
        error_rate: best_err,
        threshold: best_t,
        positives: pos.len(),
        negatives: neg.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recall_and_quantiles() {
        assert_eq!(recall_at(&[0, 3, 9, 20], 1), 0.25);
        assert_eq!(recall_at(&[0, 3, 9, 20], 10), 0.75);
        assert_eq!(quantile(&[1.0, 2.0, 3.0, 4.0], 0.5), 2.5);
        assert_eq!(quantile(&[5.0], 0.95), 5.0);
        assert!(quantile(&[], 0.5).is_nan());
    }

    #[test]
    fn pairs_separable_and_random() {
        let s = pair_stats(&[0.9, 0.8, 0.7], &[0.1, 0.2, 0.3]);
        assert_eq!(s.auc, 1.0);
        assert_eq!(s.error_rate, 0.0);
        assert!(s.threshold > 0.3 && s.threshold <= 0.7);
        let s = pair_stats(&[0.5, 0.5], &[0.5, 0.5]);
        assert_eq!(s.auc, 0.5);
        assert_eq!(s.error_rate, 0.5);
        let s = pair_stats(&[0.1, 0.2], &[0.8, 0.9]);
        assert_eq!(s.auc, 0.0);
        assert_eq!(s.error_rate, 0.5);
        let r = roc(&[0.9, 0.1], &[0.5]);
        assert_eq!(r, vec![(0.0, 0.0), (0.0, 0.5), (1.0, 0.5), (1.0, 1.0)]);
    }
}
