//! `imagine dram`: replay a DRAM request trace (DRAMsim3's text format) or a generated
//! microbenchmark through the memory access scheduler and the SDRAM channels.

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_units::desc::MachineDesc;
use imagine_units::dram::trace::{BENCHES, MAX_TRACE_REQUESTS, bench, read_trace, write_trace};
use imagine_units::dram::{DramParams, Policy, ReplayOptions, ReplayReport, TraceRequest, replay};

use super::outputs::Outputs;
use super::waves::WaveArgs;

#[derive(Args)]
#[command(after_help = "\
Trace format (DRAMsim3): one request per line, `<hex byte address> READ|WRITE <DRAM cycle>`,
cycles never decreasing; blank lines and lines starting with `#` are skipped. Limits: 1 to
16777216 requests, cycles up to 17592186044416 (2^44), lines up to 4096 bytes. Idle time
between requests costs nothing (the replay jumps over it, refreshes included) except with
--vcd, where every cycle is stepped and drawn.

Microbenchmarks (--bench NAME, after Rixner et al. ISCA 2000):
  unit-load           unit-stride reads of consecutive words, all presented at cycle 0
  unit                a unit-stride read stream and a write stream to other banks, interleaved
  unit-conflict       a read stream and a write stream to other rows of the same banks
  constrained-random  random reads (2/3) and writes (1/3) within two rows of every bank
  random              random reads and writes anywhere in memory, all at cycle 0
  random-reads        random reads anywhere in memory, one presented per cycle

Policies: in-order, first-ready, col-open, col-closed, row-open, row-closed, load-over-store,
or `all` for a comparison table. With --vcd, the window counts DRAM cycles (the design has
only the DRAM clock).")]
pub struct DramArgs {
    /// Request trace to replay (DRAMsim3 text format)
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with = "bench",
        required_unless_present = "bench"
    )]
    trace: Option<PathBuf>,
    /// Generate and replay a microbenchmark instead of a trace file
    #[arg(long, value_name = "NAME")]
    bench: Option<String>,
    /// Requests a generated microbenchmark makes
    #[arg(long, default_value_t = 8192, requires = "bench")]
    requests: usize,
    /// Present every request at cycle 0, in the trace's order, as fast as the channels
    /// take them: the bandwidth the address stream sustains with no computation (the
    /// thesis's trace bandwidth, Table 5.6)
    #[arg(long)]
    untimed: bool,
    /// Scheduling policy (default: the machine's), or `all`
    #[arg(long, value_name = "P")]
    policy: Option<String>,
    /// Machine name or description file (its [dram] and [memory] sections)
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Print the statistics as JSON
    #[arg(long)]
    json: bool,
    /// Write the requests as the channels received them, in the same trace format
    #[arg(long, value_name = "FILE")]
    dram_trace: Option<PathBuf>,
    #[command(flatten)]
    waves: WaveArgs,
}

