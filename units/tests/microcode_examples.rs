//! The example kernels in `tests/microcode/*.uc` (one per microcode feature: streaming
//! multiply-add, prefix sum across clusters, conditional output, conditional input,
//! scratchpad table lookup, software-pipelined loop) assemble and check on gold8 and gold1,
//! round-trip through text and binary, and compute what they claim.
//!
//! There is no machine yet, so "compute" is judged by a small reference executor written
//! here from the semantics documented in `microcode/mod.rs`: an instruction issues in one
//! cycle to every cluster; operands are read at issue; a result lands `latency` cycles
//! later (`imm` 1); the software-pipeline squash rule; conditional streams in cluster order.
//! It runs every example twice — with results readable in the cycle they land and only in
//! the next — and both must give the expected streams, so the examples do not depend on
//! that detail of the machine. It also fails on reading an LRF entry nobody wrote.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::check::Shape;
use imagine_units::microcode::{
    Control, Dest, Dests, ImmValue, InstructionLayout, LoopBegin, LoopKind, Permutation, Program,
    StreamDir, assemble, disassemble,
};
use imagine_units::ops::Op;

const EXAMPLES: &[(&str, &str)] = &[
    ("madd", include_str!("microcode/madd.uc")),
    ("prefix_sum", include_str!("microcode/prefix_sum.uc")),
    ("filter", include_str!("microcode/filter.uc")),
    ("cond_input", include_str!("microcode/cond_input.uc")),
    ("lookup", include_str!("microcode/lookup.uc")),
    ("saxpy", include_str!("microcode/saxpy.uc")),
];

fn example(name: &str) -> &'static str {
    EXAMPLES.iter().find(|(n, _)| *n == name).unwrap().1
}

// ---- reference executor ---------------------------------------------------------------

/// A write that lands later.
struct Pending {
    visible: u64,
    cluster: usize,
    what: Target,
    value: u32,
}

enum Target {
    Dest(Dest),
    Scratchpad { sp: usize, addr: usize },
}

struct Frame {
    begin: usize,
    end: usize,
    /// Iterations (`u64::MAX` for `until cc`), passes run, stages.
    n: u64,
    pass: u64,
    stages: u64,
    until: Option<u16>,
}

struct Exec<'a> {
    desc: &'a MachineDesc,
    sh: Shape,
    c: usize,
    /// Extra cycles before a landed result can be read (0 or 1).
    extra: u64,
    lrf: Vec<Vec<Vec<Option<u32>>>>,
    cc: Vec<Vec<bool>>,
    sp: Vec<Vec<Vec<u32>>>,
    pending: Vec<Pending>,
    inputs: Vec<(Vec<u32>, usize)>,
    outputs: Vec<Vec<u32>>,
    t: u64,
}

impl<'a> Exec<'a> {
    fn new(desc: &'a MachineDesc, p: &Program, inputs: &[Vec<u32>], extra: u64) -> Self {
        let sh = Shape::new(desc);
        let c = desc.cluster.count;
        let mut input_iter = inputs.iter();
        let streams = p
            .streams
            .iter()
            .map(|s| match s.dir {
                StreamDir::In => (
                    input_iter.next().expect("an input per In stream").clone(),
                    0,
                ),
                StreamDir::Out => (Vec::new(), 0),
            })
            .collect();
        Exec {
            desc,
            c,
            extra,
            lrf: vec![sh.lrf_sizes.iter().map(|&n| vec![None; n]).collect(); c],
            cc: vec![vec![false; sh.condition_codes]; c],
            sp: vec![vec![vec![0; sh.scratchpad_words]; sh.scratchpads]; c],
            pending: Vec::new(),
            inputs: streams,
            outputs: vec![Vec::new(); p.streams.len()],
            sh,
            t: 0,
        }
    }

    fn read(&self, cl: usize, slot: &str, input: &str, entry: u16) -> u32 {
        let (i, _) = self.sh.lrf(slot, input);
        self.lrf[cl][i][usize::from(entry)].unwrap_or_else(|| {
            panic!(
                "cycle {}: cluster {cl} reads {slot}.{input}[{entry}], never written",
                self.t
            )
        })
    }

