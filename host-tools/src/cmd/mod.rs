//! Subcommands of `orbfix`, one module each (each has `Args` and `run`).

pub mod bench;
pub mod bench_localize;
pub mod budget;
pub mod demo;
pub mod embed;
pub mod eval;
pub mod export_geotiff;
pub mod export_tflite;
pub mod fix_report;
pub mod generate;
pub mod geotiff_info;
pub mod localize;
pub mod map;
pub mod prepare_inputs;
pub mod quantize;
pub mod render;
pub mod reproject;
pub mod results;
pub mod train;
pub mod traverse;
