//! `imagine`: the command-line front end of the stream-processor model.

mod commands;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "imagine",
    version,
    about = "Bit-accurate, cycle-clocked model of an Imagine-style stream processor for graphics",
    long_about = "Bit-accurate, cycle-clocked model of an Imagine-style stream processor for \
graphics.\n\nHardware blocks (functional units, register files, scratchpad, switches, stream \
register file, microcontroller, DRAM scheduler) are clocked RTL-style modules; kernels run as \
compiled microcode. Every run can dump VCD waveforms for GTKWave."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene on the modelled machine (PNG, statistics, VCD)
    Render(commands::render::RenderArgs),
    /// Check hardware blocks against golden models
    #[command(subcommand)]
    Verify(commands::verify::VerifyCommand),
    /// Assemble, disassemble, inspect, check and run kernels
    #[command(subcommand)]
    Kernel(commands::kernel::KernelCommand),
    /// List, show and benchmark machine descriptions
    #[command(subcommand)]
    Machine(commands::machine::MachineCommand),
    /// List the built-in scenes and show what a scene file holds
    #[command(subcommand)]
    Scene(commands::scene::SceneCommand),
    /// Replay a DRAM request trace through the memory access scheduler
    Dram(commands::dram::DramArgs),
    /// Run the demonstration design (a pipelined MAC crossing into the DRAM clock domain)
    Demo(commands::demo::DemoArgs),
    /// Time whole frames: simulated cycles per host second, host seconds per frame, compile
    /// time cold and from the cache
    Bench(commands::bench::BenchArgs),
    /// Two renders' statistics (`render --stats`) side by side: cycles, frames/s, where the
    /// cycles went, kernels, bandwidths and error, with ratios, largest differences first
    Compare(commands::compare::CompareArgs),
    /// Error against run time: render a scene at every combination of knob values
    /// (machine, batch, filter, flush_to_zero), each point's cycles, frames/s and error
    /// against the reference as a CSV row, and PSNR against cycles as a plot
    Sweep(commands::sweep::SweepArgs),
    /// Run a triangle trace through the S3 superscalar out-of-order rasterizer (Wolfe &
    /// Noonburg): triangle-level parallelism, cycles, stalls, speedup over one accelerator
    S3(commands::s3::S3Args),
    /// The extreme suite: subnormals, cancellation, slivers, huge triangles, the eye plane,
    /// extreme depth ranges, degenerate faces and patches, meshes that must tile, invalid
    /// files; each case's property checked, `N passed, M failed`, non-zero exit on failure
    Stress(commands::stress::StressArgs),
}

/// Output into a closed pipe (`imagine kernel show vertex --microcode | head -1`) ends the
/// process quietly, as it ends `cat` or `grep`, instead of a panic on the failed write:
/// Rust ignores SIGPIPE by default, so the default action is restored.
fn end_quietly_on_closed_pipes() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to its default, once, before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    end_quietly_on_closed_pipes();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(a) => commands::render::run(a),
        Command::Verify(c) => commands::verify::run(c),
        Command::Kernel(c) => commands::kernel::run(c),
        Command::Machine(c) => commands::machine::run(c),
        Command::Scene(c) => commands::scene::run(c),
        Command::Dram(a) => commands::dram::run(a),
        Command::Demo(a) => commands::demo::run(a),
        Command::Bench(a) => commands::bench::frames(a),
        Command::Compare(a) => commands::compare::run(a),
        Command::Sweep(a) => commands::sweep::run(a),
        Command::S3(a) => commands::s3::run_cmd(a),
        Command::Stress(a) => commands::stress::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
