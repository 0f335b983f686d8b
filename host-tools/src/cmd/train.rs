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
    #[arg(long, default_value_t = 2e-3)]
    pub lr: f64,
    /// InfoNCE temperature.
    #[arg(long, default_value_t = 0.07)]
    pub temperature: f64,
    /// Probability that the rover's sun differs from the map's.
    #[arg(long, default_value_t = 0.5)]
    pub cross_sun_p: f64,
    /// Probability of one missing view.
    #[arg(long, default_value_t = 0.15)]
    pub missing_view_p: f64,
    /// Validation anchors.
    #[arg(long, default_value_t = 128)]
    pub val_size: usize,
    /// Steps between validations and checkpoints.
    #[arg(long, default_value_t = 50)]
    pub checkpoint_every: u64,
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
