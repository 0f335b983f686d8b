//! Requantization of int32 accumulators to int8 (TFLite / gemmlowp conventions).
//!
//! A real multiplier `M = scale_in * scale_w / scale_out` is stored as a Q0.31 fixed-point
//! `multiplier` in `[2^30, 2^31)` and a power-of-two `shift` (positive: left shift), so that
//! `M = multiplier / 2^31 * 2^shift`. Rounding is gemmlowp's: to nearest; exact halves go up
//! (towards +infinity) in the doubling high multiply and away from zero in the rounding right
//! shift.

/// Smallest valid shift (a right shift by 31).
pub const SHIFT_MIN: i32 = -31;
/// Largest valid shift (a left shift by 30).
pub const SHIFT_MAX: i32 = 30;

/// `floor(a * b / 2^31 + 1/2)` (round half up) with saturation (gemmlowp
/// `SaturatingRoundingDoublingHighMul`).
///
/// The only overflowing input, `a == b == i32::MIN`, saturates to `i32::MAX`.
#[inline(always)]
pub fn saturating_rounding_doubling_high_mul(a: i32, b: i32) -> i32 {
    if a == i32::MIN && b == i32::MIN {
        return i32::MAX;
    }
    let ab = (a as i64) * (b as i64);
    let nudge: i64 = if ab >= 0 { 1 << 30 } else { 1 - (1 << 30) };
    // Division truncates towards zero, as in C++.
    ((ab + nudge) / (1i64 << 31)) as i32
}

/// `round(x / 2^exponent)`, halves away from zero (gemmlowp `RoundingDivideByPOT`).
///
/// `exponent` must lie in `0..=31`; larger values are clamped to 31.
#[inline(always)]
pub fn rounding_divide_by_pot(x: i32, exponent: i32) -> i32 {
    let e = exponent.clamp(0, 31) as u32;
    let mask: i32 = ((1i64 << e) - 1) as i32;
    let remainder = x & mask;
    let threshold = (mask >> 1) + i32::from(x < 0);
    (x >> e) + i32::from(remainder > threshold)
}

/// `x * multiplier / 2^31 * 2^shift`, TFLite `MultiplyByQuantizedMultiplier`.
///
/// `multiplier` is Q0.31; `shift` in [`SHIFT_MIN`]`..=`[`SHIFT_MAX`] (positive: left).
#[inline(always)]
pub fn multiply_by_quantized_multiplier(x: i32, multiplier: i32, shift: i32) -> i32 {
    let left = if shift > 0 { shift } else { 0 };
    let right = if shift > 0 { 0 } else { -shift };
    let shifted = x.wrapping_mul(1i32.wrapping_shl(left as u32));
    rounding_divide_by_pot(
        saturating_rounding_doubling_high_mul(shifted, multiplier),
        right,
    )
}

/// Requantizes one accumulator to an int8 output: scale, add the output zero point, clamp
/// to `[act_min, act_max]` (the fused activation, e.g. ReLU is `act_min = zero point`).
#[inline(always)]
pub fn requantize(
    acc: i32,
    multiplier: i32,
    shift: i32,
    output_offset: i32,
    act_min: i32,
    act_max: i32,
) -> i8 {
    let v = multiply_by_quantized_multiplier(acc, multiplier, shift).saturating_add(output_offset);
    // max-then-min equals `clamp` for act_min <= act_max (validated with the weights)
    // without clamp's panic path for act_min > act_max.
    v.max(act_min).min(act_max) as i8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn high_mul_rounds_half_up() {
        // 2^30 * 1 / 2^31 = 0.5 -> 1
        assert_eq!(saturating_rounding_doubling_high_mul(1 << 30, 1), 1);
        // gemmlowp rounds exact halves up (towards +infinity) here: -0.5 -> 0, -1.5 -> -1.
        assert_eq!(saturating_rounding_doubling_high_mul(-(1 << 30), 1), 0);
        assert_eq!(saturating_rounding_doubling_high_mul(-3 << 29, 2), -1);
        assert_eq!(
            saturating_rounding_doubling_high_mul(i32::MIN, i32::MIN),
            i32::MAX
        );
        assert_eq!(
            saturating_rounding_doubling_high_mul(1 << 20, 1 << 30),
            1 << 19
        );
    }

    #[test]
    fn divide_by_pot_rounds_half_away_from_zero() {
        assert_eq!(rounding_divide_by_pot(5, 1), 3);
        assert_eq!(rounding_divide_by_pot(-5, 1), -3);
        assert_eq!(rounding_divide_by_pot(4, 1), 2);
        assert_eq!(rounding_divide_by_pot(7, 2), 2);
        assert_eq!(rounding_divide_by_pot(-7, 2), -2);
        assert_eq!(rounding_divide_by_pot(6, 2), 2);
        assert_eq!(rounding_divide_by_pot(-6, 2), -2);
        assert_eq!(rounding_divide_by_pot(123, 0), 123);
    }

    #[test]
    fn multiplier_half_scales_by_half() {
        // multiplier 2^30 = 0.5 in Q0.31, shift 0.
        assert_eq!(multiply_by_quantized_multiplier(100, 1 << 30, 0), 50);
        assert_eq!(multiply_by_quantized_multiplier(101, 1 << 30, 0), 51);
        assert_eq!(multiply_by_quantized_multiplier(-101, 1 << 30, 0), -50);
        assert_eq!(multiply_by_quantized_multiplier(-103, 1 << 30, 0), -51);
        // 0.5 * 2^-3 = 1/16
        assert_eq!(multiply_by_quantized_multiplier(160, 1 << 30, -3), 10);
        // 0.5 * 2^2 = 2
        assert_eq!(multiply_by_quantized_multiplier(21, 1 << 30, 2), 42);
    }

    #[test]
    fn requantize_clamps() {
        assert_eq!(requantize(10_000, 1 << 30, 0, 0, -128, 127), 127);
        assert_eq!(requantize(-10_000, 1 << 30, 0, 0, -128, 127), -128);
        assert_eq!(requantize(-10, 1 << 30, 0, -3, -3, 127), -3);
    }
}
