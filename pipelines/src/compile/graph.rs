//! Lowering: the kernel IR becomes machine operations (one per slot use) with their
//! dependences, per region.
//!
//! * Constants and the cluster index become immediates; parameters become reads of the
//!   hidden `params` stream (one word per cluster per read, replicated by the host); casts
//!   vanish.
//! * A conditional read becomes a masked stream read and a `select` that gives the other
//!   clusters their `otherwise` value (the masked read leaves their LRF entry as it was).
//! * A loop-carried value `x` with next value `n` becomes `m = mov(n)` in the loop, whose
//!   result is `x` one iteration later, and `mov(init)` before the loop writing the same
//!   entries (`tie`). After the loop, `x` is read through a `mov` on `add0`, so `m` also
//!   writes `add0.a` when `x` is used there.
//! * Dead values are dropped.

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{ImmValue, Permutation};
use imagine_units::ops::{Op, UnitClass};

use crate::kernel::{Kernel, LoopSpec, Node, Perm, Region, Value};

/// Which input of its slot an operand is read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Input {
    /// FU input `a` or `b`.
    A,
    B,
    /// The condition-code file (select, conditional streams).
    Cc,
    SpAddr,
    SpData,
    CommData,
    CommPerm,
    SoutData,
}

/// Where an operand's value comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// An op of the same region, this iteration.
    Local(usize),
    /// A carried value: the loop op `m` of the previous iteration (or its initial value).
    Carried(usize),
    /// A value defined in an earlier region (before the loop), live from then on.
    Earlier(usize),
}

impl Source {
    pub fn op(self) -> usize {
        match self {
            Source::Local(o) | Source::Carried(o) | Source::Earlier(o) => o,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Arg {
    pub src: Source,
    pub input: Input,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Fu(Op),
    SpRead { base: u16 },
    SpWrite { base: u16 },
    Comm(Permutation),
    StreamIn { stream: u16, cond: bool },
    StreamOut { stream: u16, cond: bool },
    Imm(ImmValue),
}

impl Kind {
    pub fn defines(self) -> bool {
        !matches!(self, Kind::SpWrite { .. } | Kind::StreamOut { .. })
    }

    pub fn is_conditional_stream(self) -> bool {
        matches!(
            self,
            Kind::StreamIn { cond: true, .. } | Kind::StreamOut { cond: true, .. }
        )
    }
}

/// A place a value is written: an LRF (index into `MachineDesc::lrf_names`) or the
/// condition-code file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Loc {
    Lrf(u16),
    Cc,
}

/// Why the scheduler added a register copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CopyKind {
    /// The value's two switch destinations are taken: the copy gives it more, and is
    /// placed as soon as the value lands.
    Fanout,
    /// The value would live longer than the initiation interval: the copy carries it on,
    /// placed as late as the value allows.
    Lifetime,
}

/// The most operands an op reads: a `select`'s condition and two values.
pub const MAX_ARGS: usize = 3;

/// An op's operands, kept inside the op: the schedulers copy the graph for every
/// schedule they try, and a list of its own per op made each copy allocate for every op.
pub type Args = arrayvec::ArrayVec<Arg, MAX_ARGS>;

/// The operands `args` as an op keeps them.
pub fn operands(args: &[Arg]) -> Args {
    Args::try_from(args).expect("an op reads at most MAX_ARGS operands")
}

#[derive(Clone, Debug)]
pub struct MOp {
    pub kind: Kind,
    pub args: Args,
    pub region: Region,
    /// The IR value it computes (for listings).
    pub ir: Option<Value>,
    /// A register copy the compiler added.
    pub copy: bool,
    /// Added by the scheduler, and why.
    pub copy_kind: Option<CopyKind>,
    /// Must issue on this FU slot.
    pub fixed_slot: Option<usize>,
    /// The slot binding chose (FU, scratchpad or comm index) and whether a commutative
    /// op's operands are swapped.
    pub slot: usize,
    pub swap: bool,
    /// A copy a later binding made unnecessary.
    pub dead: bool,
    /// A constant or scratchpad read rematerialised in the loop: placed after its readers,
    /// just in time for them.
    pub just_in_time: bool,
    /// Latest issue cycle (a lifetime copy: where its reader wanted to issue, less the
    /// copy's latency).
    pub deadline: Option<i64>,
    /// Destinations required by ops of other regions (fixed before this op is scheduled).
    pub seeded: Vec<Loc>,
    /// This op initialises a carried value: it writes the same entries as loop op `tie`.
    pub tie: Option<usize>,
}

impl MOp {
    /// An op of `region` computing (or, for a copy, carrying) IR value `ir`.
    pub fn new(kind: Kind, args: Args, region: Region, ir: Option<Value>) -> MOp {
        MOp {
            kind,
            args,
            region,
            ir,
            copy: false,
            copy_kind: None,
            fixed_slot: None,
            slot: 0,
            swap: false,
            dead: false,
            just_in_time: false,
            deadline: None,
            seeded: Vec::new(),
            tie: None,
        }
    }

