//! `imagine verify`: hardware blocks against golden models.

use std::io::{self, Write};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Subcommand;
use imagine_units::arith::fp32::FpMode;
use imagine_verif::testfloat::{FpuOp, check_stream_with_mode};

#[derive(Subcommand)]
pub enum VerifyCommand {
    /// Check an fp32 operation against Berkeley TestFloat vectors read from stdin
    ///
    /// Input: one case per line in TestFloat's format, hex operands, the expected result and
    /// the expected flags as two hex digits (inexact 1, underflow 2, overflow 4, infinite 8,
    /// invalid 16), e.g. `3F800000 40000000 40400000 00` for f32_add. Conversions to integer
    /// raise inexact as SoftFloat does with `exact` set (generate them with `-exact`).
    #[command(verbatim_doc_comment)]
    Fpu {
        /// f32_add, f32_sub, f32_mul, f32_div, f32_sqrt, f32_to_i32, i32_to_f32, f32_lt,
        /// f32_le, f32_eq (also f32_to_i32_r_minMag, f32_min, f32_max)
        op: FpuOp,
        /// Check the flush-to-zero mode instead of IEEE subnormals
        #[arg(long)]
        ftz: bool,
        /// How many mismatches to print
        #[arg(long, default_value_t = 20)]
        show: usize,
    },
}

pub fn run(c: VerifyCommand) -> Result<ExitCode> {
    match c {
        VerifyCommand::Fpu { op, ftz, show } => {
            let mode = if ftz { FpMode::FTZ } else { FpMode::IEEE };
            let stdout = io::stdout();
            let mut out = stdout.lock();
            let summary = check_stream_with_mode(op, mode, io::stdin().lock(), &mut out, show)
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
    }
}
