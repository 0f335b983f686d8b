//! Real training pairs: built through the real pipeline, cached one file per location,
//! resumable, and a truncated cache file is a clear error.

use orbfix_host::nn::data::VAL_ZONE;
use orbfix_host::nn::realdata::{
    build, fixed_triplets, load, sample_triplet, RealSpec, Sampling, RECORD_LEN, RECORD_LEN_STEREO,
};
use rand::rngs::StdRng;
use rand::SeedableRng;

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
        stereo: false,
    };
    assert_eq!(build(&dir, &spec, 2, false).unwrap(), 2);
    // Resuming renders nothing new.
    assert_eq!(build(&dir, &spec, 2, false).unwrap(), 0);
    let set = load(&dir).unwrap();
    assert_eq!(set.len(), 2);
    let s = Sampling::default();
    let trips = fixed_triplets(&set, &s, 3);
    assert_eq!(trips.len(), 2);
    // Deterministic for the seed; another seed cuts other windows.
    let again = fixed_triplets(&set, &s, 3);
    assert!(trips
        .iter()
        .zip(&again)
        .all(|(a, b)| a.positive == b.positive));
    let mut rng = StdRng::seed_from_u64(99);
    let other = sample_triplet(&set[0], &s, &mut rng).unwrap();
    assert_eq!(*other.rover, set[0].rover);
    assert_ne!(other.hard_negative, trips[0].hard_negative);
    // Bad sampling radii are refused.
    let bad = Sampling {
        pos_radius_m: 6.0,
        neg_min_m: 5.0,
        neg_max_m: 25.0,
    };
    assert!(bad.check().is_err());
    assert!(Sampling {
        neg_max_m: 30.0,
        ..s
    }
    .check()
    .is_err());
    for t in &trips {
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

#[test]
fn a_stereo_set_keeps_the_fixs_own_stereo_input_beside_the_exact_one() {
    let dir = std::env::temp_dir().join(format!("orbfix-realstereo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let spec = RealSpec {
        world_seed: 1,
        zone: VAL_ZONE,
        seed: 11,
        cross_sun_p: 0.0,
        missing_view_p: 0.0,
        stereo: true,
    };
    assert_eq!(build(&dir, &spec, 2, false).unwrap(), 2);
    for i in 0..2 {
        let f = dir.join(format!("loc_{i:06}.bin"));
        assert_eq!(
            std::fs::metadata(&f).unwrap().len() as usize,
            RECORD_LEN_STEREO
        );
    }
    let set = load(&dir).unwrap();
    assert_eq!(set.len(), 2);
    for loc in &set {
        let st = loc.rover_stereo.expect("stereo input kept");
        // The stereo top-down image is the same place seen with other (sparser) depth:
        // normalized like the exact one, correlated with it, but not equal.
        assert_ne!(st, loc.rover);
        assert!(st.iter().any(|&v| v > 16) && st.iter().any(|&v| v < -16));
        let (a, b): (Vec<f64>, Vec<f64>) = loc
            .rover
            .iter()
            .zip(st.iter())
            .filter(|(&a, &b)| a != 0 && b != 0)
            .map(|(&a, &b)| (a as f64, b as f64))
            .unzip();
        let n = a.len() as f64;
        assert!(n > 400.0, "only {n} cells valid in both inputs");
        let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
        let cov: f64 = a.iter().zip(&b).map(|(x, y)| (x - ma) * (y - mb)).sum();
        let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
        let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
        let r = cov / (va * vb).sqrt();
        assert!(r > 0.5, "stereo and exact inputs correlate only {r:.2}");
    }
    // Batches draw both rover inputs.
    let s = Sampling::default();
    let mut rng = StdRng::seed_from_u64(5);
    let (mut exact, mut stereo) = (0, 0);
    for _ in 0..40 {
        let t = sample_triplet(&set[0], &s, &mut rng).unwrap();
        if *t.rover == set[0].rover {
            exact += 1;
        } else if Some(*t.rover) == set[0].rover_stereo {
            stereo += 1;
        }
    }
    assert!(
        exact > 5 && stereo > 5 && exact + stereo == 40,
        "{exact} / {stereo}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn training_on_real_crops_is_deterministic() {
    use orbfix_host::nn::train::{train, TrainConfig};
    let base = std::env::temp_dir().join(format!("orbfix-realtrain-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let set = base.join("set");
    let spec = RealSpec {
        world_seed: 1,
        zone: VAL_ZONE,
        seed: 8,
        cross_sun_p: 0.5,
        missing_view_p: 0.0,
        stereo: false,
    };
    assert_eq!(build(&set, &spec, 3, false).unwrap(), 3);
    let cfg = TrainConfig {
        world_seed: 1,
        seed: 4,
        steps: 2,
        batch: 2,
        lr: 1e-3,
        temperature: 0.1,
        cross_sun_p: 0.5,
        missing_view_p: 0.0,
        val_size: 3,
        checkpoint_every: 1,
        real_train: Some(set.clone()),
        real_val: Some(set.clone()),
        init: None,
        sampling: Sampling::default(),
    };
    let a = train(&base.join("a"), &cfg).unwrap();
    let b = train(&base.join("b"), &cfg).unwrap();
    let la: Vec<f64> = a.history.iter().map(|p| p.train_loss).collect();
    let lb: Vec<f64> = b.history.iter().map(|p| p.train_loss).collect();
    assert_eq!(la.len(), 2);
    assert!(la.iter().all(|l| l.is_finite() && *l > 0.0));
    assert_eq!(la, lb);
    // Radii the crop cannot hold are refused before training.
    let bad = TrainConfig {
        sampling: Sampling {
            neg_max_m: 40.0,
            ..Sampling::default()
        },
        ..cfg
    };
    assert!(train(&base.join("c"), &bad).is_err());
    let _ = std::fs::remove_dir_all(&base);
}
