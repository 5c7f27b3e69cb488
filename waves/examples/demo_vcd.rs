//! Writes a VCD of the demo design: `demo_vcd CYCLES OUT.vcd [FROM:TO] [SCOPE...]`.
//! Prints the host time, so that the cost of waveform writing can be measured
//! (`/usr/bin/time -v` adds the peak memory).

use std::time::Instant;

use imagine_hdl::default_domains;
use imagine_hdl::demo::{self, DemoConfig};
use imagine_waves::{VcdOptions, VcdWriter, parse_window};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: demo_vcd CYCLES OUT.vcd [FROM:TO] [SCOPE...]".into());
    }
    let cycles: u64 = args[0].parse()?;
    let mut options = VcdOptions::default();
    if let Some(w) = args.get(2) {
        options.window = parse_window(w)?;
    }
    options.scopes = args.iter().skip(3).cloned().collect();
    let mut sim = demo::build(default_domains(), DemoConfig::default())?;
    for p in options.unmatched_scopes(sim.probes())? {
        eprintln!("warning: scope pattern `{p}` matches no signal");
    }
    let mut writer = VcdWriter::create(&args[1], &options)?;
    let summary = writer.summary_handle();
    let start = Instant::now();
    sim.attach(Box::new(writer))?;
    sim.run_core_cycles(cycles, |_| {})?;
    sim.finish()?;
    let s = summary.borrow();
    let bytes = std::fs::metadata(&args[1])?.len();
    println!(
        "{cycles} core cycles in {:.3} s: {} signals, {} values, {:.1} MB, save file {}",
        start.elapsed().as_secs_f64(),
        s.signals,
        s.values_written,
        bytes as f64 / 1e6,
        s.gtkw
            .as_ref()
            .map_or("-".into(), |p| p.display().to_string()),
    );
    Ok(())
}
