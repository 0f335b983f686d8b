//! Contrastive training of the float trunk (candle, CPU) on triplets generated on the fly.
//!
//! Loss: symmetric InfoNCE. Each batch has `B` rover inputs, their `B` satellite windows and
//! `B` hard negatives (windows 12.5-25 m away: the same crater field, the wrong place);
//! logits are cosine similarities over a temperature. Rover -> satellite rows see `2B`
//! candidates (one positive); satellite -> rover rows see the `B` rover inputs.
//!
//! Deterministic for a seed: the triplets of step `s` depend only on `(seed, s)`, weights
//! start from a seeded He initialization. Resumable: the trainer saves `checkpoint.safetensors`
//! and `state.json` atomically every `checkpoint_every` steps and continues from them
//! (AdamW moments restart from zero on resume).

use super::data::{triplet, Triplet, TRAIN_ZONE, VAL_ZONE};
use super::float_model::{batch_tensor, FloatNet};
use super::realdata::{fixed_triplets, sample_triplet, RealLoc, Sampling};
use crate::world::World;
use anyhow::{ensure, Context, Result};
use candle_core::{Device, Tensor, D};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};
use indicatif::{ProgressBar, ProgressStyle};
use orbfix::nn::input::INPUT_LEN;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Training configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// World seed.
    pub world_seed: u64,
    /// Seed of initialization and data.
    pub seed: u64,
    /// Optimizer steps.
    pub steps: u64,
    /// Anchors per batch.
    pub batch: usize,
    /// Peak learning rate (cosine decay to 5 %).
    pub lr: f64,
    /// Softmax temperature.
    pub temperature: f64,
    /// Probability that the rover's sun differs from the map's.
    pub cross_sun_p: f64,
    /// Probability of a missing view.
    pub missing_view_p: f64,
    /// Validation anchors.
    pub val_size: usize,
    /// Steps between validations and checkpoints.
    pub checkpoint_every: u64,
    /// Cached real training set (`realdata`): when set, batches are drawn from it instead
    /// of the proxy generator.
    #[serde(default)]
    pub real_train: Option<PathBuf>,
    /// Cached real validation set (used with `real_train`).
    #[serde(default)]
    pub real_val: Option<PathBuf>,
    /// Float checkpoint to start from (fine-tuning) instead of a fresh initialization.
    #[serde(default)]
    pub init: Option<PathBuf>,
    /// How positives and hard negatives are cut from the real set's crops.
    #[serde(default)]
    pub sampling: Sampling,
}

/// One logged point.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LogPoint {
    /// Step.
    pub step: u64,
    /// Mean training loss since the last point.
    pub train_loss: f64,
    /// Validation loss.
    pub val_loss: f64,
    /// Validation top-1 accuracy of rover -> satellite among `2 val_size` candidates.
    pub val_top1: f64,
    /// Seconds of training so far.
    pub elapsed_s: f64,
}

/// Saved trainer state.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainState {
    /// Configuration the run was started with.
    pub config: TrainConfig,
    /// Steps done.
    pub step: u64,
    /// Log.
    pub history: Vec<LogPoint>,
}

/// Checkpoint path inside a run directory.
pub fn checkpoint_path(dir: &Path) -> PathBuf {
    dir.join("checkpoint.safetensors")
}

fn state_path(dir: &Path) -> PathBuf {
    dir.join("state.json")
}

/// Writes `bytes` to `path` atomically, regular files only (the one implementation:
/// [`crate::fsutil::write_atomic`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    crate::fsutil::write_atomic(path, bytes)
}

fn batch(
    world: &World,
    seed: u64,
    first: u64,
    n: usize,
    cfg: &TrainConfig,
    val: bool,
) -> Vec<Triplet> {
    let zone = if val { VAL_ZONE } else { TRAIN_ZONE };
    (0..n as u64)
        .into_par_iter()
        .map(|i| {
            triplet(
                world,
                &zone,
                seed,
                first + i,
                cfg.cross_sun_p,
                cfg.missing_view_p,
            )
        })
        .collect()
}