    fn land(&mut self, latency: u64, cl: usize, dests: &Dests, value: u32) {
        for d in dests.iter().flatten() {
            self.pending.push(Pending {
                visible: self.t + latency + self.extra,
                cluster: cl,
                what: Target::Dest(*d),
                value,
            });
        }
    }

    /// Applies every write visible by now, in issue order. Two writes to one place in one
    /// cycle are a bug in the program.
    fn apply(&mut self, all: bool) {
        let now = self.t;
        let (due, rest): (Vec<_>, Vec<_>) = std::mem::take(&mut self.pending)
            .into_iter()
            .partition(|p| all || p.visible <= now);
        self.pending = rest;
        let mut due = due;
        due.sort_by_key(|p| p.visible);
        let mut seen = std::collections::HashSet::new();
        for p in due {
            match p.what {
                Target::Dest(Dest::Lrf { lrf, entry }) => {
                    assert!(
                        seen.insert((p.visible, p.cluster, lrf)),
                        "two writes to LRF {} in one cycle",
                        self.sh.lrf_names[usize::from(lrf)]
                    );
                    self.lrf[p.cluster][usize::from(lrf)][usize::from(entry)] = Some(p.value);
                }
                Target::Dest(Dest::Cc { index }) => {
                    self.cc[p.cluster][usize::from(index)] = p.value & 1 != 0;
                }
                Target::Dest(Dest::Stream { stream }) => {
                    // Appended in cluster order: pending entries of one cycle are pushed in
                    // cluster order by `issue`.
                    self.outputs[usize::from(stream)].push(p.value);
                }
                Target::Scratchpad { sp, addr } => self.sp[p.cluster][sp][addr] = p.value,
            }
        }
    }

    fn issue(&mut self, ins: &imagine_units::microcode::Instruction, active: impl Fn(u8) -> bool) {
        let l = &self.desc.latency;
        let mode = self.desc.fp_mode();
        for (k, s) in ins.fu.iter().enumerate() {
            let Some(s) = s else { continue };
            if !active(s.stage) {
                continue;
            }
            let name = self.sh.fu_name(k);
            for cl in 0..self.c {
                let value = if s.op == Op::Select {
                    let cond = self.cc[cl][usize::from(s.cc)];
                    if cond {
                        self.read(cl, &name, "a", s.a)
                    } else {
                        self.read(cl, &name, "b", s.b)
                    }
                } else {
                    let a = self.read(cl, &name, "a", s.a);
                    let b = if s.op.arity() >= 2 {
                        self.read(cl, &name, "b", s.b)
                    } else {
                        0
                    };
                    s.op.eval(a, b, 0, mode).0
                };
                self.land(u64::from(s.op.latency(l)), cl, &s.dests, value);
            }
        }
        for (k, s) in ins.sp.iter().enumerate() {
            let Some(s) = s else { continue };
            if !active(s.stage) {
                continue;
            }
            let name = format!("sp{k}");
            for cl in 0..self.c {
                let offset = s.offset.map_or(0, |o| self.read(cl, &name, "addr", o));
                let addr = usize::from(s.base) + offset as usize;
                assert!(addr < self.sh.scratchpad_words, "scratchpad address {addr}");
                if s.write {
                    let value = self.read(cl, &name, "data", s.data);
                    self.pending.push(Pending {
                        visible: self.t + u64::from(l.scratchpad_write) + self.extra,
                        cluster: cl,
                        what: Target::Scratchpad { sp: k, addr },
                        value,
                    });
                } else {
                    let value = self.sp[cl][k][addr];
                    self.land(u64::from(l.scratchpad_read), cl, &s.dests, value);
                }
            }
        }
        for (k, s) in ins.comm.iter().enumerate() {
            let Some(s) = s else { continue };
            if !active(s.stage) {
                continue;
            }
            let name = format!("comm{k}");
            let sent: Vec<u32> = (0..self.c)
                .map(|cl| self.read(cl, &name, "data", s.data))
                .collect();
            for cl in 0..self.c {
                let from = match s.perm {
                    Permutation::Rotate(r) => (cl + usize::from(r)) % self.c,
                    Permutation::Xor(x) => cl ^ usize::from(x),
                    Permutation::Broadcast(b) => usize::from(b),
                    Permutation::PerCluster(e) => self.read(cl, &name, "perm", e) as usize % self.c,
                };
                self.land(u64::from(l.comm), cl, &s.dests, sent[from]);
            }
        }
        for s in ins.sin.iter().flatten() {
            if !active(s.stage) {
                continue;
            }
            for cl in 0..self.c {
                if s.cond.is_some_and(|k| !self.cc[cl][usize::from(k)]) {
                    continue;
                }
                let (data, pos) = &mut self.inputs[usize::from(s.stream)];
                let value = *data
                    .get(*pos)
                    .unwrap_or_else(|| panic!("read past the end of input stream {}", s.stream));
                *pos += 1;
                self.land(u64::from(l.stream), cl, &s.dests, value);
            }
        }
        if let Some(s) = ins.sout.filter(|s| active(s.stage)) {
            for cl in 0..self.c {
                if s.cond.is_some_and(|k| !self.cc[cl][usize::from(k)]) {
                    continue;
                }
                let value = self.read(cl, "sout", "data", s.data);
                self.outputs[usize::from(s.stream)].push(value);
            }
        }
        if let Some(s) = ins.imm.filter(|s| active(s.stage)) {
            for cl in 0..self.c {
                let value = match s.value {
                    ImmValue::Const(v) => v,
                    ImmValue::ClusterId => cl as u32,
                };
                self.land(1, cl, &s.dests, value);
            }
        }
    }

