//! `orbfix embed`: a batch of int8 network inputs (`.npy`, `[N, 64, 64, 1]`) through the
//! core's network, int8 embeddings out (`.npy`, `[N, 2048]`), so other runtimes (TFLite
//! Micro, NumPy) can be compared with the core byte for byte.

use anyhow::{bail, Context, Result};
use orbfix::nn::input::{INPUT_LEN, INPUT_SIDE};
use orbfix::nn::model::{Arena, SiameseNet, EMBED_LEN};
use orbfix_host::npy::{read_i8, write_i8};
use rayon::prelude::*;
use std::path::PathBuf;

/// Embed a batch of prepared int8 network inputs with the core's int8 network. The input is
/// a NumPy int8 array [N, 64, 64, 1] (NHWC, the core's `prepare_input` output, e.g. from
/// `orbfix prepare-inputs`); the output is int8 [N, 2048], each row the 8 x 8 x 32 embedding
/// in NHWC order (zero point printed).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input batch (.npy, int8, shape [N, 64, 64, 1]).
    #[arg(long)]
    pub input: PathBuf,
    /// Embeddings to write (.npy, int8, shape [N, 2048]).
    #[arg(long)]
    pub out: PathBuf,
    /// Weight file (.ofw; default: the shipped weights built into the core).
    #[arg(long)]
    pub weights: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let weights = orbfix_host::nn::weights_file::load_bytes(a.weights.as_deref())?;
    let net = SiameseNet::from_bytes(&weights)
        .map_err(|e| anyhow::anyhow!("the core rejects the weight file: {e}"))?;
    let what = a.input.display().to_string();
    let bytes = std::fs::read(&a.input).with_context(|| format!("cannot read {what}"))?;
    let x = read_i8(&bytes, &what)?;
    let s = INPUT_SIDE;
    let n = match x.shape[..] {
        [n, h, w, 1] if h == s && w == s => n,
        _ => bail!(
            "{what} has shape {:?}; orbfix embed needs [N, {s}, {s}, 1] (int8 NHWC network inputs)",
            x.shape
        ),
    };
    let bar = indicatif::ProgressBar::new(n as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} embeddings",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut out = vec![0i8; n * EMBED_LEN];
    out.par_chunks_mut(EMBED_LEN)
        .zip(x.data.par_chunks(INPUT_LEN))
        .try_for_each_init(
            || Box::new(Arena::new()),
            |arena, (dst, src)| -> Result<()> {
                let input: &[i8; INPUT_LEN] = src.try_into().context("internal: input length")?;
                let dst: &mut [i8; EMBED_LEN] =
                    dst.try_into().context("internal: embedding length")?;
                net.embed(input, arena, dst)
                    .map_err(|e| anyhow::anyhow!("embedding failed: {e}"))?;
                bar.inc(1);
                Ok(())
            },
        )?;
    bar.finish_and_clear();
    orbfix_host::fsutil::write_atomic(&a.out, &write_i8(&[n, EMBED_LEN], &out)?)?;
    println!(
        "wrote {} ({n} embeddings of {EMBED_LEN} int8 values, zero point {})",
        a.out.display(),
        net.embedding_zero_point()
    );
    Ok(())
}
