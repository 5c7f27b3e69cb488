//! Trace replay serves every request of the trace, whatever its timing, and jumping over
//! idle gaps gives exactly what stepping every cycle gives.

use imagine_units::desc::MachineDesc;
use imagine_units::dram::{
    DramParams, Policy, ReplayOptions, ReplayReport, TraceKind, TraceRequest, replay,
};

fn req(byte_addr: u64, kind: TraceKind, cycle: u64) -> TraceRequest {
    TraceRequest {
        byte_addr,
        kind,
        cycle,
    }
}

fn rd(byte_addr: u64, cycle: u64) -> TraceRequest {
    req(byte_addr, TraceKind::Read, cycle)
}

fn wr(byte_addr: u64, cycle: u64) -> TraceRequest {
    req(byte_addr, TraceKind::Write, cycle)
}

fn run(desc: &MachineDesc, reqs: &[TraceRequest], policy: Policy, skip: bool) -> ReplayReport {
    let mut opts = ReplayOptions::new(policy);
    opts.record = true;
    opts.skip_idle = skip;
    replay(desc, reqs, opts).unwrap_or_else(|e| panic!("{policy}: {e}"))
}

/// Everything a replay reports except how it got there.
fn outcome(r: &ReplayReport) -> String {
    let mut r = r.clone();
    r.skipped_cycles = 0;
    format!("{r:?}")
}

/// Bytes from one row of a bank to the next row of the same bank (see the address map).
fn row_stride(p: &DramParams) -> u64 {
    (p.columns * p.channels * p.banks) as u64 * 4
}

#[test]
fn every_request_is_served_and_counted() {
    let desc = MachineDesc::gold8();
    let p = DramParams::of(&desc);
    let row = row_stride(&p);
    let traces: Vec<(&str, Vec<TraceRequest>)> = vec![
        ("the README's one line", vec![rd(0x1f40, 12)]),
        ("one write", vec![wr(0x40, 0)]),
        ("spread out", vec![rd(0x0, 5), rd(0x40, 50), rd(0x80, 100)]),
        (
            "all at cycle 0",
            (0..7).map(|i| rd(4 * i, 0)).collect::<Vec<_>>(),
        ),
        (
            "reads and writes at cycle 0",
            vec![rd(0, 0), wr(4, 0), wr(row, 0), rd(row + 8, 0), wr(12, 0)],
        ),
        (
            "reads and writes spread out",
            vec![
                wr(0x100, 3),
                rd(0x100, 3),
                rd(2 * row, 40),
                wr(0x104, 41),
                rd(0x0, 700),
                wr(3 * row + 4, 2000),
            ],
        ),
        (
            "the same word, back to back",
            vec![wr(0x20, 9), rd(0x20, 9), wr(0x20, 9), rd(0x20, 10)],
        ),
        (
            "last one long after",
            vec![rd(0x0, 0), wr(0x4, 0), rd(0x8, 9000)],
        ),
    ];
    for (name, reqs) in &traces {
        let reads = reqs.iter().filter(|r| r.kind == TraceKind::Read).count() as u64;
        let writes = reqs.len() as u64 - reads;
        let last = reqs.last().unwrap().cycle;
        for policy in Policy::ALL {
            for skip in [false, true] {
                let r = run(&desc, reqs, policy, skip);
                let what = format!("{name} under {policy} (skip {skip})");
                assert_eq!(r.requests, reqs.len() as u64, "{what}");
                assert_eq!((r.reads, r.writes), (reads, writes), "{what}");
                assert_eq!(r.recorded.len(), reqs.len(), "{what}");
                let accepted: u64 = r.channels.iter().map(|c| c.accepted).sum();
                assert_eq!(accepted, reqs.len() as u64, "{what}");
                assert!(r.finish_cycle > last, "{what}: finish {}", r.finish_cycle);
                assert_eq!(r.bytes, reqs.len() as u64 * p.burst_bytes(), "{what}");
                assert!(r.violations.is_empty(), "{what}: {}", r.violations[0]);
                if reads > 0 {
                    assert!(r.avg_read_latency >= (p.t_rcd + p.cl) as f64, "{what}");
                }
            }
        }
    }
    // The README's example, worked by hand: presented in cycle 12, in the buffer at 13,
    // ACTIVATE on the bus at 15, READ at 18 (tRCD 3), its word at 21 (CL 3).
    let r = run(&desc, &[rd(0x1f40, 12)], Policy::FirstReady, true);
    assert_eq!((r.finish_cycle, r.avg_read_latency), (21, 8.0));
    assert_eq!((r.activates, r.reads, r.refreshes), (1, 1, 0));
}

