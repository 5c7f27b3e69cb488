//! Subcommands whose hardware is not modelled yet. Their arguments are already parsed so
//! `--help` documents them; running them is an error that says what is missing.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::Args;

#[derive(Args)]
pub struct DramArgs {
    /// Request trace: `<hex byte address> READ|WRITE <DRAM cycle>` per line
    #[arg(long)]
    trace: PathBuf,
}

fn not_yet(what: &str, missing: &str) -> Result<ExitCode> {
    bail!("`imagine {what}` is not available yet: {missing} is not modelled in this build")
}

pub fn dram(_: DramArgs) -> Result<ExitCode> {
    not_yet("dram", "the memory system")
}
