//! The command line: help, clear errors with non-zero exits, and the demo's report.

use std::process::{Command, Output};

fn imagine(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imagine"))
        .args(args)
        .output()
        .expect("run imagine")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn help_lists_every_subcommand() {
    let o = imagine(&["--help"]);
    assert!(o.status.success());
    let out = stdout(&o);
    for sub in ["render", "verify", "kernel", "machine", "dram", "demo"] {
        assert!(out.contains(sub), "`{sub}` missing from help:\n{out}");
    }
    let o = imagine(&["demo", "--help"]);
    assert!(stdout(&o).contains("--vcd-window"), "{}", stdout(&o));
}

#[test]
fn bad_arguments_are_errors_not_panics() {
    for args in [
        &["demo", "--cycles", "lots"][..],
        &["no-such-command"],
        &["demo", "--vcd-window", "5:3", "--vcd", "x.vcd"],
        &["demo", "--vcd-window", "a:b", "--vcd", "x.vcd"],
        &["demo", "--core-mhz", "0"],
        &["demo", "--core-mhz", "99999999999999"],
        &["demo", "--crossing-capacity", "0"],
        &["render"],
        &["machine", "list"],
    ] {
        let o = imagine(args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains("error"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn unwritable_vcd_is_a_clear_error() {
    let o = imagine(&[
        "demo",
        "--cycles",
        "10",
        "--vcd",
        "/nonexistent-dir/out.vcd",
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.starts_with("error:") && err.contains("/nonexistent-dir/out.vcd"),
        "{err}"
    );
}

#[test]
fn vcd_options_need_a_vcd_file() {
    let o = imagine(&["demo", "--cycles", "10", "--vcd-scope", "top.mac"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--vcd"), "{}", stderr(&o));
}

#[test]
fn demo_reports_a_result_matching_its_model() {
    let o = imagine(&["demo", "--cycles", "30000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("core cycles        30000"), "{out}");
    // 30000 core cycles at 500 MHz are 10020 DRAM cycles at 167 MHz (edges 0..=10019).
    assert!(out.contains("dram cycles        10020"), "{out}");
    assert!(out.contains("results match the behavioural model"), "{out}");
}
