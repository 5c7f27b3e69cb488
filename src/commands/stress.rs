//! `imagine stress`: the extreme suite (ARCHITECTURE §8, numerical stability on stiff and
//! extreme cases). Each case is a scene built in code, or a set of invalid input files,
//! with the properties it must keep; the suite renders every case on the clocked machine
//! (gold8) and prints a verdict with a one-line reason per case, then `N passed, M failed`,
//! and exits non-zero on any failure.
//!
//! Families, one file each: [`window_space`] (slivers, needles, huge triangles, cancellation,
//! pixel-centre ties, meshes that must tile), [`world_space`] (subnormal and near-underflow
//! coordinates and texture coordinates, flush-to-zero, 10⁶ texture repeats, the eye plane,
//! extreme depth ranges, cancellation far from the origin), [`degenerate`] (faces and
//! patches of no area) and [`invalid`] (NaN, infinities and zero-size windows in files).
//! What a case checks is in [`case`]; the checks themselves, pure functions of a frame's
//! words, in [`check`].
//!
//! A case that panics is caught and reported as a failure. A case marked as a known
//! failure (its reason in the case and the README) is reported as such and does not fail
//! the run; once it passes it is reported as a failure, so that the mark is removed.

mod case;
mod check;
mod degenerate;
mod invalid;
mod window_space;
mod world_space;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_pipelines::compile::CompileCache;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;

use self::case::{Case, Measured};
use super::outputs::Outputs;

#[derive(Args)]
pub struct StressArgs {
    /// Also write the report as JSON to this file
    #[arg(long, value_name = "F.json")]
    json: Option<PathBuf>,
    /// Run only the cases whose name or family contains SUBSTR
    #[arg(long, value_name = "SUBSTR")]
    filter: Option<String>,
    /// Cases run at once [default: the host's logical CPUs]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256))]
    jobs: Option<u32>,
    /// Write each failing (or known-failing) rendered case's frame as DIR/NAME.png, and
    /// the reference's as DIR/NAME.reference.png where it was compared
    #[arg(long, value_name = "DIR")]
    images: Option<PathBuf>,
    /// List the cases (name, family, what each keeps) without running them
    #[arg(long)]
    list: bool,
}

/// Every case of the suite, in report order.
fn all_cases() -> Vec<Case> {
    let mut cases = window_space::cases();
    cases.extend(world_space::cases());
    cases.extend(degenerate::cases());
    cases.extend(invalid::cases());
    cases
}

/// A case's verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
enum Status {
    Pass,
    Fail,
    /// Fails for the reason its mark gives.
    KnownFailure,
}

impl Status {
    fn word(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Fail => "FAIL",
            Status::KnownFailure => "known",
        }
    }
}

#[derive(Serialize)]
struct CaseReport {
    name: &'static str,
    family: &'static str,
    about: &'static str,
    status: Status,
    reason: String,
    known_failure: Option<&'static str>,
    seconds: f64,
    cycles: Option<u64>,
    coverage_error_share: Option<f64>,
    visibility_error_share: Option<f64>,
    same_triangle_error_levels: Option<u8>,
    #[serde(skip)]
    images: Box<case::Images>,
}

#[derive(Serialize)]
struct Report {
    machine: &'static str,
    passed: usize,
    failed: usize,
    known_failures: usize,
    seconds: f64,
    cases: Vec<CaseReport>,
}

/// The frames of the cases that did not pass, as PNG in `dir`.
fn write_images(dir: &Path, reports: &[CaseReport]) -> Result<()> {
    for r in reports.iter().filter(|r| r.status != Status::Pass) {
        let images = [
            (&r.images.machine, format!("{}.png", r.name)),
            (&r.images.reference, format!("{}.reference.png", r.name)),
        ];
        for (image, file) in images {
            if let Some(image) = image {
                image
                    .write_png(dir.join(&file))
                    .map_err(anyhow::Error::msg)?;
            }
        }
    }
    Ok(())
}

