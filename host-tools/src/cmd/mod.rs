//! Subcommands of `orbfix`, one module each (each has `Args` and `run`).

pub mod bench;
pub mod budget;
pub mod generate;
pub mod render;
// The localize branch's commands (bench_localize, demo, eval, localize, map) are declared
// here by that branch; they do not build before its merge of render/world.
