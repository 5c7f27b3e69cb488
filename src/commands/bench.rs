//! `imagine machine bench`: simulator throughput on a compute-dense microcode loop.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use imagine_units::desc::MachineDesc;
use imagine_units::limits::MAX_DEMO_CYCLES;
use imagine_units::runner::{RunOptions, run_kernel};
use imagine_units::workloads::compute_dense;

/// Runs the compute-dense loop on `machine` for about `cycles` core cycles (VCD off) and
/// reports simulated cycles per host second and the op rate it implies.
pub fn machine(machine: &str, cycles: u64) -> Result<ExitCode> {
    if !(1..=MAX_DEMO_CYCLES).contains(&cycles) {
        bail!("--cycles {cycles}: must be 1..={MAX_DEMO_CYCLES} (MAX_DEMO_CYCLES)");
    }
    let desc = MachineDesc::resolve(machine)?;
    let body = desc.latency.divsqrt_issue_interval.max(8) as u64;
    let iterations = u32::try_from((cycles / body).max(1)).context("--cycles is too large")?;
    let program = compute_dense(&desc, iterations)?;
    let start = Instant::now();
    let run = run_kernel(
        &desc,
        &program,
        &[],
        RunOptions {
            max_cycles: cycles * 2 + 1000,
            on_start: None,
        },
    )?;
    let host = start.elapsed().as_secs_f64();
    let s = &run.stats;
    let lanes = desc.cluster.count as f64;
    let ops: u64 = s.fu_ops.iter().sum();
    let rate = s.cycles as f64 / host;
    println!("machine            {}", desc.name);
    println!("simulated cycles   {}", s.cycles);
    println!("host time          {host:.3} s");
    println!("simulated rate     {:.2} M cycles/s", rate / 1e6);
    println!(
        "ops per cycle      {:.1} (all clusters)",
        s.ops_per_cycle(desc.cluster.count)
    );
    println!(
        "simulated op rate  {:.0} M cluster-ops/s",
        ops as f64 * lanes / host / 1e6
    );
    Ok(ExitCode::SUCCESS)
}
