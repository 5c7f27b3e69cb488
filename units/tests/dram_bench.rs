//! The microbenchmarks of Rixner et al. (ISCA 2000) through the memory access scheduler and
//! the SDRAM of gold8: unit-stride reads reach the peak, reordering policies beat in-order
//! on random and conflicting traffic, closed-row beats open-row on random reads, and the
//! timing checker finds no violation anywhere.

use imagine_units::desc::MachineDesc;
use imagine_units::dram::trace::bench;
use imagine_units::dram::{DramParams, Policy, ReplayOptions, ReplayReport, replay};

fn run(name: &str, n: usize, policy: Policy) -> ReplayReport {
    let desc = MachineDesc::gold8();
    let p = DramParams::of(&desc);
    let reqs = bench(name, n, &p).expect("a known benchmark");
    let r = replay(&desc, &reqs, ReplayOptions::new(policy)).expect("replay");
    assert!(
        r.violations.is_empty(),
        "{name} under {policy}: {} timing violations, first: {}",
        r.violations.len(),
        r.violations[0]
    );
    assert_eq!(r.requests, n as u64, "{name} under {policy}");
    r
}

const N: usize = 4096;

#[test]
fn unit_stride_reads_reach_95_percent_of_peak_under_every_policy() {
    for policy in Policy::ALL {
        let r = run("unit-load", 3 * N, policy);
        assert!(
            r.fraction_of_peak() >= 0.95,
            "{policy}: {:.1}% of peak",
            100.0 * r.fraction_of_peak()
        );
        assert!(r.row_hit_rate > 0.99, "{policy}: {}", r.row_hit_rate);
    }
}

#[test]
fn reordering_beats_in_order_by_30_percent_on_random_and_conflict_traces() {
    for name in ["random", "unit-conflict", "constrained-random"] {
        let in_order = run(name, N, Policy::InOrder).gbs;
        for policy in [Policy::FirstReady, Policy::ColOpen, Policy::ColClosed] {
            let r = run(name, N, policy);
            assert!(
                r.gbs >= 1.3 * in_order,
                "{name}: {policy} {:.3} GB/s vs in-order {in_order:.3} GB/s",
                r.gbs
            );
        }
    }
}

#[test]
fn closed_row_beats_open_row_on_random_reads() {
    for (closed, open) in [
        (Policy::ColClosed, Policy::ColOpen),
        (Policy::RowClosed, Policy::RowOpen),
    ] {
        let c = run("random-reads", N, closed);
        let o = run("random-reads", N, open);
        // The offered load is the same; closing rows early takes tRP off the critical path
        // of the next reference to the bank.
        assert!(
            c.avg_read_latency < 0.9 * o.avg_read_latency,
            "{closed} latency {:.1} vs {open} {:.1}",
            c.avg_read_latency,
            o.avg_read_latency
        );
        assert!(
            c.finish_cycle <= o.finish_cycle,
            "{closed} finishes no later"
        );
        assert!(c.precharges >= o.precharges);
    }
}

#[test]
fn open_row_policies_keep_rows_open_and_closed_ones_do_not() {
    let o = run("unit", N, Policy::ColOpen);
    let c = run("unit", N, Policy::ColClosed);
    assert!(o.row_hit_rate > c.row_hit_rate);
    assert!(o.precharges < c.precharges);
    // Load-over-store: reads wait less than under plain column-first.
    let l = run("random", N, Policy::LoadOverStore);
    let f = run("random", N, Policy::ColOpen);
    assert!(l.avg_read_latency < 0.6 * f.avg_read_latency);
}

#[test]
fn long_runs_refresh_every_interval() {
    let desc = MachineDesc::gold8();
    let r = run("random", N, Policy::FirstReady);
    let intervals = r.finish_cycle / desc.dram.refresh_interval as u64;
    assert!(intervals >= 1);
    for ch in &r.channels {
        assert!(
            ch.refreshes >= intervals && ch.refreshes <= intervals + 1,
            "{} refreshes in {} cycles",
            ch.refreshes,
            r.finish_cycle
        );
    }
}

#[test]
fn replays_are_deterministic() {
    let a = run("constrained-random", 1024, Policy::RowClosed);
    let b = run("constrained-random", 1024, Policy::RowClosed);
    assert_eq!(
        (a.finish_cycle, a.activates, a.channels.clone()),
        (b.finish_cycle, b.activates, b.channels.clone())
    );
}

/// Prints every benchmark under every policy (`--ignored --nocapture`).
#[test]
#[ignore]
fn table() {
    for (name, _) in imagine_units::dram::trace::BENCHES {
        for policy in Policy::ALL {
            let r = run(name, N, policy);
            eprintln!(
                "{name:<20} {policy:<16} {:6.3} GB/s {:5.1}% finish {:6} hit {:5.1}% lat {:6.1} act {} pre {} rd {} wr {} ref {}",
                r.gbs,
                100.0 * r.fraction_of_peak(),
                r.finish_cycle,
                100.0 * r.row_hit_rate,
                r.avg_read_latency,
                r.activates,
                r.precharges,
                r.reads,
                r.writes,
                r.refreshes
            );
        }
    }
}
