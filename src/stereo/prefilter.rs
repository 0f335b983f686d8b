//! Reduction and pre-filtering of the stereo frames, one row at a time (integer).

use crate::image::ImageView;

/// Row `row` of `frame` reduced by `k` (1..=4; box average of `k x k` pixels, rounded) into
/// `out` (`frame.width() / k` pixels; a shorter `out` gets its first pixels, a longer one
/// keeps the rest). Rows past the reduced image (`row >= height / k`) leave `out` as is.
pub fn downsample_row(frame: &ImageView<'_>, k: usize, row: usize, out: &mut [u8]) {
    let k = k.clamp(1, 4);
    let w = frame.width().checked_div(k).unwrap_or(0);
    if k == 1 {
        if let Some(src) = frame.row(row) {
            for (o, &s) in out.iter_mut().zip(src).take(w) {
                *o = s;
            }
        }
        return;
    }
    let area = (k * k) as u32;
    let rows: [Option<&[u8]>; 4] = [
        frame.row(row * k),
        frame.row(row * k + 1),
        frame.row(row * k + 2),
        frame.row(row * k + 3),
    ];
    if rows.iter().take(k).any(|r| r.is_none()) {
        return;
    }
    for (i, o) in out.iter_mut().enumerate().take(w) {
        let mut s = 0u32;
        for r in rows.iter().take(k).flatten() {
            if let Some(b) = r.get(i * k..i * k + k) {
                s += b.iter().map(|&p| u32::from(p)).sum::<u32>();
            }
        }
        *o = (s + area / 2).checked_div(area).unwrap_or(0) as u8;
    }
}

/// Horizontal Sobel of the middle row of three (`above`, `mid`, `below`, equal lengths),
/// clipped to `±cap` and offset by `cap` (0..=2 cap) into `out`; the first and last columns
/// reuse their inner neighbour (replicated border).
pub fn prefilter(above: &[u8], mid: &[u8], below: &[u8], cap: u8, out: &mut [u8]) {
    let w = mid.len().min(above.len()).min(below.len()).min(out.len());
    if w == 0 {
        return;
    }
    let cap = i32::from(cap);
    let at = |r: &[u8], i: usize| r.get(i).map_or(0, |&p| i32::from(p));
    for (x, o) in out.iter_mut().enumerate().take(w) {
        let xl = x.saturating_sub(1);
        let xr = (x + 1).min(w - 1);
        let g = at(above, xr) - at(above, xl) + 2 * (at(mid, xr) - at(mid, xl)) + at(below, xr)
            - at(below, xl);
        *o = (g.clamp(-cap, cap) + cap) as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_blocks() {
        let mut buf = [0u8; 16];
        for (i, b) in buf.iter_mut().enumerate() {
            *b = (i * 10) as u8;
        }
        let img = ImageView::new(&buf, 4, 4).unwrap();
        let mut out = [0u8; 2];
        downsample_row(&img, 2, 0, &mut out);
        // (0 + 10 + 40 + 50) / 4 = 25, (20 + 30 + 60 + 70) / 4 = 45.
        assert_eq!(out, [25, 45]);
        downsample_row(&img, 2, 1, &mut out);
        assert_eq!(out, [105, 125]);
        let mut one = [0u8; 4];
        downsample_row(&img, 1, 3, &mut one);
        assert_eq!(one, [120, 130, 140, 150]);
    }

    #[test]
    fn sobel_is_clipped_and_offset() {
        let row = [10u8, 10, 20, 40, 40];
        let mut out = [0u8; 5];
        prefilter(&row, &row, &row, 31, &mut out);
        // x = 1: 4 * (20 - 10) = 40 -> clipped 31 -> 62; x = 0: 4 * (10 - 10) = 0 -> 31.
        assert_eq!(out, [31, 62, 62, 62, 31]);
        let flat = [7u8; 5];
        prefilter(&flat, &flat, &flat, 5, &mut out);
        assert_eq!(out, [5; 5]);
    }
}
