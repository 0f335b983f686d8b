//! `orbfix export-tflite`: the int8 network of a weight file as a TensorFlow Lite model
//! (`orbfix_host::tflite::export`, `docs/interop.md`).

use anyhow::{Context, Result};
use orbfix_host::nn::qmodel::HostQModel;
use std::path::PathBuf;

/// Write the int8 matcher network as a .tflite model for TensorFlow Lite Micro / LiteRT:
/// int8 input [1, 64, 64, 1], per-channel int8 convolutions with int32 biases and fused
/// ReLU, an explicit PAD before every convolution whose padding TFLite's SAME would place
/// differently; output the int8 embedding [1, 8, 8, 32] (NHWC, as `orbfix embed` flattens
/// it). Its outputs are bit-exact with the core's (scripts/tflm-check.sh checks it).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Weight file (.ofw) to export (default: the shipped weights built into the core).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// The .tflite file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Export even when the file's stored multipliers are not TFLite's derivation from its
    /// scales (TFLite recomputes them, so its outputs then differ from the core's; for
    /// measuring that difference). Without it such a file is refused.
    #[arg(long)]
    pub allow_inexact_multipliers: bool,
}

pub fn run(a: Args) -> Result<()> {
    // Only what the core accepts is exported.
    let bytes = orbfix_host::nn::weights_file::load_bytes(a.weights.as_deref())?;
    let name = a.weights.as_ref().map_or_else(
        || "weights/matcher-v2.ofw (shipped)".to_string(),
        |p| p.display().to_string(),
    );
    let q = HostQModel::from_bytes(&bytes).with_context(|| format!("reading {name}"))?;
    let description = format!("orbfix int8 matcher trunk from {name}");
    let model = orbfix_host::tflite::export::export(&q, &description, a.allow_inexact_multipliers)
        .with_context(|| format!("exporting {name}"))?;
    orbfix_host::fsutil::write_atomic(&a.out, &model)?;
    println!(
        "wrote {} ({} bytes) from {name}",
        a.out.display(),
        model.len()
    );
    Ok(())
}
