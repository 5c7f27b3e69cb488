//! `imagine machine bench`: simulator throughput on a compute-dense microcode loop.

use std::process::ExitCode;

use anyhow::{Result, bail};

pub fn machine(name: &str) -> Result<ExitCode> {
    bail!(
        "`imagine machine bench --machine {name}` is not available yet: the composed machine is not modelled in this build"
    )
}
