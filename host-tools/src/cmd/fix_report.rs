//! `orbfix fix-report`: pools `orbfix eval` reports of several world seeds into the table a
//! user of the fix reads (shares within 1 m and 5 m with 95 % intervals, median and p95
//! error, wrong-but-confident fixes, bound coverage, the study's 441-window R@k), per
//! matcher and condition.

use anyhow::Context;
use orbfix_host::fsutil::write_atomic;
use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Pool eval reports (JSON, one file per seed and condition) into one markdown table.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of the reports (`*.json` written by `orbfix eval --json`).
    #[arg(long)]
    pub dir: PathBuf,
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
    errors: Vec<f64>,
    ranks: Vec<usize>,
    ok: Vec<(f64, f64)>,
    paths: BTreeMap<String, usize>,
    seconds: Vec<f64>,
    config: String,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut pools: BTreeMap<(String, String), Pool> = BTreeMap::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(&a.dir)
        .with_context(|| format!("cannot read the report folder {}", a.dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    anyhow::ensure!(
        !files.is_empty(),
        "no .json reports in {}: run `orbfix eval --json` first",
        a.dir.display()
    );
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
            if let Some(s) = r["seed"].as_u64() {
                if !p.seeds.contains(&s) {
                    p.seeds.push(s);
                }
            }
            if let Some(c) = r["fix"]["config"].as_str() {
                p.config = c.to_string();
            }
            for q in r["per_query"].as_array().into_iter().flatten() {
                let e = q["error_m"].as_f64().unwrap_or(f64::INFINITY);
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
    let mut md = String::new();
    writeln!(md, "# {}\n", a.title)?;
    writeln!(
        md,
        "Regenerate with `{}`. Every number below is from the reports in `{}` ({} files); \
         intervals are Wilson 95 %. Wrong-but-confident: status ok and more than 5 m off. \
         Bound coverage: share of ok fixes within their stated error bound. R@k: the true \
         50 m window among the k best of the study's 441 (windows ranked by the best coarse \
         score in their 12.5 m cell).\n",
        a.command,
        a.dir.display(),
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

    #[test]
    fn wilson_interval_brackets_the_share() {
        let (l, h) = wilson(98, 100);
        assert!(l < 0.98 && h > 0.98 && l > 0.92 && h <= 1.0, "{l} {h}");
        assert!(wilson(0, 0).0.is_nan());
        assert_eq!(quantile(&mut [3.0, 1.0, 2.0], 0.5), 2.0);
    }
}
