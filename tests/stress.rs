//! `imagine stress`: a subset chosen with `--filter` runs (among them the case of clip
//! coordinates at 2^-56, which do not vanish with `normalise_clip`), prints a verdict per case and
//! `N passed, M failed`, writes its JSON report, and exits zero only when nothing failed;
//! `--list` names at least 30 cases; a filter that matches nothing is an error.

use std::path::Path;
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

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn a_filtered_subset_reports_each_case_and_the_totals() {
    let json = Path::new(env!("CARGO_TARGET_TMPDIR")).join("stress-subset.json");
    let _ = std::fs::remove_file(&json);
    // The invalid-input family (no render), a rendered case that must draw nothing, and
    // clip space scaled by 2^-56, whose determinant underflows fp32 unless `assemble_clip`
    // normalises each triangle's corners (nothing is drawn: a known failure without).
    for (filter, cases, known) in [
        ("invalid", 10, 0),
        ("zero-area", 1, 0),
        ("clip-scale-2^-56", 1, 1),
    ] {
        let o = imagine(&[
            "stress",
            "--filter",
            filter,
            "--json",
            json.to_str().unwrap(),
        ]);
        let out = text(&o.stdout);
        assert!(o.status.success(), "{filter}: {out}{}", text(&o.stderr));
        assert!(
            out.contains(&format!("{cases} passed, 0 failed ({known} known failure")),
            "{out}"
        );
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(report["passed"], cases);
        assert_eq!(report["failed"], 0);
        let listed = report["cases"].as_array().unwrap();
        assert_eq!(listed.len(), cases + known);
        for case in listed {
            let name = case["name"].as_str().unwrap();
            assert!(name.contains(filter) || case["family"] == filter, "{name}");
            let status = if name.ends_with("-unnormalised") {
                "known_failure"
            } else {
                "pass"
            };
            assert_eq!(case["status"], status, "{case}");
            assert!(out.contains(name), "{name} has its line");
        }
        if filter == "invalid" {
            // Each error names the file it came from.
            for case in listed {
                let reason = case["reason"].as_str().unwrap();
                assert!(reason.starts_with("clean error: "), "{reason}");
                assert!(
                    reason.contains(".tri") || reason.contains(".toml"),
                    "{reason}"
                );
            }
        } else {
            assert!(listed[0]["cycles"].as_u64().unwrap() > 0);
        }
    }
}

#[test]
fn the_list_holds_thirty_cases_and_an_empty_filter_is_an_error() {
    let o = imagine(&["stress", "--list"]);
    assert!(o.status.success());
    let out = text(&o.stdout);
    let count: usize = out
        .lines()
        .last()
        .and_then(|l| l.strip_suffix(" cases"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{out}"));
    assert!(count >= 30, "{count}");
    for family in ["window", "world", "degenerate", "invalid"] {
        assert!(out.lines().any(|l| l.starts_with(family)), "{family}");
    }
    let o = imagine(&["stress", "--filter", "no-such-case"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("matches no case"),
        "{}",
        text(&o.stderr)
    );
}
