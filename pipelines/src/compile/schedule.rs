//! Scheduling with unit binding: the main loop by iterative modulo scheduling (Rau,
//! "Iterative modulo scheduling", MICRO 1994: a modulo reservation table, operations placed
//! in height order within `[Estart, Estart + II)`, an op that finds no free cycle forced in
//! and the ops in its way evicted and scheduled again, II raised until the body fits) or,
//! where that fails, by modulo list scheduling (ops placed as they become ready, never
//! evicted); straight-line code by list scheduling on the same table with an unbounded
//! modulus.
//!
//! Placing an op also binds it to a slot, and so decides which LRFs its operands are read
//! from — the distributed register files make register allocation part of scheduling, as in
//! Imagine's communication scheduling (Mattson et al., MICRO 2000). An operand must then be
//! written to that LRF by its producer, which has one switch result port with two
//! destinations and needs the LRF's single write port in the cycle its result lands. In a
//! loop, a value must be read within one initiation interval of being written (the entry is
//! rewritten by the next iteration; there is no rotating register file) — or, when the
//! body is unrolled into passes that each rename it ([`reach`]), within a few intervals.
//! When an operand cannot be delivered (its producer's destinations are taken, or it would
//! live too long), the scheduler asks for a `mov` copy between producer and consumer and
//! starts over — for a big loop, from the places of the attempt that asked, so that the
//! copies add up in one schedule instead of each perturbing a new one.
//!
//! A loop schedule whose values overflow an LRF is then relaxed ([`relax`]): its ops move to
//! the free cycles where their values wait least.

use std::sync::atomic::{AtomicBool, Ordering};

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::check::Shape;
use imagine_units::ops::{Op, UnitClass};

use super::adjacency::Adjacency;
use super::circle;
use super::graph::{Arg, CopyKind, Edge, Graph, Input, Kind, Loc, Source};
use crate::kernel::Region;

/// The slots and LRFs of a cluster, as the scheduler sees them.
pub struct Slots {
    pub shape: Shape,
    /// LRF of input `a`, `b` of each FU slot.
    pub fu_inputs: Vec<[u16; 2]>,
    /// `addr`, `data` of each scratchpad.
    pub sp_inputs: Vec<[u16; 2]>,
    /// `data`, `perm` of each comm unit.
    pub comm_inputs: Vec<[u16; 2]>,
    pub sout_input: u16,
    pub stream_words: usize,
    pub conditional_words: usize,
    pub dsq_interval: usize,
    /// How much later a copy through a multiplier lands than a `mov`.
    pub mul_copy_extra: i64,
}

impl Slots {
    pub fn new(desc: &MachineDesc) -> Slots {
        let shape = Shape::new(desc);
        let lrf = |slot: &str, input: &str| shape.lrf(slot, input).0 as u16;
        let fu_inputs = (0..shape.fu_count())
            .map(|i| {
                let n = shape.fu_name(i);
                [lrf(&n, "a"), lrf(&n, "b")]
            })
            .collect();
        let sp_inputs = (0..shape.scratchpads)
            .map(|i| {
                [
                    lrf(&format!("sp{i}"), "addr"),
                    lrf(&format!("sp{i}"), "data"),
                ]
            })
            .collect();
        let comm_inputs = (0..shape.comm_units)
            .map(|i| {
                [
                    lrf(&format!("comm{i}"), "data"),
                    lrf(&format!("comm{i}"), "perm"),
                ]
            })
            .collect();
        let sout_input = lrf("sout", "data");
        Slots {
            fu_inputs,
            sp_inputs,
            comm_inputs,
            sout_input,
            stream_words: desc.srf.cluster_words_per_cycle,
            conditional_words: desc.srf.conditional_words_per_cycle,
            dsq_interval: desc.latency.divsqrt_issue_interval.max(1) as usize,
            mul_copy_extra: i64::from(Op::IMulLo.latency(&desc.latency))
                - i64::from(Op::Mov.latency(&desc.latency)),
            shape,
        }
    }

    pub fn lrfs(&self) -> usize {
        self.shape.lrf_names.len()
    }

    /// Cycles an op holds its unit's issue slot: the divide/sqrt unit's issue interval,
    /// one for every other unit.
    fn issue_cycles(&self, op: Op) -> i64 {
        if op.unit() == UnitClass::DivSqrt {
            self.dsq_interval as i64
        } else {
            1
        }
    }

    /// FU slots of a unit class.
    pub fn fu_slots(&self, class: UnitClass) -> std::ops::Range<usize> {
        let s = &self.shape;
        match class {
            UnitClass::Adder => 0..s.adders,
            UnitClass::Multiplier => s.adders..s.adders + s.multipliers,
            UnitClass::DivSqrt => s.adders + s.multipliers..s.fu_count(),
        }
    }

    /// Where operand `a` of an op bound to `slot` (operands swapped or not) is read.
    pub fn operand_loc(&self, kind: Kind, slot: usize, swap: bool, a: &Arg) -> Loc {
        self.loc(kind, slot, input_of(a, swap))
    }

    /// Where operand `input` of an op on `slot` is read.
    fn loc(&self, kind: Kind, slot: usize, input: Input) -> Loc {
        let l = match (kind, input) {
            (_, Input::Cc) => return Loc::Cc,
            (Kind::Fu(_), Input::A) => self.fu_inputs[slot][0],
            (Kind::Fu(_), Input::B) => self.fu_inputs[slot][1],
            (_, Input::SpAddr) => self.sp_inputs[slot][0],
            (_, Input::SpData) => self.sp_inputs[slot][1],
            (_, Input::CommData) => self.comm_inputs[slot][0],
            (_, Input::CommPerm) => self.comm_inputs[slot][1],
            (_, Input::SoutData) => self.sout_input,
            _ => unreachable!("operand {input:?} of {kind:?}"),
        };
        Loc::Lrf(l)
    }
}

/// Where and when an op issues.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    pub time: i64,
    /// FU, scratchpad or comm slot (0 for stream and immediate ops).
    pub slot: usize,
    /// The two operands of a commutative op are read swapped.
    pub swap: bool,
}

/// The schedule of every region so far.
#[derive(Clone, Debug, Default)]
pub struct Schedule {
    pub place: Vec<Option<Placement>>,
    /// Where each op's result is written.
    pub dests: Vec<Vec<Loc>>,
    /// Locations ops of later regions read an earlier region's value from, and the
    /// region reading it.
    pub required: Vec<Vec<(Loc, Region)>>,
}

impl Schedule {
    pub fn new(ops: usize) -> Schedule {
        Schedule {
            place: vec![None; ops],
            dests: vec![Vec::new(); ops],
            required: vec![Vec::new(); ops],
        }
    }

    pub fn grow(&mut self, ops: usize) {
        self.place.resize(ops, None);
        self.dests.resize(ops, Vec::new());
        self.required.resize(ops, Vec::new());
    }
}

/// Why a region did not schedule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Failure {
    /// Op `op` found no cycle and slot in its window.
    NoSlot { op: usize, why: String },
    /// Too many copies were needed.
    Copies { op: usize },
}

const FREE: u32 = u32::MAX;

/// The reservation table: a modulo table of `ii` rows for a loop, or for straight-line code
/// a row per cycle, grown as ops are placed (see [`Table::row`]).
struct Table {
    /// The rows of a modulo table, round its interval; `None` for straight-line code.
    circle: Option<circle::Circle>,
    fu: Vec<u32>,
    /// Each FU has one result port: ops of different latencies must not land together.
    fu_result: Vec<u32>,
    sp: Vec<u32>,
    comm: Vec<u32>,
    sout: Vec<u32>,
    imm: Vec<u32>,
    stream_words: Vec<u8>,
    conditional: Vec<u8>,
    /// LRF write ports: the op whose result lands.
    ports: Vec<u32>,
    nfu: usize,
    nsp: usize,
    ncomm: usize,
    nlrf: usize,
}

impl Table {
    /// A modulo table of `ii` rows, or with `None` a straight-line one.
    fn new(ii: Option<i64>, s: &Slots) -> Table {
        let (nfu, nsp, ncomm, nlrf) = (
            s.shape.fu_count(),
            s.shape.scratchpads,
            s.shape.comm_units,
            s.lrfs(),
        );
        let mut table = Table {
            circle: ii.map(circle::Circle::new),
            fu: Vec::new(),
            fu_result: Vec::new(),
            sp: Vec::new(),
            comm: Vec::new(),
            sout: Vec::new(),
            imm: Vec::new(),
            stream_words: Vec::new(),
            conditional: Vec::new(),
            ports: Vec::new(),
            nfu,
            nsp,
            ncomm,
            nlrf,
        };
        table.grow(ii.map_or(LINE_ROWS, |ii| ii as usize));
        table
    }

    /// Rows held (a straight-line table grows).
    fn rows(&self) -> usize {
        self.sout.len()
    }

