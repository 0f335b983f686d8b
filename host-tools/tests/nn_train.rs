//! Training plumbing: candle's CPU conv2d backward is right, training is deterministic for a
//! seed, resumes from its run directory, and quantization yields a file the core accepts.

use candle_core::{Device, Tensor, Var};
use orbfix::nn::model::SiameseNet;
use orbfix_host::nn::data::{triplet, VAL_ZONE};
use orbfix_host::nn::float_model::FloatNet;
use orbfix_host::nn::quantize::{calibrate, quantize};
use orbfix_host::nn::train::{checkpoint_path, train, TrainConfig};
use orbfix_host::world::World;

#[test]
fn candle_conv2d_backward_matches_finite_differences() {
    let dev = Device::Cpu;
    let x = Tensor::from_vec(
        (0..2 * 36)
            .map(|i| ((i * 37 % 11) as f32 - 5.0) / 5.0)
            .collect::<Vec<_>>(),
        (1, 2, 6, 6),
        &dev,
    )
    .unwrap();
    let w0: Vec<f32> = (0..3 * 2 * 9)
        .map(|i| ((i * 13 % 7) as f32 - 3.0) / 4.0)
        .collect();
    let w = Var::from_tensor(&Tensor::from_vec(w0.clone(), (3, 2, 3, 3), &dev).unwrap()).unwrap();
    let f = |w: &Tensor| -> Tensor {
        x.conv2d(w, 1, 2, 1, 1)
            .unwrap()
            .sqr()
            .unwrap()
            .sum_all()
            .unwrap()
    };
    let g = f(w.as_tensor()).backward().unwrap();
    let grad = g
        .get(&w)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1::<f32>()
        .unwrap();
    for i in [0usize, 7, 20, 53] {
        let eps = 1e-2f32;
        let mut wp = w0.clone();
        wp[i] += eps;
        let mut wm = w0.clone();
        wm[i] -= eps;
        let fp = f(&Tensor::from_vec(wp, (3, 2, 3, 3), &dev).unwrap())
            .to_scalar::<f32>()
            .unwrap();
        let fm = f(&Tensor::from_vec(wm, (3, 2, 3, 3), &dev).unwrap())
            .to_scalar::<f32>()
            .unwrap();
        let num = (fp - fm) / (2.0 * eps);
        assert!(
            (num - grad[i]).abs() < 1e-2 * (1.0 + num.abs()),
            "w[{i}]: numeric {num} vs autograd {}",
            grad[i]
        );
    }
}

fn cfg(steps: u64) -> TrainConfig {
    TrainConfig {
        world_seed: 1,
        seed: 3,
        steps,
        batch: 4,
        lr: 1e-3,
        temperature: 0.1,
        cross_sun_p: 0.5,
        missing_view_p: 0.2,
        val_size: 4,
        checkpoint_every: 1,
        real_train: None,
        real_val: None,
        init: None,
        sampling: Default::default(),
    }
}

#[test]
fn training_is_deterministic_resumable_and_quantizable() {
    let base = std::env::temp_dir().join(format!("orbfix-nn-train-{}", std::process::id()));
    let (a, b) = (base.join("a"), base.join("b"));
    let _ = std::fs::remove_dir_all(&base);
    let sa = train(&a, &cfg(2)).unwrap();
    let sb = train(&b, &cfg(2)).unwrap();
    assert_eq!(sa.step, 2);
    let la: Vec<f64> = sa.history.iter().map(|p| p.train_loss).collect();
    let lb: Vec<f64> = sb.history.iter().map(|p| p.train_loss).collect();
    assert_eq!(la, lb, "same seed, same losses");
    assert!(la.iter().all(|l| l.is_finite() && *l > 0.0));
    assert_eq!(
        std::fs::read(checkpoint_path(&a)).unwrap(),
        std::fs::read(checkpoint_path(&b)).unwrap()
    );
    // Resume to 3 steps.
    let s3 = train(&a, &cfg(3)).unwrap();
    assert_eq!(s3.step, 3);
    assert_eq!(s3.history.len(), 3);
    // Quantize the checkpoint: the core accepts the file.
    let net = FloatNet::load(&checkpoint_path(&a)).unwrap();
    let world = World::new(1);
    let calib: Vec<_> = (0..4)
        .flat_map(|i| {
            let t = triplet(&world, &VAL_ZONE, 9, i, 0.5, 0.0);
            [*t.rover, *t.positive]
        })
        .collect();
    let q = quantize(&net, &calibrate(&net, &calib).unwrap()).unwrap();
    assert!(SiameseNet::from_bytes(&q.to_bytes()).is_ok());
    // A corrupted checkpoint is a clear error, not a panic.
    std::fs::write(checkpoint_path(&b), b"garbage").unwrap();
    assert!(FloatNet::load(&checkpoint_path(&b)).is_err());
    let _ = std::fs::remove_dir_all(&base);
}
