//! `imagine sweep`: a small grid renders, its CSV has a row per point in grid order with
//! the measured columns, a rerun renders nothing and writes the same CSV, a changed scene
//! file is rendered again, and bad knobs are clear errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the CLI with its compile cache under the target directory (never the user's).
fn imagine(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imagine"))
        .env(
            "IMAGINE_CACHE_DIR",
            concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache"),
        )
        .args(args)
        .output()
        .expect("run imagine")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn succeeds(args: &[&str]) -> Output {
    let o = imagine(args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    o
}

/// A fresh directory of the test's own.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("sweep-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The CSV's header and rows, split on commas (no field holds one).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text
        .lines()
        .map(|l| l.split(',').map(String::from).collect());
    (lines.next().unwrap(), lines.collect())
}

fn column<'a>(header: &[String], row: &'a [String], name: &str) -> &'a str {
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    &row[i]
}

fn lines(path: &Path) -> usize {
    std::fs::read_to_string(path).unwrap().lines().count()
}

#[test]
fn a_batch_sweep_measures_each_point_once_and_keeps_grid_order() {
    let dir = scratch("batch");
    let csv = dir.join("rate.csv");
    let plot = dir.join("rate.png");
    let points = dir.join("rate.points.jsonl");
    let (csv_s, plot_s) = (csv.to_str().unwrap(), plot.to_str().unwrap());
    let sweep = |batches: &str| {
        succeeds(&[
            "sweep", "RATE-8", "--size", "32", "--knob", batches, "--csv", csv_s, "--plot", plot_s,
            "--jobs", "2",
        ])
    };
    let first = sweep("batch=8,64");
    assert!(
        stderr(&first).contains("2 points, 0 already"),
        "{}",
        stderr(&first)
    );
    // With batch a knob, the batch model's fit: a smaller batch costs more, so c_b > 0.
    let out = String::from_utf8_lossy(&first.stdout).to_string();
    let fit = out
        .lines()
        .find(|l| l.contains("R²"))
        .unwrap_or_else(|| panic!("no batch model in:\n{out}"));
    let c_b: f64 = fit
        .split("c_b ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        c_b > 0.0 && fit.contains("b½") && fit.contains("c∞"),
        "{fit}"
    );
    let (header, rows) = read_csv(&csv);
    for name in [
        "batch",
        "cycles",
        "frames_per_second",
        "host_seconds",
        "cluster_occupancy",
        "batch_triangles",
        "batches",
        "dram_gbs",
        "psnr_db",
        "max_abs_error",
        "differing_pixels_share",
        "coverage_differences_share",
        "covered_psnr_db",
        "covered_max_abs_error_levels",
        "wrongly_covered_share",
        "missed_share",
        "visibility_differing_share",
        "texture_cache_hit_rate",
    ] {
        assert!(
            header.iter().any(|h| h == name),
            "{name} missing from {header:?}"
        );
    }
    assert_eq!(rows.len(), 2);
    let cell = |r: &[String], name: &str| column(&header, r, name).to_string();
    assert_eq!(cell(&rows[0], "batch"), "8");
    assert_eq!(cell(&rows[1], "batch"), "64");
    let cycles: Vec<u64> = rows
        .iter()
        .map(|r| cell(r, "cycles").parse().unwrap())
        .collect();
    assert!(cycles.iter().all(|&c| c > 0));
    assert_ne!(cycles[0], cycles[1], "the batch size changes the cycles");
    // The pipeline takes at most the batch asked for, and a smaller one needs more batches.
    let number = |r: &[String], name: &str| cell(r, name).parse::<f64>().unwrap();
    assert!(number(&rows[0], "batch_triangles") <= 8.0);
    assert!(number(&rows[0], "batches") > number(&rows[1], "batches"));
    assert!((0.0..=1.0).contains(&number(&rows[0], "cluster_occupancy")));
    // Frames/s are modelled at the one machine's clock: frames/s × cycles is that clock.
    let clock: Vec<f64> = rows
        .iter()
        .map(|r| {
            cell(r, "frames_per_second").parse::<f64>().unwrap()
                * cell(r, "cycles").parse::<f64>().unwrap()
        })
        .collect();
    assert!(
        clock[0] > 0.0 && (clock[0] / clock[1] - 1.0).abs() < 1e-4,
        "{clock:?}"
    );
    for r in &rows {
        for share in [
            "wrongly_covered_share",
            "missed_share",
            "visibility_differing_share",
        ] {
            let v: f64 = cell(r, share).parse().unwrap();
            assert!((0.0..=1.0).contains(&v), "{share} {v}");
        }
    }
    // The image does not depend on the batch.
    assert_eq!(cell(&rows[0], "psnr_db"), cell(&rows[1], "psnr_db"));
    // gold8 has no texture cache.
    assert_eq!(cell(&rows[0], "texture_cache_hit_rate"), "");
    assert_eq!(&std::fs::read(&plot).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(lines(&points), 2);

    // Run again: nothing to render, the same CSV byte for byte (host seconds included:
    // they are the recorded ones).
    let before = std::fs::read(&csv).unwrap();
    let again = sweep("batch=8,64");
    assert!(stderr(&again).contains("2 already") && stderr(&again).contains("0 to render"));
    assert_eq!(std::fs::read(&csv).unwrap(), before);
    assert_eq!(lines(&points), 2);

    // The values in another order: rows follow the grid as given, still nothing rendered.
    let reversed = sweep("batch=64,8");
    assert!(
        stderr(&reversed).contains("0 to render"),
        "{}",
        stderr(&reversed)
    );
    let (_, rows_reversed) = read_csv(&csv);
    assert_eq!(rows_reversed, vec![rows[1].clone(), rows[0].clone()]);
}

#[test]
fn a_changed_scene_file_is_rendered_again() {
    let dir = scratch("changed");
    let tri = dir.join("two.tri");
    let csv = dir.join("two.csv");
    let (tri_s, csv_s) = (tri.to_str().unwrap(), csv.to_str().unwrap());
    let sweep = || {
        stderr(&succeeds(&[
            "sweep",
            tri_s,
            "--knob",
            "flush_to_zero=false",
            "--csv",
            csv_s,
        ]))
    };
    std::fs::write(
        &tri,
        "16 16\n1 1 0.5 1 0 0  14 1 0.5 0 1 0  1 14 0.5 0 0 1\n",
    )
    .unwrap();
    assert!(sweep().contains("0 already"));
    assert!(sweep().contains("1 already"));
    std::fs::write(
        &tri,
        "16 16\n1 1 0.5 1 0 0  14 1 0.5 0 1 0  14 14 0.5 0 0 1\n",
    )
    .unwrap();
    let changed = sweep();
    assert!(
        changed.contains("0 already") && changed.contains("1 to render"),
        "{changed}"
    );
    assert_eq!(read_csv(&csv).1.len(), 1);
}

#[test]
fn bad_knobs_are_clear_errors() {
    let dir = scratch("bad");
    let csv = dir.join("bad.csv");
    let csv_s = csv.to_str().unwrap();
    for (knob, says) in [
        (
            "stop_size=1,2",
            "no knob is named `stop_size`; the knobs are machine",
        ),
        (
            "stop_length=8",
            "stop_length takes Reyes's largest quad side",
        ),
        ("batch=0", "batch takes triangles per batch"),
        ("filter=cubic", "filter takes nearest, bilinear"),
        ("flush_to_zero=maybe", "true, false"),
        ("machine=gold7", "gold8"),
        ("batch", "NAME=V1,V2"),
    ] {
        let o = imagine(&["sweep", "RATE-8", "--knob", knob, "--csv", csv_s]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{knob} succeeded");
        assert!(err.contains("error") && err.contains(says), "{knob}: {err}");
        assert!(!err.contains("panicked"), "{knob}: {err}");
    }
    let o = imagine(&[
        "sweep", "RATE-8", "--knob", "batch=8", "--knob", "batch=16", "--csv", csv_s,
    ]);
    assert!(stderr(&o).contains("given twice"), "{}", stderr(&o));
    let o = imagine(&[
        "sweep",
        "TEAPOT-20",
        "--knob",
        "stop_length=1.5",
        "--knob",
        "filter=nearest",
        "--csv",
        csv_s,
    ]);
    assert!(
        stderr(&o).contains("filter is a setting of the OpenGL pipeline"),
        "{}",
        stderr(&o)
    );
    assert!(!csv.exists(), "no CSV is written for a refused sweep");
}

/// A point that cannot render (a machine whose SRF cannot hold the pipeline's streams) does
/// not stop the others: its row holds the error, the sweep exits non-zero, and a rerun
/// tries it again while keeping the points that rendered.
#[test]
fn a_failing_point_is_reported_and_the_others_are_kept() {
    let dir = scratch("failing");
    let csv = dir.join("f.csv");
    let small = dir.join("small-srf.toml");
    std::fs::write(
        &small,
        "name = \"small-srf\"\nbase = \"gold8\"\ndescription = \"too small an SRF\"\n\
         [srf]\nwords = 1024\n",
    )
    .unwrap();
    let knob = format!("machine=gold8,{}", small.display());
    let args = [
        "sweep",
        "RATE-8",
        "--size",
        "32",
        "--knob",
        &knob,
        "--csv",
        csv.to_str().unwrap(),
    ];
    let o = imagine(&args);
    assert!(!o.status.success(), "a failed point fails the sweep");
    let err = stderr(&o);
    assert!(
        err.contains("1 points failed") && !err.contains("panicked"),
        "{err}"
    );
    let (header, rows) = read_csv(&csv);
    assert_eq!(rows.len(), 2);
    assert!(column(&header, &rows[0], "error").is_empty());
    assert!(column(&header, &rows[0], "cycles").parse::<u64>().unwrap() > 0);
    assert!(column(&header, &rows[1], "cycles").is_empty());
    assert!(
        column(&header, &rows[1], "error").contains("small-srf"),
        "{rows:?}"
    );
    // The rerun renders only the failed point again.
    let again = imagine(&args);
    assert!(stderr(&again).contains("1 already"), "{}", stderr(&again));
}

/// The Reyes stop length trades cycles for error on the Utah teapot's patches: a shorter
/// one dices finer, costs more and comes closer to the densely diced reference.
#[test]
#[ignore = "compiles the Reyes kernels: minutes cold"]
fn a_shorter_reyes_stop_length_costs_cycles_and_buys_psnr() {
    let dir = scratch("reyes");
    let csv = dir.join("teapot.csv");
    let o = imagine(&[
        "sweep",
        "TEAPOT-20",
        "--machine",
        "reyes",
        "--size",
        "96",
        "--knob",
        "stop_length=1.0,3.0",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (header, rows) = read_csv(&csv);
    let value = |r: usize, name: &str| column(&header, &rows[r], name).parse::<f64>().unwrap();
    assert!(value(0, "cycles") > value(1, "cycles"));
    assert!(value(0, "quads") > 2.0 * value(1, "quads"));
    assert!(value(0, "psnr_db") > value(1, "psnr_db"));
    assert!(value(0, "psnr_db") > 25.0, "{rows:?}");
}