    fn grow(&mut self, rows: usize) {
        self.fu.resize(rows * self.nfu, FREE);
        self.fu_result.resize(rows * self.nfu, FREE);
        self.sp.resize(rows * self.nsp, FREE);
        self.comm.resize(rows * self.ncomm, FREE);
        self.sout.resize(rows, FREE);
        self.imm.resize(rows, FREE);
        self.stream_words.resize(rows, 0);
        self.conditional.resize(rows, 0);
        self.ports.resize(rows * self.nlrf, FREE);
    }

    /// The row of cycle `t`: modulo the interval, or in straight-line code the cycles from
    /// 0 up and those before 0 (a constant placed just in time may go there) interleaved,
    /// so that a straight-line table never wraps and holds only the rows its ops reach.
    fn row(&self, t: i64) -> usize {
        match &self.circle {
            Some(c) => c.row(t),
            None if t >= 0 => 2 * t as usize,
            None => (-2 * t - 1) as usize,
        }
    }

    /// Makes sure a straight-line table has the rows of cycles `from..=to`.
    fn cover(&mut self, from: i64, to: i64) {
        if self.circle.is_some() {
            return;
        }
        let needed = self.row(from).max(self.row(to)) + 1;
        if needed > self.rows() {
            self.grow(needed.max(2 * self.rows()));
        }
    }

    /// The rows an op that holds its unit for `cycles` issue cycles holds.
    fn issue_rows(&self, cycles: i64) -> i64 {
        self.circle.map_or(cycles, |c| cycles.min(c.ii()))
    }

    fn port(&self, lrf: u16, t: i64) -> u32 {
        self.ports[self.row(t) * self.nlrf + lrf as usize]
    }
}

/// Rows a straight-line table starts with (it grows as needed).
const LINE_ROWS: usize = 512;

/// Schedules the ops of `region` (bound to their slots by [`super::bind`]). `ii` is the
/// loop's initiation interval (`None`: straight line). Copies the scheduler needs are added
/// to `g`, which is then bound again.
pub fn schedule_region(
    g: &mut Graph,
    sched: &mut Schedule,
    region: Region,
    ii: Option<i64>,
    slots: &Slots,
    desc: &MachineDesc,
) -> Result<(), Failure> {
    // (Only a loop asks for copies; one that needs too many is tried at the next interval.
    // With the body unrolled, a value that outlives even that has drifted with the
    // schedule, which copies seldom mend.)
    let copies = if g.expand {
        EXPANDED_LOOP_COPIES
    } else {
        MAX_LOOP_COPIES
    };
    for _ in 0..copies {
        sched.grow(g.ops.len());
        super::bind::bind(g, sched, region, ii, slots);
        sched.grow(g.ops.len());
        let attempted = match ii {
            Some(ii) if g.repair => attempt_repair(g, sched, region, ii, slots, desc),
            Some(ii) if g.list => attempt_list_modulo(g, sched, region, ii, slots, desc),
            Some(ii) => attempt_modulo(g, sched, region, ii, slots, desc),
            None => attempt_line(g, sched, region, slots, desc),
        };
        match attempted {
            Ok(()) => return Ok(()),
            Err(Attempt::Copy {
                user,
                arg,
                wanted,
                places,
            }) => {
                let deadline = wanted - i64::from(desc.latency.int) - 1;
                g.insert_lifetime_copy(user, arg, deadline);
                // A big loop placed in the order of its straight-line schedule starts again
                // from where this attempt got to (small loops fare better starting afresh).
                if !g.hint.is_empty() {
                    g.warm = places;
                }
            }
            Err(Attempt::Fail(f)) => return Err(f),
        }
    }
    let op = g.in_region(region).last().copied().unwrap_or(0);
    Err(Failure::Copies { op })
}

enum Attempt {
    /// Operand `arg` of `user` lives too long: copy it, the copy issuing by `wanted`.
    /// `places` holds each op's last issue cycle in this attempt.
    Copy {
        user: usize,
        arg: usize,
        wanted: i64,
        places: Vec<Option<i64>>,
    },
    Fail(Failure),
}

/// Longest latency path from each op to the end of the iteration (distance-0 edges).
fn heights(n: usize, edges: &[Edge], order: &[usize]) -> Vec<i64> {
    let mut h = vec![0i64; n];
    let succ = Adjacency::new(
        n,
        edges
            .iter()
            .filter(|e| e.distance == 0)
            .map(|e| (e.from, (e.to, e.latency))),
    );
    for &u in order.iter().rev() {
        h[u] = succ[u]
            .iter()
            .map(|&(s, l)| l + h[s])
            .max()
            .unwrap_or(0)
            .max(0);
    }
    h
}

/// A topological order of the distance-0 edges.
fn topo(n: usize, ops: &[usize], edges: &[Edge]) -> Vec<usize> {
    let mut indeg = vec![0usize; n];
    let distance_0 = || edges.iter().filter(|e| e.distance == 0);
    for e in distance_0() {
        indeg[e.to] += 1;
    }
    let succ = Adjacency::new(n, distance_0().map(|e| (e.from, e.to)));
    let mut ready: Vec<usize> = ops.iter().copied().filter(|&o| indeg[o] == 0).collect();
    ready.reverse();
    let mut order = Vec::with_capacity(ops.len());
    while let Some(u) = ready.pop() {
        order.push(u);
        for &s in &succ[u] {
            indeg[s] -= 1;
            if indeg[s] == 0 {
                ready.push(s);
            }
        }
    }
    order
}

/// A region's ops and dependences, as both schedulers start from them.
struct Dag {
    ops: Vec<usize>,
    /// A topological order of the distance-0 edges.
    order: Vec<usize>,
    height: Vec<i64>,
    preds: Adjacency<Edge>,
    succs: Adjacency<Edge>,
}

impl Dag {
    /// The ops of `region` with `edges` among them; their places in `sched` are cleared
    /// (copies a rebinding removed lose their places too).
    fn new(g: &Graph, sched: &mut Schedule, region: Region, edges: &[Edge]) -> Dag {
        let ops = g.in_region(region);
        let n = g.ops.len();
        let order = topo(n, &ops, edges);
        debug_assert_eq!(order.len(), ops.len(), "distance-0 dependences form a DAG");
        let height = heights(n, edges, &order);
        for o in 0..n {
            if g.ops[o].region == region {
                sched.place[o] = None;
            }
        }
        let preds = Adjacency::new(n, edges.iter().map(|e| (e.to, *e)));
        let succs = Adjacency::new(n, edges.iter().map(|e| (e.from, *e)));
        Dag {
            ops,
            order,
            height,
            preds,
            succs,
        }
    }
}

/// List scheduling of straight-line code (or of a loop body run one iteration at a time,
/// whose interval is its length, so dependences on earlier iterations hold by themselves).
fn attempt_line(
    g: &Graph,
    sched: &mut Schedule,
    region: Region,
    slots: &Slots,
    desc: &MachineDesc,
) -> Result<(), Attempt> {
    let n = g.ops.len();
    let mut edges = g.edges(region, desc);
    edges.retain(|e| e.distance == 0);
    let Dag {
        ops,
        order,
        height,
        preds,
        succs,
    } = Dag::new(g, sched, region, &edges);
    // How far past its earliest cycle an op is looked for a place.
    const LINE: i64 = 1 << 14;
    let mut table = Table::new(None, slots);
    // A rematerialised constant is placed after its reader, just in time for it. (A
    // rematerialised scratchpad read, which has an operand, goes in order.)
    let just_in_time = |o: usize| g.ops[o].is_rematerialised_constant();
    let mut indeg = vec![0usize; n];
    for e in &edges {
        if just_in_time(e.from) {
            indeg[e.from] += 1;
        } else {
            indeg[e.to] += 1;
        }
    }
    let priority = list_priority(g, &height);
    let mut ready: std::collections::BinaryHeap<(i64, std::cmp::Reverse<usize>)> = ops
        .iter()
        .filter(|&&o| indeg[o] == 0)
        .map(|&o| (priority[o], std::cmp::Reverse(o)))
        .collect();
    while let Some((_, std::cmp::Reverse(u))) = ready.pop() {
        let mut estart = 0;
        for e in &preds[u] {
            if let Some(p) = sched.place[e.from] {
                estart = estart.max(p.time + e.latency);
            }
        }
        let mut lstart = i64::MAX;
        for e in &succs[u] {
            if let Some(p) = sched.place[e.to] {
                lstart = lstart.min(p.time - e.latency);
            }
        }
        let last = lstart.min(estart + LINE - 1);
        let times: Box<dyn Iterator<Item = i64>> = if just_in_time(u) {
            // Backwards from just before its reader, at most `CONSTANT_LEAD` away. (It
            // may go before the first cycle: times are shifted afterwards.)
            let reader = succs[u]
                .iter()
                .filter_map(|e| sched.place[e.to].map(|p| p.time))
                .max()
                .unwrap_or(0);
            let lowest = reader - CONSTANT_LEAD - g.latency(u, desc);
            Box::new((lowest..=lstart).rev())
        } else {
            Box::new(estart..=last)
        };
        let mut busy = None;
        let mut placed = false;
        for t in times {
            match try_place(g, sched, &mut table, u, t, slots, desc) {
                Ok(()) => {
                    placed = true;
                    break;
                }
                Err(b) => busy = Some(b),
            }
        }
        if !placed {
            let why = busy.map_or_else(
                || format!("its dependences leave no cycle (earliest {estart}, latest {last})"),
                |b| b.why(slots),
            );
            return Err(Attempt::Fail(Failure::NoSlot { op: u, why }));
        }
        for e in &succs[u] {
            if !just_in_time(u) {
                indeg[e.to] -= 1;
                if indeg[e.to] == 0 {
                    ready.push((priority[e.to], std::cmp::Reverse(e.to)));
                }
            }
        }
        for e in &preds[u] {
            if just_in_time(e.from) {
                indeg[e.from] -= 1;
                if indeg[e.from] == 0 {
                    ready.push((priority[e.from], std::cmp::Reverse(e.from)));
                }
            }
        }
    }
    sink(g, sched, &mut table, &order, &succs, None, slots, desc);
    // Ops placed before the first cycle (just-in-time constants) shift the whole body.
    shift_to_cycle_zero(sched, &ops, 1);
    Ok(())
}

