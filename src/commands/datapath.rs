//! `--datapath`: what computes the clusters' fp32 ops in a run.

use clap::Args;
use imagine_units::ops::Datapath;

#[derive(Args, Clone, Copy, Debug)]
pub struct DatapathArg {
    /// What computes fadd, fsub, fmul, fdiv and fsqrt: `host` (the host's IEEE arithmetic
    /// where it gives the model's exact bits and flags, proven and cross-checked against
    /// SoftFloat; the bit-level datapath for the other lanes) or `bit-level` (the datapath
    /// model of record for every lane). Results are the same; with a waveform the
    /// bit-level datapath always runs
    #[arg(long, default_value = "host", value_parser = |d: &str| d.parse::<Datapath>())]
    pub datapath: Datapath,
}
