//! Range-ring brightness equalization of a top-down image (integer only).
//!
//! Ground views see the surface obliquely, the orbiter from above: with a lunar-Lambert
//! surface the same ground looks brighter the farther it is from the rover (growing emission
//! angle), a radial trend the satellite crop does not have. This step removes it: every ring
//! of equal ground distance from the rover is scaled so that its mean equals the mean of the
//! whole valid image. Optional; [`super::Lut::apply`] never does it by itself.

/// Most rings [`equalize_rings`] uses (its working arrays: 3 KiB on the stack).
pub const MAX_RINGS: usize = 128;

/// Scales the valid cells (`mask == 255`) of an `n x n` top-down image so that every ring
/// `ring_cells` cells wide around the grid centre has the mean gray level of the whole valid
/// image (gains in Q8, clamped to 1/4 .. 4). Rings beyond [`MAX_RINGS`] are merged into the
/// last one. Returns the number of rings used, or `None` (image untouched) if the buffers are
/// not `n * n` long, `ring_cells` is 0 or no cell is valid.
pub fn equalize_rings(out: &mut [u8], mask: &[u8], n: usize, ring_cells: u32) -> Option<usize> {
    let cells = n.checked_mul(n)?;
    if out.len() != cells || mask.len() != cells || ring_cells == 0 || n == 0 {
        return None;
    }
    let ring_of = |col: usize, row: usize| -> usize {
        // Distance from the grid centre in half-cell units (integer square root).
        let dx = (2 * col + 1).abs_diff(n) as u64;
        let dy = (2 * row + 1).abs_diff(n) as u64;
        let r = (dx * dx + dy * dy).isqrt();
        ((r / (2 * u64::from(ring_cells))) as usize).min(MAX_RINGS - 1)
    };
    let mut sum = [0u64; MAX_RINGS];
    let mut count = [0u64; MAX_RINGS];
    let (mut total_sum, mut total_count) = (0u64, 0u64);
    let mut used = 0usize;
    for (row, (orow, mrow)) in out.chunks_exact(n).zip(mask.chunks_exact(n)).enumerate() {
        for (col, (&v, &m)) in orow.iter().zip(mrow).enumerate() {
            if m == 255 {
                let k = ring_of(col, row);
                if let (Some(s), Some(c)) = (sum.get_mut(k), count.get_mut(k)) {
                    *s += u64::from(v);
                    *c += 1;
                }
                total_sum += u64::from(v);
                total_count += 1;
                used = used.max(k + 1);
            }
        }
    }
    if total_count == 0 || total_sum == 0 {
        return None;
    }
    // gain_k = (total_sum / total_count) / (sum_k / count_k), Q8.
    let mut gain = [256u32; MAX_RINGS];
    for ((g, &s), &c) in gain.iter_mut().zip(sum.iter()).zip(count.iter()) {
        if s > 0 {
            let q = (total_sum * c * 256) / (total_count * s);
            *g = q.clamp(64, 1024) as u32;
        }
    }
    for (row, (orow, mrow)) in out
        .chunks_exact_mut(n)
        .zip(mask.chunks_exact(n))
        .enumerate()
    {
        for (col, (v, &m)) in orow.iter_mut().zip(mrow).enumerate() {
            if m == 255 {
                let g = gain.get(ring_of(col, row)).copied().unwrap_or(256);
                *v = ((u32::from(*v) * g + 128) >> 8).min(255) as u8;
            }
        }
    }
    Some(used)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removes_a_radial_trend_and_keeps_texture() {
        let n = 40;
        let mut img = [0u8; 1600];
        let mask = [255u8; 1600];
        for row in 0..n {
            for col in 0..n {
                let dx = col as i32 - 20;
                let dy = row as i32 - 20;
                let r = (dx * dx + dy * dy) as u32;
                let texture = if (col + row) % 2 == 0 { 10 } else { 0 };
                img[row * n + col] = (60 + r / 8 + texture) as u8;
            }
        }
        let rings = equalize_rings(&mut img, &mask, n, 2).unwrap();
        assert!(rings >= 10);
        // Ring means now agree within 3 levels; the checkerboard survives.
        let near = (img[20 * n + 20] as i32 + img[20 * n + 21] as i32) / 2;
        let far = (img[20 * n + 36] as i32 + img[20 * n + 37] as i32) / 2;
        assert!((near - far).abs() <= 4, "{near} {far}");
        assert!(img[20 * n + 36].abs_diff(img[20 * n + 37]) >= 6);
        assert_eq!(equalize_rings(&mut img, &mask[..10], n, 2), None);
        assert_eq!(equalize_rings(&mut img, &[0u8; 1600], n, 2), None);
    }
}
