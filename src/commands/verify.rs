//! `imagine verify`: hardware blocks against golden models — the fp32 ops against
//! TestFloat vectors, and every registered block testbench (`imagine_verif::blocks`) on any
//! machine description.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use imagine_units::arith::fp32::FpMode;
use imagine_units::desc::MachineDesc;
use imagine_verif::blocks::{self, BLOCKS, Config, Report, WaveRequest};
use imagine_verif::testfloat::{Datapath, FpuOp, check_stream_on};

#[derive(Subcommand)]
pub enum VerifyCommand {
    /// Check an fp32 operation against Berkeley TestFloat vectors read from stdin; with no
    /// OP, run the `fpu` block testbench (the units' fp32 pipelines against the built-in
    /// SoftFloat vectors) like any other block
    ///
    /// Input: one case per line in TestFloat's format, hex operands, the expected result and
    /// the expected flags as two hex digits (inexact 1, underflow 2, overflow 4, infinite 8,
    /// invalid 16), e.g. `3F800000 40000000 40400000 00` for f32_add. Conversions to integer
    /// raise inexact as SoftFloat does with `exact` set (generate them with `-exact`).
    #[command(verbatim_doc_comment)]
    Fpu {
        /// f32_add, f32_sub, f32_mul, f32_div, f32_sqrt, f32_to_i32, i32_to_f32, f32_lt,
        /// f32_le, f32_eq (also f32_to_i32_r_minMag, f32_min, f32_max)
        op: Option<FpuOp>,
        /// Check the flush-to-zero mode instead of IEEE subnormals
        #[arg(long)]
        ftz: bool,
        /// What evaluates the vectors: `bit-level`, the fp32 datapath one case at a time (the
        /// model of record), or `host`, the machine op over lanes with the host floating-point
        /// fast path of fadd, fsub, fmul, fdiv and fsqrt (`Op::eval_lanes_host`), in vectors
        /// of 1, 3, 8, 16, 32 and 37 lanes in turn
        #[arg(long, default_value = "bit-level", value_parser = |d: &str| d.parse::<Datapath>())]
        datapath: Datapath,
        /// How many mismatches to print
        #[arg(long, default_value_t = 20)]
        show: usize,
        /// The block testbench's options (without OP)
        #[command(flatten)]
        run: RunArgs,
    },
    /// List the block testbenches (`imagine verify BLOCK` runs one)
    List,
    /// Run every block testbench: a summary table, `N passed, M failed`
    All {
        #[command(flatten)]
        run: RunArgs,
        /// The summary as JSON
        #[arg(long)]
        json: bool,
    },
    /// A block testbench by name: `imagine verify lrf [--machine M] [--seed S]
    /// [--transactions N]` (see `imagine verify list`)
    #[command(external_subcommand)]
    Block(Vec<String>),
}

/// How a block testbench runs.
#[derive(Args, Clone, Debug)]
pub struct RunArgs {
    /// A built-in machine (gold8, gold1, gold32, ...) or a machine description file
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Stimulus seed (a failure prints the seed that replays it)
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Transactions to drive into each block
    #[arg(long, default_value_t = 2000)]
    transactions: u64,
    /// On a failure, replay the run and write a VCD of the cycles around the first mismatch
    /// to F, with a GTKWave save file next to it (`verify all`: one file per failing block,
    /// F-BLOCK.vcd)
    #[arg(long, value_name = "F")]
    vcd_on_fail: Option<PathBuf>,
}

/// `imagine verify BLOCK ...`: the arguments after the block's name.
#[derive(Parser)]
#[command(name = "imagine verify BLOCK", no_binary_name = true)]
struct BlockArgs {
    #[command(flatten)]
    run: RunArgs,
}

