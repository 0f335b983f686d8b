//! `orbfix fix-report`: pools `orbfix eval` reports of several world seeds into the table a
//! user of the fix reads (shares within 1 m and 5 m with 95 % intervals, median and p95
//! error, wrong-but-confident fixes, bound coverage, the study's 441-window R@k), per
//! matcher and condition; with `--against`, the same stops paired with another set of reports
//! (e.g. the fix's own stereo depth against truth depth), as differences with intervals.

use anyhow::Context;
use orbfix_host::fsutil::write_atomic;
use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Pool eval reports (JSON, one file per seed and condition) into one markdown table.
#[derive(clap::Args, Debug)]
#[command(after_help = "Examples:\n  \
    orbfix fix-report --dir out/fix-results-stereo --out docs/fix-results-stereo.md\n  \
    orbfix fix-report --dir out/a/stereo --dir out/b/stereo --against out/a/range \\\n    \
    --against out/b/range --out out/pooled.md   (two sets pooled, paired with truth depth)")]
pub struct Args {
    /// Folder of the reports (`*.json` written by `orbfix eval --json`); repeat to pool
    /// several folders.
    #[arg(long, required = true)]
    pub dir: Vec<PathBuf>,
    /// Folder of reports of the same stops to compare with (e.g. truth depth); repeatable.
    /// Stops are paired by seed, condition and stop number (their true positions must
    /// agree), per matcher and condition present in both.
    #[arg(long)]
    pub against: Vec<PathBuf>,
    /// Output markdown file.
    #[arg(long)]
    pub out: PathBuf,
    /// Title of the page.
    #[arg(long, default_value = "The one fix: accuracy")]
    pub title: String,
    /// The command that produced the reports (quoted in the page).
    #[arg(long, default_value = "bash scripts/fix-results.sh")]
    pub command: String,
}

/// Wilson 95 % interval of `k` successes in `n`.
fn wilson(k: usize, n: usize) -> (f64, f64) {
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let (z, nf) = (1.96f64, n as f64);
    let p = k as f64 / nf;
    let d = 1.0 + z * z / nf;
    let c = (p + z * z / (2.0 * nf)) / d;
    let h = z * (p * (1.0 - p) / nf + z * z / (4.0 * nf * nf)).sqrt() / d;
    ((c - h).max(0.0), (c + h).min(1.0))
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    v[i.min(v.len() - 1)]
}

#[derive(Default)]
struct Pool {
    seeds: Vec<u64>,
    /// Per stop, aligned with `errors`: (seed, stop number, true east and north, mm).
    stops: Vec<(u64, u64, i64, i64)>,
    errors: Vec<f64>,
    ranks: Vec<usize>,
    ok: Vec<(f64, f64)>,
    paths: BTreeMap<String, usize>,
    seconds: Vec<f64>,
    config: String,
}

type Pools = BTreeMap<(String, String), Pool>;

/// The reports of `dirs`, pooled per (matcher, condition), and the files read.
fn load(dirs: &[PathBuf]) -> anyhow::Result<(Pools, Vec<PathBuf>)> {
    let mut pools: Pools = BTreeMap::new();
    let mut files: Vec<PathBuf> = Vec::new();
    for dir in dirs {
        let mut here: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot read the report folder {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "json"))
            .collect();
        anyhow::ensure!(
            !here.is_empty(),
            "no .json reports in {}: run `orbfix eval --json` first",
            dir.display()
        );
        here.sort();
        files.extend(here);
    }
    for f in &files {
        let text =
            std::fs::read_to_string(f).with_context(|| format!("cannot read {}", f.display()))?;
        let v: Value = serde_json::from_str(&text)
            .with_context(|| format!("{} is not an eval report (JSON)", f.display()))?;
        let reports = match v {
            Value::Array(a) => a,
            o => vec![o],
        };
        for r in reports {
            let key = (
                r["matcher"].as_str().unwrap_or("?").to_string(),
                r["condition"].as_str().unwrap_or("?").to_string(),
            );
            let p = pools.entry(key).or_default();
            let seed = r["seed"].as_u64();
            if let Some(s) = seed {
                if !p.seeds.contains(&s) {
                    p.seeds.push(s);
                }
            }
            if let Some(c) = r["fix"]["config"].as_str() {
                p.config = c.to_string();
            }
            for q in r["per_query"].as_array().into_iter().flatten() {
                let e = q["error_m"].as_f64().unwrap_or(f64::INFINITY);
                let mm = |i: usize| {
                    (q["truth_m"][i].as_f64().unwrap_or(f64::NAN) * 1000.0).round() as i64
                };
                p.stops.push((
                    seed.unwrap_or(u64::MAX),
                    q["id"].as_u64().unwrap_or(u64::MAX),
                    mm(0),
                    mm(1),
                ));
                p.errors.push(e);
                p.ranks
                    .push(q["true_cell_rank"].as_u64().unwrap_or(u64::MAX) as usize);
                p.seconds.push(q["dense_s"].as_f64().unwrap_or(f64::NAN));
                if q["status"].as_str() == Some("ok") {
                    p.ok.push((e, q["error_bound_m"].as_f64().unwrap_or(f64::INFINITY)));
                }
                if let Some(path) = q["path"].as_str() {
                    *p.paths.entry(path.to_string()).or_insert(0) += 1;
                }
            }
        }
    }
    Ok((pools, files))
}

