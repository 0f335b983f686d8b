//! Sub-sample refinement of a sampled extremum by a parabola through three samples (one
//! implementation for the whole core): the float form for score maps (peaks of similarity:
//! the fix's refinement, the localizer) and the integer form for cost curves (minima of
//! matching costs: stereo disparity).

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

/// Offset of the minimum of the parabola through `(-1, l)`, `(0, c)`, `(1, r)` from the
/// middle sample, in units of `1 / one` sample (e.g. `one = 16`: Q4), rounded to nearest and
/// clamped to `[-one / 2, one / 2]`; 0 when the fit is not convex (`l + r <= 2 c`). Integer
/// only: the costs must satisfy `|l|, |c|, |r| < 2^24` and `one` lie in `1..=64` (outside
/// those, 0).
pub fn parabola_min_offset(l: i32, c: i32, r: i32, one: i32) -> i32 {
    min_offset(
        l,
        c,
        r,
        one,
        l.wrapping_add(r).wrapping_sub(c.wrapping_mul(2)),
    )
}

/// Sub-sample offset of the minimum of three integer costs `l`, `c`, `r` at -1, 0, +1 by
/// equiangular (V-shaped) line fitting: the two lines through the centre with opposite
/// slopes, the steeper side's slope, meet at `(l - r) / (2 (max(l, r) - c))`. The usual
/// fit for sums of absolute differences, whose cost is V-shaped around the true shift (the
/// parabola biases it towards whole samples). In units of `1 / one` (`one` in 1..=64),
/// rounded, in `[-one/2, one/2]`; 0 when `c` is not below both neighbours' larger one or
/// the costs are out of range (`|cost| >= 2^24`).
pub fn equiangular_min_offset(l: i32, c: i32, r: i32, one: i32) -> i32 {
    min_offset(l, c, r, one, l.max(r).wrapping_sub(c))
}

/// `(l - r) / (2 den)` samples, in units of `1 / one`, rounded half away from zero and
/// clamped to half a sample; 0 when `den <= 0` or the inputs are out of range (the two
/// fits above differ only in `den`, computed wrapping: it is used only in range).
#[inline(always)]
fn min_offset(l: i32, c: i32, r: i32, one: i32, den: i32) -> i32 {
    const LIM: i32 = 1 << 24;
    if !(1..=64).contains(&one) || l.abs() >= LIM || c.abs() >= LIM || r.abs() >= LIM {
        return 0;
    }
    if den <= 0 {
        return 0;
    }
    let num = (l - r) * one;
    let den2 = 2 * den;
    let q = if num >= 0 {
        (num + den) / den2
    } else {
        -((-num + den) / den2)
    };
    q.clamp(-one / 2, one / 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equiangular_fit_finds_the_apex_of_a_sampled_v() {
        // |x - 0.25| * 64 sampled at -1, 0, 1: apex at +0.25 = 4/16.
        let v = |x: f32| ((x - 0.25).abs() * 64.0) as i32;
        assert_eq!(equiangular_min_offset(v(-1.0), v(0.0), v(1.0), 16), 4);
        // The parabola through the same samples is pulled towards the whole sample.
        let p = parabola_min_offset(v(-1.0), v(0.0), v(1.0), 16);
        assert!(p < 4, "{p}");
        let w = |x: f32| ((x + 0.375).abs() * 64.0) as i32;
        assert_eq!(equiangular_min_offset(w(-1.0), w(0.0), w(1.0), 16), -6);
        // Flat or not a minimum: 0; bounded to half a sample.
        assert_eq!(equiangular_min_offset(5, 5, 5, 16), 0);
        assert_eq!(equiangular_min_offset(1, 5, 2, 16), 0);
        assert_eq!(equiangular_min_offset(100, 0, 0, 16), 8);
        assert_eq!(equiangular_min_offset(0, 0, 100, 16), -8);
        assert_eq!(equiangular_min_offset(1 << 25, 0, 0, 16), 0);
    }

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

    #[test]
    fn integer_minimum() {
        // c(x) = 100 (x - 0.3)^2 + 7 sampled at -1, 0, 1: vertex +0.3 -> 4.8/16 ~ 5.
        let f = |x: f64| (100.0 * (x - 0.3) * (x - 0.3) + 7.0).round() as i32;
        assert_eq!(parabola_min_offset(f(-1.0), f(0.0), f(1.0), 16), 5);
        let g = |x: f64| (100.0 * (x + 0.45) * (x + 0.45)).round() as i32;
        assert_eq!(parabola_min_offset(g(-1.0), g(0.0), g(1.0), 16), -7);
        // Flat or concave: no offset; clamped to half a sample.
        assert_eq!(parabola_min_offset(5, 5, 5, 16), 0);
        assert_eq!(parabola_min_offset(1, 5, 1, 16), 0);
        assert_eq!(parabola_min_offset(100, 0, 0, 16), 8);
        assert_eq!(parabola_min_offset(0, 0, 100, 16), -8);
        assert_eq!(parabola_min_offset(1, 0, 1, 0), 0);
    }
}
