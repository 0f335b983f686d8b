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
    /// Localize a few rover stops of the built-in world and draw them (no files needed).
    Demo(cmd::demo::Args),
    /// Localize one rover stop (dataset location or top-down image) in a map.
    Localize(cmd::localize::Args),
    /// Evaluate matchers on generated rover stops of the test zone (recall@k, errors, pairs).
    Eval(cmd::eval::Args),
    /// Drive a planned path: fixes fused with drifting odometry in the core's filter.
    Traverse(cmd::traverse::Args),
    /// Write an orbital map region of the built-in world as MAP.png + MAP.json.
    Map(cmd::map::Args),
    /// Reproject a dataset location's four views to a north-up top-down image (core LUT).
    Reproject(cmd::reproject::Args),
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
    /// Interoperability and report commands (flattened: they are top-level subcommands;
    /// a separate enum keeps clap's generated argument tables in a frame of their own).
    #[command(flatten)]
    Interop(Interop),
    /// Training, quantization, benchmarks and result pages (flattened, as above).
    #[command(flatten)]
    Tools(Tools),
}

#[derive(Subcommand, Debug)]
enum Tools {
    /// Time one localization per matcher (441 windows and dense) with operation counts.
    BenchLocalize(cmd::bench_localize::Args),
    /// Write docs/results.md from the reports of scripts/results.sh.
    Results(cmd::results::Args),
    /// Train the siamese CNN matcher (float, CPU, candle).
    Train(cmd::train::Args),
    /// Quantize a trained matcher to int8 and write the core's weight file.
    Quantize(cmd::quantize::Args),
}

#[derive(Subcommand, Debug)]
enum Interop {
    /// Pool eval reports of several seeds into the fix's accuracy table (scripts/fix-results.sh).
    FixReport(cmd::fix_report::Args),
    /// Write a region of the built-in world as DEM + orthoimage GeoTIFFs (GDAL, QGIS).
    ExportGeotiff(cmd::export_geotiff::Args),
    /// Print what orbfix reads from a GeoTIFF (georeference, CRS, values) as JSON.
    GeotiffInfo(cmd::geotiff_info::Args),
    /// Write the int8 network as a TensorFlow Lite model (.tflite) for TFLite Micro.
    ExportTflite(cmd::export_tflite::Args),
    /// Embed a batch of int8 network inputs (.npy) with the core; int8 embeddings to .npy.
    Embed(cmd::embed::Args),
    /// Write a dataset's network inputs (rover top-downs, satellite crops) as one .npy batch.
    PrepareInputs(cmd::prepare_inputs::Args),
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // The message chain on one line ("context: cause: cause"), without a backtrace
            // even when RUST_BACKTRACE is set: every message says what to do.
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    // A closed standard output (`orbfix ... | head`) ends the program quietly, as for other
    // command-line tools (exit status 141 in the shell), instead of a panic message from
    // `println!` (Rust ignores SIGPIPE by default, so the write fails with a broken pipe).
    // Safety: called first in `main`, before any thread exists; `SIG_DFL` is a valid handler
    // for SIGPIPE and `signal` has no other effect.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    match cli.command {
        Command::Generate(a) => cmd::generate::run(a)?,
        Command::Render(a) => cmd::render::run(a)?,
        Command::Bench(a) => cmd::bench::run(a)?,
        Command::Demo(a) => cmd::demo::run(a)?,
        Command::Localize(a) => cmd::localize::run(a)?,
        Command::Eval(a) => cmd::eval::run(a)?,
        Command::Traverse(a) => cmd::traverse::run(a)?,
        Command::Map(a) => cmd::map::run(a)?,
        Command::Reproject(a) => cmd::reproject::run(a)?,
        Command::Elevation { seed, x, y } => {
            let world = orbfix_host::world::World::new(seed);
            println!("{:.3}", world.height_m(x, y));
        }
        Command::Budget(args) => cmd::budget::run(args)?,
        Command::Tools(t) => match t {
            Tools::BenchLocalize(a) => cmd::bench_localize::run(a)?,
            Tools::Results(a) => cmd::results::run(a)?,
            Tools::Train(a) => cmd::train::run(a)?,
            Tools::Quantize(a) => cmd::quantize::run(a)?,
        },
        Command::Interop(i) => match i {
            Interop::FixReport(a) => cmd::fix_report::run(a)?,
            Interop::ExportGeotiff(a) => cmd::export_geotiff::run(a)?,
            Interop::GeotiffInfo(a) => cmd::geotiff_info::run(a)?,
            Interop::ExportTflite(a) => cmd::export_tflite::run(a)?,
            Interop::Embed(a) => cmd::embed::run(a)?,
            Interop::PrepareInputs(a) => cmd::prepare_inputs::run(a)?,
        },
    }
    Ok(())
}
