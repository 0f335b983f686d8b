//! `orbfix results`: writes docs/results.md from the eval reports of `scripts/results.sh`.

use anyhow::Context;
use orbfix_host::eval::write_atomic;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Write the results table (markdown) from `eval_<reprojection>_<condition>.json` reports.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of the reports (scripts/results.sh writes out/results).
    #[arg(long, default_value = "out/results")]
    pub dir: PathBuf,
    /// Output markdown file.
    #[arg(long, default_value = "docs/results.md")]
    pub out: PathBuf,
    /// The command that produced the reports (quoted in the page).
    #[arg(long, default_value = "bash scripts/results.sh")]
    pub command: String,
    /// Title of the page.
    #[arg(long, default_value = "Results: matchers x conditions")]
    pub title: String,
    /// Markdown appended after the tables.
    #[arg(long, default_value = "docs/results_notes.md")]
    pub notes: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut md = String::new();
    writeln!(md, "# {}\n", a.title)?;
    writeln!(
        md,
        "Regenerate with `{}` (it runs `orbfix eval` per reprojection and condition, then \
         `orbfix results`). Setting and metrics: `docs/localization.md`. Every number below \
         is from that run.\n",
        a.command
    )?;
    let mut first = true;
    for rep in ["lut", "range", "range-noise"] {
        for cond in ["same-sun", "cross-sun"] {
            let p = a.dir.join(format!("eval_{rep}_{cond}.json"));
            if !p.exists() {
                continue;
            }
            let text = std::fs::read_to_string(&p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let v: serde_json::Value = serde_json::from_str(&text)
                .with_context(|| format!("{} is not an eval report", p.display()))?;
            let reports = match v {
                serde_json::Value::Array(a) => a,
                o => vec![o],
            };
            if first {
                if let Some(r) = reports.first() {
                    writeln!(
                        md,
                        "World seed {}, {} queries per table (generated in the test zone), {} windows per query.\n",
                        r["seed"], r["queries"], r["windows_per_query"]
                    )?;
                }
                first = false;
            }
            let what = match rep {
                "lut" => "flight LUT reprojection (flat ground)",
                "range" => "flight range reprojection (exact depth images, mm)",
                _ => "flight range reprojection, stereo depth noise sigma = 0.001 z^2 m",
            };
            writeln!(md, "## {cond}, {what}\n")?;
            writeln!(md, "| matcher | R@1 | R@5 | R@10 | dense R@1 | dense R@5 | dense R@10 | median error m | p95 error m | within 1 m | within 5 m | pair AUC | pair error | border | conf. (ok / wrong) | dense ms | 441-window ms |")?;
            writeln!(
                md,
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
            )?;
            for r in &reports {
                let f =
                    |x: &serde_json::Value| x.as_f64().map_or("-".into(), |v| format!("{v:.2}"));
                writeln!(
                    md,
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} / {} | {:.1} | {:.1} |",
                    r["matcher"].as_str().unwrap_or("?"),
                    f(&r["recall_at"]["1"]),
                    f(&r["recall_at"]["5"]),
                    f(&r["recall_at"]["10"]),
                    f(&r["recall_at_dense"]["1"]),
                    f(&r["recall_at_dense"]["5"]),
                    f(&r["recall_at_dense"]["10"]),
                    f(&r["median_error_m"]),
                    f(&r["p95_error_m"]),
                    f(&r["within_m"]["1"]),
                    f(&r["within_m"]["5"]),
                    f(&r["pairs"]["auc"]),
                    f(&r["pairs"]["error_rate"]),
                    r["border_rejections"],
                    f(&r["mean_confidence_correct"]),
                    f(&r["mean_confidence_wrong"]),
                    r["mean_dense_s"].as_f64().unwrap_or(f64::NAN) * 1e3,
                    r["mean_windows_s"].as_f64().unwrap_or(f64::NAN) * 1e3,
                )?;
            }
            writeln!(md)?;
        }
    }
    anyhow::ensure!(
        !first,
        "no eval reports (eval_<lut|range>_<same-sun|cross-sun>.json) in {}: run scripts/results.sh",
        a.dir.display()
    );
    let notes = std::fs::read_to_string(&a.notes).unwrap_or_default();
    md.push_str(&notes);
    write_atomic(&a.out, md.as_bytes())?;
    println!("{}", a.out.display());
    Ok(())
}