/// Batch `step` drawn from a cached real set: `n` distinct locations, each with a freshly
/// cut positive and hard negative (deterministic for `(seed, step)`).
fn real_batch(
    set: &[RealLoc],
    sampling: &Sampling,
    seed: u64,
    step: u64,
    n: usize,
) -> Vec<Triplet> {
    let mut rng = StdRng::seed_from_u64(seed ^ step.wrapping_mul(0x2545_F491_4F6C_DD1D));
    let mut idx: Vec<usize> = (0..set.len()).collect();
    let mut out = Vec::with_capacity(n);
    for i in 0..set.len() {
        if out.len() == n {
            break;
        }
        let j = rng.random_range(i..idx.len());
        idx.swap(i, j);
        if let Some(t) = sample_triplet(&set[idx[i]], sampling, &mut rng) {
            out.push(t);
        }
    }
    out
}

/// Symmetric InfoNCE loss and rover -> satellite top-1 accuracy of a batch.
pub fn loss(net: &FloatNet, b: &[Triplet], temperature: f64) -> Result<(Tensor, f64)> {
    let n = b.len();
    let mut refs: Vec<&[i8; INPUT_LEN]> = b.iter().map(|t| &*t.rover).collect();
    refs.extend(b.iter().map(|t| &*t.positive));
    refs.extend(b.iter().map(|t| &*t.hard_negative));
    let e = net.embed(&batch_tensor(&refs)?)?;
    let r = e.narrow(0, 0, n)?;
    let s = e.narrow(0, n, 2 * n)?;
    let logits = (r.matmul(&s.t()?)? / temperature)?;
    let targets = Tensor::arange(0u32, n as u32, &Device::Cpu)?;
    let l1 = candle_nn::loss::cross_entropy(&logits, &targets)?;
    let logits2 = (s.narrow(0, 0, n)?.matmul(&r.t()?)? / temperature)?;
    let l2 = candle_nn::loss::cross_entropy(&logits2, &targets)?;
    let pred = logits.argmax(D::Minus1)?.to_vec1::<u32>()?;
    let acc = pred
        .iter()
        .enumerate()
        .filter(|(i, &p)| *i as u32 == p)
        .count() as f64
        / n as f64;
    Ok((((l1 + l2)? * 0.5)?, acc))
}

/// Validation loss and top-1 accuracy.
pub fn validate(net: &FloatNet, val: &[Triplet], temperature: f64) -> Result<(f64, f64)> {
    let (l, a) = loss(net, val, temperature)?;
    Ok((l.to_scalar::<f32>()? as f64, a))
}

