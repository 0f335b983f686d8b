//! Pre-processing shared by matchers: a masked high-pass (local mean removal) that takes
//! away the broad brightness gradients a grazing ground view has and an orbital view has not.
//!
//! `out = clamp(128 + (v - mean_r(v)), 0, 255)` where `mean_r` is the mean of the valid
//! pixels of the `(2r + 1) x (2r + 1)` box around the pixel (clipped at the image edges);
//! invalid pixels (mask 0) are written as 128 and excluded from every mean. Integer
//! arithmetic, separable running sums: `O(width * height)` time and two caller-provided
//! `u32` rows of scratch (`width` each).

use super::MatchError;
use crate::image::{ImageView, ImageViewMut};

/// Scratch `u32` elements [`highpass`] needs for an image `width` pixels wide.
pub const fn highpass_buffer_len(width: usize) -> usize {
    2 * width
}

/// Rectifies a high-passed image in place, `min(255, 2 |v - 128|)`: edge strength instead of
/// signed contrast, which survives a change of sun azimuth (shadows flip sides, edges stay).
pub fn rectify(img: &mut ImageViewMut<'_>) {
    for y in 0..img.height() {
        if let Some(row) = img.row_mut(y) {
            for v in row.iter_mut() {
                *v = (2 * (*v as i32 - 128).unsigned_abs()).min(255) as u8;
            }
        }
    }
}

/// Masked high-pass of `src` into `out` with box radius `radius` pixels (see the module
/// doc). `mask`: `None` = all valid. `scratch`: at least [`highpass_buffer_len`] elements.
///
/// A radius beyond the image is the whole image (the box is clipped at the edges anyway).
/// The running sums are `u32`: a box of more than `u32::MAX / 255` pixels (about 4104 x 4104)
/// is [`MatchError::TooLarge`].
pub fn highpass(
    src: &ImageView<'_>,
    mask: Option<&ImageView<'_>>,
    radius: usize,
    out: &mut ImageViewMut<'_>,
    scratch: &mut [u32],
) -> Result<(), MatchError> {
    let (w, h) = (src.width(), src.height());
    if out.width() != w || out.height() != h {
        return Err(MatchError::MaskSizeMismatch);
    }
    if let Some(m) = mask {
        if m.width() != w || m.height() != h {
            return Err(MatchError::MaskSizeMismatch);
        }
    }
    if scratch.len() < highpass_buffer_len(w) {
        return Err(MatchError::OutputTooSmall {
            needed: highpass_buffer_len(w),
        });
    }
    // A box wider than the image is the whole image: clamping keeps `y + radius` from
    // wrapping and changes no output.
    let radius = radius.min(w.max(h));
    let side = radius.saturating_mul(2).saturating_add(1);
    let box_px = side.min(w).saturating_mul(side.min(h));
    if box_px > (u32::MAX / 255) as usize {
        return Err(MatchError::TooLarge);
    }
    if mask.is_none() {
        return highpass_unmasked(src, radius, out, scratch);
    }
    let (colsum, rest) = scratch
        .split_at_mut_checked(w)
        .ok_or(MatchError::OutputTooSmall {
            needed: highpass_buffer_len(w),
        })?;
    let colcnt = rest.get_mut(..w).ok_or(MatchError::OutputTooSmall {
        needed: highpass_buffer_len(w),
    })?;
    colsum.fill(0);
    colcnt.fill(0);
    let valid = |x: usize, y: usize| -> bool {
        match mask {
            None => true,
            Some(m) => m.get(x, y).is_some_and(|v| v != 0),
        }
    };
    let add_row = |y: usize, sign: bool, colsum: &mut [u32], colcnt: &mut [u32]| {
        if let Some(row) = src.row(y) {
            for (x, ((&v, s), c)) in row
                .iter()
                .zip(colsum.iter_mut())
                .zip(colcnt.iter_mut())
                .enumerate()
            {
                if valid(x, y) {
                    if sign {
                        *s += v as u32;
                        *c += 1;
                    } else {
                        *s -= v as u32;
                        *c -= 1;
                    }
                }
            }
        }
    };
    // Prime rows 0..radius.
    for y in 0..radius.min(h) {
        add_row(y, true, colsum, colcnt);
    }
    for y in 0..h {
        if y + radius < h {
            add_row(y + radius, true, colsum, colcnt);
        }
        if y > radius {
            add_row(y - radius - 1, false, colsum, colcnt);
        }
        let Some(srow) = src.row(y) else {
            return Err(MatchError::WindowTooSmall);
        };
        // Horizontal running sums over colsum / colcnt.
        let (mut s, mut c) = (0u32, 0u32);
        for (cs, cc) in colsum.iter().zip(colcnt.iter()).take(radius.min(w)) {
            s += cs;
            c += cc;
        }
        let Some(orow) = out.row_mut(y) else {
            return Err(MatchError::WindowTooSmall);
        };
        for (x, (o, &v)) in orow.iter_mut().zip(srow).enumerate() {
            if let (Some(a), Some(b)) = (colsum.get(x + radius), colcnt.get(x + radius)) {
                s += a;
                c += b;
            }
            if let Some(k) = x.checked_sub(radius + 1) {
                if let (Some(a), Some(b)) = (colsum.get(k), colcnt.get(k)) {
                    s -= a;
                    c -= b;
                }
            }
            *o = match (s + c / 2).checked_div(c) {
                Some(mean) if valid(x, y) => (128 + v as i32 - mean as i32).clamp(0, 255) as u8,
                _ => 128,
            };
        }
    }
    Ok(())
}