pub fn run(a: DramArgs) -> Result<ExitCode> {
    let desc = MachineDesc::resolve(&a.machine)?;
    let mut outputs = Outputs::default();
    outputs.add_opt("--dram-trace", a.dram_trace.as_ref())?;
    a.waves.check_outputs(&mut outputs)?;
    let p = DramParams::of(&desc);
    let (source, mut reqs) = load_requests(&a, &p)?;
    if a.untimed {
        reqs.iter_mut().for_each(|r| r.cycle = 0);
    }
    let policies: Vec<Policy> = match a.policy.as_deref() {
        None => vec![Policy::parse(&desc.memory.policy).expect("validated")],
        Some("all") => Policy::ALL.to_vec(),
        Some(name) => match Policy::parse(name) {
            Some(p) => vec![p],
            None => bail!(
                "--policy `{name}` is not a policy; the policies are {}, or `all`",
                Policy::NAMES.join(", ")
            ),
        },
    };
    if policies.len() > 1 && (a.waves.wants_vcd() || a.dram_trace.is_some()) {
        bail!("--vcd and --dram-trace need a single --policy, not `all`");
    }
    let mut reports = Vec::new();
    for &policy in &policies {
        let mut opts = ReplayOptions::new(policy);
        opts.record = a.dram_trace.is_some();
        if a.waves.wants_vcd() {
            let waves = a.waves.clone();
            opts.on_start = Some(Box::new(move |sim| {
                waves.attach(sim).map(|_| ()).map_err(|e| format!("{e:#}"))
            }));
        }
        let r = replay(&desc, &reqs, opts).map_err(anyhow::Error::msg)?;
        reports.push(r);
    }
    if let Some(path) = &a.dram_trace {
        let f = File::create(path).with_context(|| format!("cannot write `{}`", path.display()))?;
        let mut w = BufWriter::new(f);
        write_trace(&mut w, &reports[0].recorded)
            .and_then(|_| w.flush())
            .with_context(|| format!("cannot write `{}`", path.display()))?;
    }
    if a.json {
        let runs: Vec<serde_json::Value> = reports.iter().map(json).collect();
        let out = serde_json::json!({
            "source": source,
            "machine": desc.name,
            "channels": p.channels,
            "banks": p.banks,
            "dram_mhz": desc.clocks.dram_mhz,
            "peak_gbs": p.peak_bytes_per_s() / 1e9,
            "runs": runs,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else if reports.len() == 1 {
        print_report(&source, &desc, &p, &reports[0]);
    } else {
        print_table(&source, &desc, &p, &reports);
    }
    let violations: usize = reports.iter().map(|r| r.violations.len()).sum();
    if violations > 0 {
        for r in &reports {
            for v in r.violations.iter().take(20) {
                eprintln!("timing violation ({}): {v}", r.policy);
            }
        }
        bail!("the timing checker found {violations} violation(s)");
    }
    Ok(ExitCode::SUCCESS)
}

fn load_requests(a: &DramArgs, p: &DramParams) -> Result<(String, Vec<TraceRequest>)> {
    if let Some(name) = &a.bench {
        if !(1..=MAX_TRACE_REQUESTS).contains(&a.requests) {
            bail!(
                "--requests {}: must be 1..={MAX_TRACE_REQUESTS} (the most requests a trace may hold)",
                a.requests
            );
        }
        let Some(reqs) = bench(name, a.requests, p) else {
            bail!(
                "--bench `{name}` is not a microbenchmark; they are {}",
                BENCHES.map(|(n, _)| n).join(", ")
            );
        };
        return Ok((format!("bench {name}"), reqs));
    }
    let path = a.trace.as_ref().expect("clap requires --trace or --bench");
    let file = imagine_units::limits::open_input(path)
        .with_context(|| format!("cannot read trace `{}`", path.display()))?;
    let reqs = read_trace(BufReader::new(file), p)
        .map_err(|e| anyhow::anyhow!("trace `{}`: {e}", path.display()))?;
    Ok((path.display().to_string(), reqs))
}

fn json(r: &ReplayReport) -> serde_json::Value {
    serde_json::json!({
        "policy": r.policy.name(),
        "requests": r.requests,
        "reads": r.reads,
        "writes": r.writes,
        "bytes": r.bytes,
        "finish_cycle": r.finish_cycle,
        "bandwidth_gbs": r.gbs,
        "fraction_of_peak": r.fraction_of_peak(),
        "data_bus_utilisation": r.data_bus_utilisation,
        "row_hit_rate": r.row_hit_rate,
        "commands": {
            "ACT": r.activates,
            "PRE": r.precharges,
            "READ": r.reads,
            "WRITE": r.writes,
            "REF": r.refreshes,
        },
        "avg_read_latency_cycles": r.avg_read_latency,
        "timing_violations": r.violations.len(),
    })
}

fn print_report(source: &str, desc: &MachineDesc, p: &DramParams, r: &ReplayReport) {
    println!("source         {source} ({} requests)", r.requests);
    println!(
        "machine        {}: {} channels × {} banks, {} MHz, peak {:.3} GB/s",
        desc.name, p.channels, p.banks, desc.clocks.dram_mhz, r.peak_gbs
    );
    println!("policy         {}", r.policy);
    println!("finish cycle   {}", r.finish_cycle);
    println!(
        "bandwidth      {:.3} GB/s ({:.1}% of peak)",
        r.gbs,
        100.0 * r.fraction_of_peak()
    );
    println!("data bus       {:.1}% busy", 100.0 * r.data_bus_utilisation);
    println!("row hits       {:.1}%", 100.0 * r.row_hit_rate);
    println!(
        "commands       ACT {}  PRE {}  READ {}  WRITE {}  REF {}",
        r.activates, r.precharges, r.reads, r.writes, r.refreshes
    );
    println!(
        "read latency   {:.1} DRAM cycles (mean)",
        r.avg_read_latency
    );
    println!(
        "timing check   {}",
        if r.violations.is_empty() {
            "no violations".to_string()
        } else {
            format!("{} violations", r.violations.len())
        }
    );
}

fn print_table(source: &str, desc: &MachineDesc, p: &DramParams, reports: &[ReplayReport]) {
    println!(
        "{source} on {} ({} channels × {} banks, {} MHz, peak {:.3} GB/s)",
        desc.name,
        p.channels,
        p.banks,
        desc.clocks.dram_mhz,
        p.peak_bytes_per_s() / 1e9
    );
    println!(
        "{:<16} {:>8} {:>7} {:>8} {:>6} {:>6} {:>7} {:>7} {:>7} {:>7} {:>5} {:>8} {:>5}",
        "policy",
        "GB/s",
        "% peak",
        "finish",
        "bus%",
        "hit%",
        "ACT",
        "PRE",
        "READ",
        "WRITE",
        "REF",
        "rd lat",
        "viol"
    );
    for r in reports {
        println!(
            "{:<16} {:>8.3} {:>7.1} {:>8} {:>6.1} {:>6.1} {:>7} {:>7} {:>7} {:>7} {:>5} {:>8.1} {:>5}",
            r.policy.name(),
            r.gbs,
            100.0 * r.fraction_of_peak(),
            r.finish_cycle,
            100.0 * r.data_bus_utilisation,
            100.0 * r.row_hit_rate,
            r.activates,
            r.precharges,
            r.reads,
            r.writes,
            r.refreshes,
            r.avg_read_latency,
            r.violations.len()
        );
    }
}
