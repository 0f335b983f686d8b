//! `orbfix quantize`: post-training int8 quantization of a trained checkpoint, calibrated
//! on validation-zone inputs; writes the `.ofw` file the core embeds, checks it with the
//! core's own parser, and evaluates float vs int8 (vs masked NCC) on the test zone.
//!
//! `--rederive-multipliers --weights IN.ofw` instead rewrites an existing file's
//! multipliers and shifts from its own stored scales (TFLite's derivation,
//! `orbfix_host::nn::multiplier`), leaving weights, biases, scales and zero points as they are.

use anyhow::{Context, Result};
use orbfix::nn::model::{embedding_macs, weight_count, SiameseNet};
use orbfix_host::nn::data::{triplet, TEST_ZONE, VAL_ZONE};
use orbfix_host::nn::eval::{cases, evaluate, Metrics, Scorer};
use orbfix_host::nn::float_model::FloatNet;
use orbfix_host::nn::quantize::{calibrate, quantize};
use orbfix_host::nn::train::write_atomic;
use orbfix_host::world::World;
use rayon::prelude::*;
use std::path::PathBuf;

/// Quantize a trained checkpoint to int8 and write the core's weight file.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Float checkpoint written by `orbfix train`.
    #[arg(long, default_value = "runs/matcher/checkpoint.safetensors")]
    pub checkpoint: PathBuf,
    /// Output weight file (the core embeds weights/matcher-v2.ofw).
    #[arg(long, default_value = "weights/matcher-v2.ofw")]
    pub out: PathBuf,
    /// World seed.
    #[arg(long, default_value_t = 1)]
    pub world_seed: u64,
    /// Calibration inputs (validation zone; half rover side, half satellite side).
    #[arg(long, default_value_t = 256)]
    pub calibration: usize,
    /// Test locations per condition for the float / int8 / NCC comparison (0: skip).
    #[arg(long, default_value_t = 20)]
    pub eval_locations: usize,
    /// Seed of the test locations (never used in training: those come from the test zone).
    #[arg(long, default_value_t = 1000)]
    pub eval_seed: u64,
    /// Calibrate on a cached real validation set (`orbfix train --real-train`'s
    /// `runs/realdata2/val`: real rover top-downs and map windows) instead of proxy pairs.
    #[arg(long)]
    pub calibration_real: Option<PathBuf>,
    /// Write the metrics as JSON here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Do not quantize a checkpoint: rewrite the multipliers and shifts of the weight file
    /// given with --weights from its own stored f32 scales, as TensorFlow Lite derives them
    /// (same weights, biases, scales and zero points), and write it to --out.
    #[arg(long, requires = "weights")]
    pub rederive_multipliers: bool,
    /// Weight file to re-derive (with --rederive-multipliers) or to dequantize (with
    /// --dequantize).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Do not quantize: write the float network that the weight file given with --weights
    /// stands for (weights and biases times their scales) as a checkpoint to --out, a
    /// starting point for `orbfix train --init` when the float checkpoint is not at hand.
    #[arg(long, requires = "weights", conflicts_with = "rederive_multipliers")]
    pub dequantize: bool,
}

/// `--dequantize`: the float checkpoint an int8 weight file stands for.
fn dequantize_file(input: &std::path::Path, out: &std::path::Path) -> Result<()> {
    use orbfix_host::nn::qmodel::HostQModel;
    let bytes = orbfix_host::nn::weights_file::load_bytes(Some(input))?;
    let q =
        HostQModel::from_bytes(&bytes).with_context(|| format!("reading {}", input.display()))?;
    let net = orbfix_host::nn::quantize::dequantize(&q)?;
    if let Some(dir) = out.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
    }
    net.save(out)?;
    println!(
        "{}: wrote the float network it stands for to {}",
        input.display(),
        out.display()
    );
    Ok(())
}

/// `--rederive-multipliers`: rewrites only the requantization multipliers of `input`.
fn rederive(input: &std::path::Path, out: &std::path::Path) -> Result<()> {
    use orbfix_host::nn::multiplier::rederive_multipliers;
    use orbfix_host::nn::qmodel::HostQModel;
    // Checked by the core first (CRC, structure, bounds): a damaged file is refused as such.
    let bytes = orbfix_host::nn::weights_file::load_bytes(Some(input))?;
    let mut q =
        HostQModel::from_bytes(&bytes).with_context(|| format!("reading {}", input.display()))?;
    let channels: usize = q.layers.iter().map(|l| l.out_c).sum();
    let changed = rederive_multipliers(&mut q);
    let bytes = q.to_bytes();
    SiameseNet::from_bytes(&bytes).map_err(|e| {
        anyhow::anyhow!("the core rejects the re-derived file ({e}); it was not written")
    })?;
    if let Some(dir) = out.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
    }
    orbfix_host::fsutil::write_atomic(out, &bytes)?;
    println!(
        "{}: {changed} of {channels} channels' (multiplier, shift) re-derived from the stored scales; wrote {} ({} bytes)",
        input.display(),
        out.display(),
        bytes.len()
    );
    Ok(())
}