/// The text of a panic's payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// Runs one case, a panic caught as a failure, and judges it against its known-failure
/// mark.
fn run_case(case: &Case, dir: &Path, cache: &CompileCache) -> CaseReport {
    let start = Instant::now();
    let outcome = catch_unwind(AssertUnwindSafe(|| {
        case::run(case, &dir.join(case.name), cache)
    }))
    .unwrap_or_else(|payload| {
        Err(Measured::said(format!(
            "panicked: {}",
            panic_message(payload.as_ref())
        )))
    });
    let (status, measured) = match (outcome, case.known_failure) {
        (Ok(m), None) => (Status::Pass, m),
        (Err(m), None) => (Status::Fail, m),
        (Err(m), Some(_)) => (Status::KnownFailure, m),
        (Ok(mut m), Some(_)) => {
            m.reason = format!(
                "passes, but is marked as a known failure: remove the mark ({})",
                m.reason
            );
            (Status::Fail, m)
        }
    };
    CaseReport {
        name: case.name,
        family: case.family,
        about: case.about,
        status,
        reason: measured.reason,
        known_failure: case.known_failure,
        seconds: start.elapsed().as_secs_f64(),
        cycles: measured.cycles,
        coverage_error_share: measured.coverage_error_share,
        visibility_error_share: measured.visibility_error_share,
        same_triangle_error_levels: measured.same_triangle_error_levels,
        images: measured.images,
    }
}

