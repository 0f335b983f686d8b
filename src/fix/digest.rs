//! One 32-bit digest of everything a fix produced, for the bit-exactness check between the
//! target and the host (FNV-1a, 32 bit).

use super::{FixReport, FixScratch};
use crate::reproject::FrameStatus;

const FNV_OFFSET: u32 = 0x811c_9dc5;
const FNV_PRIME: u32 = 0x0100_0193;

/// FNV-1a (32-bit) of `bytes`, continuing from `h` (start with [`fnv1a_start`]).
pub fn fnv1a(mut h: u32, bytes: &[u8]) -> u32 {
    for &b in bytes {
        h = (h ^ b as u32).wrapping_mul(FNV_PRIME);
    }
    h
}

/// The FNV-1a start value.
pub const fn fnv1a_start() -> u32 {
    FNV_OFFSET
}

fn words(mut h: u32, w: &[u32]) -> u32 {
    for v in w {
        h = fnv1a(h, &v.to_le_bytes());
    }
    h
}

fn status_code(s: FrameStatus) -> u32 {
    match s {
        FrameStatus::Ok => 0,
        FrameStatus::Missing => 1,
        FrameStatus::Black => 2,
        FrameStatus::Saturated => 3,
    }
}

/// Digest of a report and of the images it was made from (top-down image, mask, coarse
/// response and embedding in `scratch`): equal on the target and the host iff every
/// output bit is.
pub fn output_digest(r: &FixReport, scratch: &FixScratch<'_>, n: usize) -> u32 {
    let cells = n * n;
    let mut h = fnv1a(fnv1a_start(), scratch.top.get(..cells).unwrap_or_default());
    h = fnv1a(h, scratch.mask.get(..cells).unwrap_or_default());
    for v in scratch.response.iter().take(r.windows as usize) {
        h = fnv1a(h, &v.to_le_bytes());
    }
    h = fnv1a(h, &scratch.nn_embedding.map(|v| v as u8));
    let s = r.reprojection.status;
    h = words(
        h,
        &[
            r.x_m.to_bits(),
            r.y_m.to_bits(),
            r.error_bound_m.to_bits(),
            r.confidence.to_bits(),
            r.status.code(),
            r.path as u32,
            r.score.to_bits(),
            r.best_window,
            r.cnn_best_window,
            r.cnn_best_q15 as u32,
            r.windows,
            r.reprojection.range as u32,
            status_code(s[0]),
            status_code(s[1]),
            status_code(s[2]),
            status_code(s[3]),
            r.reprojection.valid_cells as u32,
            r.reprojection.stereo.map_or(0, |s| {
                s.iter()
                    .enumerate()
                    .map(|(i, e)| u32::from(e.is_some()) << (i + 1))
                    .sum::<u32>()
                    | 1
            }),
            r.coverage_permille,
        ],
    );
    for c in &r.candidates {
        h = words(
            h,
            &[
                c.x_m.to_bits(),
                c.y_m.to_bits(),
                c.score.to_bits(),
                c.refined as u32,
                c.coarse.to_bits(),
            ],
        );
    }
    let o = &r.ops;
    for v in [
        o.lut_cells,
        o.reproject_px,
        o.embed_macs,
        o.match_elements,
        o.refine_macs,
        o.stereo_pixel_disparities,
        o.stereo_cost_updates,
        o.stereo_px,
        o.stereo_depth_px,
    ] {
        h = fnv1a(h, &v.to_le_bytes());
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_reference_values() {
        assert_eq!(fnv1a(fnv1a_start(), b""), 0x811c_9dc5);
        assert_eq!(fnv1a(fnv1a_start(), b"a"), 0xe40c_292c);
        assert_eq!(fnv1a(fnv1a_start(), b"foobar"), 0xbf9c_f968);
    }
}