    /// A constant rematerialised in the loop (a scratchpad read rematerialised there has its
    /// address as an operand, and is placed after it).
    pub fn is_rematerialised_constant(&self) -> bool {
        self.just_in_time && self.args.is_empty()
    }

    /// A `mov` copying `src` (read through an adder's `a` input).
    pub fn copy_of(src: Source, region: Region, ir: Option<Value>, kind: CopyKind) -> MOp {
        let arg = Arg {
            src,
            input: Input::A,
        };
        MOp {
            copy: true,
            copy_kind: Some(kind),
            ..MOp::new(Kind::Fu(Op::Mov), operands(&[arg]), region, ir)
        }
    }

    /// Makes this `mov` copy a multiplier's `imul_lo(x, one)`, which copies `x` exactly
    /// (`one` holds the constant 1, read through the multiplier's `b` input).
    pub fn copy_through_multiplier(&mut self, one: usize) {
        self.kind = Kind::Fu(Op::IMulLo);
        self.args.push(Arg {
            src: Source::Earlier(one),
            input: Input::B,
        });
    }
}

/// An ordering constraint: `to` issues at least `latency` cycles after `from`, minus
/// `distance` initiation intervals.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    pub from: usize,
    pub to: usize,
    pub latency: i64,
    pub distance: u32,
}

/// The lowered kernel.
#[derive(Clone, Debug)]
pub struct Graph {
    pub ops: Vec<MOp>,
    /// Program streams: the kernel's, then `params` if it has parameters.
    pub params_stream: Option<u16>,
    pub main_loop: Option<LoopSpec>,
    /// Issue cycles of the loop's ops in its straight-line schedule (indexed by op; empty
    /// when there is none): the order the modulo scheduler places them in.
    pub hint: Vec<i64>,
    /// The modulo scheduler breaks ties between ops of equal priority towards the later op
    /// in program order (the earlier by default).
    pub late_ties: bool,
    /// The loop's values may outlive the initiation interval, up to
    /// [`super::schedule::reach`], each pass of the unrolled body holding them in entries of
    /// its own (modulo variable expansion); otherwise each is read within one interval.
    pub expand: bool,
    /// The loop is modulo list-scheduled (see [`super::schedule`]) instead of by Rau's
    /// iterative scheduler.
    pub list: bool,
    /// The loop is scheduled by local search (see [`super::repair`]).
    pub repair: bool,
    /// Issue cycles of the loop's ops when the modulo scheduler last asked for a lifetime
    /// copy at this interval (indexed by op; empty at first): the next attempt places them
    /// in that order, and at those cycles where it can.
    pub warm: Vec<Option<i64>>,
}

impl Graph {
    // (Inlined: the schedulers ask it for every op at every cycle they try.)
    #[inline]
    pub fn latency(&self, op: usize, desc: &MachineDesc) -> i64 {
        let l = &desc.latency;
        i64::from(match self.ops[op].kind {
            Kind::Fu(o) => o.latency(l),
            Kind::SpRead { .. } => l.scratchpad_read,
            Kind::SpWrite { .. } => l.scratchpad_write,
            Kind::Comm(_) => l.comm,
            Kind::StreamIn { .. } => l.stream,
            Kind::StreamOut { .. } => 1,
            Kind::Imm(_) => 1,
        })
    }

    pub fn in_region(&self, r: Region) -> Vec<usize> {
        (0..self.ops.len())
            .filter(|&i| self.ops[i].region == r && !self.ops[i].dead)
            .collect()
    }