    fn run(mut self, p: &Program) -> Vec<Vec<u32>> {
        let mut frames: Vec<Frame> = Vec::new();
        let mut pc = 0;
        let mut back = false;
        loop {
            assert!(self.t < 1_000_000, "runaway");
            self.apply(false);
            let ins = &p.code[pc];
            if let (Some(LoopBegin { kind, stages }), false) = (ins.control.begin, back) {
                let end = matching_end(p, pc);
                let (n, until) = match kind {
                    LoopKind::Counted(n) => (u64::from(n), None),
                    LoopKind::UntilStreamEmpty(s) => {
                        // Rows per pass: the first pass's unconditional reads of the stream.
                        let words = p.code[pc..=first_pass_end(p, pc)]
                            .iter()
                            .flat_map(|i| i.sin.iter().flatten())
                            .filter(|r| r.stream == s && r.cond.is_none())
                            .count()
                            .max(1);
                        let (data, pos) = &self.inputs[usize::from(s)];
                        let rows = (data.len() - pos) / self.c;
                        (rows.div_ceil(words) as u64, None)
                    }
                    LoopKind::UntilCc(k) => (u64::MAX, Some(k)),
                };
                frames.push(Frame {
                    begin: pc,
                    end,
                    n,
                    pass: 0,
                    stages: u64::from(stages),
                    until,
                });
                if n == 0 && stages == 1 {
                    frames.pop();
                    pc = end + 1;
                    continue;
                }
            }
            back = false;
            let (pass, n) = frames.last().map_or((0, 1), |f| (f.pass, f.n));
            self.issue(ins, |s| {
                let s = u64::from(s);
                s <= pass && pass < n.saturating_add(s)
            });
            self.t += 1;
            let Control {
                end,
                pass_end,
                done,
                ..
            } = ins.control;
            if done {
                self.apply(true);
                return self.outputs;
            }
            // A pass ends at `end` and, in a body of several passes, at `pass_end`.
            if end || pass_end {
                let f = frames.last_mut().unwrap();
                assert_eq!(end, f.end == pc);
                f.pass += 1;
                let finished = match f.until {
                    Some(k) => {
                        self.apply(false);
                        self.cc.iter().all(|cc| cc[usize::from(k)])
                    }
                    None => f.pass >= f.n + f.stages - 1,
                };
                if finished {
                    // Leaves from `end` or from the middle of the body.
                    pc = f.end + 1;
                    frames.pop();
                } else if end {
                    pc = f.begin;
                    back = true;
                } else {
                    pc += 1;
                }
            } else {
                pc += 1;
            }
        }
    }
}

fn matching_end(p: &Program, begin: usize) -> usize {
    let mut depth = 0;
    for (i, ins) in p.code.iter().enumerate().skip(begin) {
        if ins.control.begin.is_some() {
            depth += 1;
        }
        if ins.control.end {
            depth -= 1;
            if depth == 0 {
                return i;
            }
        }
    }
    panic!("unclosed loop at {begin}");
}

