//! The VCD writer driven directly through the `Tracer` API with synthetic changes: every
//! value of every width comes back from the `vcd` crate's parser as it was sent, windows
//! and scope filters cut the dump as documented, and instants that share a picosecond merge.

mod common;

use std::collections::BTreeMap;
use std::io;

use common::{Event, SharedBuf, Val, model, read};
use imagine_hdl::{ClockDomain, ProbeRegistry, SignalId, SignalKind, Tracer};
use imagine_waves::{CycleWindow, ScopeFilter, VcdOptions, VcdWriter, parse_window};
use vcd::{ReferenceIndex, VarType};

/// The test design: signals of widths 1, 7, 64, 65 and 200 in nested scopes, a clock, and
/// one signal that is never reported.
fn registry() -> ProbeRegistry {
    let mut r = ProbeRegistry::new();
    for (path, width, kind) in [
        ("top.clk_core", 1, SignalKind::Clock),
        ("top.a.bit", 1, SignalKind::Reg),
        ("top.a.b.seven", 7, SignalKind::Wire),
        ("top.a.b.c.w64", 64, SignalKind::Reg),
        ("top.a.w65", 65, SignalKind::Reg),
        ("top.x.y.w200", 200, SignalKind::Wire),
        ("top.x.silent", 9, SignalKind::Reg),
    ] {
        r.register(path.into(), width, kind);
    }
    r
}

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 ^ (self.0 >> 29)
    }
}

/// A busy synthetic run: the clock toggles every instant (two instants per core cycle), the
/// other signals change at random with random values — some repeated unchanged, as a tracer
/// may be told — and sometimes two instants share a picosecond.
fn events(reg: &ProbeRegistry, cycles: u64, seed: u64) -> Vec<Event> {
    let mut rng = Lcg(seed);
    let mut ev = Vec::new();
    let mut t = 0;
    for k in 0..cycles * 2 {
        ev.push(Event::Time(t, k / 2));
        ev.push(Event::Change(0, vec![(k + 1) % 2]));
        for (i, s) in reg.signals().iter().enumerate().skip(1) {
            if s.path == "top.x.silent" || rng.next().is_multiple_of(3) {
                continue;
            }
            let mut v: Vec<u64> = (0..s.words()).map(|_| rng.next()).collect();
            if rng.next().is_multiple_of(4) {
                v.iter_mut().for_each(|w| *w &= 3); // small values, frequent repeats
            }
            if s.width % 64 != 0 {
                let n = v.len();
                v[n - 1] &= (1 << (s.width % 64)) - 1;
            }
            ev.push(Event::Change(i as u32, v));
        }
        // Every 7th instant, a second simulator instant at the same picosecond.
        if k % 7 == 3 {
            ev.push(Event::Time(t, k / 2));
            ev.push(Event::Change(1, vec![rng.next() & 1]));
            ev.push(Event::Change(4, vec![rng.next(), rng.next() & 1]));
        }
        t += 1000;
    }
    ev
}

fn run(reg: &ProbeRegistry, ev: &[Event], opts: &VcdOptions) -> (Vec<u8>, Vec<SignalId>) {
    let mut w = VcdWriter::new(Vec::new(), opts).unwrap();
    w.start(reg, &[ClockDomain::mhz("core", 500)]).unwrap();
    for e in ev {
        match e {
            Event::Time(t, c) => w.time(*t, *c),
            Event::Change(id, v) => w.change(SignalId(*id), v),
        }
    }
    w.finish().unwrap();
    let selected = w.selected().to_vec();
    (std::mem::take(w.get_ref()), selected)
}

