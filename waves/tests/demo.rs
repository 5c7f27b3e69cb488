//! The demo design of `imagine-hdl` dumped to a file: the hierarchy, the clocks, every value
//! the simulator reported, and the GTKWave save file next to it.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::{Recorder, Tee, model, read, temp_dir};
use imagine_hdl::demo::{self, DemoConfig};
use imagine_hdl::{ProbeRegistry, Sim, default_domains};
use imagine_waves::{
    CycleWindow, VcdOptions, VcdWriter, gtkw_path, gtkw_signal_name, parse_window,
};

fn demo_sim() -> Sim {
    demo::build(default_domains(), DemoConfig::default()).unwrap()
}

/// Runs the demo for `cycles` with a VCD at `path`; returns what the simulator reported and
/// its registry.
fn dump_demo(path: &Path, cycles: u64, opts: &VcdOptions) -> (Vec<common::Event>, ProbeRegistry) {
    let mut sim = demo_sim();
    let rec = Recorder::default();
    let writer = VcdWriter::create(path, opts).unwrap();
    sim.attach(Box::new(Tee(writer, rec.clone()))).unwrap();
    sim.run_core_cycles(cycles, |_| {}).unwrap();
    sim.finish().unwrap();
    let events = rec.0.borrow().clone();
    (events, sim.probes().clone())
}

/// The dump holds exactly what the model of the recorded run says.
fn check_against_model(
    text: &[u8],
    events: &[common::Event],
    reg: &ProbeRegistry,
    opts: &VcdOptions,
) -> common::Dump {
    let dump = read(text);
    let filter = opts.filter().unwrap();
    let widths: Vec<u32> = reg.signals().iter().map(|s| s.width).collect();
    let paths: Vec<Option<String>> = reg
        .signals()
        .iter()
        .map(|s| filter.matches(&s.path, s.kind).then(|| s.path.clone()))
        .collect();
    let (expected, _) = model(events, &widths, &paths, opts.window);
    assert_eq!(dump.transitions.len(), expected.len());
    for (path, tr) in &expected {
        assert_eq!(dump.transitions.get(path), Some(tr), "{path}");
    }
    dump
}

#[test]
fn the_demo_dumps_its_hierarchy_clocks_and_every_change() {
    let dir = temp_dir("demo");
    let vcd = dir.join("demo.vcd");
    let n = 3000;
    let opts = VcdOptions::default();
    let (events, reg) = dump_demo(&vcd, n, &opts);
    let text = std::fs::read(&vcd).unwrap();
    let dump = check_against_model(&text, &events, &reg, &opts);

    for scope in [
        "top",
        "top.source",
        "top.mac",
        "top.mac.s1",
        "top.mac.s2",
        "top.mac.s3",
        "top.mac.s4",
        "top.sink",
        "top.monitor",
        "top.ops",
        "top.out",
        "top.results",
    ] {
        assert!(
            dump.scopes.iter().any(|s| s == scope),
            "scope {scope}: {:?}",
            dump.scopes
        );
    }
    assert_eq!(dump.vars.len(), reg.len());
    for s in reg.signals() {
        assert_eq!(dump.vars[&s.path].width, s.width, "{}", s.path);
    }
    assert_eq!(dump.vars["top.mac.s2.pp_lo"].width, 24);
    assert_eq!(dump.vars["top.sink.checksum"].width, 64);

    // The core clock: 1 at 0 ps, then falls at 2000k+1000 and rises at 2000k: two
    // transitions per core cycle (the run ends at the rising edge of its last cycle).
    let clk = &dump.transitions["top.clk_core"];
    assert_eq!(clk.len() as u64, 2 * (n - 1) + 1);
    for (i, (t, v)) in clk.iter().enumerate() {
        assert_eq!(*t, i as u64 * 1000);
        assert_eq!(v.as_deref(), Some(&[u64::from(i % 2 == 0)][..]), "at {t}");
    }
    // The DRAM clock: 167 MHz, half period 2994.0119… ps, rounded down.
    let dram = &dump.transitions["top.clk_dram"];
    for (k, (t, _)) in dram.iter().enumerate() {
        assert_eq!(*t, (k as u128 * 1_000_000_000_000 / 334_000_000) as u64);
    }
    assert!(dram.len() > 2 * 1000 - 2);
}