/// The last instruction of the first pass of the loop that begins at `begin`: its first
/// `pass_end` or its `end`, not counting those of nested loops.
fn first_pass_end(p: &Program, begin: usize) -> usize {
    let mut depth = 0;
    for (i, ins) in p.code.iter().enumerate().skip(begin) {
        if ins.control.begin.is_some() {
            depth += 1;
        }
        if depth == 1 && (ins.control.end || ins.control.pass_end) {
            return i;
        }
        if ins.control.end {
            depth -= 1;
        }
    }
    panic!("unclosed loop at {begin}");
}

/// Runs `name` on `desc` with both landing conventions; both must agree.
fn run(name: &str, desc: &MachineDesc, inputs: &[Vec<u32>]) -> Vec<Vec<u32>> {
    run_text(name, example(name), desc, inputs)
}

/// Runs `text` (kernel `name`) with both landing conventions: (early, late).
fn run_both(
    name: &str,
    text: &str,
    desc: &MachineDesc,
    inputs: &[Vec<u32>],
) -> (Vec<Vec<u32>>, Vec<Vec<u32>>) {
    let p = assemble(text, desc).unwrap_or_else(|e| panic!("{name}: {e}"));
    (
        Exec::new(desc, &p, inputs, 0).run(&p),
        Exec::new(desc, &p, inputs, 1).run(&p),
    )
}

/// [`run`] for a program given as text.
fn run_text(name: &str, text: &str, desc: &MachineDesc, inputs: &[Vec<u32>]) -> Vec<Vec<u32>> {
    let (early, late) = run_both(name, text, desc, inputs);
    assert_eq!(
        early, late,
        "{name} on {}: the result depends on whether a result is readable in its landing cycle",
        desc.name
    );
    early
}

fn machines() -> [MachineDesc; 2] {
    [MachineDesc::gold8(), MachineDesc::resolve("gold1").unwrap()]
}

fn random_f32s(rng: &mut SplitMix64, n: usize) -> Vec<u32> {
    (0..n)
        .map(|_| ((rng.below(2000) as f32 - 1000.0) / 64.0).to_bits())
        .collect()
}

fn fop(op: Op, a: u32, b: u32) -> u32 {
    op.eval(a, b, 0, MachineDesc::gold8().fp_mode()).0
}

// ---- tests ----------------------------------------------------------------------------

#[test]
fn examples_assemble_check_and_round_trip_on_gold8_and_gold1() {
    for desc in machines() {
        let layout = InstructionLayout::new(&desc);
        for (name, text) in EXAMPLES {
            let p = assemble(text, &desc).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&p.name, name);
            p.check(&desc).unwrap();
            let again = assemble(&disassemble(&p, &desc), &desc).unwrap();
            assert_eq!(again, p, "{name}: text round trip");
            for ins in &p.code {
                assert_eq!(&layout.decode(&layout.encode(ins)).unwrap(), ins);
            }
        }
    }
}

#[test]
fn madd_multiplies_and_adds() {
    let mut rng = SplitMix64::new(1);
    let (x, y, w) = (
        random_f32s(&mut rng, 64),
        random_f32s(&mut rng, 64),
        random_f32s(&mut rng, 64),
    );
    let want: Vec<u32> = (0..64)
        .map(|i| fop(Op::FAdd, fop(Op::FMul, x[i], y[i]), w[i]))
        .collect();
    for desc in machines() {
        let out = run("madd", &desc, &[x.clone(), y.clone(), w.clone()]);
        assert_eq!(out[3], want, "{}", desc.name);
    }
}

#[test]
fn saxpy_is_software_pipelined_and_exact() {
    let mut rng = SplitMix64::new(2);
    let (x, y) = (random_f32s(&mut rng, 64), random_f32s(&mut rng, 64));
    let a = 2.5f32.to_bits();
    let want: Vec<u32> = (0..64)
        .map(|i| fop(Op::FAdd, fop(Op::FMul, a, x[i]), y[i]))
        .collect();
    for desc in machines() {
        let out = run("saxpy", &desc, &[x.clone(), y.clone()]);
        assert_eq!(out[2], want, "{}", desc.name);
    }
    // One pass per 2 cycles: 8 iterations on gold8 take (8 + 4) passes of 2 instructions.
    let p = assemble(example("saxpy"), &MachineDesc::gold8()).unwrap();
    assert_eq!(p.code.len(), 4);
}