    /// Inserts a `mov` copy of operand `arg` of `user`, to issue by `deadline`: it carries
    /// a value that would otherwise live longer than the loop's initiation interval.
    pub fn insert_lifetime_copy(&mut self, user: usize, arg: usize, deadline: i64) -> usize {
        let a = self.ops[user].args[arg];
        let copy = self.ops.len();
        let mut mov = MOp::copy_of(
            a.src,
            self.ops[user].region,
            self.ops[user].ir,
            CopyKind::Lifetime,
        );
        mov.deadline = Some(deadline);
        self.ops.push(mov);
        self.ops[user].args[arg].src = Source::Local(copy);
        copy
    }

    /// The constant 1 made before the loop for copies through a multiplier (`imul_lo(x, 1)`
    /// copies `x` exactly), made on first use.
    pub fn copy_multiplicand(&mut self) -> usize {
        let one = Kind::Imm(ImmValue::Const(1));
        if let Some(o) = (0..self.ops.len()).find(|&o| {
            let op = &self.ops[o];
            op.region == Region::Pre && op.kind == one && op.ir.is_none() && op.args.is_empty()
        }) {
            self.ops[o].dead = false;
            return o;
        }
        self.ops.push(MOp::new(one, Args::new(), Region::Pre, None));
        self.ops.len() - 1
    }

    /// Gives loop readers of constants their own immediates in the loop, issued just before
    /// they are read, instead of LRF entries held for the whole loop: the least-read
    /// constants first, at most `budget` immediates.
    pub fn rematerialize_constants(&mut self, budget: usize) {
        let mut uses: std::collections::BTreeMap<usize, Vec<(usize, usize)>> = Default::default();
        for u in self.in_region(Region::Loop) {
            for (i, a) in self.ops[u].args.iter().enumerate() {
                if let Source::Earlier(p) = a.src
                    && matches!(self.ops[p].kind, Kind::Imm(_))
                    && self.ops[p].region == Region::Pre
                {
                    uses.entry(p).or_default().push((u, i));
                }
            }
        }
        let mut by_count: Vec<(usize, Vec<(usize, usize)>)> = uses.into_iter().collect();
        by_count.sort_by_key(|(p, r)| (r.len(), *p));
        let mut made = 0;
        for (p, readers) in by_count {
            if made + readers.len() > budget {
                break;
            }
            made += readers.len();
            for (u, i) in readers {
                let mut imm = self.ops[p].clone();
                imm.region = Region::Loop;
                imm.just_in_time = true;
                imm.seeded.clear();
                self.ops.push(imm);
                self.ops[u].args[i].src = Source::Local(self.ops.len() - 1);
            }
        }
    }

    /// Gives each loop reader of a scratchpad read that has several its own read, issued
    /// just before it, at most `budget` more reads: the value then waits in no LRF, only
    /// its address does (in the scratchpad's, which little else uses). Only when the loop
    /// writes no scratchpad word, so every read of an address gives the same word.
    pub fn rematerialize_scratchpad_reads(&mut self, budget: usize) {
        let ops = self.in_region(Region::Loop);
        if ops
            .iter()
            .any(|&o| matches!(self.ops[o].kind, Kind::SpWrite { .. }))
        {
            return;
        }
        let mut made = 0;
        for &p in &ops {
            if !matches!(self.ops[p].kind, Kind::SpRead { .. }) {
                continue;
            }
            let mut readers: Vec<usize> = ops
                .iter()
                .copied()
                .filter(|&u| self.ops[u].args.iter().any(|a| a.src == Source::Local(p)))
                .collect();
            if readers.len() < 2 || made + readers.len() - 1 > budget {
                continue;
            }
            made += readers.len() - 1;
            self.ops[p].just_in_time = true;
            readers.remove(0);
            for u in readers {
                let read = self.ops[p].clone();
                self.ops.push(read);
                let r = self.ops.len() - 1;
                for a in &mut self.ops[u].args {
                    if a.src == Source::Local(p) {
                        a.src = Source::Local(r);
                    }
                }
            }
        }
    }

