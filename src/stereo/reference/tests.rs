//! Tests of the band matcher against the scalar reference: the same disparities on random
//! pairs, and the same image however the stream is cut into bands.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::super::band;
use super::super::{StereoParams, StereoRig, SubPixel};
use super::{ref_words_len, BandReport, Output};
use crate::camera::CameraParams;
use crate::image::ImageView;

/// A small linear congruential generator (deterministic test data).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 33) as u32
    }

    fn below(&mut self, n: u32) -> u32 {
        self.next() % n.max(1)
    }
}

const FRAME_MAX: usize = 640 * 360;
const BYTES_MAX: usize = 2 * 640 * 16;
const WORDS_MAX: usize = 40_000;
const OUT_MAX: usize = 320 * 180;

/// A random textured left frame and a right frame shifted by a disparity growing down
/// the image (plus noise, some flat patches and a few saturated pixels).
fn pair(rng: &mut Lcg, w: usize, h: usize, max_shift: usize, l: &mut [u8], r: &mut [u8]) {
    for (i, p) in l.iter_mut().enumerate().take(w * h) {
        let (x, y) = (i % w, i / w);
        // Flat patches: textureless windows the gap test rejects.
        *p = if (x / 24 + y / 24) % 5 == 0 {
            90
        } else {
            (30 + rng.below(200)) as u8
        };
    }
    for y in 0..h {
        let s = max_shift * y / h;
        for x in 0..w {
            let src = l[y * w + (x + s).min(w - 1)];
            let noise = rng.below(9) as i32 - 4;
            r[y * w + x] = (i32::from(src) + noise).clamp(0, 255) as u8;
        }
    }
    for _ in 0..20 {
        let i = rng.below((w * h) as u32) as usize;
        r[i] = 255;
    }
}

/// Rows `y0..y1` by the band matcher into `new` and by the reference into `old`.
#[allow(clippy::too_many_arguments)]
fn run_both(
    rig: &StereoRig,
    l: &ImageView<'_>,
    r: &ImageView<'_>,
    y0: usize,
    y1: usize,
    mode: Output,
    new: &mut [u16],
    old: &mut [u16],
) -> (BandReport, BandReport) {
    let s = rig.buffer_sizes();
    let (w, _) = rig.output_size();
    let mut bytes = [0u8; BYTES_MAX];
    let mut words = [0xa5a5u16; WORDS_MAX];
    let n = (y1 - y0) * w;
    new[..n].fill(1);
    let a = band::run(
        rig,
        l,
        Some(r),
        y0,
        y1,
        &mut bytes[..s.bytes],
        &mut words[..s.words],
        &mut new[..n],
        mode,
    )
    .unwrap();
    bytes.fill(0);
    words.fill(0x5a5a);
    old[..n].fill(2);
    let b = super::run(
        rig,
        l,
        Some(r),
        y0,
        y1,
        &mut bytes[..s.bytes],
        &mut words[..ref_words_len(rig)],
        &mut old[..n],
        mode,
    )
    .unwrap();
    (a, b)
}

