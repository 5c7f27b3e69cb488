//! DRAM request traces (DRAMsim3 text) for gold8's memory: `parse_trace`, then a replay on
//! the clocked memory system for a few thousand DRAM cycles under one of the scheduling
//! policies; a replay that finishes must not break a DRAM timing rule.
#![no_main]

use imagine_fuzz::{MAX_CYCLES, gold8, text, write_seeds_if_asked};
use imagine_units::dram::trace::{BENCHES, bench, parse_trace, write_trace};
use imagine_units::dram::{DramParams, Policy, ReplayOptions, replay};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let desc = gold8();
    let Ok(reqs) = parse_trace(text, &DramParams::of(desc)) else {
        return;
    };
    let policy = Policy::ALL[data.len() % Policy::ALL.len()];
    let mut opts = ReplayOptions::new(policy);
    opts.max_cycles = MAX_CYCLES;
    if let Ok(report) = replay(desc, &reqs, opts) {
        assert!(
            report.violations.is_empty(),
            "timing violations under {policy}: {:?}",
            report.violations
        );
    }
});

/// The microbenchmarks' traces, 48 requests each, as `imagine dram --dram-trace` writes
/// them, and one with comments, blank lines and both spellings.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let p = DramParams::of(gold8());
    let mut seeds: Vec<(String, Vec<u8>)> = BENCHES
        .iter()
        .map(|(name, _)| {
            let mut text = Vec::new();
            let reqs = bench(name, 48, &p).expect("a microbenchmark");
            write_trace(&mut text, &reqs).expect("writes to memory");
            (format!("{name}.trace"), text)
        })
        .collect();
    seeds.push((
        "mixed.trace".into(),
        b"# a comment\n0x0 READ 0\n\n40 write 3\n0X1f40 Read 3\n0x80 WRITE 100\n".to_vec(),
    ));
    seeds
}
