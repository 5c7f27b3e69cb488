//! Test helpers: a strict VCD reader built on the `vcd` crate's parser, a reference model of
//! what a dump must contain, and a tracer that records what it is sent.

#![allow(dead_code)]

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::io;
use std::rc::Rc;

use imagine_hdl::{ClockDomain, ProbeRegistry, SignalId, Tracer};
use imagine_waves::CycleWindow;
use vcd::{Command, IdCode, ReferenceIndex, ScopeItem, SimulationCommand, TimescaleUnit, Value};

/// A value: `None` is `x` (never reported), else little-endian words.
pub type Val = Option<Vec<u64>>;

/// Per signal path: (time, value) transitions, the first being the `$dumpvars` value.
pub type Transitions = BTreeMap<String, Vec<(u64, Val)>>;

#[derive(Clone, Debug, PartialEq)]
pub struct VarInfo {
    pub code: IdCode,
    pub width: u32,
    pub var_type: vcd::VarType,
    pub index: Option<ReferenceIndex>,
}

/// A dump read back, checked for the properties every dump must have.
#[derive(Debug, Default)]
pub struct Dump {
    /// Full dotted path → declaration.
    pub vars: BTreeMap<String, VarInfo>,
    /// Scope paths, in declaration order.
    pub scopes: Vec<String>,
    pub timestamps: Vec<u64>,
    pub dumpvars_at: Option<u64>,
    pub transitions: Transitions,
    pub date: Option<String>,
    pub version: Option<String>,
}

fn collect(items: &[ScopeItem], prefix: &str, d: &mut Dump) {
    for item in items {
        match item {
            ScopeItem::Scope(s) => {
                assert_eq!(s.scope_type, vcd::ScopeType::Module);
                let p = if prefix.is_empty() {
                    s.identifier.clone()
                } else {
                    format!("{prefix}.{}", s.identifier)
                };
                d.scopes.push(p.clone());
                collect(&s.items, &p, d);
            }
            ScopeItem::Var(v) => {
                let p = format!("{prefix}.{}", v.reference);
                let info = VarInfo {
                    code: v.code,
                    width: v.size,
                    var_type: v.var_type,
                    index: v.index,
                };
                assert!(
                    d.vars.insert(p.clone(), info).is_none(),
                    "{p} declared twice"
                );
            }
            ScopeItem::Comment(_) => {}
            _ => {}
        }
    }
}

/// Reads a vector value of a `width`-bit signal: full width, MSB first, or `bx`.
fn vector(bits: &vcd::Vector, width: u32, path: &str) -> Val {
    let v: Vec<Value> = bits.iter().collect();
    if v == [Value::X] {
        return None;
    }
    assert_eq!(v.len(), width as usize, "{path}: value of {} bits", v.len());
    let mut words = vec![0u64; width.div_ceil(64) as usize];
    for (i, b) in v.iter().rev().enumerate() {
        match b {
            Value::V0 => {}
            Value::V1 => words[i / 64] |= 1 << (i % 64),
            other => panic!("{path}: unexpected bit {other:?}"),
        }
    }
    Some(words)
}

/// Parses `text` strictly: timescale 1 ps, one `$dumpvars` at the first timestamp holding
/// every variable once, strictly increasing timestamps, every change a real change, vector
/// values at full width.
pub fn read(text: &[u8]) -> Dump {
    let mut p = vcd::Parser::new(text);
    let header = p.parse_header().expect("header parses");
    assert_eq!(header.timescale, Some((1, TimescaleUnit::PS)));
    let mut d = Dump {
        date: header.date.clone(),
        version: header.version.clone(),
        ..Dump::default()
    };
    collect(&header.items, "", &mut d);
    let by_code: HashMap<IdCode, String> =
        d.vars.iter().map(|(p, v)| (v.code, p.clone())).collect();
    assert_eq!(by_code.len(), d.vars.len(), "identifier codes are unique");
    let mut now: Option<u64> = None;
    let mut in_dumpvars = false;
    let mut last: HashMap<String, Val> = HashMap::new();
    for cmd in p {
        let cmd = cmd.expect("body parses");
        let mut value = |code: IdCode, v: Val, d: &mut Dump| {
            let path = by_code.get(&code).expect("known code").clone();
            let t = now.expect("a change before any timestamp");
            if in_dumpvars {
                assert!(
                    last.insert(path.clone(), v.clone()).is_none(),
                    "{path} twice in $dumpvars"
                );
            } else {
                let prev = last.get(&path).expect("every variable is in $dumpvars");
                assert_ne!(prev, &v, "{path}: redundant value at {t}");
                last.insert(path.clone(), v.clone());
            }
            d.transitions.entry(path).or_default().push((t, v));
        };
        match cmd {
            Command::Timestamp(t) => {
                assert!(!in_dumpvars);
                if let Some(n) = now {
                    assert!(t > n, "timestamp {t} after {n}");
                }
                now = Some(t);
                d.timestamps.push(t);
            }
            Command::Begin(SimulationCommand::Dumpvars) => {
                assert!(d.dumpvars_at.is_none(), "one $dumpvars");
                assert_eq!(d.timestamps.len(), 1, "$dumpvars at the first timestamp");
                d.dumpvars_at = now;
                in_dumpvars = true;
            }
            Command::End(SimulationCommand::Dumpvars) => {
                in_dumpvars = false;
                assert_eq!(last.len(), d.vars.len(), "$dumpvars holds every variable");
            }
            Command::ChangeScalar(code, v) => {
                let path = &by_code[&code];
                assert_eq!(d.vars[path].width, 1, "{path}: scalar change of a vector");
                let v = match v {
                    Value::V0 => Some(vec![0]),
                    Value::V1 => Some(vec![1]),
                    Value::X => None,
                    Value::Z => panic!("z"),
                };
                value(code, v, &mut d);
            }
            Command::ChangeVector(code, bits) => {
                let path = by_code[&code].clone();
                let w = d.vars[&path].width;
                assert!(w > 1, "{path}: vector change of a scalar");
                value(code, vector(&bits, w, &path), &mut d);
            }
            other => panic!("unexpected command {other:?}"),
        }
    }
    assert!(!in_dumpvars, "$dumpvars closed");
    d
}