/// Modulo list scheduling of the loop body at interval `ii`: ops in the order they become
/// ready (every distance-0 predecessor placed), the highest first as in [`attempt_line`],
/// each at the first cycle from its Estart where the modulo reservation table has room; a
/// constant rematerialised for an op goes just before it. Nothing is ever evicted, so every
/// value is read as soon as the table allows: where Rau's scheduler lets a big body drift
/// through a nearly full table until its values outlive their LRF entries, this one keeps
/// them short-lived (the MARBLE shader's body, over a thousand ops, schedules some
/// intervals shorter this way). An operand that would outlive [`reach`] asks for a copy;
/// an op with no free cycle in its window fails the attempt.
fn attempt_list_modulo(
    g: &Graph,
    sched: &mut Schedule,
    region: Region,
    ii: i64,
    slots: &Slots,
    desc: &MachineDesc,
) -> Result<(), Attempt> {
    let n = g.ops.len();
    let edges = g.edges(region, desc);
    let dag = Dag::new(g, sched, region, &edges);
    let Dag {
        ops,
        height,
        preds,
        succs,
        ..
    } = &dag;
    let mut table = Table::new(Some(ii), slots);
    let reach = reach(g, ii, desc);
    let latency: Vec<i64> = (0..n).map(|o| g.latency(o, desc)).collect();
    let jit = |o: usize| g.ops[o].is_rematerialised_constant();
    let priority = list_priority(g, height);
    let readers = readers_of(g, ops);
    let ready = |o: usize, sched: &Schedule| {
        !jit(o)
            && sched.place[o].is_none()
            && preds[o]
                .iter()
                .all(|e| e.distance > 0 || jit(e.from) || sched.place[e.from].is_some())
    };
    let mut queue: std::collections::BinaryHeap<(i64, std::cmp::Reverse<usize>)> = ops
        .iter()
        .filter(|&&o| ready(o, sched))
        .map(|&o| (priority[o], std::cmp::Reverse(o)))
        .collect();
    let placed_at = |o: usize, sched: &Schedule| sched.place[o].map(|p| p.time);
    while let Some((_, std::cmp::Reverse(u))) = queue.pop() {
        if !ready(u, sched) {
            continue;
        }
        // (Loop-carried dependences bound the window from both sides, and so do the
        // lifetimes of values read in a later iteration.)
        let mut estart = 0;
        for e in &preds[u] {
            if let Some(t) = placed_at(e.from, sched) {
                estart = estart.max(t + e.latency - ii * i64::from(e.distance));
            }
        }
        for &r in &readers[u] {
            if let Some(t) = placed_at(r, sched) {
                estart = estart.max(t - latency[u] - reach);
            }
        }
        let mut last = estart + ii - 1;
        for e in &succs[u] {
            if let Some(t) = placed_at(e.to, sched) {
                last = last.min(t - e.latency + ii * i64::from(e.distance));
            }
        }
        // Each operand must still be in its entry.
        let lifetime = shortest_lifetime(g, sched, u, &latency, reach).filter(|l| l.1 < last);
        if let Some((_, limit)) = lifetime {
            last = limit;
        }
        let late = g.ops[u].copy_kind == Some(CopyKind::Lifetime);
        let times: &mut dyn Iterator<Item = i64> = if late {
            &mut late_first(g, u, estart, last)
        } else {
            &mut (estart..=last)
        };
        let dsq_align = divider_alignment(g, u, ii, slots);
        let mut busy = None;
        let mut placed = false;
        for t in times {
            if dsq_align.is_some_and(|k| t.rem_euclid(ii) % k != 0) {
                continue;
            }
            if let Err(b) = try_place(g, sched, &mut table, u, t, slots, desc) {
                busy = Some(b);
                continue;
            }
            if place_constants(g, sched, &mut table, &preds[u], t, ii, slots, desc) {
                placed = true;
                break;
            }
            unplace(g, sched, &mut table, u, slots, desc);
            busy = Some(Busy::ConstantCycle);
        }
        if !placed {
            if let Some((arg, _)) = lifetime.filter(|_| !late) {
                return Err(Attempt::Copy {
                    user: u,
                    arg,
                    wanted: estart,
                    places: sched.place.iter().map(|p| p.map(|p| p.time)).collect(),
                });
            }
            let why = busy.map_or_else(
                || format!("its dependences leave no cycle (earliest {estart}, latest {last})"),
                |b| b.why(slots),
            );
            return Err(Attempt::Fail(Failure::NoSlot { op: u, why }));
        }
        for e in &succs[u] {
            if e.distance == 0 && ready(e.to, sched) {
                queue.push((priority[e.to], std::cmp::Reverse(e.to)));
            }
        }
    }
    if let Some(&u) = ops.iter().find(|&&o| sched.place[o].is_none()) {
        return Err(Attempt::Fail(Failure::NoSlot {
            op: u,
            why: "it was never placed (internal error)".into(),
        }));
    }
    finish_loop(g, sched, table, &dag, &readers, ii, reach, slots, desc);
    Ok(())
}

/// Schedules the loop at interval `ii` by local search (see [`super::repair`]), which also
/// binds every op to its slot; the schedule is then checked against the reservation table
/// and the dependences as the other schedulers build them.
fn attempt_repair(
    g: &mut Graph,
    sched: &mut Schedule,
    region: Region,
    ii: i64,
    slots: &Slots,
    desc: &MachineDesc,
) -> Result<(), Attempt> {
    let edges = g.edges(region, desc);
    let dag = Dag::new(g, sched, region, &edges);
    let reach = reach(g, ii, desc);
    let priority = list_priority(g, &dag.height);
    // The search is a gamble: a run that ends with something broken is tried again from
    // other random choices, a few times. The runs go at once, on threads of their own, and
    // the first seed's success wins as if they had gone in turn (a run no longer wanted
    // stops early).
    let search = |seed: u64, abandoned: &AtomicBool| {
        super::repair::schedule(
            g, &dag.ops, &edges, &priority, ii, reach, slots, desc, seed, abandoned,
        )
    };
    let abandoned = AtomicBool::new(false);
    let found = std::thread::scope(|scope| {
        let later: Vec<_> = (1..REPAIR_SEEDS)
            .map(|seed| {
                let (search, abandoned) = (&search, &abandoned);
                scope.spawn(move || search(seed, abandoned))
            })
            .collect();
        let mut found = search(0, &abandoned);
        for run in later {
            if found.is_some() {
                abandoned.store(true, Ordering::Relaxed);
            }
            let places = run.join().expect("a local search panicked");
            found = found.or(places);
        }
        found
    });
    let Some(places) = found else {
        return Err(Attempt::Fail(Failure::NoSlot {
            op: dag.ops.first().copied().unwrap_or(0),
            why: "the local search left it in conflict".into(),
        }));
    };
    for (&u, &(_, slot, swap)) in dag.ops.iter().zip(&places) {
        g.ops[u].slot = slot;
        g.ops[u].swap = swap;
    }
    super::bind::destinations(g, sched, region, slots);
    let mut table = Table::new(Some(ii), slots);
    for (&u, &(t, _, _)) in dag.ops.iter().zip(&places) {
        try_place(g, sched, &mut table, u, t, slots, desc).map_err(|b| {
            Attempt::Fail(Failure::NoSlot {
                op: u,
                why: b.why(slots),
            })
        })?;
    }
    let latency = |o: usize| g.latency(o, desc);
    let at = |o: usize| sched.place[o].map_or(0, |p| p.time);
    for e in &edges {
        if at(e.from) + e.latency - ii * i64::from(e.distance) > at(e.to) {
            return Err(Attempt::Fail(Failure::NoSlot {
                op: e.to,
                why: "the local search broke a dependence (internal error)".into(),
            }));
        }
    }
    for &u in &dag.ops {
        for a in &g.ops[u].args {
            if let Source::Local(p) = a.src
                && at(u) > at(p) + latency(p) + reach
            {
                return Err(Attempt::Fail(Failure::NoSlot {
                    op: u,
                    why: "the local search let a value outlive its entry (internal error)".into(),
                }));
            }
        }
    }
    // (Sinking and relaxing, as the other schedulers finish, would undo the search's
    // balance of the LRFs.)
    shift_to_cycle_zero(sched, &dag.ops, ii);
    Ok(())
}