#[test]
fn a_demo_window_with_scopes_writes_a_matching_save_file() {
    let dir = temp_dir("window");
    let vcd = dir.join("mac.vcd");
    let opts = VcdOptions {
        window: parse_window("1000:1100").unwrap(),
        scopes: vec!["top.mac".into(), "*.valid".into()],
        max_bytes: None,
    };
    let (events, reg) = dump_demo(&vcd, 2000, &opts);
    let text = std::fs::read(&vcd).unwrap();
    let dump = check_against_model(&text, &events, &reg, &opts);
    assert_eq!(dump.dumpvars_at, Some(1000 * 2000));
    assert_eq!(*dump.timestamps.last().unwrap(), 1100 * 2000);
    let names: BTreeSet<&str> = dump.vars.keys().map(String::as_str).collect();
    assert!(names.contains("top.mac.s2.pp_lo") && names.contains("top.results.valid"));
    assert!(names.contains("top.clk_core") && names.contains("top.clk_dram"));
    assert!(!names.contains("top.source.lfsr") && !names.contains("top.sink.count"));

    // The save file: next to the dump, naming it, listing exactly the dumped signals under
    // the names GTKWave gives them, clocks first.
    let gtkw = gtkw_path(&vcd);
    assert_eq!(gtkw, dir.join("mac.gtkw"));
    let save = std::fs::read_to_string(&gtkw).unwrap();
    let abs = std::path::absolute(&vcd).unwrap();
    assert!(
        save.contains(&format!("[dumpfile] \"{}\"", abs.display())),
        "{save}"
    );
    assert!(save.contains("[timestart] 2000000\n"), "{save}");
    let listed: Vec<&str> = save.lines().filter(|l| l.starts_with("top.")).collect();
    let expected: BTreeSet<String> = dump
        .vars
        .iter()
        .map(|(p, v)| {
            if v.width > 1 {
                format!("{p}[{}:0]", v.width - 1)
            } else {
                p.clone()
            }
        })
        .collect();
    assert_eq!(
        listed
            .iter()
            .map(|s| s.to_string())
            .collect::<BTreeSet<_>>(),
        expected
    );
    assert_eq!(listed.len(), expected.len(), "each signal listed once");
    assert_eq!(&listed[..2], ["top.clk_core", "top.clk_dram"]);
    for s in reg.signals() {
        if names.contains(s.path.as_str()) {
            assert!(listed.contains(&gtkw_signal_name(s).as_str()));
        }
    }
    // Groups open and close in pairs, named after the scope.
    let lines: Vec<&str> = save.lines().collect();
    let opens = lines.windows(2).filter(|w| w[0] == "@800200").count();
    let closes = lines.windows(2).filter(|w| w[0] == "@1000200").count();
    assert_eq!(opens, closes);
    assert!(save.contains("@800200\n-top.mac.s2\n"), "{save}");
}

#[test]
fn a_window_past_the_end_of_the_run_writes_only_the_header() {
    let dir = temp_dir("late");
    let vcd = dir.join("late.vcd");
    let opts = VcdOptions {
        window: CycleWindow {
            from: 5000,
            to: None,
        },
        scopes: vec![],
        max_bytes: None,
    };
    let mut sim = demo_sim();
    let mut w = VcdWriter::create(&vcd, &opts).unwrap();
    let summary = w.summary_handle();
    sim.attach(Box::new(w)).unwrap();
    sim.run_core_cycles(100, |_| {}).unwrap();
    sim.finish().unwrap();
    let dump = read(&std::fs::read(&vcd).unwrap());
    assert!(dump.timestamps.is_empty());
    assert_eq!(dump.vars.len(), sim.probes().len());
    let s = summary.borrow();
    assert_eq!(s.first_time_ps, None);
    assert_eq!(s.gtkw.as_deref(), Some(gtkw_path(&vcd).as_path()));
}

#[test]
fn an_unwritable_dump_is_a_clear_error() {
    let dir = temp_dir("unwritable");
    let e = VcdWriter::create(dir.join("no/such/dir/x.vcd"), &VcdOptions::default())
        .err()
        .unwrap();
    assert!(e.to_string().contains("no/such/dir/x.vcd"), "{e}");
}
