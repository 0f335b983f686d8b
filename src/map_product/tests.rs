//! Tests of the map product: files written by [`super::write_header`] and its siblings
//! read back, and damaged files refused.
//!
//! Unit tests: the parent declares this module under `#[cfg(test)]`, so it is never part
//! of a flight build.

use super::*;

fn build(buf: &mut [u8; 4096], w: usize, h: usize, n: usize, step: usize) -> usize {
    let meta = MapProductMeta {
        geo: GeoRef::new(100.0, 200.0, 0.25).unwrap(),
        width: w,
        height: h,
        window_px: n,
        step_px: step,
        weights_crc: 0xdead_beef,
        sun_deg: Some((30.0, 135.0)),
        plane: RefinePlane::new(8, true).unwrap(),
        relief_block_px: 0,
    };
    let l = write_header(&meta, buf).unwrap();
    for (i, p) in buf[l.pixels_at..l.pixels_at + w * h].iter_mut().enumerate() {
        *p = i as u8;
    }
    seal(&mut buf[..l.total]).unwrap();
    l.total
}

#[test]
fn round_trip_and_every_damage_is_caught() {
    let mut buf = [0u8; 4096];
    // A 9 x 9 map with one 9 px window: header, 81 pixels, 81 plane, 2 padding, one
    // record, CRC.
    let l = MapProductLayout::new(9, 9, 9, 1).unwrap();
    assert_eq!((l.cols, l.rows), (1, 1));
    let total = build(&mut buf, 9, 9, 9, 1);
    assert_eq!(total, l.total);
    let p = MapProduct::parse(&buf[..total], CrcCheck::Verify).unwrap();
    assert_eq!(p.meta().width, 9);
    assert_eq!(p.meta().sun_deg, Some((30.0, 135.0)));
    assert_eq!(p.meta().weights_crc, 0xdead_beef);
    assert_eq!(p.meta().plane, RefinePlane::new(8, true).unwrap());
    assert_eq!((p.plane().width(), p.plane().height()), (9, 9));
    assert_eq!(p.records().len(), WINDOW_RECORD_BYTES);
    assert_eq!(p.map().get(3, 1), Some(12));
    // Every single-bit flip is caught (by the CRC).
    for byte in 0..total {
        for bit in 0..8 {
            buf[byte] ^= 1 << bit;
            assert!(MapProduct::parse(&buf[..total], CrcCheck::Verify).is_err());
            buf[byte] ^= 1 << bit;
        }
    }
    // Truncation.
    assert!(matches!(
        MapProduct::parse(&buf[..total - 1], CrcCheck::Verify),
        Err(MapProductError::CrcMismatch { .. })
    ));
    assert!(matches!(
        MapProduct::parse(&buf[..10], CrcCheck::Verify),
        Err(MapProductError::Truncated { got: 10 })
    ));
    // A plane radius of 0 or a rectification flag of 2, with a valid CRC, is refused.
    buf[60] = 0;
    seal(&mut buf[..total]).unwrap();
    assert_eq!(
        MapProduct::parse(&buf[..total], CrcCheck::Verify).unwrap_err(),
        MapProductError::BadField {
            field: "refinement plane radius"
        }
    );
    buf[60] = 8;
    buf[62] = 2;
    seal(&mut buf[..total]).unwrap();
    assert!(MapProduct::parse(&buf[..total], CrcCheck::Verify).is_err());
    buf[62] = 1;
    // A header lie with a valid CRC is caught by the structure checks.
    buf[40] = 7;
    seal(&mut buf[..total]).unwrap();
    assert_eq!(
        MapProduct::parse(&buf[..total], CrcCheck::Verify).unwrap_err(),
        MapProductError::BadField {
            field: "window columns"
        }
    );
}

#[test]
fn relief_plane_round_trip_and_version_2() {
    // A 12 x 12 map, 8 px windows every 2 px: 3 x 3 windows, 4 blocks per window side,
    // a 6 x 6 relief plane.
    let meta = MapProductMeta {
        geo: GeoRef::new(100.0, 200.0, 0.25).unwrap(),
        width: 12,
        height: 12,
        window_px: 8,
        step_px: 2,
        weights_crc: 1,
        sun_deg: None,
        plane: RefinePlane::new(8, true).unwrap(),
        relief_block_px: 2,
    };
    let l = MapProductLayout::of(&meta).unwrap();
    assert_eq!(
        (l.cols, l.relief_cols, l.relief_rows, l.relief_blocks),
        (3, 6, 6, 4)
    );
    assert_eq!(l.total, l.relief_at + 72 + 4);
    let mut buf = [0u8; 32 * 1024];
    write_header(&meta, &mut buf).unwrap();
    for k in 0..36 {
        let v = (k as i16 - 18) * 100;
        buf[l.relief_at + 2 * k..l.relief_at + 2 * k + 2].copy_from_slice(&v.to_le_bytes());
    }
    seal(&mut buf[..l.total]).unwrap();
    let p = MapProduct::parse(&buf[..l.total], CrcCheck::Verify).unwrap();
    assert_eq!(p.meta().relief_block_px, 2);
    let r = p.relief().unwrap();
    assert_eq!((r.cols(), r.rows(), r.blocks()), (6, 6, 4));
    assert_eq!(r.get(0, 0), Some(-1800));
    assert_eq!(r.get(5, 5), Some(1700));
    assert_eq!(r.get(6, 0), None);
    assert_eq!(r.get(0, 6), None);
    // A block side other than the step, or not a power of two, is refused.
    for bad in [4usize, 3] {
        let m = MapProductMeta {
            relief_block_px: bad,
            step_px: 3,
            ..meta
        };
        assert!(MapProductLayout::of(&m).is_err());
    }
    // Version 2 (no relief) is still read; version 2 with a relief field is refused.
    let mut b2 = [0u8; 4096];
    let total = build(&mut b2, 9, 9, 9, 1);
    b2[4] = 2;
    seal(&mut b2[..total]).unwrap();
    let p = MapProduct::parse(&b2[..total], CrcCheck::Verify).unwrap();
    assert!(p.relief().is_none());
    b2[6] = 1;
    seal(&mut b2[..total]).unwrap();
    assert!(MapProduct::parse(&b2[..total], CrcCheck::Verify).is_err());
}

#[test]
fn hostile_headers_are_refused() {
    assert!(MapProductLayout::new(0, 10, 1, 1).is_err());
    assert!(MapProductLayout::new(10, 10, 11, 1).is_err());
    assert!(MapProductLayout::new(10, 10, 5, 0).is_err());
    assert!(MapProductLayout::new(usize::MAX, 10, 5, 1).is_err());
    // An origin of 1e38 m cannot be built, nor read from a file with a valid CRC.
    assert!(GeoRef::new(1.0e38, 0.0, 0.25).is_err());
    let mut buf = [0u8; 4096];
    let total = build(&mut buf, 9, 9, 9, 1);
    buf[20..24].copy_from_slice(&1.0e38f32.to_bits().to_le_bytes());
    seal(&mut buf[..total]).unwrap();
    assert_eq!(
        MapProduct::parse(&buf[..total], CrcCheck::Verify).unwrap_err(),
        MapProductError::BadField { field: "origin" }
    );
}
