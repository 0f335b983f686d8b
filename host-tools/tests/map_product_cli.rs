//! `orbfix map --product`: the file the rover carries, written by the command and read back
//! by the core's own validation, as the fix reads it.

use orbfix::map_product::{CrcCheck, MapProduct, MapProductError};
use orbfix::nn::model::SHIPPED_WEIGHTS;
use std::path::Path;
use std::process::{Command, Output};

fn orbfix(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_orbfix"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the orbfix binary runs")
}

/// `orbfix map` of a `size_m` region with its product, as `NAME.png` + `NAME.ofm` in `dir`.
fn map_with_product(dir: &Path, size_m: &str, name: &str) -> Output {
    let (png, ofm) = (format!("{name}.png"), format!("{name}.ofm"));
    let args = [
        "map",
        "--x",
        "3000",
        "--y",
        "2000",
        "--size-m",
        size_m,
        "--out",
        &png,
        "--product",
        &ofm,
    ];
    orbfix(dir, &args)
}

#[test]
fn the_written_product_validates_and_holds_the_png_pixels() {
    let dir = tempfile::tempdir().unwrap();
    // 60 m at 0.25 m/px: 240 x 240 px, a 3 x 3 grid of 200 px windows every 16 px.
    let o = map_with_product(dir.path(), "60", "m");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(dir.path().join("m.ofm")).unwrap();
    let product = MapProduct::parse(&bytes, CrcCheck::Verify).expect("the product validates");
    let meta = *product.meta();
    assert_eq!((meta.width, meta.height), (240, 240));
    assert_eq!((meta.window_px, meta.step_px), (200, 16));
    assert_eq!(meta.weights_crc, orbfix::fix::weights_crc(SHIPPED_WEIGHTS));
    assert_eq!(
        meta.plane,
        orbfix::fix::FixConfig::default().refine_plane().unwrap()
    );
    let sun = meta.sun_deg.expect("a rendered map records its sun");
    assert_eq!(sun, (30.0, 135.0));
    let png = image::open(dir.path().join("m.png")).unwrap().to_luma8();
    assert_eq!(product.map().data(), png.as_raw().as_slice());
    assert_eq!(product.records().len(), 9 * 2056);

    // One flipped bit anywhere is refused by the CRC.
    let mut bad = bytes.clone();
    let at = bad.len() / 2;
    bad[at] ^= 0x10;
    assert!(matches!(
        MapProduct::parse(&bad, CrcCheck::Verify),
        Err(MapProductError::CrcMismatch { .. })
    ));
}

#[test]
fn a_map_narrower_than_the_window_is_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let o = map_with_product(dir.path(), "30", "s");
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("raise --size-m"), "{err}");
    assert!(!dir.path().join("s.png").exists(), "nothing is written");
    assert!(!dir.path().join("s.ofm").exists(), "nothing is written");
}