#[test]
fn lane_matcher_equals_the_scalar_reference_on_random_pairs() {
    let mut rng = Lcg(11);
    let mut compared = 0u64;
    let (mut valid, mut cases, mut coarse) = (0u64, 0u32, [0u64; 2]);
    let (mut lbuf, mut rbuf) = ([0u8; FRAME_MAX], [0u8; FRAME_MAX]);
    let (mut new, mut old) = ([0u16; OUT_MAX], [0u16; OUT_MAX]);
    for case in 0..32 {
        // Case 0: the default rig and settings at the default frame size.
        let (cam, p) = if case == 0 {
            (CameraParams::default(), StereoParams::default())
        } else {
            let cam = CameraParams {
                width_px: 160 + 16 * rng.below(7),
                height_px: 96 + 8 * rng.below(12),
                hfov_deg: 60.0 + rng.below(40) as f32,
                height_m: 1.5 + 0.1 * rng.below(10) as f32,
                tilt_deg: 10.0 + rng.below(20) as f32,
            };
            let cs = 1 + rng.below(2) as u8;
            let rv = 1 + rng.below(7) as u8;
            let p = StereoParams {
                baseline_m: 0.2 + 0.1 * rng.below(8) as f32,
                downsample: 1 + rng.below(2) as u8,
                radius_px: 1 + rng.below(7) as u8,
                row_factor: 1 + rng.below(2) as u8,
                column_step: cs,
                near_column_step: cs + rng.below(5 - u32::from(cs)) as u8,
                near_column_span_m: [0.0, 0.25, 1.0, 100.0][rng.below(4) as usize],
                pair_rows_m: [0.0, 0.25, 1.0, 100.0][rng.below(4) as usize],
                pair_radius_rows_px: 1 + rng.below(u32::from(rv)) as u8,
                radius_rows_px: rv,
                prefilter_cap: [1, 15, 31, 63][rng.below(4) as usize],
                uniqueness_pct: rng.below(30) as u8,
                min_gap_per_px: rng.below(3) as u8,
                lr_check: rng.below(4) != 0,
                subpixel: [SubPixel::Parabola, SubPixel::Equiangular][rng.below(2) as usize],
                min_support: rng.below(5) as u8,
                gap_fill_px: [0, 0, 1, 4, 16][rng.below(5) as usize],
                relief_below_m: 0.5 + 0.5 * rng.below(4) as f32,
                scale_levels: rng.below(3) as u8,
                scale_error_m: [0.0, 0.1, 0.3, 1.0][rng.below(4) as usize],
                horizon_grade: [0.0, 0.0, 0.2, 0.4][rng.below(4) as usize],
                horizon_coarse: rng.below(2) == 0,
                ..StereoParams::default()
            };
            (cam, p)
        };
        let Ok(rig) = StereoRig::new(&cam, &p) else {
            continue;
        };
        let (fw, fh) = (cam.width_px as usize, cam.height_px as usize);
        let (w, h) = rig.output_size();
        let shift = rig.ranges().global_max() * usize::from(p.downsample);
        let sizes = rig.buffer_sizes();
        if fw * fh > FRAME_MAX
            || sizes.bytes > BYTES_MAX
            || sizes.words > WORDS_MAX
            || ref_words_len(&rig) > WORDS_MAX
            || w * h > OUT_MAX
        {
            continue;
        }
        pair(&mut rng, fw, fh, shift, &mut lbuf, &mut rbuf);
        let lv = ImageView::new(&lbuf[..fw * fh], fw, fh).unwrap();
        let rv = ImageView::new(&rbuf[..fw * fh], fw, fh).unwrap();
        for _ in 0..3 {
            let y0 = rng.below(h as u32) as usize;
            let y1 = (y0 + 1 + rng.below(h as u32) as usize).min(h);
            let mode = if rng.below(2) == 0 {
                Output::DisparityQ4
            } else {
                Output::DepthMm
            };
            let (a, b) = run_both(&rig, &lv, &rv, y0, y1, mode, &mut new, &mut old);
            // The same outcome counts; the column-cost work differs by design (the
            // stream keeps each row's groups, the reference the band's union).
            let work = |r: BandReport| BandReport {
                cost_updates: 0,
                ..r
            };
            assert_eq!(work(a), work(b), "case {case}: counts of rows {y0}..{y1}");
            assert!(a.cost_updates > 0 || a.rows_matched == 0);
            let n = (y1 - y0) * w;
            assert!(
                new[..n] == old[..n],
                "case {case}: output of rows {y0}..{y1}"
            );
            compared += n as u64;
            valid += a.valid;
            cases += 1;
            for y in y0..y1 {
                let l = rig.scales().level_of_row(y);
                if let Some(c) = coarse.get_mut(l.wrapping_sub(1)) {
                    let row = &new[(y - y0) * w..(y - y0 + 1) * w];
                    *c += row.iter().filter(|&&v| v != 0).count() as u64;
                }
            }
        }
    }
    // The comparison saw real matches, not only empty rows, at both coarser levels.
    assert!(
        cases >= 30 && compared > 20_000 && valid > 2_000,
        "{cases} {compared} {valid}"
    );
    assert!(coarse[0] > 1_000 && coarse[1] > 1_000, "{coarse:?}");
}