/// One paired comparison of a share (errors within `limit_m`): stops right here only,
/// right there only, both counted over `n` paired stops.
#[derive(Debug, PartialEq)]
struct Paired {
    n: usize,
    here: usize,
    there: usize,
    only_here: usize,
    only_there: usize,
}

impl Paired {
    /// Pairs the stops of `a` and `b` by (seed, stop number); a stop whose true position
    /// differs between the two is an error (the reports are not of the same stops).
    fn new(a: &Pool, b: &Pool, limit_m: f64) -> anyhow::Result<Self> {
        let theirs: BTreeMap<(u64, u64), (i64, i64, f64)> = b
            .stops
            .iter()
            .zip(&b.errors)
            .map(|(&(s, i, x, y), &e)| ((s, i), (x, y, e)))
            .collect();
        let mut p = Paired {
            n: 0,
            here: 0,
            there: 0,
            only_here: 0,
            only_there: 0,
        };
        for (&(s, i, x, y), &e) in a.stops.iter().zip(&a.errors) {
            let Some(&(bx, by, be)) = theirs.get(&(s, i)) else {
                continue;
            };
            anyhow::ensure!(
                (bx, by) == (x, y),
                "seed {s} stop {i} is at ({x}, {y}) mm in one report and ({bx}, {by}) mm in \
                 the other: --against must hold reports of the same stops (same seeds, stop \
                 counts and conditions)"
            );
            let (ra, rb) = (e <= limit_m, be <= limit_m);
            p.n += 1;
            p.here += usize::from(ra);
            p.there += usize::from(rb);
            p.only_here += usize::from(ra && !rb);
            p.only_there += usize::from(rb && !ra);
        }
        Ok(p)
    }

    /// The difference of the shares (here minus there) and its 95 % interval (normal
    /// approximation of the mean of the paired differences).
    fn difference(&self) -> (f64, f64, f64) {
        if self.n == 0 {
            return (f64::NAN, f64::NAN, f64::NAN);
        }
        let n = self.n as f64;
        let d = (self.only_here as f64 - self.only_there as f64) / n;
        let second = (self.only_here + self.only_there) as f64 / n;
        let var = ((second - d * d) / (n - 1.0).max(1.0)).max(0.0);
        let h = 1.96 * var.sqrt();
        (d, d - h, d + h)
    }
}

