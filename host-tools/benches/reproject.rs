//! Reprojection benchmark (harness-free): see `orbfix_host::reproject::bench`.
//!
//! Run: `cargo bench -p orbfix-host --bench reproject` (env `ORBFIX_BENCH_REPS` sets the
//! repetitions, default 2000; `ORBFIX_PYTHON` the interpreter, default `python3`).
//! Same as `orbfix bench reproject`.

fn main() -> anyhow::Result<()> {
    let mut opts = orbfix_host::reproject::bench::BenchOptions::default();
    if let Some(r) = std::env::var("ORBFIX_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        opts.reps = r;
    }
    orbfix_host::reproject::bench::run(&opts)
}