/// Checks a dump of `ev` against the model; returns the dump.
fn check(reg: &ProbeRegistry, ev: &[Event], opts: &VcdOptions) -> common::Dump {
    let (text, selected) = run(reg, ev, opts);
    let dump = read(&text);
    let widths: Vec<u32> = reg.signals().iter().map(|s| s.width).collect();
    let paths: Vec<Option<String>> = reg
        .signals()
        .iter()
        .enumerate()
        .map(|(i, s)| {
            selected
                .contains(&SignalId(i as u32))
                .then(|| s.path.clone())
        })
        .collect();
    let (expected, end) = model(ev, &widths, &paths, opts.window);
    let declared: std::collections::BTreeSet<&String> = paths.iter().flatten().collect();
    assert!(dump.vars.keys().eq(declared), "declared signals");
    for (path, tr) in &expected {
        assert_eq!(
            dump.transitions.get(path),
            Some(tr),
            "transitions of {path}"
        );
    }
    assert_eq!(dump.transitions.len(), expected.len());
    let mut times: Vec<u64> = expected.values().flatten().map(|(t, _)| *t).collect();
    times.sort();
    times.dedup();
    if let Some(e) = end.filter(|&e| times.last().is_none_or(|&l| e > l)) {
        times.push(e);
    }
    assert_eq!(dump.timestamps, times, "timestamps");
    dump
}

#[test]
fn every_width_round_trips_through_the_vcd_parser() {
    let reg = registry();
    let ev = events(&reg, 300, 1);
    let dump = check(&reg, &ev, &VcdOptions::default());

    // Hierarchy, widths, kinds and ranges.
    assert_eq!(
        dump.scopes,
        ["top", "top.a", "top.a.b", "top.a.b.c", "top.x", "top.x.y"]
    );
    let v = |p: &str| dump.vars[p].clone();
    assert_eq!(
        (v("top.clk_core").width, v("top.clk_core").var_type),
        (1, VarType::Wire)
    );
    assert_eq!(
        (v("top.a.bit").width, v("top.a.bit").var_type),
        (1, VarType::Reg)
    );
    assert_eq!(v("top.a.bit").index, None);
    assert_eq!(v("top.a.b.seven").var_type, VarType::Wire);
    for (p, w) in [
        ("top.a.b.seven", 7),
        ("top.a.b.c.w64", 64),
        ("top.a.w65", 65),
        ("top.x.y.w200", 200),
    ] {
        assert_eq!(v(p).width, w, "{p}");
        assert_eq!(
            v(p).index,
            Some(ReferenceIndex::Range(w as i32 - 1, 0)),
            "{p}"
        );
    }
    assert_eq!(dump.dumpvars_at, Some(0));
    assert!(dump.version.unwrap().contains("imagine-waves"));
    assert!(dump.date.is_some());
    // The signal never reported stays x, and wide values really are wide.
    assert_eq!(dump.transitions["top.x.silent"], [(0, None)]);
    let wide = &dump.transitions["top.x.y.w200"];
    assert!(wide.len() > 150, "{}", wide.len());
    assert!(
        wide.iter()
            .any(|(_, v)| v.as_ref().is_some_and(|v| v[3] >> 7 != 0))
    );
    // The clock toggles at every instant.
    assert_eq!(dump.transitions["top.clk_core"].len(), 600);
}

#[test]
fn instants_sharing_a_picosecond_are_merged() {
    let reg = registry();
    let mut w = VcdWriter::new(Vec::new(), &VcdOptions::default()).unwrap();
    w.start(&reg, &[]).unwrap();
    let bit = SignalId(1);
    let w65 = SignalId(4);
    w.time(0, 0);
    w.change(bit, &[0]);
    w.change(w65, &[5, 1]);
    w.time(10, 0);
    w.change(bit, &[1]);
    w.time(10, 0); // a second instant at the same picosecond: 1 → 0 again
    w.change(bit, &[0]);
    w.change(w65, &[6, 0]);
    w.time(20, 1);
    w.change(bit, &[1]);
    w.time(15, 1); // never backwards: treated as the same instant as 20
    w.change(w65, &[7, 0]);
    w.time(30, 1);
    w.finish().unwrap();
    let text = String::from_utf8(std::mem::take(w.get_ref())).unwrap();
    let dump = read(text.as_bytes());
    assert_eq!(dump.timestamps, [0, 10, 20], "{text}");
    assert_eq!(
        dump.transitions["top.a.bit"],
        [(0, Some(vec![0])), (20, Some(vec![1]))],
        "the glitch at 10 ps merged away: {text}"
    );
    let v65: Vec<(u64, Val)> = vec![
        (0, Some(vec![5, 1])),
        (10, Some(vec![6, 0])),
        (20, Some(vec![7, 0])),
    ];
    assert_eq!(dump.transitions["top.a.w65"], v65);
    assert_eq!(text.matches("\n#10\n").count(), 1);
}

