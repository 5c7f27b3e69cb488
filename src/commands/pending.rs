//! Subcommands whose hardware is not modelled yet. Their arguments are already parsed so
//! `--help` documents them; running them is an error that says what is missing.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::{Args, Subcommand};

#[derive(Subcommand)]
pub enum KernelCommand {
    /// Assemble microcode text into a binary microcode image
    Asm { file: PathBuf },
    /// Disassemble a microcode image into text
    Disasm { file: PathBuf },
    /// List the kernel library
    List,
    /// Show a kernel's schedule and resource use
    Show { name: String },
    /// Run a kernel on random inputs on the machine and in the interpreter and compare
    Check { name: String },
    /// Run a microcode program on given input streams
    Run { file: PathBuf },
}

#[derive(Args)]
pub struct DramArgs {
    /// Request trace: `<hex byte address> READ|WRITE <DRAM cycle>` per line
    #[arg(long)]
    trace: PathBuf,
}

fn not_yet(what: &str, missing: &str) -> Result<ExitCode> {
    bail!("`imagine {what}` is not available yet: {missing} is not modelled in this build")
}

pub fn kernel(c: KernelCommand) -> Result<ExitCode> {
    let what = match c {
        KernelCommand::Asm { .. } => "kernel asm",
        KernelCommand::Disasm { .. } => "kernel disasm",
        KernelCommand::List => "kernel list",
        KernelCommand::Show { .. } => "kernel show",
        KernelCommand::Check { .. } => "kernel check",
        KernelCommand::Run { .. } => "kernel run",
    };
    not_yet(what, "the microcode format and kernel compiler")
}

pub fn dram(_: DramArgs) -> Result<ExitCode> {
    not_yet("dram", "the memory system")
}