/// What a tracer is sent.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    Time(u64, u64),
    Change(u32, Vec<u64>),
}

/// The transitions a dump of `events` over `window` must hold, for the signals in `paths`
/// (indexed by signal id; `None` for unselected signals), and the end-of-window timestamp.
pub fn model(
    events: &[Event],
    widths: &[u32],
    paths: &[Option<String>],
    window: CycleWindow,
) -> (Transitions, Option<u64>) {
    let mut state: Vec<Val> = vec![None; widths.len()];
    let mut snapshots: Vec<(u64, Vec<Val>)> = Vec::new();
    let mut group: Option<u64> = None;
    let mut end = None;
    for e in events {
        match e {
            Event::Time(t, c) => {
                if window.contains(*c) {
                    if group != Some(*t) {
                        if let Some(g) = group {
                            snapshots.push((g, state.clone()));
                        }
                        group = Some(*t);
                    }
                } else if group.is_some() && window.to.is_some_and(|to| *c >= to) {
                    end = Some(*t);
                    break;
                }
            }
            Event::Change(id, v) => {
                let id = *id as usize;
                let w = widths[id];
                let mut v = v.clone();
                v.resize(w.div_ceil(64) as usize, 0);
                if !w.is_multiple_of(64) {
                    let n = v.len();
                    v[n - 1] &= (1 << (w % 64)) - 1;
                }
                state[id] = Some(v);
            }
        }
    }
    if let Some(g) = group {
        snapshots.push((g, state.clone()));
    }
    let mut out = Transitions::new();
    for (id, path) in paths.iter().enumerate() {
        let Some(path) = path else { continue };
        let mut tr: Vec<(u64, Val)> = Vec::new();
        for (t, snap) in &snapshots {
            if tr.last().is_none_or(|(_, v)| *v != snap[id]) {
                tr.push((*t, snap[id].clone()));
            }
        }
        if !tr.is_empty() {
            out.insert(path.clone(), tr);
        }
    }
    if end.is_some_and(|e| snapshots.last().is_some_and(|(t, _)| *t >= e)) {
        end = None;
    }
    (out, end)
}

/// Records the events it is sent.
#[derive(Clone, Default)]
pub struct Recorder(pub Rc<RefCell<Vec<Event>>>);

impl Tracer for Recorder {
    fn start(&mut self, _: &ProbeRegistry, _: &[ClockDomain]) -> io::Result<()> {
        Ok(())
    }
    fn time(&mut self, t: u64, c: u64) {
        self.0.borrow_mut().push(Event::Time(t, c));
    }
    fn change(&mut self, id: SignalId, v: &[u64]) {
        self.0.borrow_mut().push(Event::Change(id.0, v.to_vec()));
    }
    fn finish(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Sends everything to two tracers.
pub struct Tee<A, B>(pub A, pub B);

impl<A: Tracer, B: Tracer> Tracer for Tee<A, B> {
    fn start(&mut self, p: &ProbeRegistry, c: &[ClockDomain]) -> io::Result<()> {
        self.0.start(p, c)?;
        self.1.start(p, c)
    }
    fn time(&mut self, t: u64, c: u64) {
        self.0.time(t, c);
        self.1.time(t, c);
    }
    fn change(&mut self, id: SignalId, v: &[u64]) {
        self.0.change(id, v);
        self.1.change(id, v);
    }
    fn finish(&mut self) -> io::Result<()> {
        let a = self.0.finish();
        let b = self.1.finish();
        a.and(b)
    }
}

/// A writer into a shared buffer, so a test can read what a boxed tracer wrote.
#[derive(Clone, Default)]
pub struct SharedBuf(pub Rc<RefCell<Vec<u8>>>);

impl io::Write for SharedBuf {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A fresh, empty directory for one test's files, removed when dropped.
pub struct TempDir(std::path::PathBuf);

impl std::ops::Deref for TempDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub fn temp_dir(name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("imagine-waves-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}
