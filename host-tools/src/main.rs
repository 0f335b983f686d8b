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
    /// Train the siamese CNN matcher (float, CPU, candle).
    Train(cmd::train::Args),
    /// Quantize a trained matcher to int8 and write the core's weight file.
    Quantize(cmd::quantize::Args),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Elevation { seed, x, y } => {
            let world = orbfix_host::world::World::new(seed);
            println!("{:.3}", world.height_m(x, y));
        }
        Command::Train(a) => cmd::train::run(a)?,
        Command::Quantize(a) => cmd::quantize::run(a)?,
    }
    Ok(())
}
