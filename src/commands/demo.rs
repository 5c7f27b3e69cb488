//! `imagine demo`: the demonstration design of `imagine-hdl` (a 4-stage pipelined
//! multiply-accumulate whose results cross into the DRAM clock domain).

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_hdl::ClockDomain;
use imagine_hdl::demo::{self, DemoConfig, DemoReport};
use imagine_units::limits::{MAX_CROSSING_CAPACITY, MAX_DEMO_CYCLES, MAX_MHZ};

use super::outputs::Outputs;
use super::waves::WaveArgs;

#[derive(Args)]
pub struct DemoArgs {
    /// Core-clock cycles to simulate
    #[arg(long, default_value_t = 100_000)]
    cycles: u64,
    /// Core clock frequency in MHz
    #[arg(long, default_value_t = 500)]
    core_mhz: u64,
    /// DRAM clock frequency in MHz
    #[arg(long, default_value_t = 167)]
    dram_mhz: u64,
    /// Entries of the clock-crossing FIFO
    #[arg(long, default_value_t = DemoConfig::default().crossing_capacity)]
    crossing_capacity: usize,
    #[command(flatten)]
    waves: WaveArgs,
}

pub fn run(a: DemoArgs) -> Result<ExitCode> {
    for (flag, mhz) in [("--core-mhz", a.core_mhz), ("--dram-mhz", a.dram_mhz)] {
        if !(1..=MAX_MHZ).contains(&mhz) {
            bail!("{flag} {mhz}: a clock frequency must be 1..={MAX_MHZ} MHz (MAX_MHZ)");
        }
    }
    if !(1..=MAX_CROSSING_CAPACITY).contains(&a.crossing_capacity) {
        bail!(
            "--crossing-capacity {}: must be 1..={MAX_CROSSING_CAPACITY} entries \
             (MAX_CROSSING_CAPACITY)",
            a.crossing_capacity
        );
    }
    if !(1..=MAX_DEMO_CYCLES).contains(&a.cycles) {
        bail!(
            "--cycles {}: must be 1..={MAX_DEMO_CYCLES} (MAX_DEMO_CYCLES)",
            a.cycles
        );
    }
    a.waves.check_outputs(&mut Outputs::default())?;
    let domains = vec![
        ClockDomain::mhz("core", a.core_mhz),
        ClockDomain::mhz("dram", a.dram_mhz),
    ];
    let cfg = DemoConfig {
        crossing_capacity: a.crossing_capacity,
        ..DemoConfig::default()
    };
    let mut sim = demo::build(domains, cfg).context("cannot build the demo design")?;
    let vcd = a.waves.attach(&mut sim)?;
    let start = Instant::now();
    sim.run_core_cycles(a.cycles, |_| {})?;
    sim.finish().context("cannot finish writing the waveform")?;
    let host_s = start.elapsed().as_secs_f64();
    let r = DemoReport::of(&sim);
    println!("core cycles        {}", r.core_cycles);
    println!("dram cycles        {}", r.dram_cycles);
    println!(
        "results produced   {} (checksum {:016x})",
        r.produced, r.monitor_checksum
    );
    println!(
        "results delivered  {} (checksum {:016x})",
        r.delivered, r.sink_checksum
    );
    println!("host time          {host_s:.3} s");
    println!(
        "simulated rate     {:.0} core cycles/s",
        r.core_cycles as f64 / host_s.max(1e-9)
    );
    if let Some(paths) = vcd {
        println!("waveform           {}", paths.vcd.display());
        println!("gtkwave save file  {}", paths.gtkw.display());
    }
    if !r.matches_golden() {
        bail!("the demo's results differ from its behavioural model");
    }
    println!("results match the behavioural model");
    Ok(ExitCode::SUCCESS)
}
