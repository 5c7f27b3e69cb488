//! The timing checker catches violations; the SDRAM stores what is written; the trace
//! format is parsed strictly and written back the same; the address map is a bijection.

use imagine_hdl::bits::{u4, u12};
use imagine_units::desc::MachineDesc;
use imagine_units::dram::trace::{bench, parse_trace, write_trace};
use imagine_units::dram::{
    Command, DramParams, Policy, ReplayOptions, TimingChecker, TraceKind, replay,
};

fn params() -> DramParams {
    DramParams::of(&MachineDesc::gold8())
}

fn act(bank: u8, row: u16) -> Command {
    Command::Activate {
        bank: u4::new(bank),
        row,
    }
}

fn read(bank: u8, column: u16) -> Command {
    Command::Read {
        bank: u4::new(bank),
        column: u12::new(column),
    }
}

fn write(bank: u8, column: u16) -> Command {
    Command::Write {
        bank: u4::new(bank),
        column: u12::new(column),
    }
}

fn pre(bank: u8) -> Command {
    Command::Precharge {
        bank: u4::new(bank),
    }
}

/// Feeds `(cycle, command)` pairs (cycles ascending) and returns the rules broken.
fn check(cmds: &[(u64, Command)]) -> Vec<&'static str> {
    check_with(&params(), cmds)
}

fn check_with(p: &DramParams, cmds: &[(u64, Command)]) -> Vec<&'static str> {
    let mut c = TimingChecker::new(0, p);
    let last = cmds.last().map_or(0, |x| x.0);
    let mut it = cmds.iter().peekable();
    for cycle in 0..=last {
        let cmd = match it.peek() {
            Some(&&(c, cmd)) if c == cycle => {
                it.next();
                Some(cmd)
            }
            _ => None,
        };
        c.observe(cycle, cmd);
    }
    c.violations().iter().map(|v| v.rule).collect()
}

#[test]
fn a_legal_sequence_passes() {
    // gold8: tRCD 3, tRAS 7, tRP 3, tRC 10, tRRD 2, CL 3, tWR 2, turnaround 1.
    let v = check(&[
        (0, act(0, 5)),
        (2, act(1, 9)),
        (3, read(0, 0)),
        (4, read(0, 1)),
        (5, read(1, 0)),
        (10, write(1, 4)),
        (11, write(0, 7)),
        (12, pre(1)),
        (14, pre(0)),
        (17, act(0, 6)),
    ]);
    assert!(v.is_empty(), "{v:?}");
}

#[test]
fn each_rule_is_caught() {
    let cases: Vec<(&str, Vec<(u64, Command)>)> = vec![
        ("tRCD", vec![(0, act(0, 1)), (2, read(0, 0))]),
        ("tRAS", vec![(0, act(0, 1)), (6, pre(0))]),
        ("tRP", vec![(0, act(0, 1)), (7, pre(0)), (9, act(0, 2))]),
        ("tRRD", vec![(0, act(0, 1)), (1, act(1, 1))]),
        ("tWR", vec![(0, act(0, 1)), (6, write(0, 0)), (7, pre(0))]),
        (
            "turnaround",
            vec![(0, act(0, 1)), (3, read(0, 0)), (7, write(0, 1))],
        ),
        ("bank state", vec![(0, read(2, 0))]),
        ("bank state", vec![(0, act(0, 1)), (10, act(0, 2))]),
    ];
    for (rule, cmds) in cases {
        let v = check(&cmds);
        assert!(v.contains(&rule), "{rule}: {v:?}");
    }
    // gold8's tRC is exactly tRAS + tRP; with a longer one, tRC is its own rule.
    let mut p = params();
    p.t_rc = 12;
    let v = check_with(&p, &[(0, act(0, 1)), (7, pre(0)), (10, act(0, 2))]);
    assert_eq!(v, ["tRC"]);
    // Two-word bursts one cycle apart overlap on the data bus.
    p.burst = 2;
    let v = check_with(&p, &[(0, act(0, 1)), (3, write(0, 0)), (4, write(0, 2))]);
    assert_eq!(v, ["data bus"]);
}

#[test]
fn refresh_rules_are_caught() {
    let p = params();
    let mut c = TimingChecker::new(0, &p);
    c.observe(0, Some(act(0, 1)));
    c.observe(20, Some(Command::Refresh));
    assert!(c.violations().iter().any(|v| v.rule == "bank state"));
    let mut c = TimingChecker::new(0, &p);
    c.observe(0, Some(Command::Refresh));
    c.observe(5, Some(act(0, 1)));
    assert!(c.violations().iter().any(|v| v.rule == "tRFC"));
    let mut c = TimingChecker::new(0, &p);
    for cycle in 0..3 * p.t_refi {
        c.observe(cycle, None);
    }
    let v = c.violations();
    assert!(
        v.iter().any(|v| v.rule == "refresh interval"),
        "no refresh in three intervals: {v:?}"
    );
}

