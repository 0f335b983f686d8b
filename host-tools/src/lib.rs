//! # orbfix-host
//!
//! The std side of orbfix: the procedural lunar world the flight core is trained and judged
//! on, its renderer, datasets, training, quantization, evaluation, figures and the flight
//! budget. Uses the `orbfix` core as a library; frames and units are those of the core
//! (`docs/frames.md`).

pub mod budget;
pub mod dataset;
pub mod eval;
pub mod fix;
pub mod fsutil;
pub mod geotiff;
pub mod nn;
pub mod npy;
pub mod render;
pub mod reproject;
pub mod stereo_bench;
pub mod tflite;
pub mod traverse;
pub mod world;