/// A burst at cycle 0, a burst at `at` and one more a little later, over several banks,
/// rows and both directions.
fn gap_trace(p: &DramParams, at: u64) -> Vec<TraceRequest> {
    let row = row_stride(p);
    vec![
        rd(0x0, 0),
        wr(0x44, 0),
        rd(row + 0x10, 1),
        wr(3 * row + 0x400, 2),
        rd(0x0, at),
        wr(2 * row + 0x8, at),
        rd(row + 0x10, at + 1),
        rd(0x4, at + 37),
    ]
}

/// A machine whose refresh interval is the shortest allowed, so that gaps cross many.
fn fast_refresh() -> MachineDesc {
    let mut d = MachineDesc::gold8();
    d.dram.refresh_interval = 4 * (d.dram.t_rc + d.dram.t_rfc);
    d.validate().expect("a valid machine");
    d
}

#[test]
fn skipping_idle_gaps_gives_exactly_what_stepping_gives() {
    let mut skipped_some = 0;
    for desc in [MachineDesc::gold8(), fast_refresh()] {
        let p = DramParams::of(&desc);
        let (refi, rfc) = (p.t_refi, p.t_rfc);
        // Arrivals: short gaps (nothing to skip), gaps of whole refresh intervals, and
        // arrivals on and around a refresh (k · tREFI ± a few, and around its tRFC).
        let mut arrivals = vec![1, 5, 30, 100, refi / 2, 50_000];
        for k in [1, 2, 3, 7] {
            for d in [
                -3i64,
                -2,
                -1,
                0,
                1,
                2,
                rfc as i64 - 1,
                rfc as i64,
                rfc as i64 + 1,
            ] {
                arrivals.push((k * refi).checked_add_signed(d).unwrap());
            }
        }
        for &at in &arrivals {
            let reqs = gap_trace(&p, at);
            for policy in Policy::ALL {
                let stepped = run(&desc, &reqs, policy, false);
                let fast = run(&desc, &reqs, policy, true);
                assert_eq!(stepped.skipped_cycles, 0);
                assert_eq!(
                    outcome(&fast),
                    outcome(&stepped),
                    "{} tREFI {refi}, burst at {at}, {policy}",
                    desc.name
                );
                assert_eq!(fast.requests, reqs.len() as u64);
                skipped_some += (fast.skipped_cycles > 0) as usize;
            }
        }
        // Many gaps in one trace, each landing at a different phase of the refresh.
        let row = row_stride(&p);
        let mut reqs = Vec::new();
        let mut t = 0;
        for i in 0..24u64 {
            t += (i * 997) % (3 * refi) + i % 5;
            reqs.push(rd((i * 0x44) % (4 * row), t));
            if i % 3 == 0 {
                reqs.push(wr(row + i * 8, t));
            }
        }
        for policy in Policy::ALL {
            let stepped = run(&desc, &reqs, policy, false);
            let fast = run(&desc, &reqs, policy, true);
            assert_eq!(outcome(&fast), outcome(&stepped), "many gaps, {policy}");
            skipped_some += (fast.skipped_cycles > 0) as usize;
        }
    }
    // The comparison above is not vacuous: most of those runs did jump.
    assert!(skipped_some > 100, "only {skipped_some} runs skipped");
}

#[test]
fn a_gap_of_a_trillion_cycles_is_crossed_in_one_step() {
    let desc = MachineDesc::gold8();
    let p = DramParams::of(&desc);
    let gap = 1_000_000_000_000u64;
    for policy in [Policy::FirstReady, Policy::RowClosed] {
        let r = run(&desc, &[rd(0x0, 5), rd(0x40, gap)], policy, true);
        assert_eq!(r.requests, 2);
        // The second read is served as after any idle time: in the buffer one cycle after
        // it is presented; the bank is closed (the refreshes closed it), so ACTIVATE,
        // tRCD, READ, CL.
        assert_eq!(r.finish_cycle, gap + 1 + 1 + p.t_rcd + p.cl + 1, "{policy}");
        // Every channel refreshed on time throughout: one REFRESH per interval up to the
        // end.
        for c in &r.channels {
            assert_eq!(c.refreshes, r.finish_cycle / p.t_refi, "{policy}");
            assert_eq!(c.cycles, r.finish_cycle + 1, "{policy}");
        }
        assert!(r.violations.is_empty());
        assert!(
            r.skipped_cycles > gap - 2 * p.t_refi,
            "{}",
            r.skipped_cycles
        );
    }
}
