//! One module per subcommand of `orbfix` (each has `Args` and `run`).

pub mod budget;