/// Trains into `dir`, resuming from its state if present. Returns the final state.
pub fn train(dir: &Path, cfg: &TrainConfig) -> Result<TrainState> {
    ensure!(cfg.batch >= 2, "batch must be at least 2");
    ensure!(cfg.val_size >= 2, "val-size must be at least 2");
    ensure!(
        cfg.checkpoint_every >= 1,
        "checkpoint-every must be at least 1"
    );
    cfg.sampling.check()?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let world = World::new(cfg.world_seed);
    let (net, mut state) = if state_path(dir).exists() {
        let s: TrainState =
            serde_json::from_slice(&std::fs::read(state_path(dir)).context("reading state.json")?)
                .context("state.json is corrupted; delete the run directory to start over")?;
        ensure!(
            s.config.seed == cfg.seed
                && s.config.batch == cfg.batch
                && s.config.world_seed == cfg.world_seed,
            "{} holds a run with another seed/batch/world; use another --out or the same settings",
            dir.display()
        );
        let net = FloatNet::load(&checkpoint_path(dir))?;
        eprintln!("resuming {} at step {}", dir.display(), s.step);
        (
            net,
            TrainState {
                config: cfg.clone(),
                ..s
            },
        )
    } else if let Some(init) = &cfg.init {
        eprintln!("fine-tuning from {}", init.display());
        (
            FloatNet::load(init)?,
            TrainState {
                config: cfg.clone(),
                step: 0,
                history: Vec::new(),
            },
        )
    } else {
        (
            FloatNet::init(cfg.seed)?,
            TrainState {
                config: cfg.clone(),
                step: 0,
                history: Vec::new(),
            },
        )
    };
    let params = ParamsAdamW {
        lr: cfg.lr,
        weight_decay: 1e-4,
        ..Default::default()
    };
    let mut opt = AdamW::new(net.vars(), params)?;
    let real = match &cfg.real_train {
        Some(d) => {
            let set = super::realdata::load(d)?;
            ensure!(
                set.len() >= cfg.batch,
                "the real set {} holds {} usable locations, fewer than --batch {}",
                d.display(),
                set.len(),
                cfg.batch
            );
            eprintln!(
                "real training set: {} locations from {}",
                set.len(),
                d.display()
            );
            Some(set)
        }
        None => None,
    };
    let val = match (&real, &cfg.real_val) {
        (Some(_), Some(d)) => {
            let mut v = fixed_triplets(&super::realdata::load(d)?, &cfg.sampling, 0x7A1D);
            v.truncate(cfg.val_size);
            ensure!(
                v.len() >= 2,
                "the real validation set {} is empty",
                d.display()
            );
            v
        }
        _ => batch(
            &world,
            cfg.seed ^ 0x005E_ED0F_7A11,
            0,
            cfg.val_size,
            cfg,
            true,
        ),
    };
    let pb = ProgressBar::new(cfg.steps);
    pb.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} step  eta {eta}  {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_position(state.step);
    let start = Instant::now();
    let base_elapsed = state.history.last().map(|p| p.elapsed_s).unwrap_or(0.0);
    let (mut acc_loss, mut acc_n) = (0f64, 0usize);
    while state.step < cfg.steps {
        let t = state.step as f64 / cfg.steps as f64;
        opt.set_learning_rate(
            cfg.lr * (0.05 + 0.95 * 0.5 * (1.0 + (std::f64::consts::PI * t).cos())),
        );
        let b = match &real {
            Some(set) => real_batch(set, &cfg.sampling, cfg.seed, state.step, cfg.batch),
            None => batch(
                &world,
                cfg.seed,
                state.step * cfg.batch as u64,
                cfg.batch,
                cfg,
                false,
            ),
        };
        let (l, _) = loss(&net, &b, cfg.temperature)?;
        opt.backward_step(&l)?;
        let lv = l.to_scalar::<f32>()? as f64;
        ensure!(
            lv.is_finite(),
            "training diverged at step {} (loss {lv}); lower --lr",
            state.step
        );
        acc_loss += lv;
        acc_n += 1;
        state.step += 1;
        pb.set_position(state.step);
        pb.set_message(format!("loss {lv:.3}"));
        if state.step % cfg.checkpoint_every == 0 || state.step == cfg.steps {
            let (vl, va) = validate(&net, &val, cfg.temperature)?;
            let p = LogPoint {
                step: state.step,
                train_loss: acc_loss / acc_n.max(1) as f64,
                val_loss: vl,
                val_top1: va,
                elapsed_s: base_elapsed + start.elapsed().as_secs_f64(),
            };
            let line = format!(
                "step {:>6}  train loss {:.4}  val loss {:.4}  val top-1 {:.3}  ({:.0} s)",
                p.step, p.train_loss, p.val_loss, p.val_top1, p.elapsed_s
            );
            if pb.is_hidden() {
                eprintln!("{line}");
            } else {
                pb.println(line);
            }
            state.history.push(p);
            (acc_loss, acc_n) = (0.0, 0);
            net.save(&checkpoint_path(dir))?;
            write_atomic(&state_path(dir), &serde_json::to_vec_pretty(&state)?)?;
        }
    }
    pb.finish();
    Ok(state)
}
