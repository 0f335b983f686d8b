//! `orbfix train`: contrastive training of the float siamese trunk on pairs generated on
//! the fly from the world's training zone, validated on the disjoint validation zone.

use anyhow::Result;
use orbfix_host::nn::train::{checkpoint_path, train, TrainConfig};
use std::path::PathBuf;

/// Train the siamese CNN matcher (float, CPU). Resumes from --out if it holds a run.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Run directory (checkpoint.safetensors, state.json).
    #[arg(long, default_value = "runs/matcher")]
    pub out: PathBuf,
    /// World seed.
    #[arg(long, default_value_t = 1)]
    pub world_seed: u64,
    /// Seed of initialization and training data.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Optimizer steps.
    #[arg(long, default_value_t = 600)]
    pub steps: u64,
    /// Anchors per batch (each brings a positive and a hard negative window).
    #[arg(long, default_value_t = 32)]
    pub batch: usize,
    /// Peak learning rate (AdamW, cosine decay).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 2e-3)]
    pub lr: f64,
    /// InfoNCE temperature.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 0.07)]
    pub temperature: f64,
    /// Probability that the rover's sun differs from the map's.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::probability_f64, default_value_t = 0.5)]
    pub cross_sun_p: f64,
    /// Probability of one missing view.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::probability_f64, default_value_t = 0.15)]
    pub missing_view_p: f64,
    /// Validation anchors.
    #[arg(long, default_value_t = 128)]
    pub val_size: usize,
    /// Steps between validations and checkpoints.
    #[arg(long, default_value_t = 50)]
    pub checkpoint_every: u64,
    /// Train on REAL pairs: build (resumably) this many training-zone locations through the
    /// real pipeline (rendered views + core range reprojection vs the map renderer's
    /// satellite windows) under --real-dir, then draw batches from them (0 = proxy pairs).
    #[arg(long, default_value_t = 0)]
    pub real_train: usize,
    /// Validation-zone locations of the real set (used with --real-train).
    #[arg(long, default_value_t = 64)]
    pub real_val: usize,
    /// Cache of the real set (train/ and val/ subfolders, one file per location).
    #[arg(long, default_value = "runs/realdata2")]
    pub real_dir: PathBuf,
    /// Real set with stereo pairs: each location also keeps the rover input the fix makes
    /// from its own stereo depth, and batches draw it or the exact-depth one with equal
    /// probability (a set built without it is rebuilt: the file size differs).
    #[arg(long)]
    pub real_stereo: bool,
    /// Only build the real set, do not train.
    #[arg(long)]
    pub build_only: bool,
    /// Start from this float checkpoint (fine-tuning) instead of a fresh initialization.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// Real set: largest offset of the positive window's centre from the truth, metres.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 2.5)]
    pub pos_radius_m: f64,
    /// Real set: smallest offset of the hard negative window's centre, metres.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::non_negative_f64, default_value_t = 5.0)]
    pub neg_min_m: f64,
    /// Real set: largest offset of the hard negative window's centre, metres (<= 25).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 25.0)]
    pub neg_max_m: f64,
}

pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!(
        (0.0..=1.0).contains(&a.cross_sun_p) && (0.0..=1.0).contains(&a.missing_view_p),
        "--cross-sun-p and --missing-view-p are probabilities in 0..1"
    );
    anyhow::ensure!(
        a.lr.is_finite() && a.lr > 0.0 && a.temperature.is_finite() && a.temperature > 0.0,
        "--lr and --temperature must be positive numbers"
    );
    let (mut real_train, mut real_val) = (None, None);
    if a.real_train > 0 {
        use orbfix_host::nn::data::{TRAIN_ZONE, VAL_ZONE};
        use orbfix_host::nn::realdata::{build, RealSpec};
        let spec = |zone, seed| RealSpec {
            world_seed: a.world_seed,
            zone,
            seed,
            cross_sun_p: a.cross_sun_p,
            missing_view_p: a.missing_view_p,
            stereo: a.real_stereo,
        };
        let (td, vd) = (a.real_dir.join("train"), a.real_dir.join("val"));
        let t0 = std::time::Instant::now();
        let n = build(&td, &spec(TRAIN_ZONE, a.seed ^ 0x7EA1), a.real_train, true)?;
        let m = build(&vd, &spec(VAL_ZONE, a.seed ^ 0x7A1D), a.real_val, true)?;
        eprintln!(
            "real set: rendered {n} training and {m} validation locations in {:.0} s",
            t0.elapsed().as_secs_f64()
        );
        real_train = Some(td);
        real_val = Some(vd);
    }
    if a.build_only {
        return Ok(());
    }
    let cfg = TrainConfig {
        world_seed: a.world_seed,
        seed: a.seed,
        steps: a.steps,
        batch: a.batch,
        lr: a.lr,
        temperature: a.temperature,
        cross_sun_p: a.cross_sun_p,
        missing_view_p: a.missing_view_p,
        val_size: a.val_size,
        checkpoint_every: a.checkpoint_every,
        real_train,
        real_val,
        init: a.init,
        sampling: orbfix_host::nn::realdata::Sampling {
            pos_radius_m: a.pos_radius_m,
            neg_min_m: a.neg_min_m,
            neg_max_m: a.neg_max_m,
        },
    };
    let state = train(&a.out, &cfg)?;
    if let Some(p) = state.history.last() {
        println!(
            "trained {} steps in {:.0} s: val loss {:.4}, val top-1 {:.3}; checkpoint {}",
            p.step,
            p.elapsed_s,
            p.val_loss,
            p.val_top1,
            checkpoint_path(&a.out).display()
        );
    }
    Ok(())
}