/// Runs of the local search per interval (see [`attempt_repair`]).
const REPAIR_SEEDS: u64 = 2;

/// How many cycles before its reader a list scheduler looks for a slot for a
/// rematerialised constant: a short wait, so the constant holds its LRF entry briefly.
const CONSTANT_LEAD: i64 = 64;

/// Places the rematerialised constants among `preds` (of an op placed at `t`) just before
/// it, at most `CONSTANT_LEAD` (or the interval) away; false (with any it placed taken out again) if
/// one finds no cycle.
#[allow(clippy::too_many_arguments)]
fn place_constants(
    g: &Graph,
    sched: &mut Schedule,
    table: &mut Table,
    preds: &[Edge],
    t: i64,
    ii: i64,
    slots: &Slots,
    desc: &MachineDesc,
) -> bool {
    let constants = preds
        .iter()
        .filter(|e| e.distance == 0 && g.ops[e.from].is_rematerialised_constant());
    let mut placed = Vec::new();
    for e in constants {
        let latest = t - e.latency;
        let fits = (latest - ii.min(CONSTANT_LEAD)..=latest)
            .rev()
            .any(|tc| try_place(g, sched, table, e.from, tc, slots, desc).is_ok());
        if !fits {
            for c in placed {
                unplace(g, sched, table, c, slots, desc);
            }
            return false;
        }
        placed.push(e.from);
    }
    true
}

/// The operand of `u` whose placed producer's value leaves its entry first, and the last
/// cycle `u` may read it.
fn shortest_lifetime(
    g: &Graph,
    sched: &Schedule,
    u: usize,
    latency: &[i64],
    reach: i64,
) -> Option<(usize, i64)> {
    g.ops[u]
        .args
        .iter()
        .enumerate()
        .filter_map(|(i, a)| match a.src {
            Source::Local(p) => sched.place[p].map(|q| (i, q.time + latency[p] + reach)),
            _ => None,
        })
        .min_by_key(|&(i, limit)| (limit, i))
}

/// The issue interval a divide/sqrt op's row must be a multiple of (a divider in a loop
/// whose interval it divides), if any.
fn divider_alignment(g: &Graph, u: usize, ii: i64, slots: &Slots) -> Option<i64> {
    match g.ops[u].kind {
        Kind::Fu(o) if o.unit() == UnitClass::DivSqrt => {
            let k = slots.dsq_interval as i64;
            (k > 1 && ii % k == 0).then_some(k)
        }
        _ => None,
    }
}

/// The cycles of `[estart, last]` a lifetime copy tries: as late as it may, to carry its
/// value furthest — back from its deadline, then after it.
fn late_first(g: &Graph, u: usize, estart: i64, last: i64) -> impl Iterator<Item = i64> {
    let d = g.ops[u]
        .deadline
        .unwrap_or(last)
        .clamp(estart, last.max(estart));
    (estart..=d).rev().chain(d + 1..=last)
}

/// The ops among `ops` that read each op's value.
fn readers_of(g: &Graph, ops: &[usize]) -> Adjacency<usize> {
    let reads = ops.iter().flat_map(|&u| {
        g.ops[u].args.iter().filter_map(move |a| match a.src {
            Source::Local(p) => Some((p, u)),
            _ => None,
        })
    });
    Adjacency::new(g.ops.len(), reads)
}

/// List scheduling priority: mostly program order (it keeps values short-lived, which the
/// small LRFs need), leaning towards the critical path.
fn list_priority(g: &Graph, height: &[i64]) -> Vec<i64> {
    (0..g.ops.len())
        .map(|o| height[o] * 10 - i64::from(g.ops[o].ir.map_or(0, |v| v.0)))
        .collect()
}

/// Moves the ops of a region later, by a multiple of `step`, so that none is placed before
/// cycle 0.
fn shift_to_cycle_zero(sched: &mut Schedule, ops: &[usize], step: i64) {
    let first = ops
        .iter()
        .filter_map(|&o| sched.place[o].map(|p| p.time))
        .min()
        .unwrap_or(0);
    if first < 0 {
        let shift = (-first + step - 1) / step * step;
        for &o in ops {
            if let Some(p) = &mut sched.place[o] {
                p.time += shift;
            }
        }
    }
}

/// How long a loop value may wait in its LRF entry at interval `ii`: `ii` cycles for each
/// pass of the body. The body is unrolled into as many passes as its longest-lived value
/// needs, each with its own entries for it (modulo variable expansion, Lam, "Software
/// pipelining", PLDI 1988: with no rotating register file, the entry is renamed in the code
/// instead), as far as half the microcode store holds them and up to [`MAX_PASSES`].
pub fn reach(g: &Graph, ii: i64, desc: &MachineDesc) -> i64 {
    if !g.expand || ii <= 1 {
        return ii;
    }
    let passes = (desc.microcontroller.store_words as i64 / 2 / ii).clamp(1, MAX_PASSES);
    ii * passes
}

/// Passes a loop body may be unrolled into. (Letting values wait longer lets the schedule
/// drift later: up to 16, as many as the stages, vertex_unlit and viewport_cull came out an
/// interval longer on gold8.)
pub const MAX_PASSES: i64 = 4;

/// Lifetime copies one attempt at an initiation interval may ask for.
const MAX_LOOP_COPIES: usize = 64;

/// Lifetime copies one attempt may ask for when the loop body is unrolled.
const EXPANDED_LOOP_COPIES: usize = 8;

/// Ops Rau's scheduler may place per op of the loop before it gives up at this interval.
const BUDGET_RATIO: usize = 8;

