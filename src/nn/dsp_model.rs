//! Portable models of the Armv7E-M DSP instructions that `nn::dsp` wraps (`SXTB16`,
//! `SXTAB16`, `SMLAD`), bit for bit as the Armv7-M Architecture Reference Manual defines
//! them, so that the host's unit tests run the DSP kernels of [`super::mat_mult`] and compare
//! them with the portable kernels. Test builds off Arm only.

/// Sign-extended int8 lane `i` (0..=3) of `x`, as an int16 bit pattern.
fn lane8(x: u32, i: u32) -> u32 {
    ((x >> (8 * i)) as u8 as i8 as i16 as u16) as u32
}

/// `SXTB16 x`.
pub(crate) fn sxtb16(x: u32) -> u32 {
    lane8(x, 0) | lane8(x, 2) << 16
}

/// `SXTB16 x, ROR #8`.
pub(crate) fn sxtb16_ror8(x: u32) -> u32 {
    lane8(x, 1) | lane8(x, 3) << 16
}

/// Adds two int16 lane pairs, each lane modulo `2^16`.
fn add16(a: u32, b: u32) -> u32 {
    let lo = (a as u16).wrapping_add(b as u16) as u32;
    let hi = ((a >> 16) as u16).wrapping_add((b >> 16) as u16) as u32;
    lo | hi << 16
}

/// `SXTAB16 a, x`.
pub(crate) fn sxtab16(a: u32, x: u32) -> u32 {
    add16(a, sxtb16(x))
}

/// `SXTAB16 a, x, ROR #8`.
pub(crate) fn sxtab16_ror8(a: u32, x: u32) -> u32 {
    add16(a, sxtb16_ror8(x))
}

/// `SMLAD acc, x, y` (the sum modulo `2^32`, as the instruction writes it).
pub(crate) fn smlad(acc: i32, x: u32, y: u32) -> i32 {
    let p = |s: u32| (x >> s) as u16 as i16 as i32 * ((y >> s) as u16 as i16 as i32);
    acc.wrapping_add(p(0)).wrapping_add(p(16))
}
