//! The float siamese trunk in candle (CPU), mirroring the core's compiled network
//! (`orbfix::nn::model::SPEC`): NCHW tensors, OIHW weights, the same symmetric padding.
//!
//! Input: the core's prepared int8 input dequantized (`q / 32`), shape `[B, 1, 64, 64]`.
//! Embedding: the last layer's `[B, 32, 8, 8]` map flattened and L2-normalized, so the dot
//! product of two embeddings is the cosine similarity the core computes.

use anyhow::{ensure, Context, Result};
use candle_core::{DType, Device, Tensor, Var, D};
use orbfix::nn::input::{INPUT_LEN, INPUT_SIDE, INPUT_UNITS_PER_SIGMA};
use orbfix::nn::model::SPEC;
use orbfix::nn::weights::LayerKind;
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::collections::HashMap;
use std::path::Path;

/// Float network: one weight `[out, in, k, k]` and bias `[out]` variable per layer of
/// `SPEC`.
pub struct FloatNet {
    /// Weights, OIHW.
    pub weights: Vec<Var>,
    /// Biases.
    pub biases: Vec<Var>,
}

impl FloatNet {
    /// He-normal initialization, deterministic for `seed`.
    pub fn init(seed: u64) -> Result<Self> {
        let mut rng = StdRng::seed_from_u64(seed);
        let (mut weights, mut biases) = (Vec::new(), Vec::new());
        for s in SPEC.iter() {
            let fan_in = s.in_c * s.kernel * s.kernel;
            let std = (2.0 / fan_in as f64).sqrt();
            let d = Normal::new(0.0, std)?;
            let n = s.out_c * fan_in;
            let w: Vec<f32> = (0..n).map(|_| d.sample(&mut rng) as f32).collect();
            let w = Tensor::from_vec(w, (s.out_c, s.in_c, s.kernel, s.kernel), &Device::Cpu)?;
            weights.push(Var::from_tensor(&w)?);
            biases.push(Var::from_tensor(&Tensor::zeros(
                s.out_c,
                DType::F32,
                &Device::Cpu,
            )?)?);
        }
        Ok(Self { weights, biases })
    }

    /// All trainable variables.
    pub fn vars(&self) -> Vec<Var> {
        self.weights.iter().chain(&self.biases).cloned().collect()
    }

    /// Forward pass; returns every layer's output (the last is the embedding map).
    pub fn forward_all(&self, x: &Tensor) -> Result<Vec<Tensor>> {
        let mut outs = Vec::with_capacity(SPEC.len());
        let mut x = x.clone();
        for (i, s) in SPEC.iter().enumerate() {
            let y = x.conv2d(self.weights[i].as_tensor(), s.pad, s.stride, 1, 1)?;
            let y = y.broadcast_add(&self.biases[i].as_tensor().reshape((1, s.out_c, 1, 1))?)?;
            let y = if s.relu { y.relu()? } else { y };
            debug_assert!(matches!(s.kind, LayerKind::Conv) || s.kernel == 1);
            outs.push(y.clone());
            x = y;
        }
        Ok(outs)
    }

    /// L2-normalized embeddings `[B, 2048]`.
    pub fn embed(&self, x: &Tensor) -> Result<Tensor> {
        let outs = self.forward_all(x)?;
        let y = outs.last().context("empty network")?.flatten_from(1)?;
        let n = y.sqr()?.sum_keepdim(D::Minus1)?.affine(1.0, 1e-8)?.sqrt()?;
        Ok(y.broadcast_div(&n)?)
    }

    /// Saves as safetensors (`w0..`, `b0..`), atomically (temporary file + rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        let mut map = HashMap::new();
        for (i, (w, b)) in self.weights.iter().zip(&self.biases).enumerate() {
            map.insert(format!("w{i}"), w.as_tensor().clone());
            map.insert(format!("b{i}"), b.as_tensor().clone());
        }
        let tmp = path.with_extension("tmp");
        candle_core::safetensors::save(&map, &tmp)
            .with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))?;
        Ok(())
    }

    /// Loads a checkpoint written by [`Self::save`], checking every shape against `SPEC`.
    pub fn load(path: &Path) -> Result<Self> {
        let map = candle_core::safetensors::load(path, &Device::Cpu).with_context(|| {
            format!(
                "reading checkpoint {} (is it a safetensors file written by `orbfix train`?)",
                path.display()
            )
        })?;
        let (mut weights, mut biases) = (Vec::new(), Vec::new());
        for (i, s) in SPEC.iter().enumerate() {
            let w = map
                .get(&format!("w{i}"))
                .with_context(|| format!("checkpoint lacks w{i}"))?;
            let b = map
                .get(&format!("b{i}"))
                .with_context(|| format!("checkpoint lacks b{i}"))?;
            ensure!(
                w.dims() == [s.out_c, s.in_c, s.kernel, s.kernel] && b.dims() == [s.out_c],
                "checkpoint layer {i} has shape {:?}/{:?}, the network needs [{}, {}, {}, {}]",
                w.dims(),
                b.dims(),
                s.out_c,
                s.in_c,
                s.kernel,
                s.kernel
            );
            weights.push(Var::from_tensor(&w.to_dtype(DType::F32)?)?);
            biases.push(Var::from_tensor(&b.to_dtype(DType::F32)?)?);
        }
        Ok(Self { weights, biases })
    }
}

/// Stacks prepared int8 inputs into a dequantized `[B, 1, 64, 64]` tensor.
pub fn batch_tensor(inputs: &[&[i8; INPUT_LEN]]) -> Result<Tensor> {
    let inv = 1.0 / INPUT_UNITS_PER_SIGMA as f32;
    let mut v = Vec::with_capacity(inputs.len() * INPUT_LEN);
    for x in inputs {
        v.extend(x.iter().map(|&q| q as f32 * inv));
    }
    Ok(Tensor::from_vec(
        v,
        (inputs.len(), 1, INPUT_SIDE, INPUT_SIDE),
        &Device::Cpu,
    )?)
}