/// [`highpass`] without a mask: every pixel valid, so a box's count is its clipped area
/// (rows times columns) and only the column sums are kept. Same result to the bit.
fn highpass_unmasked(
    src: &ImageView<'_>,
    radius: usize,
    out: &mut ImageViewMut<'_>,
    scratch: &mut [u32],
) -> Result<(), MatchError> {
    let (w, h) = (src.width(), src.height());
    let colsum = scratch.get_mut(..w).ok_or(MatchError::OutputTooSmall {
        needed: highpass_buffer_len(w),
    })?;
    colsum.fill(0);
    let add = |y: usize, colsum: &mut [u32]| {
        if let Some(row) = src.row(y) {
            for (s, &v) in colsum.iter_mut().zip(row) {
                *s += v as u32;
            }
        }
    };
    let sub = |y: usize, colsum: &mut [u32]| {
        if let Some(row) = src.row(y) {
            for (s, &v) in colsum.iter_mut().zip(row) {
                *s -= v as u32;
            }
        }
    };
    for y in 0..radius.min(h) {
        add(y, colsum);
    }
    for y in 0..h {
        if y + radius < h {
            add(y + radius, colsum);
        }
        if let Some(k) = y.checked_sub(radius.saturating_add(1)) {
            sub(k, colsum);
        }
        let rows = (y + radius).min(h - 1) + 1 - y.saturating_sub(radius);
        let (Some(srow), Some(orow)) = (src.row(y), out.row_mut(y)) else {
            return Err(MatchError::WindowTooSmall);
        };
        let mut s: u32 = colsum.iter().take(radius.min(w)).sum();
        for (x, (o, &v)) in orow.iter_mut().zip(srow).enumerate() {
            if let Some(a) = colsum.get(x + radius) {
                s += a;
            }
            if let Some(a) = x
                .checked_sub(radius.saturating_add(1))
                .and_then(|k| colsum.get(k))
            {
                s -= a;
            }
            let cols = (x + radius).min(w - 1) + 1 - x.saturating_sub(radius);
            let c = (rows * cols) as u32;
            *o = match (s + c / 2).checked_div(c) {
                Some(mean) => (128 + v as i32 - mean as i32).clamp(0, 255) as u8,
                None => 128,
            };
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removes_gradients_and_keeps_detail() {
        // A ramp plus one bright pixel: the ramp goes to ~128, the pixel stays bright.
        let mut img = [0u8; 20 * 20];
        for y in 0..20 {
            for x in 0..20 {
                img[y * 20 + x] = (x * 10) as u8;
            }
        }
        img[10 * 20 + 10] = 255;
        let src = ImageView::new(&img, 20, 20).unwrap();
        let mut out = [0u8; 400];
        let mut o = ImageViewMut::new(&mut out, 20, 20).unwrap();
        let mut scratch = [0u32; 40];
        highpass(&src, None, 2, &mut o, &mut scratch).unwrap();
        assert!((out[5 * 20 + 5] as i32 - 128).abs() <= 1);
        assert!(out[10 * 20 + 10] > 200);
        // The unmasked path equals the masked one with an all-valid mask, for every radius.
        let all = [255u8; 400];
        let av = ImageView::new(&all, 20, 20).unwrap();
        for r in [1, 2, 5, 19, 40] {
            let mut a = [0u8; 400];
            let mut b = [0u8; 400];
            highpass(
                &src,
                None,
                r,
                &mut ImageViewMut::new(&mut a, 20, 20).unwrap(),
                &mut scratch,
            )
            .unwrap();
            highpass(
                &src,
                Some(&av),
                r,
                &mut ImageViewMut::new(&mut b, 20, 20).unwrap(),
                &mut scratch,
            )
            .unwrap();
            assert_eq!(a, b, "radius {r}");
        }
        // Brute-force reference with a mask.
        let mut m = [255u8; 400];
        m[3 * 20 + 4] = 0;
        m[7 * 20 + 7] = 0;
        let mv = ImageView::new(&m, 20, 20).unwrap();
        let mut o = ImageViewMut::new(&mut out, 20, 20).unwrap();
        highpass(&src, Some(&mv), 3, &mut o, &mut scratch).unwrap();
        assert!(highpass(&src, None, 2, &mut o, &mut scratch[..10]).is_err());
        highpass(&src, Some(&mv), 3, &mut o, &mut scratch).unwrap();
        // A huge radius is the whole image (no wrap): every valid pixel is v - global mean.
        let mut whole = [0u8; 400];
        let mut ow = ImageViewMut::new(&mut whole, 20, 20).unwrap();
        highpass(&src, None, usize::MAX, &mut ow, &mut scratch).unwrap();
        let mut whole19 = [0u8; 400];
        let mut o19 = ImageViewMut::new(&mut whole19, 20, 20).unwrap();
        highpass(&src, None, 19, &mut o19, &mut scratch).unwrap();
        assert_eq!(whole, whole19);
        let total: u32 = img.iter().map(|&v| v as u32).sum();
        let mean = ((total + 200) / 400) as i32;
        assert_eq!(whole[7], (128 + img[7] as i32 - mean).clamp(0, 255) as u8);
        let mut o = ImageViewMut::new(&mut out, 20, 20).unwrap();
        highpass(&src, Some(&mv), 3, &mut o, &mut scratch).unwrap();
        for y in 0..20i32 {
            for x in 0..20i32 {
                let i = (y * 20 + x) as usize;
                if m[i] == 0 {
                    assert_eq!(out[i], 128);
                    continue;
                }
                let (mut s, mut c) = (0u32, 0u32);
                for yy in (y - 3).max(0)..=(y + 3).min(19) {
                    for xx in (x - 3).max(0)..=(x + 3).min(19) {
                        let j = (yy * 20 + xx) as usize;
                        if m[j] != 0 {
                            s += img[j] as u32;
                            c += 1;
                        }
                    }
                }
                let want = (128 + img[i] as i32 - ((s + c / 2) / c) as i32).clamp(0, 255);
                assert_eq!(out[i] as i32, want, "({x}, {y})");
            }
        }
    }
}