#[test]
fn a_window_opens_with_the_state_at_from_and_stops_at_to() {
    let reg = registry();
    let ev = events(&reg, 300, 2);
    for w in [
        "100:150", "0:1", "299:", "123:124", ":40", "100:1000", "500:600",
    ] {
        let opts = VcdOptions {
            window: parse_window(w).unwrap(),
            scopes: vec![],
            max_bytes: None,
        };
        let dump = check(&reg, &ev, &opts);
        let from = opts.window.from;
        if from >= 300 {
            assert_eq!(dump.timestamps, Vec::<u64>::new(), "{w}: never reached");
            continue;
        }
        // Cycle c starts at 2000·c ps in this run.
        assert_eq!(dump.dumpvars_at, Some(from * 2000), "{w}");
        let last = *dump.timestamps.last().unwrap();
        match opts.window.to.filter(|&t| t < 300) {
            Some(to) => assert_eq!(last, to * 2000, "{w}: ends at the rising edge of TO"),
            None => assert!(last < 600_000, "{w}"),
        }
    }
}

#[test]
fn values_before_the_window_appear_in_its_dumpvars() {
    let reg = registry();
    let seven = SignalId(2);
    let w200 = SignalId(5);
    let opts = VcdOptions {
        window: parse_window("10:12").unwrap(),
        scopes: vec![],
        max_bytes: None,
    };
    let mut w = VcdWriter::new(Vec::new(), &opts).unwrap();
    w.start(&reg, &[]).unwrap();
    w.time(0, 0);
    w.change(seven, &[0x55]);
    w.change(w200, &[1, 2, 3, 0xF0]);
    w.time(5000, 2);
    w.change(seven, &[0x7F]);
    w.time(20_000, 10);
    w.change(w200, &[4, 5, 6, 0x80]);
    w.time(21_000, 10);
    w.change(seven, &[0x01]);
    w.time(22_000, 11);
    w.change(seven, &[0x02]);
    w.time(24_000, 12);
    w.change(seven, &[0x03]); // after the window: not written
    w.time(26_000, 13);
    w.change(seven, &[0x04]);
    w.finish().unwrap();
    let dump = read(w.get_ref());
    assert_eq!(dump.dumpvars_at, Some(20_000));
    assert_eq!(
        dump.transitions["top.a.b.seven"],
        [
            (20_000, Some(vec![0x7F])),
            (21_000, Some(vec![1])),
            (22_000, Some(vec![2]))
        ]
    );
    assert_eq!(
        dump.transitions["top.x.y.w200"],
        [(20_000, Some(vec![4, 5, 6, 0x80]))]
    );
    assert_eq!(dump.transitions["top.a.bit"], [(20_000, None)]);
    assert_eq!(dump.timestamps, [20_000, 21_000, 22_000, 24_000]);
}

