//! `imagine verify`: hardware blocks against golden models.

use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::Subcommand;

#[derive(Subcommand)]
pub enum VerifyCommand {
    /// Check an fp32 operation against Berkeley TestFloat vectors read from stdin
    Fpu {
        /// f32_add, f32_sub, f32_mul, f32_div, f32_sqrt, f32_to_i32, i32_to_f32, f32_lt, f32_le, f32_eq
        op: String,
    },
}

pub fn run(c: VerifyCommand) -> Result<ExitCode> {
    match c {
        VerifyCommand::Fpu { .. } => bail!("`imagine verify fpu` is not available yet"),
    }
}