#[test]
fn a_stream_cut_anywhere_equals_the_reference_image() {
    let mut rng = Lcg(5);
    let (mut lbuf, mut rbuf) = ([0u8; FRAME_MAX], [0u8; FRAME_MAX]);
    let (mut new, mut old) = ([0u16; OUT_MAX], [0u16; OUT_MAX]);
    let mut streamed = 0u64;
    for case in 0..4 {
        let cam = CameraParams::default();
        let p = StereoParams {
            scale_levels: case as u8 % 3,
            scale_error_m: [0.125, 0.3, 1.0, 0.2][case],
            // Rows reduced by two more (a shorter window down) in two cases.
            row_factor: 1 + (case as u8 & 1),
            radius_rows_px: [3, 1, 3, 2][case],
            // Every other column decided in two cases; every second, third or fourth
            // in the near rows in three.
            column_step: [1, 2, 2, 1][case],
            near_column_step: [1, 4, 2, 3][case],
            near_column_span_m: [0.25, 0.25, 0.5, 1.0][case],
            // Near rows of the working size in pairs in three cases.
            pair_rows_m: [0.25, 0.0, 0.5, 1.0][case],
            pair_radius_rows_px: [2, 1, 1, 2][case],
            // Short gaps of the output rows filled in two cases.
            gap_fill_px: [0, 8, 0, 3][case],
            // The horizon rows searched in two cases.
            horizon_grade: [0.0, 0.3, 0.0, 0.2][case],
            // In pairs in one of them.
            horizon_coarse: case == 1,
            ..StereoParams::default()
        };
        let rig = StereoRig::new(&cam, &p).unwrap();
        let (w, h) = rig.output_size();
        let shift = rig.ranges().global_max() * usize::from(p.downsample);
        pair(&mut rng, 640, 360, shift, &mut lbuf, &mut rbuf);
        let lv = ImageView::new(&lbuf[..640 * 360], 640, 360).unwrap();
        let rv = ImageView::new(&rbuf[..640 * 360], 640, 360).unwrap();
        let s = rig.buffer_sizes();
        let (mut bytes, mut words) = ([0u8; BYTES_MAX], [0u16; WORDS_MAX]);
        // The reference: the whole image as one band.
        let mut rbytes = [0u8; BYTES_MAX];
        let mut rwords = [0u16; WORDS_MAX];
        super::run(
            &rig,
            &lv,
            Some(&rv),
            0,
            h,
            &mut rbytes[..s.bytes],
            &mut rwords[..ref_words_len(&rig)],
            &mut old[..w * h],
            Output::DisparityQ4,
        )
        .unwrap();
        // The stream: bands of random heights (odd ones split coarse rows), now and
        // then one row back (a coarse row finished twice) or a jump (a fresh start).
        new[..w * h].fill(7);
        let mut view = rig
            .view(&lv, Some(&rv), &mut bytes[..s.bytes], &mut words[..s.words])
            .unwrap();
        let mut y0 = 0;
        while y0 < h {
            let y1 = (y0 + 1 + rng.below(23) as usize).min(h);
            view.disparity_rows(y0, y1, &mut new[y0 * w..y1 * w])
                .unwrap();
            y0 = match rng.below(6) {
                0 if y1 > 1 && y1 < h => y1 - 1,
                1 => (y1 + 3).min(h),
                _ => y1,
            };
            if y0 > y1 {
                // Rows skipped by the jump: match them on their own.
                let y = y1;
                view.disparity_rows(y, y0, &mut new[y * w..y0 * w]).unwrap();
            }
        }
        assert!(new[..w * h] == old[..w * h], "case {case}");
        streamed += new[..w * h].iter().filter(|&&v| v != 0).count() as u64;
    }
    assert!(streamed > 20_000, "{streamed}");
}
