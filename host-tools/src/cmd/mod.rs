//! Subcommands of `orbfix`, one module each.

pub mod bench_localize;
pub mod demo;
pub mod eval;
pub mod localize;
pub mod map;
