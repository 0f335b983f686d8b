//! The coarse stage: Q15 cosines of the rover's embedding against every map-window record
//! (the response over the map product's window grid), its best peaks after non-maximum
//! suppression, and the one confidence of the fix.

use super::FixError;
use crate::localize::MAX_CANDIDATES;
use crate::nn::model::EMBED_LEN;
use crate::nn::window_cosine::{
    cosine_q15_window, cosine_q15_windows, TemplateStats, WindowRecord, WINDOWS_PER_PASS,
    WINDOW_RECORD_BYTES,
};

/// Writes the cosine (Q15) of `embedding` against every record into `response` (row-major,
/// one per record). Returns the number of windows scored.
#[inline(never)]
pub fn cosine_response(
    embedding: &[i8; EMBED_LEN],
    zp: i8,
    records: &[u8],
    response: &mut [i32],
) -> Result<usize, FixError> {
    let windows = records.len() / WINDOW_RECORD_BYTES;
    if windows == 0 || records.len() % WINDOW_RECORD_BYTES != 0 {
        return Err(FixError::MapMismatch {
            what: "window records are not a whole number of records",
        });
    }
    let out = response
        .get_mut(..windows)
        .ok_or(FixError::ScratchTooSmall { buffer: "response" })?;
    let stats = TemplateStats::new(embedding, zp);
    const PASS: usize = WINDOWS_PER_PASS;
    let groups = records.chunks_exact(PASS * WINDOW_RECORD_BYTES);
    let rest = groups.remainder();
    let mut dst = out.iter_mut();
    for g in groups {
        let mut ws = [WindowRecord::EMPTY; PASS];
        for (w, r) in ws.iter_mut().zip(g.chunks_exact(WINDOW_RECORD_BYTES)) {
            *w = WindowRecord::parse(r)?;
        }
        for c in cosine_q15_windows(embedding, &stats, &ws) {
            if let Some(d) = dst.next() {
                *d = c;
            }
        }
    }
    for r in rest.chunks_exact(WINDOW_RECORD_BYTES) {
        let w = WindowRecord::parse(r)?;
        if let Some(d) = dst.next() {
            *d = cosine_q15_window(embedding, &stats, &w);
        }
    }
    Ok(windows)
}

/// Best peaks of a `cols`-wide response after non-maximum suppression (Euclidean radius
/// `radius_cells` grid cells), best first: `(index, score)`; ties keep the lower index.
pub fn peaks(
    response: &[i32],
    cols: usize,
    radius_cells: f32,
    k: usize,
) -> heapless::Vec<(usize, i32), MAX_CANDIDATES> {
    let mut out: heapless::Vec<(usize, i32), MAX_CANDIDATES> = heapless::Vec::new();
    if cols == 0 {
        return out;
    }
    let r2 = radius_cells * radius_cells;
    let near = |a: usize, b: usize| {
        let (dc, dr) = (
            (a % cols).abs_diff(b % cols) as f32,
            (a / cols).abs_diff(b / cols) as f32,
        );
        dc * dc + dr * dr <= r2
    };
    while out.len() < k.min(MAX_CANDIDATES) {
        let mut best: Option<(usize, i32)> = None;
        for (i, &s) in response.iter().enumerate() {
            if best.is_some_and(|(_, b)| s <= b) {
                continue;
            }
            if !out.iter().any(|&(p, _)| near(p, i)) {
                best = Some((i, s));
            }
        }
        match best {
            Some(b) if out.push(b).is_ok() => {}
            _ => break,
        }
    }
    out
}

/// The fix's confidence, `[0, 1]`: `(s1 - s2) / (s1 - mean)` on the coarse response, with
/// `s1` the score of the chosen window, `s2` the best score farther than `radius_cells`
/// from it, and `mean` the mean score (0 when the response is flat or another window
/// scores at least as high).
pub fn confidence(response: &[i32], cols: usize, chosen: usize, radius_cells: f32) -> f32 {
    let (Some(&s1), true) = (response.get(chosen), cols > 0) else {
        return 0.0;
    };
    let r2 = radius_cells * radius_cells;
    let mut s2 = i32::MIN;
    let mut sum = 0i64;
    for (i, &s) in response.iter().enumerate() {
        sum += s as i64;
        let (dc, dr) = (
            (i % cols).abs_diff(chosen % cols) as f32,
            (i / cols).abs_diff(chosen / cols) as f32,
        );
        if dc * dc + dr * dr > r2 && s > s2 {
            s2 = s;
        }
    }
    let mean = sum as f32 / response.len() as f32;
    let (s1, s2) = (s1 as f32, s2 as f32);
    if s2 == i32::MIN as f32 || s1 - mean <= 1.0 {
        return 0.0;
    }
    ((s1 - s2) / (s1 - mean)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_are_suppressed_and_ordered() {
        let mut r = [0i32; 100];
        r[55] = 100;
        r[56] = 90;
        r[11] = 50;
        let p = peaks(&r, 10, 2.0, 3);
        assert_eq!(p[0], (55, 100));
        assert_eq!(p[1], (11, 50));
        assert_eq!(p.len(), 3);
        assert!(peaks(&r, 0, 2.0, 3).is_empty());
    }

    #[test]
    fn confidence_of_distinct_and_ambiguous_peaks() {
        let mut r = [0i32; 100];
        r[55] = 1000;
        assert_eq!(confidence(&r, 10, 55, 2.0), 1.0);
        r[11] = 1000;
        assert_eq!(confidence(&r, 10, 55, 2.0), 0.0);
        r[11] = 500;
        let c = confidence(&r, 10, 55, 2.0);
        assert!((c - 0.5 / (1.0 - 0.015)).abs() < 0.01, "{c}");
        assert_eq!(confidence(&[7; 100], 10, 3, 2.0), 0.0, "flat");
        assert_eq!(confidence(&r, 10, 500, 2.0), 0.0, "out of range");
    }
}
