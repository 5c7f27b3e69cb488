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
        #[command(flatten)]
        datapath: super::datapath::DatapathArg,
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
        MachineCommand::Bench {
            machine,
            cycles,
            datapath,
        } => {
            return super::bench::machine(&machine, cycles, datapath.datapath);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Every section of a machine description, one titled block each, with units. Keys that
/// are not plain counts are named as the description file names them (`t_rcd`,
/// `queue_entries`), so a value can be found in, or written to, a `.toml` file.
pub fn describe(m: &MachineDesc) -> String {
    let mut s = String::new();
    let mut line = |title: &str, text: String| {
        s += &format!("{title:<18} {text}\n");
    };
    let c = &m.cluster;
    let l = &m.latency;
    let ns = |mhz: u64| 1000.0 / mhz.max(1) as f64;
    line("machine", format!("{}  ({})", m.name, m.description));
    line(
        "clocks",
        format!(
            "core {} MHz ({:.2} ns), DRAM {} MHz ({:.2} ns)",
            m.clocks.core_mhz,
            ns(m.clocks.core_mhz),
            m.clocks.dram_mhz,
            ns(m.clocks.dram_mhz)
        ),
    );
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    line(
        "cluster",
        format!(
            "{} × ({} adders, {} multipliers, {}, {}, {}, {} condition codes)",
            c.count,
            c.adders,
            c.multipliers,
            plural(c.divsqrt, "divide/sqrt unit", "divide/sqrt units"),
            plural(c.scratchpads, "scratchpad", "scratchpads"),
            plural(c.comm_units, "comm unit", "comm units"),
            c.condition_codes
        ),
    );
    line(
        "arithmetic",
        if m.arithmetic.flush_to_zero {
            "fp32 subnormal inputs and results flushed to zero (flush_to_zero)".into()
        } else {
            "fp32 subnormals kept, IEEE 754 (flush_to_zero off)".into()
        },
    );
    line(
        "latency",
        format!(
            "core cycles: int {}, fp_add {}, mul {}, div {}, sqrt {} (divsqrt_issue_interval {}), \
             scratchpad_read {}, scratchpad_write {}, comm {}, stream {}",
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
        ),
    );
    let names = m.lrf_names();
    let entries: usize = names.iter().map(|n| m.lrf_entries(n)).sum();
    line(
        "lrf",
        format!(
            "{} per cluster, {entries} entries of 32 bits: {} entries each, \
             {} in the large ones ({})",
            names.len(),
            m.lrf.entries,
            m.lrf.large_entries,
            if m.lrf.large.is_empty() {
                "none".into()
            } else {
                m.lrf.large.join(", ")
            }
        ),
    );
    for n in &names {
        line("", format!("  {n:<12} {} entries", m.lrf_entries(n)));
    }
    let sp = &m.scratchpad;
    line(
        "scratchpad",
        format!("{} words ({} bytes) per scratchpad", sp.words, sp.words * 4),
    );
    let r = &m.srf;
    line(
        "srf",
        format!(
            "{} words ({} KB), {} banks, {}-word blocks, {} words/cycle, {} stream buffers, \
             {} streams per kernel",
            r.words,
            r.words * 4 / 1024,
            r.banks,
            r.block_words,
            r.words_per_cycle,
            r.stream_buffers,
            r.kernel_streams
        ),
    );
    line(
        "",
        format!(
            "per cluster {} stream words/cycle unconditional, {} conditional",
            r.cluster_words_per_cycle, r.conditional_words_per_cycle
        ),
    );
    line(
        "microcontroller",
        format!(
            "{} instructions of microcode store, loops nested {} deep",
            m.microcontroller.store_words, m.microcontroller.loop_depth
        ),
    );
    let d = &m.dram;
    let bytes = d.channels * d.banks * d.rows * d.columns * 4;
    let peak = d.channels as f64 * 4.0 * m.clocks.dram_mhz as f64 / 1000.0;
    line(
        "dram",
        format!(
            "{} channels × {} banks × {} rows × {} columns of 32-bit words ({} MB), \
             burst_words {}, peak {peak:.2} GB/s",
            d.channels,
            d.banks,
            d.rows,
            d.columns,
            bytes >> 20,
            d.burst_words
        ),
    );
    line(
        "",
        format!(
            "DRAM cycles: cas_latency {}, t_rcd {}, t_rp {}, t_ras {}, t_rc {}, t_rrd {}, t_wr {}, \
             turnaround {}, t_rfc {}, refresh_interval {} ({:.1} µs)",
            d.cas_latency,
            d.t_rcd,
            d.t_rp,
            d.t_ras,
            d.t_rc,
            d.t_rrd,
            d.t_wr,
            d.turnaround,
            d.t_rfc,
            d.refresh_interval,
            d.refresh_interval as f64 * ns(m.clocks.dram_mhz) / 1000.0
        ),
    );
    let mem = &m.memory;
    line(
        "memory",
        format!(
            "policy {}, pending_references {} per channel, address_generators {} \
             (ag_words_per_cycle {} words/cycle, ag_reorder_words {} words outstanding), \
             crossing_entries {} per clock-crossing FIFO, sync_stages {} flip-flops",
            mem.policy,
            mem.pending_references,
            mem.address_generators,
            mem.ag_words_per_cycle,
            mem.ag_reorder_words,
            mem.crossing_entries,
            mem.sync_stages
        ),
    );
    if let Some(t) = &m.texture_cache {
        line(
            "texture cache",
            format!(
                "words {} ({} KB), line_words {}, direct-mapped, read-only, \
                 hit_words_per_cycle {} words/cycle",
                t.words,
                t.words * 4 / 1024,
                t.line_words,
                t.hit_words_per_cycle
            ),
        );
    }
    if let Some(r) = &m.rasterizer {
        line(
            "rasterizer",
            format!(
                "latency {} core cycles, output_words_per_cycle {} words/cycle, \
                 input_words_per_cycle {} words/cycle per stream, triangles_in_flight {}, \
                 pixels_per_cycle {} candidates/cycle",
                r.latency,
                r.output_words_per_cycle,
                r.input_words_per_cycle,
                r.triangles_in_flight,
                r.pixels_per_cycle
            ),
        );
    }
    let sc = &m.stream_controller;
    line(
        "stream controller",
        format!(
            "queue_entries {} instructions, scoreboard_entries {} instructions, \
             min_kernel_cycles {} core cycles, host_words_per_cycle {} (host interface)",
            sc.queue_entries, sc.scoreboard_entries, sc.min_kernel_cycles, sc.host_words_per_cycle
        ),
    );
    let s3 = &m.s3;
    line(
        "s3",
        format!(
            "accelerators {}, window_per_accelerator {} ({} candidate buffers, {} destination \
             RS), source_slots {}, split {}, split_height {} rows, chain_break {}, select {} \
             (select_seed {}), queue_entries {}, setup_cycles {}, memory {}, memory_latency {} \
             (superscalar rasterizer, `imagine s3`)",
            s3.accelerators,
            s3.window_per_accelerator,
            s3.accelerators * s3.window_per_accelerator,
            s3.accelerators * (s3.window_per_accelerator + 1),
            s3.source_slots,
            s3.split,
            s3.split_height,
            s3.chain_break,
            s3.select,
            s3.select_seed,
            s3.queue_entries,
            s3.setup_cycles,
            s3.memory,
            s3.memory_latency
        ),
    );
    s
}