pub fn run(a: StressArgs) -> Result<ExitCode> {
    let cases: Vec<Case> = all_cases()
        .into_iter()
        .filter(|c| {
            a.filter
                .as_deref()
                .is_none_or(|f| c.name.contains(f) || c.family.contains(f))
        })
        .collect();
    if cases.is_empty() {
        bail!(
            "--filter `{}` matches no case (`imagine stress --list` lists them)",
            a.filter.as_deref().unwrap_or_default()
        );
    }
    if a.list {
        for c in &cases {
            let mark = if c.known_failure.is_some() {
                " [known failure]"
            } else {
                ""
            };
            println!("{:<12} {:<34} {}{mark}", c.family, c.name, c.about);
        }
        println!("{} cases", cases.len());
        return Ok(ExitCode::SUCCESS);
    }
    Outputs::default().add_opt("--json", a.json.as_ref())?;
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--images: cannot create `{}`", dir.display()))?;
    }
    let jobs = a.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |j| j as usize,
    );
    // Invalid cases write their files here; removed at the end.
    let dir = std::env::temp_dir().join(format!("imagine-stress-{}", std::process::id()));
    let cache = CompileCache::from_env();
    let start = Instant::now();
    let bar = ProgressBar::new(cases.len() as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} cases, {elapsed} {msg}")
            .expect("a valid template"),
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start the suite's threads")?;
    // A caught panic is reported in the case's line; the default hook would also print
    // it over the progress bar.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let report_cases: Vec<CaseReport> = pool.install(|| {
        cases
            .par_iter()
            .map(|case| {
                let report = run_case(case, &dir, &cache);
                bar.set_message(case.name);
                bar.inc(1);
                report
            })
            .collect()
    });
    std::panic::set_hook(hook);
    bar.finish_and_clear();
    let _ = std::fs::remove_dir_all(&dir);

    for r in &report_cases {
        println!(
            "{:<5} {:<12} {:<34} {:>6.1} s  {}",
            r.status.word(),
            r.family,
            r.name,
            r.seconds,
            r.reason
        );
        if let (Status::KnownFailure, Some(why)) = (r.status, r.known_failure) {
            println!("      {:<12} {:<34}           known: {why}", "", "");
        }
    }
    if let Some(dir) = &a.images {
        write_images(dir, &report_cases)?;
    }
    let count = |s: Status| report_cases.iter().filter(|r| r.status == s).count();
    let report = Report {
        machine: case::MACHINE,
        passed: count(Status::Pass),
        failed: count(Status::Fail),
        known_failures: count(Status::KnownFailure),
        seconds: start.elapsed().as_secs_f64(),
        cases: report_cases,
    };
    println!(
        "{} passed, {} failed ({} known failures) in {:.1} s",
        report.passed, report.failed, report.known_failures, report.seconds
    );
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&report)? + "\n";
        std::fs::write(path, text).with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    Ok(if report.failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

#[cfg(test)]
mod tests {
    use super::case::{Expect, Invalid, Kind, Render};
    use super::*;

    fn render_case(
        scene: impl Fn() -> Result<imagine_pipelines::scene::model::Scene> + Send + Sync + 'static,
        expect: Vec<Expect>,
        known_failure: Option<&'static str>,
    ) -> Case {
        Case {
            name: "test",
            family: "test",
            about: "a test",
            kind: Kind::Render(Render {
                scene: Box::new(scene),
                flush_to_zero: false,
                expect,
            }),
            known_failure,
        }
    }

    fn one_triangle() -> Result<imagine_pipelines::scene::model::Scene> {
        window_space::tri(
            "one",
            "16 16\n1 1 0.5 1 0 0  15 2 0.5 0 1 0  8 15 0.5 0 0 1\n",
        )
    }

    fn judge(case: &Case) -> CaseReport {
        let dir = std::env::temp_dir().join(format!("imagine-stress-test-{}", std::process::id()));
        let report = run_case(case, &dir, &CompileCache::disabled());
        let _ = std::fs::remove_dir_all(&dir);
        report
    }

    #[test]
    fn a_broken_property_a_panic_and_a_passing_known_failure_fail() {
        let good = judge(&render_case(one_triangle, vec![Expect::Covers(0.3)], None));
        assert_eq!(good.status, Status::Pass, "{}", good.reason);
        assert!(good.cycles.is_some_and(|c| c > 0));
        // The triangle is drawn: a frame that must be empty is not.
        let broken = judge(&render_case(one_triangle, vec![Expect::Empty], None));
        assert_eq!(broken.status, Status::Fail);
        assert!(broken.reason.contains("pixels drawn"), "{}", broken.reason);
        let panics = judge(&render_case(
            || panic!("a scene that cannot be built"),
            vec![],
            None,
        ));
        assert_eq!(panics.status, Status::Fail);
        assert!(
            panics
                .reason
                .contains("panicked: a scene that cannot be built")
        );
        let known = judge(&render_case(one_triangle, vec![Expect::Empty], Some("why")));
        assert_eq!(known.status, Status::KnownFailure);
        let fixed = judge(&render_case(one_triangle, vec![], Some("why")));
        assert_eq!(fixed.status, Status::Fail);
        assert!(fixed.reason.contains("remove the mark"), "{}", fixed.reason);
    }

    #[test]
    fn an_accepted_invalid_file_or_a_vague_error_fails() {
        let case = |text: &str, must_name: Vec<&'static str>| Case {
            name: "invalid",
            family: "test",
            about: "a test",
            kind: Kind::Invalid(Invalid {
                files: vec![("x.tri", text.into())],
                must_name,
            }),
            known_failure: None,
        };
        let nan = "4 4\nnan 1 0.5 1 1 1  3 1 0.5 1 1 1  2 3 0.5 1 1 1\n";
        assert_eq!(
            judge(&case(nan, vec!["x.tri", "line 2"])).status,
            Status::Pass
        );
        let vague = judge(&case(nan, vec!["x.tri", "line 7"]));
        assert_eq!(vague.status, Status::Fail);
        assert!(
            vague.reason.contains("does not name `line 7`"),
            "{}",
            vague.reason
        );
        let fine = "4 4\n1 1 0.5 1 1 1  3 1 0.5 1 1 1  2 3 0.5 1 1 1\n";
        let accepted = judge(&case(fine, vec![]));
        assert_eq!(accepted.status, Status::Fail);
        assert!(
            accepted.reason.starts_with("accepted"),
            "{}",
            accepted.reason
        );
    }

    #[test]
    fn the_suite_has_thirty_cases_with_unique_names() {
        let cases = all_cases();
        assert!(cases.len() >= 30, "{}", cases.len());
        let mut names: Vec<&str> = cases.iter().map(|c| c.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), cases.len(), "case names are unique");
    }
}