    /// The dependences among the ops of region `r` (for the loop, with loop-carried ones).
    pub fn edges(&self, r: Region, desc: &MachineDesc) -> Vec<Edge> {
        let ops = self.in_region(r);
        let mut edges = Vec::new();
        for &u in &ops {
            for a in &self.ops[u].args {
                match a.src {
                    Source::Local(p) => edges.push(Edge {
                        from: p,
                        to: u,
                        latency: self.latency(p, desc) + 1,
                        distance: 0,
                    }),
                    Source::Carried(m) if r == Region::Loop => {
                        // Read the previous iteration's value, before `m` overwrites it.
                        let lm = self.latency(m, desc);
                        edges.push(Edge {
                            from: m,
                            to: u,
                            latency: lm + 1,
                            distance: 1,
                        });
                        // (Not when `u` is `m` itself, a value carried unchanged: an op
                        // reads its operands before its result lands, and a distance-0
                        // self-edge would be a cycle no schedule can order.)
                        if u != m {
                            edges.push(Edge {
                                from: u,
                                to: m,
                                latency: -lm,
                                distance: 0,
                            });
                        }
                    }
                    _ => {}
                }
            }
        }
        // Program order among accesses to one stream, and to the scratchpad when the
        // kernel writes it.
        let sp_writes = ops
            .iter()
            .any(|&o| matches!(self.ops[o].kind, Kind::SpWrite { .. }));
        let key = |o: usize| match self.ops[o].kind {
            Kind::StreamIn { stream, .. } | Kind::StreamOut { stream, .. } => Some((0, stream)),
            Kind::SpRead { .. } | Kind::SpWrite { .. } if sp_writes => Some((1, 0)),
            _ => None,
        };
        let is_write = |o: usize| matches!(self.ops[o].kind, Kind::SpWrite { .. });
        let mut order: Vec<usize> = ops.iter().copied().filter(|&o| key(o).is_some()).collect();
        order.sort_by_key(|&o| self.ops[o].ir.map_or(u32::MAX, |v| v.0));
        let sp_write_latency = i64::from(desc.latency.scratchpad_write);
        for (i, &x) in order.iter().enumerate() {
            for &y in &order[i + 1..] {
                if key(x) != key(y) {
                    continue;
                }
                let memory = key(x) == Some((1, 0));
                if memory && !is_write(x) && !is_write(y) {
                    continue;
                }
                let latency = if memory && is_write(x) {
                    sp_write_latency
                } else {
                    1
                };
                edges.push(Edge {
                    from: x,
                    to: y,
                    latency,
                    distance: 0,
                });
                if r == Region::Loop {
                    // The next iteration's access comes after this one's.
                    let back = if memory && is_write(y) {
                        sp_write_latency
                    } else {
                        1
                    };
                    edges.push(Edge {
                        from: y,
                        to: x,
                        latency: back,
                        distance: 1,
                    });
                }
            }
        }
        // The words of a record go out together: an output word waits for the data of the
        // words after it (of the next word only, in long records, whose data would not all
        // fit `sout.data` at once), so one iteration's writes span as little as possible.
        for (i, &x) in order.iter().enumerate() {
            if !matches!(self.ops[x].kind, Kind::StreamOut { .. }) {
                continue;
            }
            let later: Vec<usize> = order[i + 1..]
                .iter()
                .copied()
                .filter(|&y| key(y) == key(x))
                .collect();
            let record = order.iter().filter(|&&y| key(y) == key(x)).count();
            let waits = if record <= 8 {
                &later[..]
            } else {
                &later[..later.len().min(1)]
            };
            for &y in waits {
                for a in &self.ops[y].args {
                    if let Source::Local(p) = a.src {
                        edges.push(Edge {
                            from: p,
                            to: x,
                            latency: self.latency(p, desc) + 1,
                            distance: 0,
                        });
                    }
                }
            }
        }
        if r == Region::Loop {
            // A lone access still follows its own previous iteration.
            for &x in &order {
                let latency = if is_write(x) { sp_write_latency } else { 1 };
                edges.push(Edge {
                    from: x,
                    to: x,
                    latency,
                    distance: 1,
                });
            }
        }
        edges
    }
}