#[test]
fn prefix_sum_scans_across_clusters() {
    let mut rng = SplitMix64::new(3);
    let x: Vec<u32> = (0..64).map(|_| rng.next_u32()).collect();
    let want: Vec<u32> = x
        .iter()
        .scan(0u32, |s, &v| {
            *s = s.wrapping_add(v);
            Some(*s)
        })
        .collect();
    for desc in machines() {
        let out = run("prefix_sum", &desc, std::slice::from_ref(&x));
        assert_eq!(out[1], want, "{}", desc.name);
    }
}

#[test]
fn filter_keeps_elements_above_the_threshold_in_order() {
    let mut rng = SplitMix64::new(4);
    let x = random_f32s(&mut rng, 64);
    let want: Vec<u32> = x
        .iter()
        .copied()
        .filter(|&v| f32::from_bits(v) > 0.5)
        .collect();
    assert!(!want.is_empty() && want.len() < x.len());
    for desc in machines() {
        let out = run("filter", &desc, std::slice::from_ref(&x));
        assert_eq!(out[1], want, "{}", desc.name);
    }
}

#[test]
fn cond_input_replaces_negatives_from_the_second_stream() {
    let mut rng = SplitMix64::new(5);
    let x: Vec<u32> = (0..64)
        .map(|_| rng.below(200) as i32 - 100)
        .map(|v| v as u32)
        .collect();
    let y: Vec<u32> = (0..64).map(|i| 1000 + i).collect();
    let mut next = y.iter();
    let want: Vec<u32> = x
        .iter()
        .map(|&v| {
            if (v as i32) < 0 {
                *next.next().unwrap()
            } else {
                v
            }
        })
        .collect();
    for desc in machines() {
        let out = run("cond_input", &desc, &[x.clone(), y.clone()]);
        assert_eq!(out[2], want, "{}", desc.name);
    }
}

#[test]
fn lookup_reads_the_table_from_the_scratchpad() {
    let mut rng = SplitMix64::new(6);
    let table: Vec<u32> = (0..16).map(|_| rng.next_u32()).collect();
    let x: Vec<u32> = (0..64).map(|_| rng.below(16)).collect();
    let want: Vec<u32> = x.iter().map(|&i| table[i as usize]).collect();
    for desc in machines() {
        let c = desc.cluster.count;
        let replicated: Vec<u32> = table
            .iter()
            .flat_map(|&v| std::iter::repeat_n(v, c))
            .collect();
        let out = run("lookup", &desc, &[replicated, x.clone()]);
        assert_eq!(out[2], want, "{}", desc.name);
    }
}

/// z = x + 1.0 in a loop body of two passes (see the file).
const PLUS_ONE_TWO_PASSES: &str = include_str!("microcode/plus1_passes.uc");

#[test]
fn a_body_of_two_passes_runs_every_iteration_once_whatever_the_parity() {
    let one = 1.0f32.to_bits();
    for desc in machines() {
        let c = desc.cluster.count;
        // Odd row counts end in the middle of the body (N + 4 passes is odd).
        for rows in 1..=6 {
            let x: Vec<u32> = (0..rows * c).map(|i| (i as f32 * 0.75).to_bits()).collect();
            let want: Vec<u32> = x.iter().map(|&v| fop(Op::FAdd, v, one)).collect();
            let out = run_text(
                "plus1",
                PLUS_ONE_TWO_PASSES,
                &desc,
                std::slice::from_ref(&x),
            );
            assert_eq!(out[1], want, "{}, {rows} rows", desc.name);
        }
        // With one copy, each x is overwritten as it is read: the result then depends on
        // whether a result is readable in its landing cycle, which is why the body is
        // unrolled.
        let one_copy = PLUS_ONE_TWO_PASSES.replace(
            "pass\n    sin0 x -> add0.a[1] | add0 fadd a[1], b[0] -> stream z @4\n",
            "",
        );
        assert!(!one_copy.contains("pass"));
        let x: Vec<u32> = (0..4 * c).map(|i| (i as f32).to_bits()).collect();
        let (early, late) = run_both("plus1", &one_copy, &desc, std::slice::from_ref(&x));
        assert_ne!(early, late, "{}", desc.name);
    }
}