pub fn run(c: VerifyCommand) -> Result<ExitCode> {
    match c {
        VerifyCommand::Fpu {
            op: None,
            ftz: false,
            datapath: Datapath::BitLevel,
            run,
            ..
        } => run_one(blocks::find("fpu").expect("registered"), &run),
        VerifyCommand::Fpu { op: None, .. } => {
            bail!(
                "--ftz and --datapath apply to vectors on stdin (`imagine verify fpu OP --ftz --datapath host`); the fpu block testbench takes the machine's mode and the units' datapath"
            )
        }
        VerifyCommand::Fpu {
            op: Some(op),
            ftz,
            datapath,
            show,
            ..
        } => {
            let mode = if ftz { FpMode::FTZ } else { FpMode::IEEE };
            let stdout = io::stdout();
            let mut out = stdout.lock();
            let input = io::stdin().lock();
            let summary = check_stream_on(op, mode, datapath, input, &mut out, show)
                .with_context(|| format!("reading {op} vectors from stdin"))?;
            writeln!(out, "{summary}")?;
            if summary.total() == 0 {
                anyhow::bail!("no {op} vectors on stdin: nothing was checked");
            }
            Ok(if summary.failed == 0 {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            })
        }
        VerifyCommand::List => {
            let w = name_width();
            for b in BLOCKS {
                println!("{:<w$} {}", b.name, b.about);
            }
            Ok(ExitCode::SUCCESS)
        }
        VerifyCommand::All { run, json } => all(&run, json),
        VerifyCommand::Block(words) => {
            let (name, rest) = words.split_first().context("no block named")?;
            let Some(block) = blocks::find(name) else {
                bail!("unknown block `{name}`; `imagine verify list` names the blocks");
            };
            let args = match BlockArgs::try_parse_from(rest) {
                Ok(a) => a,
                Err(e) => e.exit(),
            };
            run_one(block, &args.run)
        }
    }
}

/// `imagine verify BLOCK`: one testbench, its coverage and verdict.
fn run_one(block: &blocks::Block, run: &RunArgs) -> Result<ExitCode> {
    let (desc, config) = prepare(run)?;
    let vcd = run.vcd_on_fail.as_deref();
    let report = labelled(
        blocks::run_block_with_waves(block, &desc, &config, vcd),
        run,
    );
    print_report(&report);
    report_waves(&report)?;
    Ok(exit_code(report.passed()))
}

/// The machine and run configuration, or an error naming the bad option.
fn prepare(run: &RunArgs) -> Result<(MachineDesc, Config)> {
    if run.transactions == 0 {
        bail!("--transactions must be at least 1");
    }
    let desc =
        MachineDesc::resolve(&run.machine).with_context(|| format!("--machine {}", run.machine))?;
    if let Some(path) = &run.vcd_on_fail {
        check_vcd_path(path)?;
    }
    Ok((desc, Config::new(run.seed, run.transactions)))
}

/// The report names the machine as the user gave it, so its replay line can be pasted.
fn labelled(mut report: Report, run: &RunArgs) -> Report {
    report.machine = run.machine.clone();
    report
}

/// A waveform path must name a `.vcd` file in a directory that exists, so that a failure
/// late in a long run is not lost to a typo.
fn check_vcd_path(path: &Path) -> Result<()> {
    if path.extension().is_none_or(|e| e != "vcd") {
        bail!(
            "--vcd-on-fail {}: the waveform file must end in `.vcd` (its GTKWave save file is written next to it as `.gtkw`)",
            path.display()
        );
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    if let Some(dir) = dir
        && !dir.is_dir()
    {
        bail!(
            "--vcd-on-fail {}: no directory `{}`",
            path.display(),
            dir.display()
        );
    }
    Ok(())
}

/// `F.vcd` → `F-BLOCK.vcd`: `verify all` writes one waveform per failing block.
fn per_block_path(path: &Path, block: &str) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!("{stem}-{block}.vcd"))
}

/// Says where the waveform of a failure went, or why it could not be written.
fn report_waves(r: &Report) -> Result<()> {
    let (Some(path), Some(first)) = (&r.vcd, &r.scoreboard.first) else {
        return Ok(());
    };
    match &r.waves {
        Ok(summary) => {
            let window = WaveRequest::around(path, first.cycle).window;
            let gtkw = summary
                .as_ref()
                .and_then(|s| s.gtkw.clone())
                .unwrap_or_else(|| path.with_extension("gtkw"));
            println!(
                "waveform of cycles {window} around the first mismatch: {} (gtkwave {})",
                path.display(),
                gtkw.display()
            );
            Ok(())
        }
        Err(e) => bail!("{}: writing the waveform {}: {e}", r.block, path.display()),
    }
}

