//! Subcommands of `orbfix`, one module each (each has `Args` and `run`).

pub mod budget;
// The localize branch's commands (bench_localize, demo, eval, localize, map) are declared
// here by that branch once render/world land; they do not build without them yet.
