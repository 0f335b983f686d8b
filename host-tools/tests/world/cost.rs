//! The world's cost and statistics, run by hand (`--ignored`): throughput and relief
//! statistics.

use orbfix_host::world::{zones, World};

/// CPU time of the calling thread, seconds (wall time is meaningless on a shared machine).
fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // Safety: `ts` is a valid, writable timespec; the clock id is a constant the OS knows.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime failed");
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Throughput in release, in thread CPU time: `cargo test --release -p orbfix-host --test
/// world -- --ignored --nocapture throughput`.
#[test]
#[ignore]
fn throughput() {
    let world = World::new(1);
    let n = 400_000;
    let t = thread_cpu_s();
    let mut s = 0.0;
    for i in 0..n {
        let (h, a) = world.sample(500.0 + 0.013 * i as f64, 700.0 + 0.0071 * i as f64);
        s += h + a;
    }
    let point = (thread_cpu_s() - t) * 1e6 / n as f64;
    let t = thread_cpu_s();
    let mut hs = 0.0;
    for i in 0..n {
        hs += world.height_m(500.0 + 0.013 * i as f64, 700.0 + 0.0071 * i as f64);
    }
    let height_only = (thread_cpu_s() - t) * 1e6 / n as f64;
    // A single-thread pool runs the grid on this thread, so thread CPU time counts it all.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build()
        .expect("pool");
    let mut line = String::new();
    for (m, side) in [
        (0.05, 1000usize),
        (0.22, 224),
        (0.5, 600),
        (0.8, 400),
        (1.6, 300),
        (5.0, 100),
        (12.8, 100),
    ] {
        let t = thread_cpu_s();
        let g = pool.install(|| world.sample_grid(500.0, 800.0, m, side, side));
        let grid = (thread_cpu_s() - t) * 1e6 / (side * side) as f64;
        s += f64::from(g.height_m[0]);
        line += &format!(
            "; grid {side} x {side} at {m} m/px {grid:.3} us/sample (point/grid {:.2}x)",
            point / grid
        );
    }
    println!(
        "world sample, 1 thread CPU time: point sample() {point:.3} us, height_m() {height_only:.3} us{line} (checksum {:.3})",
        s + hs
    );
}

/// Terrain statistics for docs/world.md: `cargo test --release -p orbfix-host --test world
/// -- --ignored --nocapture statistics`.
#[test]
#[ignore]
fn statistics() {
    let world = World::new(1);
    let mut counts = Vec::new();
    let mut sds = Vec::new();
    let mut ranges = Vec::new();
    for z in zones::ALL {
        let loc = z.location_area();
        for j in 0..10 {
            for i in 0..10 {
                let x = loc.x_min_m + (i as f64 + 0.5) * loc.width_m() / 10.0;
                let y = loc.y_min_m + (j as f64 + 0.5) * loc.height_m() / 10.0;
                let n = world
                    .craters_in(x - 25.0, y - 25.0, x + 25.0, y + 25.0, 2.0)
                    .expect("rect ok")
                    .iter()
                    .filter(|c| c.diameter_m <= 50.0)
                    .count();
                counts.push(n as f64);
                let g = world.sample_grid(x - 150.0, y + 150.0, 2.0, 150, 150);
                let v: Vec<f64> = g.height_m.iter().map(|&h| f64::from(h)).collect();
                let mean = v.iter().sum::<f64>() / v.len() as f64;
                let sd =
                    (v.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
                sds.push(sd);
                let lo = v.iter().cloned().fold(f64::MAX, f64::min);
                let hi = v.iter().cloned().fold(f64::MIN, f64::max);
                ranges.push(hi - lo);
            }
        }
    }
    let q = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        let n = v.len();
        (v[0], v[n / 10], v[n / 2], v[9 * n / 10], v[n - 1])
    };
    println!("{} locations on a 10 x 10 lattice per zone", counts.len());
    println!(
        "craters 2..50 m per 50 x 50 m patch (min, p10, median, p90, max): {:?}",
        q(&mut counts)
    );
    println!(
        "height sd over the 300 x 300 m map region, m: {:?}",
        q(&mut sds)
    );
    println!(
        "height range over the 300 x 300 m map region, m: {:?}",
        q(&mut ranges)
    );
}