/// Iterative modulo scheduling of the loop body at interval `ii` (Rau, MICRO 1994): ops go
/// in height order to the first free cycle of `[Estart, Estart + II)`; when none is free,
/// the op is forced in (at Estart, or one cycle after where it last went) and evicts the
/// ops holding the resources it needs and the placed ops whose dependences it breaks,
/// which are scheduled again. A rematerialised constant is placed once every reader is,
/// just in time for them, and leaves with any of them. A rematerialised scratchpad read is
/// placed the same way, after its address too; it stays when its reader leaves, so that a
/// read forced in later than the reader takes the reader later with it.
///
/// The loop's values must also be read within one interval (or [`reach`]) of landing:
/// that bounds a reader's latest cycle by its placed producers and a producer's earliest by
/// its placed readers. A reader whose producers leave it no cycle at all asks for a copy.
fn attempt_modulo(
    g: &Graph,
    sched: &mut Schedule,
    region: Region,
    ii: i64,
    slots: &Slots,
    desc: &MachineDesc,
) -> Result<(), Attempt> {
    let n = g.ops.len();
    let edges = g.edges(region, desc);
    let dag = Dag::new(g, sched, region, &edges);
    let Dag {
        ops,
        order,
        height,
        preds,
        succs,
    } = &dag;
    let mut table = Table::new(Some(ii), slots);
    let reach = reach(g, ii, desc);
    let readers = readers_of(g, ops);
    let jit = |o: usize| g.ops[o].just_in_time;
    let latency: Vec<i64> = (0..n).map(|o| g.latency(o, desc)).collect();
    // Ops go in the order of the last attempt at this interval, if it asked for a copy, or
    // of the loop body's straight-line schedule when there is one (copies added since then
    // just after what they copy), else in height order.
    let hinted: Vec<Option<i64>> = if !g.warm.is_empty() {
        g.warm.clone()
    } else {
        g.hint.iter().map(|&t| (t >= 0).then_some(t)).collect()
    };
    let hinted_height: Vec<i64>;
    let height: &[i64] = if !hinted.is_empty() {
        let mut h = vec![0i64; n];
        for &o in order {
            h[o] = match hinted.get(o) {
                Some(&Some(t)) => t,
                _ => preds[o]
                    .iter()
                    .filter(|e| e.distance == 0)
                    .map(|e| h[e.from] + e.latency)
                    .max()
                    .unwrap_or(0),
            };
        }
        hinted_height = h.iter().map(|&t| -t).collect();
        &hinted_height
    } else {
        height
    };
    // The queue pops the greatest (height, tie): ties go to the earlier op in program order,
    // or with `late_ties` to the later one.
    let tie = |o: usize| if g.late_ties { o as i64 } else { -(o as i64) };
    let mut queue: std::collections::BinaryHeap<(i64, i64, usize)> = ops
        .iter()
        .filter(|&&o| !jit(o) || succs[o].is_empty())
        .map(|&o| (height[o], tie(o), o))
        .collect();
    let mut previous: Vec<Option<i64>> = vec![None; n];
    let mut moved_for_lifetime = vec![false; n];
    let mut budget = ops.len() * BUDGET_RATIO + 64;
    // Takes `v` out of the schedule (with the constants made just for it) and queues it.
    let evict = |v: usize,
                 sched: &mut Schedule,
                 table: &mut Table,
                 queue: &mut std::collections::BinaryHeap<(i64, i64, usize)>| {
        unplace(g, sched, table, v, slots, desc);
        // (A rematerialised read stays: `v` goes back after it, which makes progress when
        // the read was forced in late.)
        for e in &preds[v] {
            if e.distance == 0
                && g.ops[e.from].is_rematerialised_constant()
                && sched.place[e.from].is_some()
            {
                unplace(g, sched, table, e.from, slots, desc);
            }
        }
        // (A constant waiting for a reader is queued again when the reader is placed.)
        queue.push((height[v], tie(v), v));
    };
    while let Some((_, _, u)) = queue.pop() {
        if sched.place[u].is_some()
            || (jit(u) && succs[u].iter().any(|e| sched.place[e.to].is_none()))
        {
            continue;
        }
        if budget == 0 {
            return Err(Attempt::Fail(Failure::NoSlot {
                op: u,
                why: format!("no schedule within {BUDGET_RATIO} placements per op"),
            }));
        }
        budget -= 1;
        let placed_at = |o: usize, sched: &Schedule| sched.place[o].map(|p| p.time);
        let mut estart = i64::MIN;
        // The latest cycle `u` may issue for the values it reads through a rematerialised
        // read still to be placed (which must read its address within an interval).
        let mut through_jit = i64::MAX;
        for e in &preds[u] {
            if let Some(t) = placed_at(e.from, sched) {
                estart = estart.max(t + e.latency - ii * i64::from(e.distance));
            } else if jit(e.from) && e.distance == 0 {
                // The read goes between its address and `u`.
                for e2 in &preds[e.from] {
                    if let Some(t2) = placed_at(e2.from, sched) {
                        let lands = t2 + e2.latency - ii * i64::from(e2.distance);
                        estart = estart.max(lands + e.latency);
                        through_jit = through_jit.min(t2 + latency[e2.from] + ii + e.latency);
                    }
                }
            }
        }
        let has_placed_pred = estart != i64::MIN;
        // Placed readers must still find the value in its entry.
        for &r in &readers[u] {
            if let Some(t) = placed_at(r, sched) {
                estart = estart.max(t - latency[u] - reach);
            }
        }
        let mut lstart = i64::MAX;
        for e in &succs[u] {
            if let Some(t) = placed_at(e.to, sched) {
                lstart = lstart.min(t - e.latency + ii * i64::from(e.distance));
            }
        }
        if estart == i64::MIN {
            estart = if jit(u) { lstart.min(0) } else { 0 };
        }
        let mut last = (estart + ii - 1).min(through_jit.max(estart));
        let mut lifetime = shortest_lifetime(g, sched, u, &latency, reach).filter(|l| l.1 < last);
        if let Some((_, limit)) = lifetime {
            last = limit;
        }
        let late = g.ops[u].copy_kind == Some(CopyKind::Lifetime);
        if let Some((arg, limit)) = lifetime
            && limit < estart
            && !late
            && !jit(u)
        {
            // The producer landed too early for `u`. The first time, it moves later (it is
            // evicted once `u` is placed); if it is too early again, the value gets a copy.
            // (Letting it move more often makes schedules drift later and need more copies.)
            let Source::Local(p) = g.ops[u].args[arg].src else {
                unreachable!("lifetimes are of local values")
            };
            if moved_for_lifetime[p] && !jit(p) {
                return Err(Attempt::Copy {
                    user: u,
                    arg,
                    wanted: estart,
                    places: last_places(sched, &previous),
                });
            }
            moved_for_lifetime[p] = true;
            last = estart + ii - 1;
            lifetime = None;
        }
        let dsq_align = divider_alignment(g, u, ii, slots);
        let aligned = |t: i64| dsq_align.is_none_or(|k| t.rem_euclid(ii) % k == 0);
        // (Tried in turn, without collecting them: most ops fit one of the first few.)
        let times: &mut dyn Iterator<Item = i64> = if jit(u) {
            // Backwards from just before its reader, no further than its value may live.
            let reader = succs[u]
                .iter()
                .filter_map(|e| placed_at(e.to, sched))
                .max()
                .unwrap_or(0);
            let lowest = reader - ii - latency[u];
            if has_placed_pred {
                &mut (lowest.max(estart)..=lstart.min(last)).rev()
            } else {
                &mut (lowest..=lstart).rev()
            }
        } else if late {
            &mut late_first(g, u, estart, last)
        } else {
            // (Where the last attempt placed it first, if that is still in the window.)
            let warm = g.warm.get(u).copied().flatten();
            &mut warm
                .filter(|&t| t > estart && t <= last)
                .into_iter()
                .chain(estart..=last)
        };
        let free = times
            .filter(|&t| aligned(t))
            .find(|&t| try_place(g, sched, &mut table, u, t, slots, desc).is_ok());
        let t = match free {
            Some(t) => t,
            None => {
                // Forced: at Estart, or just after its last place so that it makes progress.
                let mut t = if jit(u) && lstart != i64::MAX {
                    // (Between its operands and its readers, later each time so that it
                    // makes progress: whichever it breaks leaves.)
                    match previous[u] {
                        Some(p) if has_placed_pred && p >= estart => p + 1,
                        _ if has_placed_pred => lstart.min(last).max(estart),
                        _ => lstart,
                    }
                } else {
                    match previous[u] {
                        Some(p) if p >= estart => p + 1,
                        _ => estart,
                    }
                };
                while !aligned(t) {
                    t += 1;
                }
                if let Some((arg, limit)) = lifetime
                    && t > limit
                    && !late
                    && !jit(u)
                {
                    return Err(Attempt::Copy {
                        user: u,
                        arg,
                        wanted: estart.max(last),
                        places: last_places(sched, &previous),
                    });
                }
                loop {
                    match try_place(g, sched, &mut table, u, t, slots, desc) {
                        Ok(()) => break,
                        Err(b) => {
                            let holders = blockers(g, sched, &table, ops, u, t, slots, desc);
                            if holders.is_empty() {
                                return Err(Attempt::Fail(Failure::NoSlot {
                                    op: u,
                                    why: b.why(slots),
                                }));
                            }
                            for v in holders {
                                evict(v, sched, &mut table, &mut queue);
                            }
                        }
                    }
                }
                t
            }
        };
        previous[u] = Some(t);
        // Placed ops whose dependences on `u` now fail leave again.
        let mut broken: Vec<usize> = Vec::new();
        for e in &succs[u] {
            if let Some(s) = placed_at(e.to, sched)
                && s < t + e.latency - ii * i64::from(e.distance)
            {
                broken.push(e.to);
            }
        }
        for e in &preds[u] {
            if let Some(p) = placed_at(e.from, sched)
                && t < p + e.latency - ii * i64::from(e.distance)
            {
                broken.push(e.from);
            }
        }
        for &r in &readers[u] {
            if placed_at(r, sched).is_some_and(|s| s > t + latency[u] + reach) {
                broken.push(r);
            }
        }
        for a in &g.ops[u].args {
            if let Source::Local(p) = a.src
                && placed_at(p, sched).is_some_and(|s| s + latency[p] + reach < t)
            {
                broken.push(p);
            }
        }
        for v in broken {
            if sched.place[v].is_some() {
                evict(v, sched, &mut table, &mut queue);
            }
        }
        // Its constants can go now.
        for e in &preds[u] {
            if e.distance == 0 && jit(e.from) && sched.place[u].is_some() {
                queue.push((height[e.from], tie(e.from), e.from));
            }
        }
    }
    finish_loop(g, sched, table, &dag, &readers, ii, reach, slots, desc);
    if let Some(&u) = ops.iter().find(|&&o| sched.place[o].is_none()) {
        return Err(Attempt::Fail(Failure::NoSlot {
            op: u,
            why: "it was never placed (internal error)".into(),
        }));
    }
    Ok(())
}

/// Each op's issue cycle, or where it last was if it has been evicted.
fn last_places(sched: &Schedule, previous: &[Option<i64>]) -> Vec<Option<i64>> {
    previous
        .iter()
        .enumerate()
        .map(|(o, &p)| {
            sched
                .place
                .get(o)
                .copied()
                .flatten()
                .map(|pl| pl.time)
                .or(p)
        })
        .collect()
}

