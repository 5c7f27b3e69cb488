//! `imagine render`: a scene through the rendering pipeline on the machine.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::Args;

use super::waves::WaveArgs;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene name or scene file (default: SPHERE)
    scene: Option<String>,
    /// Machine description name or file
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Write the frame as PNG
    #[arg(long)]
    png: Option<PathBuf>,
    /// Write statistics as JSON
    #[arg(long)]
    stats: Option<PathBuf>,
    #[command(flatten)]
    waves: WaveArgs,
}

pub fn run(_: RenderArgs) -> Result<ExitCode> {
    bail!(
        "`imagine render` is not available yet: the rendering pipeline is not modelled in this build"
    )
}
