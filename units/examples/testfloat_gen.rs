//! TestFloat-format vector generator backed by Berkeley SoftFloat 3 (RISC-V specialisation).
//!
//! ```text
//! cargo run --release -p imagine-units --features softfloat --example testfloat_gen -- \
//!     [--no-edge] [--ftz] [--uniform PERCENT] OP COUNT [SEED]
//! ```
//!
//! Writes `COUNT` lines `operands result flags` (see `arith::fp32::testfloat`) for `OP`
//! (`f32_add`, `f32_sub`, `f32_mul`, `f32_div`, `f32_sqrt`, `f32_lt`, `f32_le`, `f32_eq`,
//! `f32_min`, `f32_max`, `f32_to_i32`, `f32_to_i32_r_minMag`, `i32_to_f32`) to stdout.
//! Expected results and flags come from SoftFloat; the operands are, in order: the op's
//! deterministic edge cases (unless `--no-edge`), then random operands from seed `SEED`
//! (default 1), of which `PERCENT` % (default 25) are uniform bit patterns and the rest
//! biased to the hard cases. `--ftz` generates flush-to-zero vectors from the SoftFloat-based
//! FTZ reference instead. Different seeds give independent streams, e.g. to feed
//! `imagine verify fpu OP`:
//!
//! ```text
//! cargo run --release -p imagine-units --features softfloat --example testfloat_gen -- \
//!     --no-edge f32_div 10000000 7 | imagine verify fpu f32_div
//! ```
//!
//! The committed vectors under `units/tests/vectors/` are regenerated with
//! `units/tests/vectors/regenerate.sh`.

use imagine_units::arith::fp32::reference;
use imagine_units::arith::fp32::testfloat::{Case, Op, format_case};
use imagine_units::arith::fp32::testgen::SplitMix64;
use std::io::{BufWriter, Write};
use std::process::ExitCode;

const USAGE: &str = "usage: testfloat_gen [--no-edge] [--ftz] [--uniform PERCENT] OP COUNT [SEED]";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("testfloat_gen: {msg}\n{USAGE}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), String> {
    let mut edge = true;
    let mut ftz = false;
    let mut uniform_pct = 25u32;
    let mut positional = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--no-edge" => edge = false,
            "--ftz" => ftz = true,
            "--uniform" => {
                let v = args.next().ok_or("--uniform needs a value")?;
                uniform_pct = v
                    .parse()
                    .ok()
                    .filter(|p| *p <= 100)
                    .ok_or(format!("bad --uniform `{v}`"))?;
            }
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            _ => positional.push(arg),
        }
    }
    let [op, count, rest @ ..] = positional.as_slice() else {
        return Err("missing OP or COUNT".into());
    };
    let op = Op::from_name(op).ok_or(format!("unknown op `{op}`"))?;
    let count: u64 = count.parse().map_err(|_| format!("bad COUNT `{count}`"))?;
    let seed: u64 = match rest {
        [] => 1,
        [s] => s.parse().map_err(|_| format!("bad SEED `{s}`"))?,
        _ => return Err("too many arguments".into()),
    };
    let eval = |a, b| {
        if ftz {
            reference::eval_ftz(op, a, b)
        } else {
            reference::eval(op, a, b)
        }
    };
    let stdout = std::io::stdout().lock();
    let mut out = BufWriter::new(stdout);
    let mut emit = |a: u32, b: u32| -> bool {
        let (result, flags) = eval(a, b);
        let line = format_case(
            op,
            &Case {
                a,
                b,
                result,
                flags,
            },
        );
        // A closed pipe (e.g. `| head`) ends generation quietly.
        writeln!(out, "{line}").is_ok()
    };
    let mut written = 0u64;
    if edge {
        for (a, b) in op.edge_operands() {
            if written == count || !emit(a, b) {
                return Ok(());
            }
            written += 1;
        }
    }
    let mut rng = SplitMix64::new(seed);
    while written < count {
        let (a, b) = if rng.below(100) < uniform_pct {
            op.uniform_operands(&mut rng)
        } else {
            op.biased_operands(&mut rng)
        };
        if !emit(a, b) {
            return Ok(());
        }
        written += 1;
    }
    out.flush().or(Ok(()))
}
