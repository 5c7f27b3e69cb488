//! `imagine compare A.json B.json`: two renders' statistics (`render --stats`) side by side
//! — cycles, frames/s, where the cycles went, the kernel breakdown, bandwidths and the error
//! against the reference — each with B's ratio to A, the largest differences first.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::Value;

#[derive(Args)]
pub struct CompareArgs {
    /// Statistics of the first render (`imagine render ... --stats A.json`)
    a: PathBuf,
    /// Statistics of the second render, compared with the first
    b: PathBuf,
    /// The comparison as JSON
    #[arg(long)]
    json: bool,
    /// Show at most N rows (the largest differences)
    #[arg(long, value_name = "N")]
    top: Option<usize>,
}

/// One quantity of both renders.
struct Row {
    section: &'static str,
    name: String,
    unit: &'static str,
    a: f64,
    b: f64,
}

impl Row {
    /// B over A (`None` when A is 0 and B is not).
    fn ratio(&self) -> Option<f64> {
        if self.a == self.b {
            Some(1.0)
        } else if self.a == 0.0 {
            None
        } else {
            Some(self.b / self.a)
        }
    }

    /// How far apart the two are, for ordering: |ln(B/A)|, a value present in one render
    /// only counting as the farthest.
    fn distance(&self) -> f64 {
        match self.ratio() {
            Some(r) if r > 0.0 => r.ln().abs(),
            _ => f64::INFINITY,
        }
    }
}

fn read(path: &Path) -> Result<Value> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read `{}`", path.display()))?;
    let v: Value =
        serde_json::from_str(&text).with_context(|| format!("`{}` is not JSON", path.display()))?;
    if !v["frame"]["cycles"].is_u64() {
        bail!(
            "`{}` is not a render's statistics (written by `imagine render --stats F.json`): no frame.cycles",
            path.display()
        );
    }
    Ok(v)
}

fn number(v: &Value) -> f64 {
    v.as_f64().unwrap_or(0.0)
}

/// Every compared quantity of `a` and `b`.
fn rows(a: &Value, b: &Value) -> Vec<Row> {
    let (fa, fb) = (&a["frame"], &b["frame"]);
    let mut rows = Vec::new();
    let mut add = |section, name: &str, unit, key: &dyn Fn(&Value) -> &Value| {
        rows.push(Row {
            section,
            name: name.to_string(),
            unit,
            a: number(key(a)),
            b: number(key(b)),
        });
    };
    for (name, unit, key) in [
        ("cycles", "cycles", "cycles"),
        ("frames per second", "frames/s", "frames_per_second"),
        ("vertices per second", "vertices/s", "vertices_per_second"),
        (
            "fragments per second",
            "fragments/s",
            "fragments_per_second",
        ),
        ("fragments", "fragments", "fragments"),
        ("ops per cycle", "ops/cycle", "ops_per_cycle"),
        ("cluster occupancy", "share", "cluster_occupancy"),
        ("batches", "batches", "batches"),
        ("composite rounds", "rounds", "composite_rounds"),
    ] {
        add("frame", name, unit, &|v: &Value| &v["frame"][key]);
    }
    for (name, unit, key) in [
        ("DRAM", "GB/s", "dram_gbs"),
        ("DRAM row hits", "share", "dram_row_hit_rate"),
        ("SRF", "words/cycle", "srf_words_per_cycle"),
        ("LRF reads", "words/cycle", "lrf_reads_per_cycle"),
        ("LRF writes", "words/cycle", "lrf_writes_per_cycle"),
    ] {
        add("bandwidth", name, unit, &|v: &Value| &v["frame"][key]);
    }
    for (name, unit, key) in [
        ("PSNR", "dB", "psnr_db"),
        ("max abs error", "levels of 255", "max_abs_error"),
        ("pixels differing", "share", "differing_share"),
        ("coverage differing", "share", "coverage_mismatch_share"),
    ] {
        add("error", name, unit, &|v: &Value| &v["reference_error"][key]);
    }
    // Categories and kernels present in either render.
    let keys = |v: &Value| -> Vec<String> {
        v.as_object()
            .map(|o| o.keys().cloned().collect())
            .unwrap_or_default()
    };
    for (section, key) in [
        ("where cycles went", "attribution"),
        ("waiting, on what", "waiting_on"),
    ] {
        let mut categories = keys(&fa[key]);
        for k in keys(&fb[key]) {
            if !categories.contains(&k) {
                categories.push(k);
            }
        }
        for c in categories {
            rows.push(Row {
                section,
                name: c.replace('_', " "),
                unit: "cycles",
                a: number(&fa[key][&c]),
                b: number(&fb[key][&c]),
            });
        }
    }
    let kernels = |v: &Value| -> Vec<(String, f64)> {
        v["kernels"]
            .as_array()
            .map(|ks| {
                ks.iter()
                    .map(|k| {
                        (
                            k["kernel"].as_str().unwrap_or("?").to_string(),
                            number(&k["cycles"]),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default()
    };
    let (ka, kb) = (kernels(fa), kernels(fb));
    let mut names: Vec<&String> = ka.iter().map(|(n, _)| n).collect();
    names.extend(
        kb.iter()
            .map(|(n, _)| n)
            .filter(|n| !ka.iter().any(|(m, _)| m == *n)),
    );
    for name in names {
        let of = |ks: &[(String, f64)]| ks.iter().find(|(n, _)| n == name).map_or(0.0, |k| k.1);
        rows.push(Row {
            section: "kernel cycles",
            name: name.clone(),
            unit: "cycles",
            a: of(&ka),
            b: of(&kb),
        });
    }
    rows
}

fn label(v: &Value) -> String {
    let f = &v["frame"];
    format!(
        "{} on {} ({}x{})",
        f["scene"].as_str().unwrap_or("?"),
        f["machine"].as_str().unwrap_or("?"),
        f["width"],
        f["height"]
    )
}

pub fn run(args: CompareArgs) -> Result<ExitCode> {
    let (a, b) = (read(&args.a)?, read(&args.b)?);
    let mut rows = rows(&a, &b);
    rows.sort_by(|x, y| y.distance().total_cmp(&x.distance()));
    if let Some(n) = args.top {
        rows.truncate(n);
    }
    if args.json {
        let out: Vec<Value> = rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "section": r.section, "name": r.name, "unit": r.unit,
                    "a": r.a, "b": r.b, "ratio": r.ratio(),
                })
            })
            .collect();
        let doc = serde_json::json!({
            "a": {"file": args.a, "render": label(&a)},
            "b": {"file": args.b, "render": label(&b)},
            "rows": out,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("A  {}  {}", args.a.display(), label(&a));
    println!("B  {}  {}", args.b.display(), label(&b));
    println!("(largest differences first; ratio is B / A)");
    println!(
        "{:<18} {:<26} {:>16} {:>16} {:>9}  unit",
        "section", "quantity", "A", "B", "B/A"
    );
    for r in &rows {
        let ratio = match r.ratio() {
            Some(x) => format!("{x:.3}"),
            None => "new".into(),
        };
        println!(
            "{:<18} {:<26} {:>16} {:>16} {:>9}  {}",
            r.section,
            r.name,
            show(r.a),
            show(r.b),
            ratio,
            r.unit
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Whole numbers as they are, others to four significant places.
fn show(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{x:.0}")
    } else if x.abs() >= 1000.0 {
        format!("{x:.1}")
    } else {
        format!("{x:.4}")
    }
}