/// Lowers `kernel`; `add0_a` is the LRF index of `add0.a`, where carried values read after
/// the loop must be.
pub fn lower(kernel: &Kernel, add0_a: u16) -> Graph {
    let n = kernel.nodes.len();
    // Which IR values are needed: writes and what they read, transitively. A carried
    // value's next value comes later in program order, so the backward pass repeats until
    // nothing changes.
    let mut live = vec![false; n];
    let mut changed = true;
    while changed {
        changed = false;
        for i in (0..n).rev() {
            let d = &kernel.nodes[i];
            if matches!(
                d.node,
                Node::Write { .. } | Node::SpWrite { .. } | Node::Param(_) | Node::Read { .. }
            ) {
                // Parameters are read in order from the params stream and reads advance
                // their streams: all are kept.
                live[i] = true;
            }
            if live[i] {
                let next = match d.node {
                    Node::Carried { next: Some(nx), .. } => Some(nx),
                    _ => None,
                };
                for a in d.node.operands().into_iter().chain(next) {
                    changed |= !live[a.index()];
                    live[a.index()] = true;
                }
            }
        }
    }
    let params_stream = (!kernel.params.is_empty()).then_some(kernel.streams.len() as u16);
    let mut l = Lowerer {
        kernel,
        add0_a,
        g: Graph {
            ops: Vec::new(),
            params_stream,
            main_loop: kernel.main_loop,
            hint: Vec::new(),
            late_ties: false,
            expand: false,
            list: false,
            repair: false,
            warm: Vec::new(),
        },
        op_of: vec![None; n],
        carried_mov: vec![None; n],
        final_mov: vec![None; n],
    };
    let mut pending_next: Vec<(usize, Value)> = Vec::new();
    for (i, &needed) in live.iter().enumerate() {
        if !needed {
            continue;
        }
        let d = &kernel.nodes[i];
        let region = d.region;
        let v = Value(i as u32);
        let op = match &d.node {
            Node::Cast { .. } => continue,
            Node::Const(x) => l.push(Kind::Imm(ImmValue::Const(*x)), Args::new(), region, v),
            Node::ClusterId => l.push(Kind::Imm(ImmValue::ClusterId), Args::new(), region, v),
            Node::Param(_) => {
                let stream = params_stream.expect("has params");
                l.push(
                    Kind::StreamIn {
                        stream,
                        cond: false,
                    },
                    Args::new(),
                    region,
                    v,
                )
            }
            Node::Op { op, args } => {
                let inputs: &[Input] = if *op == Op::Select {
                    &[Input::Cc, Input::A, Input::B]
                } else {
                    &[Input::A, Input::B]
                };
                let a = args
                    .iter()
                    .zip(inputs)
                    .map(|(&x, &inp)| l.arg(x, inp, region))
                    .collect();
                l.push(Kind::Fu(*op), a, region, v)
            }
            Node::Read { stream, cond: None } => {
                let kind = Kind::StreamIn {
                    stream: stream.0,
                    cond: false,
                };
                l.push(kind, Args::new(), region, v)
            }
            Node::Read {
                stream,
                cond: Some((c, otherwise)),
            } => {
                let ca = l.arg(*c, Input::Cc, region);
                let kind = Kind::StreamIn {
                    stream: stream.0,
                    cond: true,
                };
                let read = l.push(kind, operands(&[ca]), region, v);
                let oa = l.arg(*otherwise, Input::B, region);
                let got = Arg {
                    src: Source::Local(read),
                    input: Input::A,
                };
                l.push(Kind::Fu(Op::Select), operands(&[ca, got, oa]), region, v)
            }
            Node::Write {
                stream,
                value,
                cond,
            } => {
                let mut a = operands(&[l.arg(*value, Input::SoutData, region)]);
                if let Some(c) = cond {
                    a.push(l.arg(*c, Input::Cc, region));
                }
                let kind = Kind::StreamOut {
                    stream: stream.0,
                    cond: cond.is_some(),
                };
                l.push(kind, a, region, v)
            }
            Node::SpRead { base, offset } => {
                let a = offset
                    .iter()
                    .map(|&o| l.arg(o, Input::SpAddr, region))
                    .collect();
                l.push(Kind::SpRead { base: *base }, a, region, v)
            }
            Node::SpWrite { base, offset, data } => {
                let mut a: Args = offset
                    .iter()
                    .map(|&o| l.arg(o, Input::SpAddr, region))
                    .collect();
                a.push(l.arg(*data, Input::SpData, region));
                l.push(Kind::SpWrite { base: *base }, a, region, v)
            }
            Node::Comm { value, perm } => {
                let mut a = operands(&[l.arg(*value, Input::CommData, region)]);
                let p = match *perm {
                    Perm::Rotate(k) => Permutation::Rotate(k),
                    Perm::Xor(k) => Permutation::Xor(k),
                    Perm::Broadcast(k) => Permutation::Broadcast(k),
                    Perm::PerCluster(p) => {
                        a.push(l.arg(p, Input::CommPerm, region));
                        Permutation::PerCluster(0)
                    }
                };
                l.push(Kind::Comm(p), a, region, v)
            }
            Node::Carried { init, next } => {
                // The loop mov (its operand, the next value, is set once the body is
                // lowered) and the mov before the loop that writes the initial value into
                // the same entries.
                let m = l.push(Kind::Fu(Op::Mov), Args::new(), Region::Loop, v);
                l.g.ops[m].copy = true;
                l.carried_mov[i] = Some(m);
                pending_next.push((m, next.expect("verified")));
                let init_arg = l.arg(*init, Input::A, Region::Pre);
                let init_mov = l.push(Kind::Fu(Op::Mov), operands(&[init_arg]), Region::Pre, v);
                l.g.ops[init_mov].copy = true;
                l.g.ops[init_mov].tie = Some(m);
                m
            }
        };
        l.op_of[i] = Some(op);
    }
    for (m, next) in pending_next {
        let a = l.arg(next, Input::A, Region::Loop);
        l.g.ops[m].args = operands(&[a]);
    }
    l.g
}

