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

/// The model of `nn::dsp::mac_2x2`: the same reads, products and pointer steps.
///
/// # Safety
/// As `nn::dsp::mac_2x2`: `*col` points to four readable, aligned `u32`, `*wa` and `*wb`
/// to four readable bytes each.
pub(crate) unsafe fn mac_2x2(
    acc: &mut [i32; 4],
    col: &mut *const u32,
    wa: &mut *const i8,
    wb: &mut *const i8,
) {
    // Safety: the caller guarantees every read below is inside its buffer.
    let (c, x, y) = unsafe {
        (
            [
                col.read(),
                col.add(1).read(),
                col.add(2).read(),
                col.add(3).read(),
            ],
            wa.cast::<u32>().read_unaligned(),
            wb.cast::<u32>().read_unaligned(),
        )
    };
    let [a0, a1, b0, b1] = acc;
    let (ea, oa, eb, ob) = (sxtb16(x), sxtb16_ror8(x), sxtb16(y), sxtb16_ror8(y));
    *a0 = smlad(smlad(*a0, c[0], ea), c[2], oa);
    *a1 = smlad(smlad(*a1, c[1], ea), c[3], oa);
    *b0 = smlad(smlad(*b0, c[0], eb), c[2], ob);
    *b1 = smlad(smlad(*b1, c[1], eb), c[3], ob);
    // Safety: one past the four values read, inside or one past the caller's buffers.
    unsafe {
        *col = col.add(4);
        *wa = wa.add(4);
        *wb = wb.add(4);
    }
}
