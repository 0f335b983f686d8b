//! `orbfix`: command-line front end of the host tools.

use clap::{Parser, Subcommand};

mod cmd;

/// orbfix: absolute rover localization from ground views and an orbital map.
#[derive(Parser, Debug)]
#[command(name = "orbfix", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a dataset (views, satellite crops, manifest); see docs/dataset.md.
    Generate(cmd::generate::Args),
    /// Render pictures: one location, a map region, or the docs figure.
    Render(cmd::render::Args),
    /// Measure speed beside the anchors (e.g. `orbfix bench world`).
    Bench(cmd::bench::Args),
    /// Print the terrain elevation (metres) at a world point of the built-in world.
    Elevation {
        /// World seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// East, metres.
        #[arg(long, allow_negative_numbers = true)]
        x: f64,
        /// North, metres.
        #[arg(long, allow_negative_numbers = true)]
        y: f64,
    },
    /// Build the flight firmware, run it in QEMU and write the timing and memory budget.
    Budget(cmd::budget::Args),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Generate(a) => cmd::generate::run(a)?,
        Command::Render(a) => cmd::render::run(a)?,
        Command::Bench(a) => cmd::bench::run(a)?,
        Command::Elevation { seed, x, y } => {
            let world = orbfix_host::world::World::new(seed);
            println!("{:.3}", world.height_m(x, y));
        }
        Command::Budget(args) => cmd::budget::run(args)?,
    }
    Ok(())
}
