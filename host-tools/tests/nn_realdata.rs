//! Real training pairs: built through the real pipeline, cached one file per location,
//! resumable, and a truncated cache file is a clear error.

use orbfix_host::nn::data::VAL_ZONE;
use orbfix_host::nn::realdata::{build, load, RealSpec, RECORD_LEN};

#[test]
fn real_set_builds_resumes_and_rejects_truncated_files() {
    let dir = std::env::temp_dir().join(format!("orbfix-realdata-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let spec = RealSpec {
        world_seed: 1,
        zone: VAL_ZONE,
        seed: 5,
        cross_sun_p: 0.5,
        missing_view_p: 0.5,
    };
    assert_eq!(build(&dir, &spec, 2, false).unwrap(), 2);
    // Resuming renders nothing new.
    assert_eq!(build(&dir, &spec, 2, false).unwrap(), 0);
    let set = load(&dir).unwrap();
    assert_eq!(set.len(), 2);
    for t in &set {
        // Real inputs: normalized, with contrast on both sides, and the rover differs from
        // its positive window (a different camera, reprojection, maybe sun).
        assert!(t.rover.iter().any(|&v| v != 0));
        assert!(t.positive.iter().any(|&v| v > 16) && t.positive.iter().any(|&v| v < -16));
        assert_ne!(t.rover, t.positive);
        assert_ne!(t.positive, t.hard_negative);
    }
    // A truncated file is rejected with a message naming it; rebuilding repairs it.
    let f = dir.join("loc_000001.bin");
    std::fs::write(&f, vec![0u8; RECORD_LEN / 2]).unwrap();
    let e = load(&dir).unwrap_err().to_string();
    assert!(e.contains("loc_000001.bin"), "{e}");
    assert_eq!(build(&dir, &spec, 2, false).unwrap(), 1);
    assert_eq!(load(&dir).unwrap().len(), 2);
    let _ = std::fs::remove_dir_all(&dir);
}
