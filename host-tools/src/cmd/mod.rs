//! Subcommands of `orbfix`, one module each.

pub mod bench;
pub mod generate;
pub mod render;
pub mod reproject;