#[test]
fn scope_filters_select_subtrees_and_keep_the_clocks() {
    let reg = registry();
    let ev = events(&reg, 50, 3);
    let names = |scopes: &[&str]| -> Vec<String> {
        let opts = VcdOptions {
            window: CycleWindow::ALL,
            scopes: scopes.iter().map(|s| s.to_string()).collect(),
            max_bytes: None,
        };
        check(&reg, &ev, &opts).vars.into_keys().collect()
    };
    assert_eq!(
        names(&["top.a.b"]),
        ["top.a.b.c.w64", "top.a.b.seven", "top.clk_core"]
    );
    assert_eq!(names(&["top.a.b.*"]), names(&["top.a.b"]));
    assert_eq!(
        names(&["*.w6?"]),
        ["top.a.b.c.w64", "top.a.w65", "top.clk_core"]
    );
    assert_eq!(
        names(&["*.y.*", "top.a.bit"]),
        ["top.a.bit", "top.clk_core", "top.x.y.w200"]
    );
    assert_eq!(names(&["top.nothing"]), ["top.clk_core"]);
    assert_eq!(names(&[]).len(), reg.len());

    let opts = VcdOptions {
        window: CycleWindow::ALL,
        scopes: vec!["top.a".into(), "top.zz*".into()],
        max_bytes: None,
    };
    assert_eq!(opts.unmatched_scopes(&reg).unwrap(), ["top.zz*"]);
    let mut w = VcdWriter::new(Vec::new(), &opts).unwrap();
    w.start(&reg, &[]).unwrap();
    assert_eq!(w.unmatched_scopes(), ["top.zz*"]);
    assert!(ScopeFilter::new(&["top.["]).is_err());
    let bad = VcdOptions {
        scopes: vec!["[".into()],
        ..VcdOptions::default()
    };
    assert!(VcdWriter::new(Vec::new(), &bad).is_err());
    let e = VcdWriter::create(std::env::temp_dir().join("never.vcd"), &bad)
        .err()
        .unwrap();
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
}

/// Fails every write after `budget` bytes.
struct Failing {
    budget: usize,
}
impl io::Write for Failing {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        if b.len() > self.budget {
            return Err(io::Error::other("disk full"));
        }
        self.budget -= b.len();
        Ok(b.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[test]
fn write_errors_are_returned_by_finish() {
    let reg = registry();
    let ev = events(&reg, 2000, 4);
    let mut w = VcdWriter::new(Failing { budget: 100_000 }, &VcdOptions::default()).unwrap();
    w.start(&reg, &[]).unwrap();
    for e in &ev {
        match e {
            Event::Time(t, c) => w.time(*t, *c),
            Event::Change(id, v) => w.change(SignalId(*id), v),
        }
    }
    let e = w.finish().unwrap_err();
    assert!(e.to_string().contains("disk full"), "{e}");

    let mut w = VcdWriter::new(Failing { budget: 10 }, &VcdOptions::default()).unwrap();
    assert!(w.start(&reg, &[]).is_err());
}

#[test]
fn a_boxed_writer_reports_through_its_summary_handle() {
    let reg = registry();
    let buf = SharedBuf::default();
    let mut w = VcdWriter::new(buf.clone(), &VcdOptions::default()).unwrap();
    let summary = w.summary_handle();
    let mut t: Box<dyn Tracer> = Box::new(w);
    t.start(&reg, &[]).unwrap();
    t.time(100, 0);
    t.change(SignalId(1), &[1]);
    t.time(200, 0);
    t.change(SignalId(1), &[0]);
    t.finish().unwrap();
    let s = summary.borrow().clone();
    assert_eq!(s.signals, reg.len());
    assert_eq!(s.first_time_ps, Some(100));
    assert_eq!(s.last_time_ps, Some(200));
    assert_eq!(s.values_written, reg.len() as u64 + 1);
    assert_eq!(s.gtkw, None);
    let dump = read(&buf.0.borrow());
    let expected: BTreeMap<_, _> = [(
        "top.a.bit".to_string(),
        vec![(100, Some(vec![1])), (200, Some(vec![0]))],
    )]
    .into_iter()
    .collect();
    assert_eq!(dump.transitions["top.a.bit"], expected["top.a.bit"]);
}
