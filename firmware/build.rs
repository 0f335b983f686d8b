//! Puts memory.x (repository root) on the linker path and copies the test vectors from
//! $ORBFIX_VECTORS_DIR (written by `orbfix budget`) into OUT_DIR for `include!`.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest =
        PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let memory_x = manifest.join("../memory.x");
    fs::copy(&memory_x, out.join("memory.x"))
        .unwrap_or_else(|e| panic!("cannot copy {}: {e}", memory_x.display()));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());

    println!("cargo:rerun-if-env-changed=ORBFIX_VECTORS_DIR");
    let dir = env::var("ORBFIX_VECTORS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| {
            panic!(
            "ORBFIX_VECTORS_DIR is not set: the firmware embeds test vectors made by the host. \
             Run `orbfix budget` (it writes them and builds this crate), or \
             `orbfix budget --vectors-dir DIR` once and set ORBFIX_VECTORS_DIR=DIR."
        )
        });
    for name in [
        "vectors.rs",
        "frames.bin",
        "depths.bin",
        "rights.bin",
        "product.bin",
        "weights.bin",
    ] {
        let src = dir.join(name);
        fs::copy(&src, out.join(name)).unwrap_or_else(|e| {
            panic!(
                "cannot copy test vector {}: {e} (regenerate with `orbfix budget`)",
                src.display()
            )
        });
        println!("cargo:rerun-if-changed={}", src.display());
    }
}
