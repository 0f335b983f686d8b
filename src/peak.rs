//! Sub-sample peak location: the vertex of the parabola through a maximum and its two
//! neighbours (one implementation, used by every stage that refines a peak).

/// Vertex offset, in samples, of the parabola through `(-1, l)`, `(0, c)`, `(1, r)`, where
/// `c` is the largest of the three; clamped to `[-0.5, 0.5]`. Returns 0 when the three do
/// not form a maximum (flat, convex, or not finite).
pub fn parabola_offset(l: f32, c: f32, r: f32) -> f32 {
    let den = l - 2.0 * c + r;
    if den >= 0.0 || !den.is_finite() {
        return 0.0;
    }
    let d = 0.5 * (l - r) / den;
    if d.is_finite() {
        d.clamp(-0.5, 0.5)
    } else {
        0.0
    }
}

/// Sub-sample offsets `(dx, dy)` of the maximum at `(c, r)` of a row-major `cols x rows`
/// response (`at(c, r)` reads it): a parabola per axis through the neighbours that exist
/// (0 on an edge).
pub fn peak_offset_2d<F: Fn(usize, usize) -> Option<f32>>(at: F, c: usize, r: usize) -> (f32, f32) {
    let Some(s) = at(c, r) else {
        return (0.0, 0.0);
    };
    let dx = match (c.checked_sub(1).and_then(|x| at(x, r)), at(c + 1, r)) {
        (Some(a), Some(b)) => parabola_offset(a, s, b),
        _ => 0.0,
    };
    let dy = match (r.checked_sub(1).and_then(|y| at(c, y)), at(c, r + 1)) {
        (Some(a), Some(b)) => parabola_offset(a, s, b),
        _ => 0.0,
    };
    (dx, dy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_of_a_sampled_parabola() {
        let f = |x: f32| -(x - 0.25) * (x - 0.25);
        let d = parabola_offset(f(-1.0), f(0.0), f(1.0));
        assert!((d - 0.25).abs() < 1e-5, "{d}");
        assert_eq!(parabola_offset(1.0, 1.0, 1.0), 0.0);
        assert_eq!(parabola_offset(0.0, -1.0, 0.0), 0.0, "a minimum is no peak");
        assert_eq!(parabola_offset(f32::NAN, 1.0, 0.0), 0.0);
    }

    #[test]
    fn two_dimensional_peak() {
        // 3 x 3 samples of -(x - 1.2)^2 - (y - 0.9)^2.
        let at = |c: usize, r: usize| {
            (c < 3 && r < 3).then(|| {
                let (x, y) = (c as f32 - 1.2, r as f32 - 0.9);
                -(x * x) - y * y
            })
        };
        let (dx, dy) = peak_offset_2d(at, 1, 1);
        assert!(
            (dx - 0.2).abs() < 1e-5 && (dy + 0.1).abs() < 1e-5,
            "{dx} {dy}"
        );
        // On an edge only the inner axis is refined.
        let (dx, _) = peak_offset_2d(at, 0, 1);
        assert_eq!(dx, 0.0);
    }
}