/// The placed ops holding a resource op `u` needs at cycle `t` (see [`try_place`]).
#[allow(clippy::too_many_arguments)]
fn blockers(
    g: &Graph,
    sched: &Schedule,
    table: &Table,
    ops: &[usize],
    u: usize,
    t: i64,
    slots: &Slots,
    desc: &MachineDesc,
) -> Vec<usize> {
    let op = &g.ops[u];
    let slot = op.slot;
    let row = table.row(t);
    let write = t + g.latency(u, desc);
    let mut held: Vec<u32> = Vec::new();
    // Stream ops issuing in `row`, conditional ones only if asked.
    let streams_in_row = |conditional_only: bool| -> Vec<u32> {
        ops.iter()
            .copied()
            .filter(|&o| {
                sched.place[o].is_some_and(|p| table.row(p.time) == row)
                    && match g.ops[o].kind {
                        Kind::StreamIn { cond, .. } | Kind::StreamOut { cond, .. } => {
                            cond || !conditional_only
                        }
                        _ => false,
                    }
            })
            .map(|o| o as u32)
            .collect()
    };
    match op.kind {
        Kind::Fu(o) => {
            for k in 0..table.issue_rows(slots.issue_cycles(o)) {
                held.push(table.fu[table.row(t + k) * table.nfu + slot]);
            }
            held.push(table.fu_result[table.row(write) * table.nfu + slot]);
        }
        Kind::SpRead { .. } | Kind::SpWrite { .. } => {
            held.push(table.sp[row * table.nsp + slot]);
            if table.conditional[row] > 0 {
                held.extend(streams_in_row(true));
            }
        }
        Kind::Comm(_) => {
            held.push(table.comm[row * table.ncomm + slot]);
            if slot == 0 && table.conditional[row] > 0 {
                held.extend(streams_in_row(true));
            }
        }
        Kind::StreamIn { cond, .. } | Kind::StreamOut { cond, .. } => {
            if table.stream_words[row] as usize >= slots.stream_words {
                held.extend(streams_in_row(false).first());
            }
            if matches!(op.kind, Kind::StreamOut { .. }) {
                held.push(table.sout[row]);
            }
            if cond {
                if table.conditional[row] as usize >= slots.conditional_words {
                    held.extend(streams_in_row(true).first());
                }
                held.push(table.comm[row * table.ncomm]);
                held.push(table.sp[row * table.nsp]);
            }
        }
        Kind::Imm(_) => held.push(table.imm[row]),
    }
    for l in &sched.dests[u] {
        if let Loc::Lrf(x) = *l {
            held.push(table.port(x, write));
        }
    }
    let mut held: Vec<usize> = held
        .into_iter()
        .filter(|&h| h != FREE)
        .map(|h| h as usize)
        .collect();
    held.sort_unstable();
    held.dedup();
    held
}

/// Moves ops as late as their readers allow (last first), so values are made when they
/// are needed rather than waiting in the small LRFs. In a loop at interval `ii`, an op also
/// stays within one interval of its operands' landing (see [`attempt_modulo`]).
#[allow(clippy::too_many_arguments)]
fn sink(
    g: &Graph,
    sched: &mut Schedule,
    table: &mut Table,
    order: &[usize],
    succs: &Adjacency<Edge>,
    ii: Option<i64>,
    slots: &Slots,
    desc: &MachineDesc,
) {
    for &u in order.iter().rev() {
        let Some(p) = sched.place[u] else { continue };
        if !matches!(
            g.ops[u].kind,
            Kind::Fu(_)
                | Kind::Imm(_)
                | Kind::SpRead { .. }
                | Kind::Comm(_)
                | Kind::StreamIn { cond: false, .. }
        ) {
            continue;
        }
        // (A divider's place in a loop is aligned to its issue interval; it stays.)
        if ii.is_some() && matches!(g.ops[u].kind, Kind::Fu(o) if o.unit() == UnitClass::DivSqrt) {
            continue;
        }
        let interval = ii.unwrap_or(0);
        let latest = succs[u]
            .iter()
            .filter(|e| ii.is_some() || e.distance == 0)
            .filter_map(|e| {
                sched.place[e.to].map(|q| q.time - e.latency + interval * i64::from(e.distance))
            })
            .min();
        let Some(mut latest) = latest else { continue };
        if let Some(ii) = ii {
            for a in &g.ops[u].args {
                if let Source::Local(p) = a.src
                    && let Some(q) = sched.place[p]
                {
                    latest = latest.min(q.time + g.latency(p, desc) + ii);
                }
            }
        }
        if latest <= p.time {
            continue;
        }
        unplace(g, sched, table, u, slots, desc);
        let moved = (p.time + 1..=latest)
            .rev()
            .any(|t| try_place(g, sched, table, u, t, slots, desc).is_ok());
        if !moved {
            try_place(g, sched, table, u, p.time, slots, desc).expect("its old place is free");
        }
    }
}

/// Frees the resources op `u` holds.
fn unplace(
    g: &Graph,
    sched: &mut Schedule,
    table: &mut Table,
    u: usize,
    slots: &Slots,
    desc: &MachineDesc,
) {
    let Some(p) = sched.place[u].take() else {
        return;
    };
    let op = &g.ops[u];
    let row = table.row(p.time);
    let write = p.time + g.latency(u, desc);
    match op.kind {
        Kind::Fu(o) => {
            for k in 0..table.issue_rows(slots.issue_cycles(o)) {
                let r = table.row(p.time + k);
                table.fu[r * table.nfu + p.slot] = FREE;
            }
            let r = table.row(write);
            table.fu_result[r * table.nfu + p.slot] = FREE;
        }
        Kind::Imm(_) => table.imm[row] = FREE,
        Kind::SpRead { .. } | Kind::SpWrite { .. } => table.sp[row * table.nsp + p.slot] = FREE,
        Kind::Comm(_) => table.comm[row * table.ncomm + p.slot] = FREE,
        Kind::StreamIn { cond, .. } | Kind::StreamOut { cond, .. } => {
            table.stream_words[row] -= 1;
            if matches!(op.kind, Kind::StreamOut { .. }) {
                table.sout[row] = FREE;
            }
            if cond {
                table.conditional[row] -= 1;
            }
        }
    }
    for l in &sched.dests[u] {
        if let Loc::Lrf(x) = *l {
            let i = table.row(write) * table.nlrf + x as usize;
            table.ports[i] = FREE;
        }
    }
}

/// The input an operand is read through when a commutative op's operands are swapped.
pub fn input_of(a: &Arg, swap: bool) -> Input {
    match (a.input, swap) {
        (Input::A, true) => Input::B,
        (Input::B, true) => Input::A,
        (i, _) => i,
    }
}

/// Why an op cannot go where it was tried. (Put into words only when a schedule fails: the
/// schedulers try millions of places.)
#[derive(Clone, Copy, Debug)]
enum Busy {
    Unit(usize),
    ResultPort(usize),
    Scratchpad(usize),
    Comm(usize),
    StreamWords,
    StreamOutput,
    ConditionalStream,
    Immediate,
    WritePort(u16),
    /// A rematerialised constant the op reads finds no cycle before it.
    ConstantCycle,
}

impl Busy {
    fn why(self, slots: &Slots) -> String {
        match self {
            Busy::Unit(slot) => format!("{} is busy", slots.shape.fu_name(slot)),
            Busy::ResultPort(slot) => {
                format!("the result port of {} is busy", slots.shape.fu_name(slot))
            }
            Busy::Scratchpad(slot) => format!("sp{slot} is busy"),
            Busy::Comm(slot) => format!("comm{slot} is busy"),
            Busy::StreamWords => "the SRF stream words of the cycle are used".into(),
            Busy::StreamOutput => "the stream output slot is used".into(),
            Busy::ConditionalStream => {
                "a conditional stream needs comm0 and sp0 in its cycle".into()
            }
            Busy::Immediate => "the immediate slot is used".into(),
            Busy::WritePort(lrf) => format!(
                "the write port of {} is taken when the result lands",
                slots.shape.lrf_names[lrf as usize]
            ),
            Busy::ConstantCycle => "no cycle is free for a constant it reads".into(),
        }
    }
}

