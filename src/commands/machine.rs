//! `imagine machine`: the machine descriptions.

use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use imagine_units::desc::{BUILTIN, MachineDesc};

#[derive(Subcommand)]
pub enum MachineCommand {
    /// List the built-in machine descriptions
    List,
    /// Show a machine description (a built-in name or a .toml file)
    Show {
        /// Machine name (see `imagine machine list`) or path to a description
        name: String,
    },
    /// Measure simulated cycles per host second on a compute-dense loop
    Bench {
        /// Machine name or description file
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// Core cycles to simulate
        #[arg(long, default_value_t = 4_000_000)]
        cycles: u64,
    },
}

pub fn run(c: MachineCommand) -> Result<ExitCode> {
    match c {
        MachineCommand::List => {
            for (name, _) in BUILTIN {
                let m = MachineDesc::resolve(name)?;
                println!("{name:<12} {}", m.description);
            }
        }
        MachineCommand::Show { name } => print!("{}", describe(&MachineDesc::resolve(&name)?)),
        MachineCommand::Bench { machine, cycles } => {
            return super::bench::machine(&machine, cycles);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A readable summary of a machine description.
pub fn describe(m: &MachineDesc) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let c = &m.cluster;
    let l = &m.latency;
    let _ = writeln!(s, "machine      {}  ({})", m.name, m.description);
    let _ = writeln!(
        s,
        "clocks       core {} MHz, DRAM {} MHz",
        m.clocks.core_mhz, m.clocks.dram_mhz
    );
    let _ = writeln!(
        s,
        "clusters     {} × ({} adders, {} multipliers, {} divide/sqrt, {} scratchpads, {} comm units, {} condition codes)",
        c.count, c.adders, c.multipliers, c.divsqrt, c.scratchpads, c.comm_units, c.condition_codes
    );
    let _ = writeln!(
        s,
        "latencies    int {}, fp add {}, mul {}, div {}, sqrt {} (issue every {}), scratchpad read {} / write {}, comm {}, stream {}",
        l.int,
        l.fp_add,
        l.mul,
        l.div,
        l.sqrt,
        l.divsqrt_issue_interval,
        l.scratchpad_read,
        l.scratchpad_write,
        l.comm,
        l.stream
    );
    let names = m.lrf_names();
    let entries: usize = names.iter().map(|n| m.lrf_entries(n)).sum();
    let _ = writeln!(
        s,
        "LRFs         {} per cluster, {entries} entries:",
        names.len()
    );
    for n in &names {
        let _ = writeln!(s, "               {n:<12} {} entries", m.lrf_entries(n));
    }
    let _ = writeln!(s, "scratchpad   {} words per cluster", m.scratchpad.words);
    let r = &m.srf;
    let _ = writeln!(
        s,
        "SRF          {} words ({} KB), {} banks, {}-word blocks, {} words/cycle, {} stream buffers, {} streams per kernel",
        r.words,
        r.words * 4 / 1024,
        r.banks,
        r.block_words,
        r.words_per_cycle,
        r.stream_buffers,
        r.kernel_streams
    );
    let _ = writeln!(
        s,
        "cluster I/O  {} stream words/cycle unconditional, {} conditional",
        r.cluster_words_per_cycle, r.conditional_words_per_cycle
    );
    let _ = writeln!(
        s,
        "microcode    {} instructions, loops nested {} deep",
        m.microcontroller.store_words, m.microcontroller.loop_depth
    );
    s
}