fn row(name: &str, m: &Metrics) {
    println!(
        "{name:<24} {:>4} {:>6.3} {:>6.3} {:>6.3} {:>8.1} {:>8.1} {:>6.3}",
        m.n,
        m.recall_at_1,
        m.recall_at_5,
        m.recall_at_10,
        m.median_error_m,
        m.p95_error_m,
        m.pair_auc
    );
}

pub fn run(a: Args) -> Result<()> {
    if let (true, Some(input)) = (a.rederive_multipliers, &a.weights) {
        return rederive(input, &a.out);
    }
    if let (true, Some(input)) = (a.dequantize, &a.weights) {
        return dequantize_file(input, &a.out);
    }
    anyhow::ensure!(
        a.weights.is_none(),
        "--weights is only used with --rederive-multipliers or --dequantize"
    );
    let net = FloatNet::load(&a.checkpoint)?;
    let world = World::new(a.world_seed);
    anyhow::ensure!(a.calibration >= 2, "--calibration must be at least 2");
    let calib: Vec<_> = match &a.calibration_real {
        Some(dir) => {
            use orbfix_host::nn::realdata::{fixed_triplets, load, Sampling};
            let set = fixed_triplets(&load(dir)?, &Sampling::default(), 0xCA11);
            anyhow::ensure!(
                !set.is_empty(),
                "the real calibration set {} is empty",
                dir.display()
            );
            set.iter()
                .take(a.calibration / 2)
                .flat_map(|t| [*t.rover, *t.positive])
                .collect()
        }
        None => (0..a.calibration as u64 / 2)
            .into_par_iter()
            .flat_map_iter(|i| {
                let t = triplet(&world, &VAL_ZONE, 0xCA11_B4A7, i, 0.5, 0.15);
                [*t.rover, *t.positive]
            })
            .collect(),
    };
    println!("calibration: {} inputs", calib.len());
    let ranges = calibrate(&net, &calib)?;
    let q = quantize(&net, &ranges)?;
    let bytes = q.to_bytes();
    // The core must accept what we ship.
    let qnet = SiameseNet::from_bytes(&bytes)
        .map_err(|e| anyhow::anyhow!("the core rejects the quantized file: {e}"))?;
    if let Some(dir) = a.out.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
    }
    write_atomic(&a.out, &bytes)?;
    println!(
        "wrote {} ({} bytes; {} int8 weights, {} MACs per embedding)",
        a.out.display(),
        bytes.len(),
        weight_count(),
        embedding_macs()
    );
    for (i, (l, r)) in q.layers.iter().zip(&ranges).enumerate() {
        println!(
            "  layer {i}: range [{:.3}, {:.3}] scale {:.5} zp {}",
            r.0, r.1, l.output_scale, l.output_zp
        );
    }
    // Host time per embedding (one thread, int8 core kernels vs candle float batch 64).
    {
        use orbfix::nn::model::{Arena, EMBED_LEN};
        use orbfix_host::nn::float_model::batch_tensor;
        let reps = calib.len().min(128);
        let mut arena = Box::new(Arena::new());
        let mut e = [0i8; EMBED_LEN];
        let t = std::time::Instant::now();
        for x in &calib[..reps] {
            qnet.embed(x, &mut arena, &mut e)
                .map_err(|e| anyhow::anyhow!("int8 embedding failed: {e}"))?;
        }
        let int8_us = t.elapsed().as_secs_f64() * 1e6 / reps as f64;
        let refs: Vec<_> = calib[..reps].iter().collect();
        let t = std::time::Instant::now();
        for chunk in refs.chunks(64) {
            net.embed(&batch_tensor(chunk)?)?;
        }
        let f32_us = t.elapsed().as_secs_f64() * 1e6 / reps as f64;
        println!(
            "host time per embedding: int8 core {int8_us:.0} us (1 thread), f32 candle {f32_us:.0} us (batch 64, all threads); {reps} inputs"
        );
    }
    if a.eval_locations == 0 {
        return Ok(());
    }
    let mut report = serde_json::Map::new();
    println!(
        "{:<24} {:>4} {:>6} {:>6} {:>6} {:>8} {:>8} {:>6}",
        "matcher / sun", "n", "R@1", "R@5", "R@10", "med m", "p95 m", "AUC"
    );
    for (label, cross) in [("same-sun", false), ("cross-sun", true)] {
        let cs = cases(&world, &TEST_ZONE, a.eval_locations, a.eval_seed, cross);
        for (name, scorer) in [
            ("masked-ncc", Scorer::MaskedNcc),
            ("cnn-f32", Scorer::Float(&net)),
            ("cnn-int8", Scorer::Int8(&qnet)),
        ] {
            let m = evaluate(&scorer, &cs)?;
            row(&format!("{name} {label}"), &m);
            report.insert(format!("{name}/{label}"), serde_json::to_value(&m)?);
        }
    }
    if let Some(p) = &a.report {
        write_atomic(p, &serde_json::to_vec_pretty(&report)?)?;
    }
    Ok(())
}