struct Lowerer<'k> {
    kernel: &'k Kernel,
    add0_a: u16,
    g: Graph,
    /// IR value → the op computing it.
    op_of: Vec<Option<usize>>,
    /// Carried IR value → its loop mov.
    carried_mov: Vec<Option<usize>>,
    /// Carried IR value → the mov reading its final value after the loop.
    final_mov: Vec<Option<usize>>,
}

impl Lowerer<'_> {
    fn push(&mut self, kind: Kind, args: Args, region: Region, ir: Value) -> usize {
        self.g.ops.push(MOp::new(kind, args, region, Some(ir)));
        self.g.ops.len() - 1
    }

    /// How an op of `region` reads IR value `x` through `input`.
    fn arg(&mut self, x: Value, input: Input, region: Region) -> Arg {
        let mut s = x.index();
        while let Node::Cast { value } = self.kernel.nodes[s].node {
            s = value.index();
        }
        let def = &self.kernel.nodes[s];
        let carried = matches!(def.node, Node::Carried { .. });
        let src = match (def.region, region) {
            (Region::Loop, Region::Loop) if carried => {
                Source::Carried(self.carried_mov[s].expect("carried movs come first"))
            }
            (Region::Loop, Region::Post) => Source::Local(self.final_mov(s)),
            (a, b) if a == b => Source::Local(self.op_of[s].expect("defined before use")),
            _ => Source::Earlier(self.op_of[s].expect("defined before use")),
        };
        Arg { src, input }
    }

    /// The mov on `add0` that reads carried value `s` after the loop.
    fn final_mov(&mut self, s: usize) -> usize {
        if let Some(f) = self.final_mov[s] {
            return f;
        }
        let m = self.carried_mov[s].expect("carried");
        let add0_a = Loc::Lrf(self.add0_a);
        if !self.g.ops[m].seeded.contains(&add0_a) {
            self.g.ops[m].seeded.push(add0_a);
        }
        let arg = Arg {
            src: Source::Earlier(m),
            input: Input::A,
        };
        let f = self.push(
            Kind::Fu(Op::Mov),
            operands(&[arg]),
            Region::Post,
            Value(s as u32),
        );
        self.g.ops[f].copy = true;
        self.g.ops[f].fixed_slot = Some(0);
        self.final_mov[s] = Some(f);
        f
    }
}

/// The unit class an op needs, for FU ops.
pub fn unit_class(k: Kind) -> Option<UnitClass> {
    match k {
        Kind::Fu(op) => Some(op.unit()),
        _ => None,
    }
}

/// Ops whose two operands may be swapped.
pub fn commutative(op: Op) -> bool {
    use Op::*;
    matches!(
        op,
        FAdd | FMul
            | FMin
            | FMax
            | FEq
            | IAdd
            | IMulLo
            | IMulHiS
            | IMulHiU
            | And
            | Or
            | Xor
            | IEq
            | INe
            | IMinS
            | IMaxS
            | IMinU
            | IMaxU
            | Add16x2
            | AddSat16x2S
            | AddSat16x2U
            | Eq16x2
            | Min16x2S
            | Max16x2S
            | Min16x2U
            | Max16x2U
            | Add8x4
            | AddSat8x4S
            | AddSat8x4U
            | Eq8x4
            | Min8x4S
            | Max8x4S
            | Min8x4U
            | Max8x4U
            | Mul16x2Lo
            | Mul16x2HiS
            | Mul16x2HiU
    )
}
