//! Sub-sample refinement of a sampled extremum by a parabola through three samples.
//!
//! One helper for the whole core: the float form for score maps (peaks of similarity) and
//! the integer form for cost curves (minima of matching costs, e.g. stereo disparity).

/// Offset of the vertex of the parabola through `(-1, l)`, `(0, c)`, `(1, r)` from the
/// middle sample, in samples, clamped to `[-0.5, 0.5]`; 0 when `c` is not a strict maximum
/// of a concave fit or a value is not finite.
pub fn parabola(l: f32, c: f32, r: f32) -> f32 {
    let den = l - 2.0 * c + r;
    if den >= 0.0 || !den.is_finite() {
        return 0.0;
    }
    (0.5 * (l - r) / den).clamp(-0.5, 0.5)
}

/// Offset of the minimum of the parabola through `(-1, l)`, `(0, c)`, `(1, r)` from the
/// middle sample, in units of `1 / one` sample (e.g. `one = 16`: Q4), rounded to nearest and
/// clamped to `[-one / 2, one / 2]`; 0 when the fit is not convex (`l + r <= 2 c`). Integer
/// only: the costs must satisfy `|l|, |c|, |r| < 2^24` and `one` lie in `1..=64` (outside
/// those, 0).
pub fn parabola_min_offset(l: i32, c: i32, r: i32, one: i32) -> i32 {
    const LIM: i32 = 1 << 24;
    if !(1..=64).contains(&one) || l.abs() >= LIM || c.abs() >= LIM || r.abs() >= LIM {
        return 0;
    }
    let den = l + r - 2 * c;
    if den <= 0 {
        return 0;
    }
    // (l - r) / (2 den) samples, in units of 1/one, rounded half away from zero.
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
    fn float_vertex() {
        let f = |x: f32| -(x - 0.25) * (x - 0.25);
        assert!((parabola(f(-1.0), f(0.0), f(1.0)) - 0.25).abs() < 1e-5);
        assert_eq!(parabola(1.0, 1.0, 1.0), 0.0);
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
