//! Subcommands of the `orbfix` binary, one module each.

pub mod quantize;
pub mod train;