/// Places op `u` at cycle `t` on its bound slot, if its resources are free: the slot (a
/// divide/sqrt unit for its issue interval), the unit's result port, stream and immediate
/// slots, and the write port of every LRF its result goes to, in the cycle it lands.
fn try_place(
    g: &Graph,
    sched: &mut Schedule,
    table: &mut Table,
    u: usize,
    t: i64,
    slots: &Slots,
    desc: &MachineDesc,
) -> Result<(), Busy> {
    let op = &g.ops[u];
    let slot = op.slot;
    let write = t + g.latency(u, desc);
    let held_until = match op.kind {
        Kind::Fu(o) => write.max(t + slots.issue_cycles(o) - 1),
        _ => write,
    };
    table.cover(t, held_until);
    let row = table.row(t);
    match op.kind {
        Kind::Fu(o) => {
            for k in 0..table.issue_rows(slots.issue_cycles(o)) {
                if table.fu[table.row(t + k) * table.nfu + slot] != FREE {
                    return Err(Busy::Unit(slot));
                }
            }
            if table.fu_result[table.row(write) * table.nfu + slot] != FREE {
                return Err(Busy::ResultPort(slot));
            }
        }
        Kind::SpRead { .. } | Kind::SpWrite { .. } => {
            if table.sp[row * table.nsp + slot] != FREE || table.conditional[row] > 0 {
                return Err(Busy::Scratchpad(slot));
            }
        }
        Kind::Comm(_) => {
            let cond_blocks = slot == 0 && table.conditional[row] > 0;
            if table.comm[row * table.ncomm + slot] != FREE || cond_blocks {
                return Err(Busy::Comm(slot));
            }
        }
        Kind::StreamIn { cond, .. } | Kind::StreamOut { cond, .. } => {
            if table.stream_words[row] as usize >= slots.stream_words {
                return Err(Busy::StreamWords);
            }
            if matches!(op.kind, Kind::StreamOut { .. }) && table.sout[row] != FREE {
                return Err(Busy::StreamOutput);
            }
            if cond
                && (table.conditional[row] as usize >= slots.conditional_words
                    || table.comm[row * table.ncomm] != FREE
                    || table.sp[row * table.nsp] != FREE)
            {
                return Err(Busy::ConditionalStream);
            }
        }
        Kind::Imm(_) => {
            if table.imm[row] != FREE {
                return Err(Busy::Immediate);
            }
        }
    }
    for l in &sched.dests[u] {
        if let Loc::Lrf(x) = *l
            && table.port(x, write) != FREE
        {
            return Err(Busy::WritePort(x));
        }
    }
    // Commit.
    let id = u as u32;
    match op.kind {
        Kind::Fu(o) => {
            for k in 0..table.issue_rows(slots.issue_cycles(o)) {
                let r = table.row(t + k);
                table.fu[r * table.nfu + slot] = id;
            }
            let r = table.row(write);
            table.fu_result[r * table.nfu + slot] = id;
        }
        Kind::SpRead { .. } | Kind::SpWrite { .. } => table.sp[row * table.nsp + slot] = id,
        Kind::Comm(_) => table.comm[row * table.ncomm + slot] = id,
        Kind::StreamIn { cond, .. } | Kind::StreamOut { cond, .. } => {
            table.stream_words[row] += 1;
            if matches!(op.kind, Kind::StreamOut { .. }) {
                table.sout[row] = id;
            }
            if cond {
                table.conditional[row] += 1;
            }
        }
        Kind::Imm(_) => table.imm[row] = id,
    }
    for l in &sched.dests[u] {
        if let Loc::Lrf(x) = *l {
            let i = table.row(write) * table.nlrf + x as usize;
            table.ports[i] = id;
        }
    }
    sched.place[u] = Some(Placement {
        time: t,
        slot,
        swap: op.swap,
    });
    Ok(())
}

/// A way to take value `p` out of an LRF for a while (see [`relieve`]).
#[derive(Clone, Debug)]
struct Relief {
    /// Cycles of the LRF freed.
    saved: i64,
    p: usize,
    /// The adder whose `a` LRF holds the value meanwhile, and whose `mov`s copy it back.
    adder: usize,
    /// `p` still writes the LRF (for its early readers).
    keep: bool,
    /// Each copy: its issue cycle and the first and last reader cycles it serves.
    copies: Vec<(i64, i64, i64)>,
}

/// Takes values out of the loop's LRF `loc` until no more than `target` are live in it at
/// once, without moving any op: a value waiting long in `loc` for its readers is written
/// to an adder's `a` LRF instead (or as well, for the readers before the wait), and a `mov`
/// on that adder, placed in a free adder issue slot as late as the readers allow, carries
/// it back into `loc` just in time (two `mov`s when the value has early readers and no
/// destination to spare). This is the copy insertion of communication scheduling (Mattson
/// et al., MICRO 2000) applied after the fact to a modulo schedule, as register-pressure
/// repairs of modulo schedules add spill code to a schedule rather than schedule again
/// (Zalamea et al., "Improved spill code generation for software pipelined loops", PLDI
/// 2000), with copies to roomier LRFs in place of spills. Returns whether `loc` got down to
/// `target`.
#[allow(clippy::too_many_arguments)]
pub fn relieve(
    g: &mut Graph,
    sched: &mut Schedule,
    ii: i64,
    loc: Loc,
    target: usize,
    slots: &Slots,
    desc: &MachineDesc,
) -> bool {
    use super::alloc::{Liveness, index};
    use super::last_reads::LastReads;
    let Loc::Lrf(lrf) = loc else { return false };
    let mut table = Table::new(Some(ii), slots);
    for u in g.in_region(Region::Loop) {
        let Some(p) = sched.place[u] else {
            return false;
        };
        if try_place(g, sched, &mut table, u, p.time, slots, desc).is_err() {
            return false;
        }
    }
    let lm = i64::from(Op::Mov.latency(&desc.latency));
    let k = index(slots, loc);
    let adders: Vec<usize> = slots.fu_slots(UnitClass::Adder).collect();
    let reach = reach(g, ii, desc);
    // (Each copy frees part of a row at least; this only bounds a runaway.)
    for _ in 0..ii.max(64) {
        let ops = g.in_region(Region::Loop);
        let perm = super::alloc::permanent(g);
        let last_read = LastReads::new(g, sched, slots, Some(Region::Loop));
        let live = Liveness::with_last_reads(g, sched, slots, ii, desc, &last_read);
        if live.peak(k) <= target {
            return true;
        }
        let peak = live.rows[k].iter().copied().max().unwrap_or(0);
        let row = live.rows[k].iter().position(|&x| x == peak).unwrap_or(0) as i64;
        let covers =
            |from: i64, to: i64| (from..to.min(from + ii)).any(|c| c.rem_euclid(ii) == row);
        // Readers of each value through `loc`, and when.
        let mut times: std::collections::BTreeMap<usize, Vec<i64>> = Default::default();
        for &r in &ops {
            let Some(pr) = sched.place[r] else { continue };
            for a in &g.ops[r].args {
                if let Source::Local(p) = a.src
                    && slots.operand_loc(g.ops[r].kind, pr.slot, pr.swap, a) == loc
                {
                    times.entry(p).or_default().push(pr.time);
                }
            }
        }
        let mut best: Option<Relief> = None;
        for (&p, times) in &mut times {
            times.sort_unstable();
            times.dedup();
            let op = &g.ops[p];
            if perm[p]
                || !sched.dests[p].contains(&loc)
                || op.seeded.contains(&loc)
                || sched.required[p].iter().any(|&(l, _)| l == loc)
            {
                continue;
            }
            let Some(pp) = sched.place[p] else { continue };
            let w = pp.time + g.latency(p, desc);
            if !covers(w, times[times.len() - 1]) {
                continue;
            }
            for &a in &adders {
                let dst_lrf = slots.fu_inputs[a][0];
                let dst = Loc::Lrf(dst_lrf);
                if dst == loc {
                    continue;
                }
                let d = index(slots, dst);
                let already = sched.dests[p].contains(&dst);
                if !already && table.port(dst_lrf, w) != FREE {
                    continue;
                }
                let can_keep = already || sched.dests[p].len() < 2;
                // The value in the adder's LRF until `t`: room for it there (one entry
                // spare for the packing).
                let held_from = if already {
                    last_read.get(slots, p, dst).unwrap_or(w)
                } else {
                    w
                };
                let cap = slots.shape.lrf_sizes[d];
                let room = |t: i64| {
                    circle::cycles(held_from, t, ii).all(|run| {
                        live.rows[d][run]
                            .iter()
                            .all(|&x| live.kept[d] + x + 2 <= cap)
                    })
                };
                // The latest cycle a copy may issue before `until`, not in `taken`'s row.
                let slot = |until: i64, taken: Option<i64>| -> Option<i64> {
                    (w + 1..=(until - lm - 1).min(w + reach)).rev().find(|&t| {
                        taken.is_none_or(|x| table.row(x) != table.row(t))
                            && table.fu[table.row(t) * table.nfu + a] == FREE
                            && table.fu_result[table.row(t + lm) * table.nfu + a] == FREE
                            && table.port(lrf, t + lm) == FREE
                            && room(t)
                    })
                };
                for split in 0..times.len() {
                    let first = times[split];
                    let Some(t2) = slot(first, None) else {
                        continue;
                    };
                    let last = times[times.len() - 1];
                    let late = (t2, first, last);
                    let candidate = if split == 0 {
                        (covers(w, t2 + lm)).then(|| Relief {
                            saved: t2 + lm - w,
                            p,
                            adder: a,
                            keep: false,
                            copies: vec![late],
                        })
                    } else {
                        let start = times[split - 1];
                        if !covers(start, t2 + lm) {
                            continue;
                        }
                        if can_keep {
                            Some(Relief {
                                saved: t2 + lm - start,
                                p,
                                adder: a,
                                keep: true,
                                copies: vec![late],
                            })
                        } else {
                            slot(times[0], Some(t2)).map(|t1| Relief {
                                // (A second copy costs an adder slot.)
                                saved: t2 + lm - start + t1 + lm - w - 4,
                                p,
                                adder: a,
                                keep: false,
                                copies: vec![(t1, times[0], start), late],
                            })
                        }
                    };
                    if let Some(c) = candidate
                        && best.as_ref().is_none_or(|b| c.saved > b.saved)
                    {
                        best = Some(c);
                    }
                }
            }
        }
        let Some(r) = best else {
            return false;
        };
        // `p` writes the adder's LRF (instead of `loc` unless it keeps it); the copies
        // write `loc`.
        let p = r.p;
        let pp = sched.place[p].expect("placed");
        let dst = Loc::Lrf(slots.fu_inputs[r.adder][0]);
        unplace(g, sched, &mut table, p, slots, desc);
        if !r.keep {
            sched.dests[p].retain(|&l| l != loc);
        }
        if !sched.dests[p].contains(&dst) {
            sched.dests[p].push(dst);
        }
        try_place(g, sched, &mut table, p, pp.time, slots, desc).expect("its ports are free");
        for &(t, from, to) in &r.copies {
            let c = g.ops.len();
            let mut mov = super::graph::MOp::copy_of(
                Source::Local(p),
                Region::Loop,
                g.ops[p].ir,
                CopyKind::Lifetime,
            );
            mov.slot = r.adder;
            g.ops.push(mov);
            sched.grow(g.ops.len());
            sched.dests[c] = vec![loc];
            for &u in &ops {
                let Some(pu) = sched.place[u] else { continue };
                if pu.time < from || pu.time > to {
                    continue;
                }
                let kind = g.ops[u].kind;
                for arg in &mut g.ops[u].args {
                    if arg.src == Source::Local(p)
                        && slots.operand_loc(kind, pu.slot, pu.swap, arg) == loc
                    {
                        arg.src = Source::Local(c);
                    }
                }
            }
            try_place(g, sched, &mut table, c, t, slots, desc).expect("its slot is free");
        }
    }
    false
}