/// The folders as the page names them: `a`, `b`.
fn quoted(dirs: &[PathBuf]) -> String {
    dirs.iter()
        .map(|d| format!("`{}`", d.display()))
        .collect::<Vec<_>>()
        .join(", ")
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let (mut pools, files) = load(&a.dir)?;
    let against = if a.against.is_empty() {
        None
    } else {
        Some(load(&a.against)?.0)
    };
    let dirs = quoted(&a.dir);
    let mut md = String::new();
    writeln!(md, "# {}\n", a.title)?;
    writeln!(
        md,
        "Regenerate with `{}`. Every number below is from the reports in {} ({} files); \
         intervals are Wilson 95 %. Wrong-but-confident: status ok and more than 5 m off. \
         Bound coverage: share of ok fixes within their stated error bound. R@k: the true \
         50 m window among the k best of the study's 441 (windows ranked by the best coarse \
         score in their 12.5 m cell).\n",
        a.command,
        dirs,
        files.len()
    )?;
    writeln!(md, "| matcher | condition | seeds | stops | within 1 m | within 5 m | median m | p95 m | ok | wrong-confident | bound coverage | R@1 | R@5 | R@10 | paths | ms/fix (host) |")?;
    writeln!(
        md,
        "|---|---|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|"
    )?;
    let mut configs = BTreeMap::new();
    for ((m, c), p) in &mut pools {
        let n = p.errors.len();
        let k1 = p.errors.iter().filter(|&&e| e <= 1.0).count();
        let k5 = p.errors.iter().filter(|&&e| e <= 5.0).count();
        let (l1, h1) = wilson(k1, n);
        let (l5, h5) = wilson(k5, n);
        let share = |k: usize| k as f64 / n.max(1) as f64;
        let wrong = p.ok.iter().filter(|(e, _)| *e > 5.0).count();
        let covered = p.ok.iter().filter(|(e, b)| e <= b).count();
        let r = |k: usize| share(p.ranks.iter().filter(|&&x| x < k).count());
        let paths: Vec<String> = p
            .paths
            .iter()
            .map(|(k, v)| format!("{k} {:.0} %", 100.0 * share(*v)))
            .collect();
        let mut seeds = p.seeds.clone();
        seeds.sort();
        writeln!(
            md,
            "| {m} | {c} | {} | {n} | {:.3} [{:.3}, {:.3}] | {:.3} [{:.3}, {:.3}] | {:.3} | {:.2} | {} | {} ({:.1} %) | {} | {:.3} | {:.3} | {:.3} | {} | {:.1} |",
            seeds.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", "),
            share(k1), l1, h1,
            share(k5), l5, h5,
            quantile(&mut p.errors.clone(), 0.5),
            quantile(&mut p.errors.clone(), 0.95),
            p.ok.len(),
            wrong,
            100.0 * share(wrong),
            if p.ok.is_empty() { "-".to_string() } else { format!("{:.3}", covered as f64 / p.ok.len() as f64) },
            r(1), r(5), r(10),
            if paths.is_empty() { "-".to_string() } else { paths.join(", ") },
            1000.0 * quantile(&mut p.seconds.clone(), 0.5),
        )?;
        if !p.config.is_empty() {
            configs.insert(m.clone(), p.config.clone());
        }
    }
    if let Some(other) = &against {
        let there = quoted(&a.against);
        writeln!(
            md,
            "\nThe same stops paired with the reports in {there} (same matcher and condition): \
             the share here, there, and here minus there with its 95 % interval (normal \
             approximation of the paired differences); \"only here / only there\": stops within \
             the distance in one set of reports and not in the other.\n"
        )?;
        let mut rows = Vec::new();
        for ((m, c), p) in &pools {
            let Some(q) = other.get(&(m.clone(), c.clone())) else {
                continue;
            };
            let one = Paired::new(p, q, 1.0)?;
            let five = Paired::new(p, q, 5.0)?;
            if one.n == 0 {
                continue;
            }
            let cell = |x: &Paired| {
                let (d, l, h) = x.difference();
                let n = x.n as f64;
                (
                    format!("{:.3} / {:.3}", x.here as f64 / n, x.there as f64 / n),
                    format!("{d:+.3} [{l:+.3}, {h:+.3}]"),
                    format!("{} / {}", x.only_here, x.only_there),
                )
            };
            let (a1, b1, c1) = cell(&one);
            let (a5, b5, c5) = cell(&five);
            rows.push(format!(
                "| {m} | {c} | {} | {a1} | {b1} | {c1} | {a5} | {b5} | {c5} |",
                one.n
            ));
        }
        anyhow::ensure!(
            !rows.is_empty(),
            "no stop of these reports has a partner in {there} (same matcher, condition, seed \
             and stop number): --against needs reports of the same seeds and conditions"
        );
        writeln!(md, "| matcher | condition | paired stops | within 1 m here / there | difference [95 %] | only here / only there | within 5 m here / there | difference [95 %] | only here / only there |")?;
        writeln!(md, "|---|---|---:|---|---|---|---|---|---|")?;
        for r in rows {
            writeln!(md, "{r}")?;
        }
    }
    if !configs.is_empty() {
        writeln!(
            md,
            "\nExact configuration of the core's fix per matcher (`FixConfig`):\n"
        )?;
        for (m, c) in configs {
            writeln!(md, "- `{m}`: `{c}`")?;
        }
    }
    write_atomic(&a.out, md.as_bytes())?;
    println!("{md}");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pool(stops: &[(u64, u64, f64)]) -> Pool {
        Pool {
            stops: stops
                .iter()
                .map(|&(s, i, _)| (s, i, 1000 * i as i64, 7))
                .collect(),
            errors: stops.iter().map(|&(_, _, e)| e).collect(),
            ..Pool::default()
        }
    }

    #[test]
    fn paired_shares_count_the_same_stops() {
        let a = pool(&[
            (2, 0, 0.1),
            (2, 1, 9.0),
            (2, 2, 0.5),
            (3, 0, 3.0),
            (3, 1, 0.2),
        ]);
        let b = pool(&[
            (2, 0, 0.1),
            (2, 1, 0.3),
            (2, 2, 7.0),
            (3, 0, 0.4),
            (4, 0, 0.1),
        ]);
        let p = Paired::new(&a, &b, 1.0).unwrap();
        // (3, 1) and (4, 0) have no partner.
        assert_eq!(
            p,
            Paired {
                n: 4,
                here: 2,
                there: 3,
                only_here: 1,
                only_there: 2
            }
        );
        let (d, l, h) = p.difference();
        assert!((d + 0.25).abs() < 1e-12 && l < d && h > d, "{d} {l} {h}");
        let same = Paired::new(&a, &a, 5.0).unwrap();
        assert_eq!(same.difference(), (0.0, 0.0, 0.0));
        // Another stop under the same number is refused.
        let mut moved = pool(&[(2, 0, 0.1)]);
        moved.stops[0].3 = 8;
        let e = Paired::new(&a, &moved, 1.0).unwrap_err().to_string();
        assert!(e.contains("same stops"), "{e}");
    }

    #[test]
    fn wilson_interval_brackets_the_share() {
        let (l, h) = wilson(98, 100);
        assert!(l < 0.98 && h > 0.98 && l > 0.92 && h <= 1.0, "{l} {h}");
        assert!(wilson(0, 0).0.is_nan());
        assert_eq!(quantile(&mut [3.0, 1.0, 2.0], 0.5), 2.0);
    }
}