#[test]
fn an_injected_scheduler_bug_is_caught_in_a_full_run() {
    let desc = MachineDesc::gold8();
    let p = params();
    let reqs = bench("random", 512, &p).unwrap();
    // The scheduler believes tRCD is 1 cycle and tWR 0: the checker, which knows the
    // datasheet, must object, naming the rule, the channel, the bank and the cycle.
    let mut wrong = p.clone();
    wrong.t_rcd = 1;
    let mut opts = ReplayOptions::new(Policy::FirstReady);
    opts.scheduler_params = Some(wrong);
    let r = replay(&desc, &reqs, opts).unwrap();
    assert!(!r.violations.is_empty());
    assert!(
        r.violations.iter().all(|v| v.rule == "tRCD"),
        "{:?}",
        &r.violations[..3]
    );
    let msg = r.violations[0].to_string();
    assert!(
        msg.contains("tRCD") && msg.contains("bank") && msg.contains("DRAM cycle"),
        "{msg}"
    );
    // The same trace with the right timing is clean.
    let r = replay(&desc, &reqs, ReplayOptions::new(Policy::FirstReady)).unwrap();
    assert!(r.violations.is_empty());
}

#[test]
fn the_address_map_is_a_bijection_within_memory() {
    let p = params();
    for addr in (0..p.capacity_bytes()).step_by(4 * 997) {
        let l = p.map(addr).unwrap();
        assert_eq!(p.unmap(&l), addr);
        assert!((l.row as usize) < p.rows && (l.bank.value() as usize) < p.banks);
    }
    assert!(p.map(p.capacity_bytes()).is_none());
    // Consecutive words go to consecutive channels.
    let chans: Vec<usize> = (0..8).map(|w| p.map(w * 4).unwrap().channel).collect();
    assert_eq!(chans, [0, 1, 2, 3, 0, 1, 2, 3]);
    assert!((p.peak_bytes_per_s() / 1e9 - 2.672).abs() < 1e-9);
}

#[test]
fn traces_parse_strictly_and_round_trip() {
    let p = params();
    let ok = "# a comment\n0x40 READ 0\n\n80 write 2\n0X100 READ 2\n";
    let reqs = parse_trace(ok, &p).unwrap();
    assert_eq!(reqs.len(), 3);
    assert_eq!(reqs[1].byte_addr, 0x80);
    assert_eq!(reqs[1].kind, TraceKind::Write);
    let mut out = Vec::new();
    write_trace(&mut out, &reqs).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert_eq!(text, "0x40 READ 0\n0x80 WRITE 2\n0x100 READ 2\n");
    assert_eq!(parse_trace(&text, &p).unwrap(), reqs);
    for (bad, line, what) in [
        ("0x0 READ 5\n0x4 READ 4\n", 2, "must not decrease"),
        ("0x0 READ\n", 1, "3 fields"),
        ("0xg READ 1\n", 1, "hexadecimal"),
        ("0x0 FETCH 1\n", 1, "READ or WRITE"),
        ("0x0 READ -1\n", 1, "cycle number"),
        ("0x0 READ 1\n0x4000000 READ 1\n", 2, "out of range"),
    ] {
        let e = parse_trace(bad, &p).unwrap_err();
        assert_eq!(e.line, line, "{bad}: {e}");
        assert!(e.to_string().contains(what), "{bad}: {e}");
    }
}

#[test]
fn recorded_traces_replay_to_the_same_requests() {
    let desc = MachineDesc::gold8();
    let p = params();
    let reqs = bench("unit", 256, &p).unwrap();
    let mut opts = ReplayOptions::new(Policy::ColOpen);
    opts.record = true;
    let r = replay(&desc, &reqs, opts).unwrap();
    assert_eq!(r.recorded.len(), reqs.len());
    let mut a: Vec<u64> = reqs.iter().map(|r| r.byte_addr).collect();
    let mut b: Vec<u64> = r.recorded.iter().map(|r| r.byte_addr).collect();
    a.sort();
    b.sort();
    assert_eq!(a, b);
    let mut opts = ReplayOptions::new(Policy::ColOpen);
    opts.record = true;
    let again = replay(&desc, &r.recorded, opts).unwrap();
    assert_eq!(again.requests, r.requests);
    assert!(again.violations.is_empty());
}

#[test]
fn probes_show_banks_queues_commands_and_decisions() {
    use imagine_hdl::Recorder;
    let desc = MachineDesc::gold8();
    let reqs = bench("unit-conflict", 256, &params()).unwrap();
    let rec = Recorder::default();
    let mut opts = ReplayOptions::new(Policy::ColOpen);
    let r2 = rec.clone();
    opts.on_start = Some(Box::new(move |sim| {
        sim.attach(Box::new(r2)).map_err(|e| e.to_string())
    }));
    replay(&desc, &reqs, opts).unwrap();
    let r = rec.recording();
    let has = |path: &str, v: u64| r.values(path).is_some_and(|vals| vals.contains(&v));
    // ACT, READ, WRITE and PRE all appear on channel 0's command bus.
    for code in [1, 2, 3, 4] {
        assert!(has("top.mem.ch0.cmd", code), "command code {code}");
    }
    assert!(has("top.mem.ch0.bank0.state", 1));
    assert!(
        r.values("top.mem.ch0.bank0.row").unwrap().len() > 1,
        "rows change"
    );
    let depth = r.values("top.mem.ch0.queue_depth").unwrap();
    assert!(
        depth.iter().any(|&d| d >= 16),
        "the buffer fills: {depth:?}"
    );
    for d in [1, 2, 3] {
        assert!(has("top.mem.ch0.decision", d), "decision {d}");
    }
    assert_eq!(
        r.probes
            .get(r.probes.find("top.mem.ch0.bank0.row").unwrap())
            .width,
        12
    );
    assert_eq!(
        r.probes
            .get(r.probes.find("top.mem.ch0.cmd_bank").unwrap())
            .width,
        2
    );
}