/// Ends a complete loop schedule: ops sunk towards their readers, the waits relaxed if
/// values overflow an LRF, and the body shifted by whole intervals so that no op is placed
/// before cycle 0 (rows stay, stages grow).
#[allow(clippy::too_many_arguments)]
fn finish_loop(
    g: &Graph,
    sched: &mut Schedule,
    mut table: Table,
    dag: &Dag,
    readers: &Adjacency<usize>,
    ii: i64,
    reach: i64,
    slots: &Slots,
    desc: &MachineDesc,
) {
    sink(
        g,
        sched,
        &mut table,
        &dag.order,
        &dag.succs,
        Some(ii),
        slots,
        desc,
    );
    relax(g, sched, table, dag, readers, ii, reach, slots, desc);
    shift_to_cycle_zero(sched, &dag.ops, ii);
}

/// Sweeps [`relax`] makes through the body, alternately forwards and backwards.
const RELAX_SWEEPS: usize = 4;

/// Shortens the waits of a loop schedule whose values overflow an LRF: each FU op and
/// scratchpad read moves, within what its placed dependences and lifetimes allow, to the
/// free cycle where the values it reads and writes wait least in their LRFs (an op reading
/// two values and writing one goes early, one feeding several readers late), in sweeps
/// forwards and backwards through the body. This is the lifetime-sensitive placement of
/// Huff ("Lifetime-sensitive modulo scheduling", PLDI 1993) applied after the fact, to a
/// schedule whose ops went to the first free cycle. The schedule is kept only if the
/// values over the LRFs' sizes (summed over the LRFs, at their peaks) become fewer.
#[allow(clippy::too_many_arguments)]
fn relax(
    g: &Graph,
    sched: &mut Schedule,
    mut table: Table,
    dag: &Dag,
    readers: &Adjacency<usize>,
    ii: i64,
    reach: i64,
    slots: &Slots,
    desc: &MachineDesc,
) {
    let overflow = |sched: &Schedule| {
        let live = super::alloc::Liveness::new(g, sched, slots, ii, desc);
        (0..slots.lrfs())
            .map(|l| live.peak(l).saturating_sub(slots.shape.lrf_sizes[l]))
            .sum::<usize>()
    };
    let before = overflow(sched);
    if before == 0 {
        return;
    }
    let kept = sched.clone();
    let Dag {
        ops, preds, succs, ..
    } = dag;
    let latency: Vec<i64> = (0..g.ops.len()).map(|o| g.latency(o, desc)).collect();
    let at = |o: usize, sched: &Schedule| sched.place[o].map(|p| p.time);
    // Whether reader `r` reads value `p` from `l`.
    let reads_from = |r: usize, p: usize, l: Loc, sched: &Schedule| -> bool {
        let op = &g.ops[r];
        let pl = sched.place[r];
        op.args
            .iter()
            .filter(|a| a.src == Source::Local(p))
            .any(|a| {
                slots.operand_loc(
                    op.kind,
                    pl.map_or(op.slot, |q| q.slot),
                    pl.map_or(op.swap, |q| q.swap),
                    a,
                ) == l
            })
    };
    // The last cycle `p`'s value is read from `l` by a placed reader other than `u`.
    let last_read_but = |p: usize, l: Loc, u: usize, sched: &Schedule| -> Option<i64> {
        readers[p]
            .iter()
            .filter(|&&r| r != u && reads_from(r, p, l, sched))
            .filter_map(|&r| at(r, sched))
            .max()
    };
    for sweep in 0..RELAX_SWEEPS {
        let order: Vec<usize> = if sweep % 2 == 0 {
            ops.to_vec()
        } else {
            ops.iter().rev().copied().collect()
        };
        // (Kept from op to op: a sweep allocates them once.)
        let mut operands: Vec<(Option<i64>, i64)> = Vec::new();
        let mut last_reads: Vec<i64> = Vec::new();
        let mut candidates: Vec<(i64, i64, i64)> = Vec::new();
        for &u in &order {
            let Some(pl) = sched.place[u] else { continue };
            match g.ops[u].kind {
                Kind::Fu(o) if o.unit() != UnitClass::DivSqrt => {}
                Kind::SpRead { .. } => {}
                _ => continue,
            }
            let mut lo = i64::MIN;
            let mut hi = i64::MAX;
            for e in &preds[u] {
                if let Some(t) = at(e.from, sched) {
                    lo = lo.max(t + e.latency - ii * i64::from(e.distance));
                }
            }
            for e in &succs[u] {
                if let Some(t) = at(e.to, sched) {
                    hi = hi.min(t - e.latency + ii * i64::from(e.distance));
                }
            }
            for &r in &readers[u] {
                if let Some(t) = at(r, sched) {
                    lo = lo.max(t - latency[u] - reach);
                }
            }
            for a in &g.ops[u].args {
                if let Source::Local(p) = a.src
                    && let Some(t) = at(p, sched)
                {
                    hi = hi.min(t + latency[p] + reach);
                }
            }
            if lo == i64::MIN || hi == i64::MAX || lo >= hi {
                continue;
            }
            // The waits of its operands (each until its last read, `u`'s at `t` among them)
            // and of its value (from its landing, `t` plus its latency, until its readers'
            // last read), as functions of `t`: what the other reads fix is found once.
            operands.clear();
            operands.extend(g.ops[u].args.iter().filter_map(|a| match a.src {
                Source::Local(p) => at(p, sched).map(|tp| {
                    let l = slots.operand_loc(g.ops[u].kind, pl.slot, pl.swap, a);
                    (last_read_but(p, l, u, sched), tp + latency[p])
                }),
                _ => None,
            }));
            last_reads.clear();
            last_reads.extend(sched.dests[u].iter().filter_map(|&l| {
                readers[u]
                    .iter()
                    .filter(|&&r| reads_from(r, u, l, sched))
                    .filter_map(|&r| at(r, sched))
                    .max()
            }));
            let cost = |t: i64| -> i64 {
                let mut c = 0;
                for &(others, lands) in &operands {
                    c += others.map_or(t, |o| o.max(t)) - lands;
                }
                for &last in &last_reads {
                    c += last - (t + latency[u]);
                }
                c
            };
            let now = cost(pl.time);
            // (Least wait first, then nearest.)
            candidates.clear();
            candidates.extend(
                (lo..=hi)
                    .filter(|&t| t != pl.time)
                    .map(|t| (cost(t), (t - pl.time).abs(), t))
                    .filter(|&(c, _, _)| c < now),
            );
            if candidates.is_empty() {
                continue;
            }
            candidates.sort_unstable();
            unplace(g, sched, &mut table, u, slots, desc);
            let moved = candidates
                .iter()
                .any(|&(_, _, t)| try_place(g, sched, &mut table, u, t, slots, desc).is_ok());
            if !moved {
                try_place(g, sched, &mut table, u, pl.time, slots, desc)
                    .expect("its old place is free");
            }
        }
    }
    if overflow(sched) >= before {
        *sched = kept;
    }
}
