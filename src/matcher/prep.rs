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
    let (colsum, rest) = scratch.split_at_mut(w);
    let colcnt = &mut rest[..w];
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
            for (x, &v) in row.iter().enumerate() {
                if valid(x, y) {
                    if sign {
                        colsum[x] += v as u32;
                        colcnt[x] += 1;
                    } else {
                        colsum[x] -= v as u32;
                        colcnt[x] -= 1;
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
        for x in 0..radius.min(w) {
            s += colsum[x];
            c += colcnt[x];
        }
        let Some(orow) = out.row_mut(y) else {
            return Err(MatchError::WindowTooSmall);
        };
        for x in 0..w {
            if x + radius < w {
                s += colsum[x + radius];
                c += colcnt[x + radius];
            }
            if x > radius {
                s -= colsum[x - radius - 1];
                c -= colcnt[x - radius - 1];
            }
            orow[x] = if valid(x, y) && c > 0 {
                let mean = ((s + c / 2) / c) as i32;
                (128 + srow[x] as i32 - mean).clamp(0, 255) as u8
            } else {
                128
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
