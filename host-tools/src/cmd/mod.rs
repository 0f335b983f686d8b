//! Subcommands of `orbfix`, one module each.

pub mod bench;
pub mod bench_localize;
pub mod demo;
pub mod eval;
pub mod generate;
pub mod localize;
pub mod map;
pub mod quantize;
pub mod render;
pub mod train;