/// The width of the block-name column: the longest name.
fn name_width() -> usize {
    BLOCKS.iter().map(|b| b.name.len()).max().unwrap_or(5)
}

fn exit_code(passed: bool) -> ExitCode {
    if passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

fn print_report(r: &Report) {
    let sb = &r.scoreboard;
    println!(
        "{} on {} (seed {}): {} transactions, {} checks, {} mismatches, coverage {}/{} bins, {:.3} s",
        r.block,
        r.machine,
        r.seed,
        sb.transactions,
        sb.checks,
        sb.mismatches,
        r.coverage.reached(),
        r.coverage.total(),
        r.host_time.as_secs_f64()
    );
    for (bin, hits) in r.coverage.bins() {
        println!("  {bin:<48} {hits:>8}");
    }
    match r.first_mismatch() {
        Some(m) => println!("FAIL {m}"),
        None if r.passed() => println!("PASS"),
        None => println!("FAIL no transaction was driven"),
    }
}

fn all(run: &RunArgs, json: bool) -> Result<ExitCode> {
    let (desc, config) = prepare(run)?;
    let reports: Vec<Report> = BLOCKS
        .iter()
        .map(|b| {
            let vcd = run
                .vcd_on_fail
                .as_deref()
                .map(|p| per_block_path(p, b.name));
            labelled(
                blocks::run_block_with_waves(b, &desc, &config, vcd.as_deref()),
                run,
            )
        })
        .collect();
    let failed = reports.iter().filter(|r| !r.passed()).count();
    let passed = reports.len() - failed;
    if json {
        for r in &reports {
            if let (Some(vcd), Err(e)) = (&r.vcd, &r.waves) {
                bail!("{}: writing the waveform {}: {e}", r.block, vcd.display());
            }
        }
        let rows: Vec<_> = reports
            .iter()
            .map(|r| {
                serde_json::json!({
                    "block": r.block,
                    "machine": r.machine,
                    "seed": r.seed,
                    "transactions": r.scoreboard.transactions,
                    "checks": r.scoreboard.checks,
                    "mismatches": r.scoreboard.mismatches,
                    "first_mismatch": r.scoreboard.first.as_ref().map(|m| serde_json::json!({
                        "cycle": m.cycle, "what": m.what, "expected": m.expected, "got": m.got,
                    })),
                    "coverage": r.coverage.bins().iter()
                        .map(|(bin, hits)| serde_json::json!({"bin": bin, "hits": hits}))
                        .collect::<Vec<_>>(),
                    "coverage_reached": r.coverage.reached(),
                    "coverage_total": r.coverage.total(),
                    "host_seconds": r.host_time.as_secs_f64(),
                    "waveform": r.vcd.as_ref().filter(|_| r.waves.is_ok()),
                    "passed": r.passed(),
                })
            })
            .collect();
        let summary = serde_json::json!({"blocks": rows, "passed": passed, "failed": failed});
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(exit_code(failed == 0));
    }
    let w = name_width();
    println!(
        "{:<w$} {:>12} {:>10} {:>9} {:>9}",
        "block", "transactions", "mismatches", "coverage", "host s"
    );
    for r in &reports {
        println!(
            "{:<w$} {:>12} {:>10} {:>9} {:>9.3}",
            r.block,
            r.scoreboard.transactions,
            r.scoreboard.mismatches,
            format!("{}/{}", r.coverage.reached(), r.coverage.total()),
            r.host_time.as_secs_f64()
        );
    }
    for r in &reports {
        if let Some(m) = r.first_mismatch() {
            println!("FAIL {m}");
            report_waves(r)?;
        }
    }
    println!("{passed} passed, {failed} failed");
    Ok(exit_code(failed == 0))
}
