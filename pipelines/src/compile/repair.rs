//! Modulo scheduling by local search, for loops that fill their units.
//!
//! When a loop body keeps a unit class busy in nearly every row of the interval (the MARBLE
//! shader's 651 adder ops in 654 adder slots at its bound), a constructive scheduler places
//! its last ops wherever a row is still free, far from their operands and readers, and the
//! values wait in the small LRFs until they overflow. This scheduler instead starts from a
//! greedy placement (each op where it costs least near its earliest cycle) and repairs it:
//! each step takes an op that breaks something (or whose values crowd a full LRF) and moves
//! it — the min-conflicts heuristic (Minton et al., "Minimizing conflicts", Artificial
//! Intelligence 58, 1992) under simulated annealing:
//!
//! - an op in a taken slot or port moves by an ejection chain: a breadth-first search, as
//!   for an augmenting path of a matching, for a sequence of moves each within its
//!   dependences that displaces at most one op, ending at a free place, so free slots
//!   travel to where the body needs them;
//! - a value with a third destination has every reader of one of its places moved (by
//!   chains) to read one of the others, if it can no later than that place is read already;
//! - a broken dependence pushes its reader later or pulls its writer earlier;
//! - otherwise the op goes to the cheapest of a few places within its dependence window.
//!
//! Binding is part of the search: an op may move to any unit of its class and swap a
//! commutative op's operands, which changes the LRFs its operands are written to. The cost
//! counts what the hardware forbids — two ops in one issue slot, result port or LRF write
//! port, a dependence broken, a value read after its entry is reused ([`super::schedule::reach`]),
//! a result with more than two destinations — and the values live beyond an LRF's entries
//! (less a margin for the allocator) in each row; the start also weighs every value's wait.
//! A class whose ops have two latencies issues them by a plan ([`latency_plan`]) under which
//! its result ports cannot clash. A schedule is returned only when nothing is broken and
//! every LRF holds its values at every row.

use rustc_hash::FxHashMap as HashMap;
use std::sync::atomic::{AtomicBool, Ordering};

use imagine_units::desc::MachineDesc;
use imagine_units::ops::UnitClass;

use super::circle;
use super::graph::{Edge, Graph, Input, Kind, Loc, MAX_ARGS, Source};
use super::schedule::Slots;

mod probe;

/// Where a loop op reads an operand from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Src {
    /// A loop op's result (this iteration's, or the previous one's for a carried value).
    Loop { op: usize, carried: bool },
    /// A value made before the loop and kept in its entry throughout (numbered densely
    /// among the loop's earlier operands).
    Earlier(usize),
}

/// A loop op as the search sees it.
struct LOp {
    kind: Kind,
    lat: i64,
    /// Consecutive issue rows its unit is held (the divide/sqrt unit's issue interval).
    issue: i64,
    /// Its issue row must be a multiple of this (a divider whose interval divides the II).
    align: Option<i64>,
    /// (slot, operands swapped) choices.
    options: Vec<(usize, bool)>,
    args: Vec<(Src, Input)>,
    /// Where each argument is read on each choice: `[(slot * 2 + swap) * args + i]` (the
    /// search asks millions of times).
    arg_locs: Vec<Loc>,
    /// Destinations fixed by other regions.
    seeded: Vec<Loc>,
    /// Its entries are held for the whole loop (a carried value).
    permanent: bool,
    /// A rematerialised constant, placed just before its reader.
    jit: bool,
}

/// Resources per row of the table: FU issue slots, FU result ports, scratchpads, comm units,
/// the stream output slot, the immediate slot, the SRF words, the LRF write ports.
struct Resources {
    nfu: usize,
    nsp: usize,
    ncomm: usize,
    per_row: usize,
    cap: Vec<i32>,
}

impl Resources {
    fn new(slots: &Slots) -> Resources {
        let s = &slots.shape;
        let (nfu, nsp, ncomm, nlrf) = (s.fu_count(), s.scratchpads, s.comm_units, slots.lrfs());
        let per_row = 2 * nfu + nsp + ncomm + 3 + nlrf;
        let mut cap = vec![1; per_row];
        cap[2 * nfu + nsp + ncomm + 2] = slots.stream_words as i32;
        Resources {
            nfu,
            nsp,
            ncomm,
            per_row,
            cap,
        }
    }
    fn issue(&self, k: usize) -> usize {
        k
    }
    fn result(&self, k: usize) -> usize {
        self.nfu + k
    }
    fn sp(&self, k: usize) -> usize {
        2 * self.nfu + k
    }
    fn comm(&self, k: usize) -> usize {
        2 * self.nfu + self.nsp + k
    }
    fn sout(&self) -> usize {
        2 * self.nfu + self.nsp + self.ncomm
    }
    fn imm(&self) -> usize {
        self.sout() + 1
    }
    fn words(&self) -> usize {
        self.sout() + 2
    }
    fn port(&self, l: u16) -> usize {
        self.sout() + 3 + l as usize
    }
}

/// What may issue in a row of a unit under a latency plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Row {
    Latency(i64),
    Empty,
}

/// A latency plan for a unit class whose ops have two latencies and leave few rows free.
///
/// A unit's single result port takes an op of the long latency at row `r` and one of the
/// short latency at row `r + gap` (the latencies' difference) in the same cycle. Following
/// the rows `gap` apart (an orbit, of which there are `gcd(gap, ii)` per unit), the long
/// ops must therefore come in runs that each end at an empty row. The plan gives each
/// unit's orbits their rows in advance: some all long, then some mixed (a run of long
/// rows ending at an empty row, the rest short, the empty rows spread over the interval),
/// the rest all short, so that no placement can clash at a result port. Returns the row
/// kinds of each unit, or `None` when the ops do not fit.
fn latency_plan(
    units: usize,
    ii: i64,
    (short, n_short): (i64, usize),
    (long, n_long): (i64, usize),
) -> Option<Vec<Vec<Row>>> {
    let rows = ii as usize;
    let gap = (long - short) as usize;
    let orbits = gcd(gap, rows);
    let m = rows / orbits;
    let pairs = units * orbits;
    let spare = (units * rows).checked_sub(n_short + n_long)?;
    // The fewest all-long orbits, then the most mixed ones (each costs its empty row).
    let (full, mixed) = (0..=pairs).find_map(|full| {
        let rest = n_long.saturating_sub(full * m);
        (0..=(pairs - full).min(spare)).rev().find_map(|mixed| {
            let shorts = (pairs - full - mixed) * m + mixed * (m - 1);
            let fits = rest <= mixed * (m - 1) && (rest == 0 || mixed > 0);
            (fits && shorts >= rest + n_short).then_some((full, mixed))
        })
    })?;
    let rest = n_long.saturating_sub(full * m);
    // Spare rows of the mixed orbits go to each latency in proportion.
    let spare_rows = (pairs - full - mixed) * m + mixed * (m - 1) - rest - n_short;
    let extra = if mixed > 0 {
        spare_rows * n_long / (n_long + n_short).max(1)
    } else {
        0
    };
    let mut plan = vec![vec![Row::Latency(short); rows]; units];
    // Orbits in turn over the units, so that the long ones spread over them.
    let order: Vec<(usize, usize)> = (0..orbits)
        .flat_map(|o| (0..units).map(move |k| (k, o)))
        .collect();
    for &(k, o) in &order[..full] {
        for r in (o..rows).step_by(orbits) {
            plan[k][r] = Row::Latency(long);
        }
    }
    for (i, &(k, o)) in order[full..full + mixed].iter().enumerate() {
        let n = ((rest + extra) / mixed + usize::from(i < (rest + extra) % mixed)).min(m - 1);
        // The empty rows spread evenly over the interval, each in its orbit.
        let e = (i * rows / mixed) / orbits * orbits + o;
        plan[k][e] = Row::Empty;
        for q in 1..=n {
            let r = (e + rows * q - gap * q) % rows;
            plan[k][r] = Row::Latency(long);
        }
    }
    Some(plan)
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The unit of the cost's weights.
const SCALE: i64 = 8;

/// Cost of each broken resource or destination limit.
const HARD: i64 = 100;
/// Cost of a broken dependence or lifetime, plus one per cycle it is broken by.
const BROKEN: i64 = 100;
/// Cost of each value over an LRF's entries in a row.
const CROWD: i64 = 12;

/// A small deterministic generator (SplitMix64).
pub(super) struct Rng(pub(super) u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub(super) fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The problem: the loop's ops, dependences and readers.
struct Problem {
    ii: i64,
    circle: circle::Circle,
    reach: i64,
    ops: Vec<LOp>,
    /// Dependences (local indices) and, per op, the edges it is in.
    edges: Vec<(usize, usize, i64, u32)>,
    incident: Vec<Vec<usize>>,
    /// Per op: the ops reading its value, and through which argument.
    readers: Vec<Vec<(usize, usize)>>,
    /// Per op: each argument read from a loop value, the value, and the read's index
    /// among the value's `readers`.
    read_index: Vec<Vec<(usize, usize, usize)>>,
    /// Per op: it reads its own value (of the iteration before).
    reads_itself: Vec<bool>,
    res: Resources,
    /// Locations: the LRFs, then the condition codes.
    nloc: usize,
    /// Values made before the loop that it reads.
    earlier: usize,
    cap: Vec<i32>,
    /// Per FU slot, per row: which latency may issue there (see [`latency_plan`]); empty
    /// for a slot of a class without a plan.
    rows: Vec<Vec<Row>>,
}

impl Problem {
    /// The search's view of the loop's `ops` at interval `ii`; `None` if the search
    /// cannot schedule them (a conditional stream, an op with no unit to go to).
    fn new(
        g: &Graph,
        ops: &[usize],
        edges: &[Edge],
        ii: i64,
        reach: i64,
        slots: &Slots,
        desc: &MachineDesc,
    ) -> Option<Problem> {
        let n = ops.len();
        let mut local = vec![usize::MAX; g.ops.len()];
        for (i, &o) in ops.iter().enumerate() {
            local[o] = i;
        }
        let mut lops = Vec::with_capacity(n);
        let mut earlier: HashMap<usize, usize> = HashMap::default();
        for &o in ops {
            let op = &g.ops[o];
            let (issue, align) = match op.kind {
                Kind::Fu(x) if x.unit() == UnitClass::DivSqrt => {
                    let k = slots.dsq_interval as i64;
                    (k, (k > 1 && ii % k == 0).then_some(k))
                }
                _ => (1, None),
            };
            let options: Vec<(usize, bool)> = match op.kind {
                Kind::Fu(x) => super::bind::fu_options(op, x, slots),
                Kind::SpRead { .. } | Kind::SpWrite { .. } => (0..slots.shape.scratchpads.min(1))
                    .map(|k| (k, false))
                    .collect(),
                Kind::Comm(_) => (0..slots.shape.comm_units).map(|k| (k, false)).collect(),
                _ => vec![(0, false)],
            };
            if options.is_empty() || op.kind.is_conditional_stream() {
                return None;
            }
            let mut args = Vec::with_capacity(op.args.len());
            for a in &op.args {
                let src = match a.src {
                    Source::Local(q) | Source::Carried(q) if local[q] == usize::MAX => return None,
                    Source::Local(q) => Src::Loop {
                        op: local[q],
                        carried: false,
                    },
                    Source::Carried(q) => Src::Loop {
                        op: local[q],
                        carried: true,
                    },
                    Source::Earlier(q) => {
                        let next = earlier.len();
                        Src::Earlier(*earlier.entry(q).or_insert(next))
                    }
                };
                args.push((src, a.input));
            }
            let choices = options.iter().map(|&(k, _)| k + 1).max().unwrap_or(1) * 2;
            let mut arg_locs = vec![Loc::Cc; choices * op.args.len()];
            for &(k, swap) in &options {
                for (i, a) in op.args.iter().enumerate() {
                    arg_locs[(k * 2 + usize::from(swap)) * op.args.len() + i] =
                        slots.operand_loc(op.kind, k, swap, a);
                }
            }
            lops.push(LOp {
                kind: op.kind,
                lat: g.latency(o, desc),
                issue,
                align,
                options,
                args,
                arg_locs,
                seeded: op.seeded.clone(),
                // A loop mov that a value before the loop initialises holds a carried value.
                permanent: g.ops.iter().any(|x| x.tie == Some(o)),
                jit: op.is_rematerialised_constant(),
            });
        }
        let mut ledges = Vec::new();
        let mut incident = vec![Vec::new(); n];
        for e in edges {
            let (a, b) = (local[e.from], local[e.to]);
            if a == usize::MAX || b == usize::MAX {
                continue;
            }
            incident[a].push(ledges.len());
            if b != a {
                incident[b].push(ledges.len());
            }
            ledges.push((a, b, e.latency, e.distance));
        }
        let mut readers = vec![Vec::new(); n];
        let mut read_index = vec![Vec::new(); n];
        for (u, op) in lops.iter().enumerate() {
            for (i, &(src, _)) in op.args.iter().enumerate() {
                if let Src::Loop { op: x, .. } = src {
                    read_index[u].push((i, x, readers[x].len()));
                    readers[x].push((u, i));
                }
            }
        }
        let reads_itself = (0..n)
            .map(|u| read_index[u].iter().any(|&(_, x, _)| x == u))
            .collect();
        let mut cap: Vec<i32> = slots
            .shape
            .lrf_sizes
            .iter()
            .map(|&c| c as i32 - LRF_MARGIN)
            .collect();
        cap.push(slots.shape.condition_codes as i32);
        // A class whose ops have two latencies issues them by a plan, so that its result
        // ports cannot clash.
        let mut rows = vec![Vec::new(); slots.shape.fu_count()];
        for class in [UnitClass::Adder, UnitClass::Multiplier] {
            let mut by_latency: std::collections::BTreeMap<i64, usize> = Default::default();
            for op in &lops {
                if matches!(op.kind, Kind::Fu(x) if x.unit() == class) {
                    *by_latency.entry(op.lat).or_default() += 1;
                }
            }
            let (2, Some((&s, &ns)), Some((&l, &nl))) = (
                by_latency.len(),
                by_latency.first_key_value(),
                by_latency.last_key_value(),
            ) else {
                continue;
            };
            let units = slots.fu_slots(class);
            let plan = latency_plan(units.len(), ii, (s, ns), (l, nl))?;
            for (k, unit_rows) in units.zip(plan) {
                rows[k] = unit_rows;
            }
        }
        Some(Problem {
            ii,
            circle: circle::Circle::new(ii),
            reach,
            ops: lops,
            edges: ledges,
            incident,
            readers,
            read_index,
            reads_itself,
            res: Resources::new(slots),
            nloc: slots.lrfs() + 1,
            earlier: earlier.len(),
            cap,
            rows,
        })
    }
}

impl Problem {
    /// The issue slot op `u` holds at cycle `t` on `slot` (as an index into the usage
    /// table), if it holds exactly one.
    fn primary(&self, u: usize, t: i64, slot: usize) -> Option<usize> {
        let op = &self.ops[u];
        let r = match op.kind {
            Kind::Fu(_) if op.issue == 1 => self.res.issue(slot),
            Kind::SpRead { .. } | Kind::SpWrite { .. } => self.res.sp(slot),
            Kind::Comm(_) => self.res.comm(slot),
            Kind::Imm(_) => self.res.imm(),
            _ => return None,
        };
        Some(self.row(t) * self.res.per_row + r)
    }

    /// Whether op `u` may issue at cycle `t` on `slot` under the latency plan.
    fn allowed(&self, u: usize, t: i64, slot: usize) -> bool {
        let op = &self.ops[u];
        if !matches!(op.kind, Kind::Fu(_)) {
            return true;
        }
        match self.rows[slot].get(self.row(t)) {
            None => true,
            Some(Row::Latency(l)) => *l == op.lat,
            Some(Row::Empty) => false,
        }
    }

    fn loc_index(&self, l: Loc) -> usize {
        match l {
            Loc::Lrf(x) => x as usize,
            Loc::Cc => self.nloc - 1,
        }
    }
    /// Where op `u`, on `slot` with operands swapped or not, reads argument `i`.
    fn arg_loc(&self, u: usize, i: usize, slot: usize, swap: bool) -> Loc {
        let op = &self.ops[u];
        op.arg_locs[(slot * 2 + usize::from(swap)) * op.args.len() + i]
    }
    fn row(&self, t: i64) -> usize {
        self.circle.row(t)
    }
    /// Whether op `u` may issue at cycle `t`: its row is a multiple of its alignment.
    fn aligned(&self, u: usize, t: i64) -> bool {
        self.ops[u]
            .align
            .is_none_or(|k| self.row(t) as i64 % k == 0)
    }
}

/// The search state: every op's place and the tallies the cost is made of.
struct State<'p> {
    p: &'p Problem,
    placed: Vec<bool>,
    t: Vec<i64>,
    slot: Vec<usize>,
    swap: Vec<bool>,
    usage: Vec<i32>,
    /// The ops holding each issue slot (FU, scratchpad, comm, immediate) per row.
    holders: Vec<Vec<usize>>,
    /// The ops using each resource per row.
    users: Vec<Vec<usize>>,
    /// Per value: its destinations and how many placed readers read each (seeded ones
    /// count for ever).
    dests: Vec<Vec<(Loc, u32)>>,
    /// Values live per location and row.
    live: Vec<Vec<i32>>,
    /// Entries held for the whole loop per location.
    kept: Vec<i32>,
    /// Readers per (earlier value, location).
    kept_pairs: Vec<u32>,
    /// Per value, for each of its `readers`: where and when it reads the value, if placed
    /// (what [`Self::live_end`] asks most often, side by side).
    reads: Vec<Vec<(Option<Loc>, i64)>>,
    /// Ejection chains searched so far, and per op the last search that reached it and
    /// the move that displaced it there (see [`Self::search_chain`]).
    chain_search: u32,
    chain_seen: Vec<u32>,
    chain_parent: Vec<Move>,
    /// The operands' lifetimes before a move, and which of them are still there after
    /// (kept between moves so that a move allocates nothing).
    lifetimes_before: Vec<Lifetime>,
    lifetime_matched: Vec<bool>,
    /// Scratch of [`Self::attach_cost`].
    probe: probe::Probe,
    /// Scratch of [`Self::around`], [`Self::search_chain`] and [`Self::window`].
    around: Around,
    chain_scratch: ChainScratch,
    times: Vec<i64>,
    /// Weight of the waits against [`SCALE`].
    wait_weight: i64,
    over: i64,
    dest_over: i64,
    broken: i64,
    crowd: i64,
    wait: i64,
}

const SEEDED: u32 = 1 << 20;

/// The placed ops around an op being placed, as [`State::quick`] weighs them (kept in
/// [`State`] between moves, so that finding it allocates nothing).
#[derive(Default)]
struct Around {
    /// Per destination of the op: the last cycle a placed reader reads it there.
    last_reads: Vec<i64>,
    /// The last cycle a placed reader reads its value.
    last_reader: i64,
    /// The cycles it may issue at without breaking a dependence.
    window: (i64, i64),
    /// What its operands cost on each (slot, swap) choice: `[slot * 2 + swap]`.
    operand_ports: Vec<i64>,
}

/// The parts of [`State::quick`] that depend on the cycle only: resources and destinations
/// taken, dependences and lifetimes broken, waits.
#[derive(Clone, Copy)]
struct Quick {
    hard: i64,
    broken: i64,
    wait: i64,
}

/// An op's place: (op, cycle, slot, swap).
type Move = (usize, i64, usize, bool);

/// An op and the placed ops whose values it reads (see [`State::affected`]; the search
/// asks for them at every move, so they are kept off the heap).
type Affected = arrayvec::ArrayVec<usize, { 1 + MAX_ARGS }>;

/// The ops in the way of a move (see [`State::blockers_at`] and [`State::operand_blockers`]):
/// an ejection chain goes on only through a move that displaces at most one.
#[derive(Clone, Copy)]
enum Blockers {
    None,
    One(usize),
    Many,
}

impl Blockers {
    fn add(&mut self, op: usize) {
        *self = match *self {
            Blockers::None => Blockers::One(op),
            Blockers::One(x) if x == op => Blockers::One(x),
            _ => Blockers::Many,
        };
    }

    /// Those of both.
    fn and(mut self, other: Blockers) -> Blockers {
        match other {
            Blockers::None => {}
            Blockers::One(y) => self.add(y),
            Blockers::Many => self = Blockers::Many,
        }
        self
    }
}

/// Scratch of [`State::search_chain`]: its queue and each option's
/// [`State::operand_blockers`].
type ChainScratch = (std::collections::VecDeque<usize>, Vec<Option<Blockers>>);

/// A value's entry in a location and when its lifetime there ends (`None` for a value held
/// for the whole loop): (value, location, end).
type Lifetime = (usize, Loc, Option<i64>);

impl<'p> State<'p> {
    fn new(p: &'p Problem) -> Self {
        let n = p.ops.len();
        let rows = p.ii as usize;
        let mut dests: Vec<Vec<(Loc, u32)>> = vec![Vec::new(); n];
        for (u, op) in p.ops.iter().enumerate() {
            for &l in &op.seeded {
                dests[u].push((l, SEEDED));
            }
        }
        let mut s = State {
            p,
            placed: vec![false; n],
            t: vec![0; n],
            slot: p.ops.iter().map(|o| o.options[0].0).collect(),
            swap: vec![false; n],
            usage: vec![0; rows * p.res.per_row],
            holders: vec![Vec::new(); rows * p.res.per_row],
            users: vec![Vec::new(); rows * p.res.per_row],
            dests,
            live: vec![vec![0; rows]; p.nloc],
            kept: vec![0; p.nloc],
            kept_pairs: vec![0; p.earlier * p.nloc],
            reads: p.readers.iter().map(|r| vec![(None, 0); r.len()]).collect(),
            chain_search: 0,
            chain_seen: vec![0; n],
            chain_parent: vec![(0, 0, 0, false); n],
            lifetimes_before: Vec::new(),
            lifetime_matched: Vec::new(),
            probe: probe::Probe::default(),
            around: Around::default(),
            chain_scratch: ChainScratch::default(),
            times: Vec::new(),
            wait_weight: SCALE,
            over: 0,
            dest_over: 0,
            broken: 0,
            crowd: 0,
            wait: 0,
        };
        // Seeded destinations of carried values are kept from the start.
        for u in 0..n {
            if p.ops[u].permanent {
                let locs: Vec<Loc> = s.dests[u].iter().map(|d| d.0).collect();
                for l in locs {
                    s.add_kept(l, 1);
                }
            }
        }
        s
    }

    fn cost(&self) -> i64 {
        SCALE * (HARD * (self.over + self.dest_over) + self.broken + CROWD * self.crowd)
            + self.wait_weight * self.wait
    }

    fn hard(&self) -> i64 {
        self.over + self.dest_over + self.broken
    }

    fn use_res(&mut self, row: usize, r: usize, d: i32, owner: usize) {
        let i = row * self.p.res.per_row + r;
        let cap = self.p.res.cap[r];
        if d > 0 {
            self.users[i].push(owner);
        } else if let Some(j) = self.users[i].iter().position(|&x| x == owner) {
            self.users[i].swap_remove(j);
        }
        if d > 0 {
            if self.usage[i] >= cap {
                self.over += 1;
            }
            self.usage[i] += 1;
        } else {
            self.usage[i] -= 1;
            if self.usage[i] >= cap {
                self.over -= 1;
            }
        }
    }

    fn add_kept(&mut self, l: Loc, d: i32) {
        let k = self.p.loc_index(l);
        let cap = self.p.cap[k];
        let before: i64 = self.live[k]
            .iter()
            .map(|&x| i64::from((x + self.kept[k] - cap).max(0)))
            .sum();
        self.kept[k] += d;
        let after: i64 = self.live[k]
            .iter()
            .map(|&x| i64::from((x + self.kept[k] - cap).max(0)))
            .sum();
        self.crowd += after - before;
    }

    /// Adds (`d` = 1) or removes (-1) value `x` live in location `k` over `[w, r)`.
    fn interval(&mut self, k: usize, w: i64, r: i64, d: i32) {
        let cap = self.p.cap[k] - self.kept[k];
        let live = &mut self.live[k];
        // (Counted, then updated, run by run: two plain passes the compiler vectorises.)
        let mut crowd = 0usize;
        for run in circle::cycles(w, r, self.p.ii) {
            let run = &mut live[run];
            if d > 0 {
                crowd += run.iter().filter(|&&x| x >= cap).count();
                run.iter_mut().for_each(|x| *x += 1);
            } else {
                crowd += run.iter().filter(|&&x| x > cap).count();
                run.iter_mut().for_each(|x| *x -= 1);
            }
        }
        self.crowd += i64::from(d) * crowd as i64;
        self.wait += i64::from(d) * (r - w);
    }

    fn pen(excess: i64) -> i64 {
        if excess > 0 { BROKEN + excess } else { 0 }
    }

    /// What op `u` at cycle `t` would add for the dependences with placed ops it breaks.
    fn dependences_broken(&self, u: usize, t: i64) -> i64 {
        let p = self.p;
        let mut broken = 0;
        for &e in &p.incident[u] {
            let (a, b, lat, dist) = p.edges[e];
            if a == b {
                continue;
            }
            let (ta, tb) = if a == u {
                if !self.placed[b] {
                    continue;
                }
                (t, self.t[b])
            } else {
                if !self.placed[a] {
                    continue;
                }
                (self.t[a], t)
            };
            broken += Self::pen(ta + lat - p.ii * i64::from(dist) - tb);
        }
        broken
    }

    /// The last cycle value `x` is read from `l` by a placed reader (at least the cycle
    /// after it lands).
    fn live_end(&self, x: usize, l: Loc, w: i64) -> i64 {
        let mut r = w + 1;
        for &(at, t) in &self.reads[x] {
            if at == Some(l) {
                r = r.max(t);
            }
        }
        r
    }

    /// Records where and when op `u` reads its loop operands (or that it does not, out of
    /// the schedule) in their values' [`State::reads`].
    fn note_reads(&mut self, u: usize) {
        let p = self.p;
        for &(i, x, j) in &p.read_index[u] {
            self.reads[x][j] = if self.placed[u] {
                (Some(p.arg_loc(u, i, self.slot[u], self.swap[u])), self.t[u])
            } else {
                (None, 0)
            };
        }
    }

    /// Adds or removes everything value `x` (placed) costs: its write ports, destinations
    /// beyond two, its entries' lifetimes, its readers' lifetime limits.
    fn value(&mut self, x: usize, d: i32) {
        self.value_but_lifetimes(x, d);
        let p = self.p;
        if !p.ops[x].permanent {
            let w = self.t[x] + p.ops[x].lat;
            for j in 0..self.dests[x].len() {
                let l = self.dests[x][j].0;
                let r = self.live_end(x, l, w);
                self.interval(p.loc_index(l), w, r, d);
            }
        }
    }

    /// The destinations of the placed operands of op `u` (`affected`, `u` excepted) and
    /// when each lifetime there ends, into `ends`.
    fn operand_lifetimes(&self, u: usize, affected: &[usize], ends: &mut Vec<Lifetime>) {
        let p = self.p;
        ends.clear();
        for &x in affected {
            if x == u || !self.placed[x] {
                continue;
            }
            let w = self.t[x] + p.ops[x].lat;
            for &(l, _) in &self.dests[x] {
                let end = (!p.ops[x].permanent).then(|| self.live_end(x, l, w));
                ends.push((x, l, end));
            }
        }
    }

    /// Adds (`d` = 1) or removes (-1) what op `u` (placed) adds to its operands' values:
    /// the lifetimes its reads break.
    fn operand_reads(&mut self, u: usize, d: i32) {
        let p = self.p;
        for &(src, _) in &p.ops[u].args {
            if let Src::Loop {
                op: x,
                carried: false,
            } = src
                && x != u
                && self.placed[x]
            {
                let w = self.t[x] + p.ops[x].lat;
                self.broken += i64::from(d) * Self::pen(self.t[u] - (w + p.reach));
            }
        }
    }

    /// Brings the write ports and destination counts of op `u`'s operands from `before`
    /// (see [`Self::operand_lifetimes`]) to their destinations now that `u` moved.
    fn update_operand_dests(&mut self, u: usize, affected: &[usize], before: &[Lifetime]) {
        let p = self.p;
        for &x in affected {
            if x == u || !self.placed[x] {
                continue;
            }
            let row = p.row(self.t[x] + p.ops[x].lat);
            let had = || before.iter().filter(move |e| e.0 == x).map(|e| e.1);
            let old = had().count() as i64;
            let new = self.dests[x].len() as i64;
            self.dest_over += (new - 2).max(0) - (old - 2).max(0);
            for l in had() {
                if let Loc::Lrf(lrf) = l
                    && !self.dests[x].iter().any(|e| e.0 == l)
                {
                    self.use_res(row, p.res.port(lrf), -1, x);
                }
            }
            for j in 0..self.dests[x].len() {
                let l = self.dests[x][j].0;
                if let Loc::Lrf(lrf) = l
                    && !had().any(|m| m == l)
                {
                    self.use_res(row, p.res.port(lrf), 1, x);
                }
            }
        }
    }

    /// Brings the lifetimes of op `u`'s operands from `before` (see
    /// [`Self::operand_lifetimes`]) to what they are now that `u` moved: only the cycles
    /// between the old and the new end change (an operand's landing stays), so a long
    /// lifetime costs no more than a short one.
    fn update_operand_lifetimes(&mut self, u: usize, affected: &[usize], before: &[Lifetime]) {
        let p = self.p;
        let mut matched = std::mem::take(&mut self.lifetime_matched);
        matched.clear();
        matched.resize(before.len(), false);
        for &x in affected {
            if x == u || !self.placed[x] || p.ops[x].permanent {
                continue;
            }
            let w = self.t[x] + p.ops[x].lat;
            for j in 0..self.dests[x].len() {
                let l = self.dests[x][j].0;
                let k = p.loc_index(l);
                let r = self.live_end(x, l, w);
                match before.iter().position(|&(y, m, _)| (y, m) == (x, l)) {
                    Some(i) => {
                        matched[i] = true;
                        let old = before[i].2.expect("a value not held for the loop");
                        if r > old {
                            self.interval(k, old, r, 1);
                        } else if r < old {
                            self.interval(k, r, old, -1);
                        }
                    }
                    None => self.interval(k, w, r, 1),
                }
            }
        }
        for (i, &(x, l, end)) in before.iter().enumerate() {
            if let (false, Some(r)) = (matched[i], end) {
                let w = self.t[x] + p.ops[x].lat;
                self.interval(p.loc_index(l), w, r, -1);
            }
        }
        self.lifetime_matched = matched;
    }

    /// [`Self::value`] but for the lifetimes of its entries.
    fn value_but_lifetimes(&mut self, x: usize, d: i32) {
        let p = self.p;
        let op = &p.ops[x];
        let w = self.t[x] + op.lat;
        let row = p.row(w);
        let n = self.dests[x].len() as i64;
        self.dest_over += i64::from(d) * (n - 2).max(0);
        for j in 0..self.dests[x].len() {
            if let Loc::Lrf(lrf) = self.dests[x][j].0 {
                self.use_res(row, p.res.port(lrf), d, x);
            }
        }
        for j in 0..p.readers[x].len() {
            let (u, i) = p.readers[x][j];
            if self.placed[u] && matches!(p.ops[u].args[i].0, Src::Loop { carried: false, .. }) {
                let e = Self::pen(self.t[u] - (w + p.reach));
                self.broken += i64::from(d) * e;
            }
        }
    }

    /// Adds or removes op `u`'s own resources, dependences and reads.
    fn op(&mut self, u: usize, d: i32) {
        let p = self.p;
        let op = &p.ops[u];
        let (t, k, s) = (self.t[u], self.slot[u], self.swap[u]);
        let res = &p.res;
        if let Some(i) = p.primary(u, t, k) {
            if d > 0 {
                self.holders[i].push(u);
            } else {
                self.holders[i].retain(|&x| x != u);
            }
        }
        match op.kind {
            Kind::Fu(_) => {
                for c in 0..op.issue.min(p.ii) {
                    self.use_res(p.row(t + c), res.issue(k), d, u);
                }
                self.use_res(p.row(t + op.lat), res.result(k), d, u);
            }
            Kind::SpRead { .. } | Kind::SpWrite { .. } => self.use_res(p.row(t), res.sp(k), d, u),
            Kind::Comm(_) => self.use_res(p.row(t), res.comm(k), d, u),
            Kind::StreamIn { .. } => self.use_res(p.row(t), res.words(), d, u),
            Kind::StreamOut { .. } => {
                self.use_res(p.row(t), res.words(), d, u);
                self.use_res(p.row(t), res.sout(), d, u);
            }
            Kind::Imm(_) => self.use_res(p.row(t), res.imm(), d, u),
        }
        for &e in &p.incident[u] {
            let (a, b, lat, dist) = p.edges[e];
            if a == b || !self.placed[a] || !self.placed[b] {
                continue;
            }
            let excess = self.t[a] + lat - p.ii * i64::from(dist) - self.t[b];
            self.broken += i64::from(d) * Self::pen(excess);
        }
        for i in 0..op.args.len() {
            let l = p.arg_loc(u, i, k, s);
            match op.args[i].0 {
                Src::Loop { op: x, .. } => {
                    let ds = &mut self.dests[x];
                    if d > 0 {
                        match ds.iter_mut().find(|e| e.0 == l) {
                            Some(e) => e.1 += 1,
                            None => ds.push((l, 1)),
                        }
                    } else {
                        let j = ds.iter().position(|e| e.0 == l).expect("read counted");
                        ds[j].1 -= 1;
                        if ds[j].1 == 0 {
                            ds.remove(j);
                        }
                    }
                    // (A carried value's entries are held for the whole loop.)
                    if p.ops[x].permanent {
                        let has = self.dests[x].iter().any(|e| e.0 == l);
                        let n = self.dests[x].iter().find(|e| e.0 == l).map_or(0, |e| e.1);
                        if d > 0 && n == 1 {
                            self.add_kept(l, 1);
                        } else if d < 0 && !has {
                            self.add_kept(l, -1);
                        }
                    }
                }
                Src::Earlier(x) => {
                    let c = &mut self.kept_pairs[x * p.nloc + p.loc_index(l)];
                    if d > 0 {
                        *c += 1;
                        if *c == 1 {
                            self.add_kept(l, 1);
                        }
                    } else {
                        *c -= 1;
                        if *c == 0 {
                            self.add_kept(l, -1);
                        }
                    }
                }
            }
        }
    }

    /// A greedy start: ops in priority order once their operands are placed, each where
    /// it costs least within an interval of its earliest cycle, a rematerialised constant
    /// just before its reader. Returns whether every op found a place.
    fn start(&mut self, priority: &[i64]) -> bool {
        let p = self.p;
        let (n, ii) = (p.ops.len(), p.ii);
        let mut indeg = vec![0usize; n];
        let mut succ: Vec<Vec<usize>> = vec![Vec::new(); n];
        for &(a, b, _, dist) in &p.edges {
            if dist == 0 && a != b && !p.ops[a].jit {
                indeg[b] += 1;
                succ[a].push(b);
            }
        }
        let mut heap: std::collections::BinaryHeap<(i64, std::cmp::Reverse<usize>)> = (0..n)
            .filter(|&u| indeg[u] == 0 && !p.ops[u].jit)
            .map(|u| (priority[u], std::cmp::Reverse(u)))
            .collect();
        while let Some((_, std::cmp::Reverse(u))) = heap.pop() {
            let mut earliest = 0;
            for &e in &p.incident[u] {
                let (a, b, lat, dist) = p.edges[e];
                if b == u && a != u && self.placed[a] {
                    earliest = earliest.max(self.t[a] + lat - ii * i64::from(dist));
                }
            }
            if !self.place_best(u, earliest..earliest + ii) {
                return false;
            }
            let t = self.t[u];
            for &e in &p.incident[u] {
                let (a, b, lat, _) = p.edges[e];
                if b == u
                    && p.ops[a].jit
                    && !self.placed[a]
                    && !self.place_best(a, (t - lat - CONSTANT_LEAD..=t - lat).rev())
                {
                    return false;
                }
            }
            for &v in &succ[u] {
                indeg[v] -= 1;
                if indeg[v] == 0 {
                    heap.push((priority[v], std::cmp::Reverse(v)));
                }
            }
        }
        self.placed.iter().all(|&x| x)
    }

    /// Places op `u` (out of the schedule) where it costs least at one of `times`.
    /// Returns whether it found an allowed place.
    fn place_best(&mut self, u: usize, times: impl Iterator<Item = i64>) -> bool {
        let p = self.p;
        let mut best: Option<(i64, i64, usize, bool)> = None;
        let around = self.around(u);
        for t in times {
            if !p.aligned(u, t) {
                continue;
            }
            let at = self.quick_at(u, &around, t);
            for &(k, s) in &p.ops[u].options {
                if !p.allowed(u, t, k) {
                    continue;
                }
                let c = self.quick(u, &around, at, t, k, s);
                if best.is_none_or(|b| c < b.0) {
                    best = Some((c, t, k, s));
                }
            }
        }
        self.around = around;
        let Some((_, t, k, s)) = best else {
            return false;
        };
        let aff = self.affected(u);
        self.attach(u, t, k, s, &aff);
        true
    }

    /// Whether nothing is broken and every LRF holds its values at every row.
    fn solved(&self) -> bool {
        self.hard() == 0 && self.crowd == 0
    }

    /// For the broken dependence `e`: pushes its reader later (`forward`) or pulls its
    /// writer earlier to where it holds, and so on for what that breaks. Returns the
    /// places the moved ops left.
    fn push_apart(&mut self, e: usize, forward: bool) -> Vec<Move> {
        let (a, b, lat, dist) = self.p.edges[e];
        let shift = lat - self.p.ii * i64::from(dist);
        let mut log = Vec::new();
        let mut budget = PUSH_LIMIT;
        if forward {
            self.push(b, self.t[a] + shift, true, &mut budget, &mut log);
        } else {
            self.push(a, self.t[b] - shift, false, &mut budget, &mut log);
        }
        log
    }

    /// The placed values whose costs depend on op `u`'s place: its own and its operands'.
    fn affected(&self, u: usize) -> Affected {
        let mut v = Affected::new();
        v.push(u);
        for &(src, _) in &self.p.ops[u].args {
            if let Src::Loop { op: x, .. } = src
                && !v.contains(&x)
                && self.placed[x]
            {
                v.push(x);
            }
        }
        v
    }

    /// Moves op `u` to cycle `at` or later (`forward`) or earlier, to its cheapest place
    /// within [`PUSH_SLACK`] cycles, then its successors (predecessors) whose dependences that
    /// breaks, recursively, at most `budget` ops in all. Records each op's old place in
    /// `log`.
    fn push(
        &mut self,
        u: usize,
        at: i64,
        forward: bool,
        budget: &mut usize,
        log: &mut Vec<(usize, i64, usize, bool)>,
    ) {
        if *budget == 0 {
            return;
        }
        *budget -= 1;
        let p = self.p;
        let aff = self.affected(u);
        log.push((u, self.t[u], self.slot[u], self.swap[u]));
        self.detach(u, &aff);
        let mut best: Option<(i64, i64, usize, bool)> = None;
        let around = self.around(u);
        for d in 0..=PUSH_SLACK {
            let t = if forward { at + d } else { at - d };
            let at_t = self.quick_at(u, &around, t);
            for &(k, s) in &p.ops[u].options {
                if !p.allowed(u, t, k) || !p.aligned(u, t) {
                    continue;
                }
                let c = self.quick(u, &around, at_t, t, k, s);
                if best.is_none_or(|b| c < b.0) {
                    best = Some((c, t, k, s));
                }
            }
        }
        self.around = around;
        let (t, k, s) = match best {
            Some((_, t, k, s)) => (t, k, s),
            None => (at, self.slot[u], self.swap[u]),
        };
        self.attach(u, t, k, s, &aff);
        for &e in &p.incident[u] {
            let (a, b, lat, dist) = p.edges[e];
            if a == b {
                continue;
            }
            let shift = lat - p.ii * i64::from(dist);
            if forward && a == u && self.t[b] < t + shift {
                self.push(b, t + shift, true, budget, log);
            }
            if !forward && b == u && self.t[a] > t - shift {
                self.push(a, t - shift, false, budget, log);
            }
        }
    }

    /// Puts back the places `log` recorded (last first).
    fn restore(&mut self, log: &[(usize, i64, usize, bool)]) {
        for &(x, t, k, s) in log.iter().rev() {
            let aff = self.affected(x);
            self.detach(x, &aff);
            self.attach(x, t, k, s, &aff);
        }
    }

    /// Whether op `u` breaks something: shares a slot or port, or breaks a dependence or
    /// lifetime.
    fn troubled_op(&self, u: usize) -> bool {
        let p = self.p;
        let res = &p.res;
        let op = &p.ops[u];
        let over = |row: usize, r: usize| self.usage[row * res.per_row + r] > res.cap[r];
        let (t, k) = (self.t[u], self.slot[u]);
        if let Some(i) = p.primary(u, t, k)
            && self.holders[i].len() > 1
        {
            return true;
        }
        if matches!(op.kind, Kind::Fu(_)) && over(p.row(t + op.lat), res.result(k)) {
            return true;
        }
        let w = t + op.lat;
        for &(l, _) in &self.dests[u] {
            if let Loc::Lrf(x) = l
                && over(p.row(w), res.port(x))
            {
                return true;
            }
        }
        p.incident[u].iter().any(|&e| {
            let (a, b, lat, dist) = p.edges[e];
            a != b && self.t[a] + lat - p.ii * i64::from(dist) > self.t[b]
        })
    }

    /// Takes op `u` out of the schedule.
    fn detach(&mut self, u: usize, affected: &[usize]) {
        // (Of its operands' values only what `u` reads changes.)
        let mut before = std::mem::take(&mut self.lifetimes_before);
        self.operand_lifetimes(u, affected, &mut before);
        self.value(u, -1);
        self.operand_reads(u, -1);
        self.op(u, -1);
        self.placed[u] = false;
        self.note_reads(u);
        self.update_operand_dests(u, affected, &before);
        self.update_operand_lifetimes(u, affected, &before);
        self.lifetimes_before = before;
    }

    /// Puts op `u` (out of the schedule) at cycle `t` on `slot`.
    fn attach(&mut self, u: usize, t: i64, slot: usize, swap: bool, affected: &[usize]) {
        let mut before = std::mem::take(&mut self.lifetimes_before);
        self.operand_lifetimes(u, affected, &mut before);
        self.t[u] = t;
        self.slot[u] = slot;
        self.swap[u] = swap;
        self.placed[u] = true;
        self.note_reads(u);
        self.op(u, 1);
        self.value(u, 1);
        self.operand_reads(u, 1);
        self.update_operand_dests(u, affected, &before);
        self.update_operand_lifetimes(u, affected, &before);
        self.lifetimes_before = before;
    }

    /// What [`Self::quick`] needs to know of the placed ops around op `u` (out of the
    /// schedule), which stay put while `u` is tried at many places. It is taken out of the
    /// state's scratch: put it back when done.
    fn around(&mut self, u: usize) -> Around {
        let p = self.p;
        let mut around = std::mem::take(&mut self.around);
        // (`live_end` for a landing before every read: the last read.)
        around.last_reads.clear();
        around.last_reads.extend(
            self.dests[u]
                .iter()
                .map(|&(l, _)| self.live_end(u, l, i64::MIN + 1)),
        );
        around.last_reader = p.readers[u]
            .iter()
            .filter(|&&(r, _)| self.placed[r])
            .map(|&(r, _)| self.t[r])
            .max()
            .unwrap_or(i64::MIN);
        around.window = self.dependence_window(u);
        self.operand_ports(u, &mut around.operand_ports);
        around
    }

    /// A quick estimate of what op `u` (out of the schedule, with `around` it) would cost
    /// at `(t, slot, swap)`, `at` being [`Self::quick_at`] `t`: its own resources and
    /// dependences, new destinations for its operands, and the waits it makes.
    fn quick(&self, u: usize, around: &Around, at: Quick, t: i64, slot: usize, swap: bool) -> i64 {
        let taken = self.issue_taken(u, self.p.row(t), slot);
        self.quick_taken(around, at, taken, slot, swap)
    }

    /// The least [`Self::quick_taken`] can be with `at`: no issue slot, result port or
    /// operand's write port taken.
    fn quick_least(&self, at: Quick) -> i64 {
        SCALE * (HARD * at.hard + at.broken) + self.wait_weight * at.wait
    }

    /// [`Self::quick`] with the issue slots and result ports taken on `slot` counted already
    /// ([`Self::issue_taken`]).
    fn quick_taken(&self, around: &Around, at: Quick, taken: i64, slot: usize, swap: bool) -> i64 {
        let hard = at.hard + taken + around.operand_ports[slot * 2 + usize::from(swap)];
        SCALE * (HARD * hard + at.broken) + self.wait_weight * at.wait
    }

    /// The issue slots and result ports op `u` would find taken issuing at `row` (the row
    /// of its cycle, which the caller finds once for every slot) on `slot`.
    fn issue_taken(&self, u: usize, row: usize, slot: usize) -> i64 {
        let p = self.p;
        let op = &p.ops[u];
        let res = &p.res;
        let taken = |row: usize, r: usize| self.usage[row * res.per_row + r] >= res.cap[r];
        // (Rows after `row` are found from it: a compare, not a division, within the table.)
        let after = |d: i64| p.row(row as i64 + d);
        let mut hard = 0;
        match op.kind {
            Kind::Fu(_) => {
                for c in 0..op.issue.min(p.ii) {
                    hard += i64::from(taken(after(c), res.issue(slot)));
                }
                hard += i64::from(taken(after(op.lat), res.result(slot)));
            }
            Kind::SpRead { .. } | Kind::SpWrite { .. } => {
                hard += i64::from(taken(row, res.sp(slot)))
            }
            Kind::Comm(_) => hard += i64::from(taken(row, res.comm(slot))),
            Kind::StreamIn { .. } => hard += i64::from(taken(row, res.words())),
            Kind::StreamOut { .. } => {
                hard += i64::from(taken(row, res.words()));
                hard += i64::from(taken(row, res.sout()));
            }
            Kind::Imm(_) => hard += i64::from(taken(row, res.imm())),
        }
        hard
    }

    /// What op `u`'s operands would cost on each (slot, swap) choice, wherever it goes:
    /// new destinations, whose write ports may be taken, beyond two.
    fn operand_ports(&self, u: usize, costs: &mut Vec<i64>) {
        let p = self.p;
        let op = &p.ops[u];
        let res = &p.res;
        let taken = |row: usize, r: usize| self.usage[row * res.per_row + r] >= res.cap[r];
        let choices = op.options.iter().map(|&(k, _)| k + 1).max().unwrap_or(1) * 2;
        costs.clear();
        costs.resize(choices, 0);
        for &(slot, swap) in &op.options {
            let mut hard = 0;
            for (i, &(src, _)) in op.args.iter().enumerate() {
                let Src::Loop { op: x, .. } = src else {
                    continue;
                };
                if !self.placed[x] {
                    continue;
                }
                let l = p.arg_loc(u, i, slot, swap);
                let wx = self.t[x] + p.ops[x].lat;
                if !self.dests[x].iter().any(|e| e.0 == l) {
                    if let Loc::Lrf(lrf) = l {
                        hard += i64::from(taken(p.row(wx), res.port(lrf)));
                    }
                    hard += i64::from(self.dests[x].len() >= 2);
                }
            }
            costs[slot * 2 + usize::from(swap)] = hard;
        }
    }

    /// What op `u` (with `around` it) would cost at cycle `t` on any slot: its result's
    /// write ports and waits, its readers' and operands' lifetimes, its dependences.
    fn quick_at(&self, u: usize, around: &Around, t: i64) -> Quick {
        let p = self.p;
        let op = &p.ops[u];
        let res = &p.res;
        let taken = |row: usize, r: usize| self.usage[row * res.per_row + r] >= res.cap[r];
        let mut hard = 0;
        let land = p.row(t + op.lat);
        let mut wait = 0;
        let mut broken = 0;
        for (&(l, _), &last) in self.dests[u].iter().zip(&around.last_reads) {
            if let Loc::Lrf(x) = l {
                hard += i64::from(taken(land, res.port(x)));
            }
            if !op.permanent {
                // (As `live_end`: at least the cycle after it lands.)
                wait += last.max(t + op.lat + 1) - (t + op.lat);
            }
        }
        // (No reader too late, no lifetime broken.)
        if around.last_reader > t + op.lat + p.reach {
            for &(r, _) in &p.readers[u] {
                if self.placed[r] {
                    broken += Self::pen(self.t[r] - (t + op.lat + p.reach));
                }
            }
        }
        for &(src, _) in &op.args {
            let Src::Loop { op: x, carried } = src else {
                continue;
            };
            if !self.placed[x] || carried {
                continue;
            }
            let wx = self.t[x] + p.ops[x].lat;
            broken += Self::pen(t - (wx + p.reach));
            wait += (t - wx).max(0);
        }
        // (Within its dependence window no dependence is broken.)
        if !(around.window.0..=around.window.1).contains(&t) {
            broken += self.dependences_broken(u, t);
        }
        Quick { hard, broken, wait }
    }

    /// The cycles op `u` may move to without breaking a dependence on its placed
    /// neighbours, at most `span` from where it is.
    fn free_window(&self, u: usize, span: i64) -> (i64, i64) {
        let (lo, hi) = self.dependence_window(u);
        (lo.max(self.t[u] - span), hi.min(self.t[u] + span))
    }

    /// The cycles op `u` may issue at without breaking a dependence on its placed
    /// neighbours (`i64::MIN` / `i64::MAX` where none bounds it).
    fn dependence_window(&self, u: usize) -> (i64, i64) {
        let p = self.p;
        let mut lo = i64::MIN;
        let mut hi = i64::MAX;
        for &e in &p.incident[u] {
            let (a, b, lat, dist) = p.edges[e];
            if a == b {
                continue;
            }
            let shift = lat - p.ii * i64::from(dist);
            if b == u && self.placed[a] {
                lo = lo.max(self.t[a] + shift);
            }
            if a == u && self.placed[b] {
                hi = hi.min(self.t[b] - shift);
            }
        }
        (lo, hi)
    }

    /// The ops in the way of op `u` at cycle `t` on `slot`: the holders of the issue slot,
    /// result port and write ports it would need (its own where it already holds them
    /// excepted). `None` if something in the way cannot be cleared by moving one op (a
    /// resource over-full already). With [`Self::operand_blockers`] of the same slot and a
    /// swap ([`Blockers::and`]), what is in the way of the move.
    fn blockers_at(&self, u: usize, t: i64, slot: usize) -> Option<Blockers> {
        let p = self.p;
        let op = &p.ops[u];
        let res = &p.res;
        let mut found = Blockers::None;
        let need = |row: usize, r: usize, found: &mut Blockers| self.room(u, row, r, found);
        let ok = match op.kind {
            Kind::Fu(_) if op.issue != 1 => return None,
            Kind::Fu(_) => {
                need(p.row(t), res.issue(slot), &mut found)
                    && need(p.row(t + op.lat), res.result(slot), &mut found)
            }
            Kind::SpRead { .. } | Kind::SpWrite { .. } => need(p.row(t), res.sp(slot), &mut found),
            Kind::Comm(_) => need(p.row(t), res.comm(slot), &mut found),
            Kind::Imm(_) => need(p.row(t), res.imm(), &mut found),
            Kind::StreamIn { .. } => need(p.row(t), res.words(), &mut found),
            Kind::StreamOut { .. } => {
                need(p.row(t), res.words(), &mut found) && need(p.row(t), res.sout(), &mut found)
            }
        };
        if !ok {
            return None;
        }
        let w = p.row(t + op.lat);
        for &(l, _) in &self.dests[u] {
            if let Loc::Lrf(x) = l
                && !need(w, res.port(x), &mut found)
            {
                return None;
            }
        }
        Some(found)
    }

    /// Whether op `u` fits resource `r` in `row`: there is room, or the one other op holding
    /// a single-unit resource (added to `found`) could move away.
    // (Inlined: the local search asks it for every resource of every cycle it tries.)
    #[inline(always)]
    fn room(&self, u: usize, row: usize, r: usize, found: &mut Blockers) -> bool {
        let res = &self.p.res;
        let i = row * res.per_row + r;
        let mut others = self.users[i].iter().copied().filter(|&x| x != u);
        let count = others.clone().count() as i32;
        if count < res.cap[r] {
            return true;
        }
        if count > res.cap[r] || res.cap[r] != 1 {
            return false;
        }
        found.add(others.next().expect("one other user"));
        true
    }

    /// The ops in the way of op `u` reading its operands on `(slot, swap)`, wherever it
    /// issues: the holders of the write ports of the new destinations its operands would
    /// need. `None` if a value would need a third destination, or a port is over-full.
    fn operand_blockers(&self, u: usize, slot: usize, swap: bool) -> Option<Blockers> {
        let p = self.p;
        let op = &p.ops[u];
        let res = &p.res;
        let mut found = Blockers::None;
        for (i, &(src, _)) in op.args.iter().enumerate() {
            let Src::Loop { op: x, .. } = src else {
                continue;
            };
            if !self.placed[x] {
                continue;
            }
            let l = p.arg_loc(u, i, slot, swap);
            let ds = &self.dests[x];
            if ds.iter().any(|e| e.0 == l) {
                continue;
            }
            // (A destination only `u` reads from goes when it moves.)
            let mine = if self.placed[u] {
                let cur = p.arg_loc(u, i, self.slot[u], self.swap[u]);
                ds.iter().filter(|e| e.0 == cur && e.1 == 1).count()
            } else {
                0
            };
            if ds.len() - mine >= 2 {
                return None;
            }
            if let Loc::Lrf(lrf) = l {
                let row = p.row(self.t[x] + p.ops[x].lat);
                let i = row * res.per_row + res.port(lrf);
                let mut others = self.users[i].iter().copied().filter(|&y| y != x);
                match (others.next(), others.next()) {
                    (None, _) => {}
                    (Some(y), None) if y != u => found.add(y),
                    _ => return None,
                }
            }
        }
        Some(found)
    }

    /// An ejection chain for op `u`: a shortest sequence of moves, each op to a place within
    /// its dependence window where at most one op is in its way, which moves next, ending
    /// with an op that finds a place nobody holds (breadth-first, as an augmenting path of
    /// a matching). Returns the moves, last first.
    fn chain(&mut self, u: usize) -> Option<Vec<Move>> {
        self.search_chain(u, &|_, _, _| true)
    }

    /// A breadth-first ejection chain from op `u`, whose own move must satisfy `first`.
    fn search_chain(
        &mut self,
        u: usize,
        first: &dyn Fn(i64, usize, bool) -> bool,
    ) -> Option<Vec<Move>> {
        // (Ops this search has seen carry its number, so the marks need no clearing.)
        self.chain_search += 1;
        self.chain_seen[u] = self.chain_search;
        let mut scratch = std::mem::take(&mut self.chain_scratch);
        scratch.0.clear();
        scratch.0.push_back(u);
        let found = self.chain_from(u, first, &mut scratch);
        self.chain_scratch = scratch;
        found
    }

    /// [`Self::search_chain`] with its queue and a place for each op's
    /// [`Self::operand_blockers`] per option.
    fn chain_from(
        &mut self,
        u: usize,
        first: &dyn Fn(i64, usize, bool) -> bool,
        (queue, operands): &mut ChainScratch,
    ) -> Option<Vec<Move>> {
        let p = self.p;
        let search = self.chain_search;
        let mut visited = 0;
        while let Some(x) = queue.pop_front() {
            visited += 1;
            if visited > CHAIN_LIMIT {
                return None;
            }
            // (What is in the way of a move is what is in the way of its place and of its
            // operands' destinations, which do not depend on its cycle: found once.)
            let options = &p.ops[x].options;
            operands.clear();
            operands.extend(options.iter().map(|&(k, s)| self.operand_blockers(x, k, s)));
            let (lo, hi) = self.free_window(x, CHAIN_SPAN);
            for t in nearest_first(self.t[x], lo, hi) {
                // (The options of a slot come together.)
                let mut at: Option<(usize, Option<Blockers>)> = None;
                for (&(k, s), &of_operands) in options.iter().zip(operands.iter()) {
                    if !p.allowed(x, t, k) || (t, k, s) == (self.t[x], self.slot[x], self.swap[x]) {
                        continue;
                    }
                    if x == u && !first(t, k, s) {
                        continue;
                    }
                    let of_place = match at {
                        Some((slot, b)) if slot == k => b,
                        _ => self.blockers_at(x, t, k),
                    };
                    at = Some((k, of_place));
                    let Some(blocking) = of_place.zip(of_operands).map(|(a, b)| a.and(b)) else {
                        continue;
                    };
                    match blocking {
                        Blockers::None => {
                            let mut moves = vec![(x, t, k, s)];
                            let mut y = x;
                            while y != u {
                                let m = self.chain_parent[y];
                                moves.push(m);
                                y = m.0;
                            }
                            return Some(moves);
                        }
                        Blockers::One(y) if self.chain_seen[y] != search => {
                            self.chain_seen[y] = search;
                            self.chain_parent[y] = (x, t, k, s);
                            queue.push_back(y);
                        }
                        _ => {}
                    }
                }
            }
        }
        None
    }

    /// For a value `x` read from more than two places: ejection chains that move every
    /// reader of one of its places (the least read first) to the others. Makes the moves
    /// and returns the places they left, or `None` with nothing moved.
    fn fewer_dests(&mut self, x: usize) -> Option<Vec<Move>> {
        let p = self.p;
        let mut places: Vec<(u32, Loc)> = self.dests[x]
            .iter()
            .filter(|e| e.1 < SEEDED)
            .map(|e| (e.1, e.0))
            .collect();
        places.sort_unstable();
        for (_, dropped) in places {
            // Each kept place and the last cycle it is read at: a reader moved there no
            // later keeps the value there no longer.
            let keep: Vec<(Loc, i64)> = self.dests[x]
                .iter()
                .filter(|e| e.0 != dropped)
                .map(|e| {
                    let last = p.readers[x]
                        .iter()
                        .filter(|&&(r, i)| p.arg_loc(r, i, self.slot[r], self.swap[r]) == e.0)
                        .map(|&(r, _)| self.t[r])
                        .max()
                        .unwrap_or(i64::MIN);
                    (e.0, last)
                })
                .collect();
            let mut log = Vec::new();
            for &(r, i) in &p.readers[x] {
                if p.arg_loc(r, i, self.slot[r], self.swap[r]) != dropped {
                    continue;
                }
                let within = |t: i64, k: usize, s: bool| {
                    let l = p.arg_loc(r, i, k, s);
                    keep.iter().any(|&(kl, last)| kl == l && t <= last)
                };
                let anywhere = |_t: i64, k: usize, s: bool| {
                    let l = p.arg_loc(r, i, k, s);
                    keep.iter().any(|&(kl, _)| kl == l)
                };
                let Some(moves) = self
                    .search_chain(r, &within)
                    .or_else(|| self.search_chain(r, &anywhere))
                else {
                    break;
                };
                self.make(&moves, &mut log);
            }
            if self.dests[x].len() <= 2 {
                return Some(log);
            }
            self.restore(&log);
        }
        None
    }

    /// Makes `moves` in order, recording each op's old place in `log`.
    fn make(&mut self, moves: &[Move], log: &mut Vec<Move>) {
        for &(y, t, k, s) in moves {
            log.push((y, self.t[y], self.slot[y], self.swap[y]));
            let aff = self.affected(y);
            self.detach(y, &aff);
            self.attach(y, t, k, s, &aff);
        }
    }

    /// The cycles op `u` may go to: its dependence window, at most `span` cycles from
    /// each end.
    fn window(&self, u: usize, span: i64, times: &mut Vec<i64>) {
        let p = self.p;
        let (mut lo, hi) = self.dependence_window(u);
        if p.ops[u].jit && hi != i64::MAX {
            lo = lo.max(hi - CONSTANT_LEAD);
        }
        let (lo, hi) = match (lo == i64::MIN, hi == i64::MAX) {
            (true, true) => (self.t[u], self.t[u]),
            (true, false) => (hi - span, hi),
            (false, true) => (lo, lo + span),
            (false, false) => (lo, hi),
        };
        times.clear();
        let (a, b) = (lo.min(hi), lo.max(hi));
        if b - a <= 2 * span {
            times.extend(a..=b);
        } else {
            times.extend(a..=a + span);
            times.extend(b - span..=b);
        }
        if self.placed[u] && !times.contains(&self.t[u]) {
            times.push(self.t[u]);
        }
        if p.ops[u].align.is_some() {
            times.retain(|&t| p.aligned(u, t));
        }
    }
}

/// Schedules the loop's `ops` at interval `ii` by local search, its random choices drawn
/// from `seed`. On success returns each op's (cycle, slot, swap); `None` if the search
/// ran out of moves with something broken or an LRF still too full, or if `abandoned` was
/// set (its result is no longer wanted).
#[allow(clippy::too_many_arguments)]
pub fn schedule(
    g: &Graph,
    ops: &[usize],
    edges: &[Edge],
    priority: &[i64],
    ii: i64,
    reach: i64,
    slots: &Slots,
    desc: &MachineDesc,
    seed: u64,
    abandoned: &AtomicBool,
) -> Option<Vec<(i64, usize, bool)>> {
    let problem = Problem::new(g, ops, edges, ii, reach, slots, desc)?;
    let p = &problem;
    let n = ops.len();
    let mut st = State::new(p);
    let mut rng = Rng(0x5EED ^ (ii as u64) ^ ((n as u64) << 32) ^ seed.wrapping_mul(0x9E37_79B9));
    let priority: Vec<i64> = ops.iter().map(|&o| priority[o]).collect();
    if !st.start(&priority) {
        return None;
    }
    // Repair. The waits steered the start; from here only what breaks or crowds counts,
    // so that free slots may travel far.
    st.wait_weight = 0;
    let budget = n * MOVES_PER_OP;
    let mut worklist: Vec<usize> = Vec::new();
    let mut temperature = START_TEMPERATURE;
    let cooling = (END_TEMPERATURE / START_TEMPERATURE).powf(1.0 / budget as f64);
    for step in 0..budget {
        if st.solved() {
            break;
        }
        if step % REFRESH == 0 {
            if abandoned.load(Ordering::Relaxed) {
                return None;
            }
            // A search still paying for more than one broken constraint per op once it has
            // settled is hopeless (a body whose values cannot fit the LRFs at all).
            if step >= budget / SETTLE && st.cost() > n as i64 * SCALE * HARD {
                return None;
            }
            worklist = troubled(&st);
        }
        temperature *= cooling;
        let accept = |before: i64, after: i64, rng: &mut Rng| {
            after <= before || rng.unit() < (-((after - before) as f64) / temperature).exp()
        };
        // A troubled op most of the time, else any (annealing moves the rest too).
        let u = if !worklist.is_empty() && rng.below(10) < 8 {
            worklist[rng.below(worklist.len())]
        } else {
            rng.below(n)
        };
        let before = st.cost();
        // A value with a third destination: move every reader of one of its places.
        let crowded_value = std::iter::once(u)
            .chain(p.ops[u].args.iter().filter_map(|&(src, _)| match src {
                Src::Loop { op: x, .. } => Some(x),
                Src::Earlier(_) => None,
            }))
            .find(|&x| st.dests[x].len() > 2);
        if let Some(x) = crowded_value
            && let Some(log) = st.fewer_dests(x)
        {
            if accept(before, st.cost(), &mut rng) {
                continue;
            }
            st.restore(&log);
        }
        // A broken dependence: push the reader later or pull the writer earlier, with
        // whatever that breaks in turn.
        let stretched = p.incident[u].iter().copied().find(|&e| {
            let (a, b, lat, dist) = p.edges[e];
            a != b && st.t[a] + lat - ii * i64::from(dist) > st.t[b]
        });
        if let Some(e) = stretched {
            // (Pulling is tried last and, when it wins, kept as it is rather than undone
            // and made again: the state is the same either way.)
            let log = st.push_apart(e, true);
            let pushed = st.cost();
            st.restore(&log);
            let log = st.push_apart(e, false);
            let pulled = st.cost();
            // (On a tie the pull, as the least of (cost, forward).)
            let forward = pushed < pulled;
            if accept(before, pushed.min(pulled), &mut rng) {
                if forward {
                    st.restore(&log);
                    st.push_apart(e, true);
                }
                continue;
            }
            st.restore(&log);
        }
        // An op in a taken place: an ejection chain to a free one.
        if st.troubled_op(u)
            && let Some(moves) = st.chain(u)
        {
            let mut log = Vec::new();
            st.make(&moves, &mut log);
            if accept(before, st.cost(), &mut rng) {
                continue;
            }
            st.restore(&log);
        }
        // Else the best of the cheapest few places in the op's window (min-conflicts).
        let (t0, k0, s0) = (st.t[u], st.slot[u], st.swap[u]);
        let aff = st.affected(u);
        st.detach(u, &aff);
        let mut cands = Shortlist::default();
        let around = st.around(u);
        let mut times = std::mem::take(&mut st.times);
        st.window(u, WINDOW, &mut times);
        for &t in &times {
            let at = st.quick_at(u, &around, t);
            // (A full shortlist whose last place costs less than any place at `t` may cost
            // takes none of them: their tie-breaks are still drawn, their slots not counted.)
            let beaten = cands.worst().is_some_and(|w| st.quick_least(at) > w);
            let row = p.row(t);
            // (The options of a slot come together, its swaps side by side.)
            let mut taken: Option<(usize, i64)> = None;
            for &(k, s) in &p.ops[u].options {
                if p.allowed(u, t, k) && (t, k, s) != (t0, k0, s0) {
                    if beaten {
                        rng.next();
                        continue;
                    }
                    let slot_taken = match taken {
                        Some((slot, n)) if slot == k => n,
                        _ => st.issue_taken(u, row, k),
                    };
                    taken = Some((k, slot_taken));
                    let c = st.quick_taken(&around, at, slot_taken, k, s);
                    cands.offer((c, rng.next(), t, k, s));
                }
            }
        }
        st.times = times;
        st.around = around;
        // (The first place of least cost, weighed without making the move: see `probe`.)
        let detached = st.cost();
        let mut best: Option<(i64, i64, usize, bool)> = None;
        for &(_, _, t, k, s) in cands.best() {
            let bound = best.map_or(i64::MAX, |b| b.0 - detached);
            if let Some(added) = st.attach_cost(u, t, k, s, bound) {
                best = Some((detached + added, t, k, s));
            }
        }
        match best.filter(|&(c, ..)| accept(before, c, &mut rng)) {
            Some((_, t, k, s)) => st.attach(u, t, k, s, &aff),
            None => st.attach(u, t0, k0, s0, &aff),
        }
    }
    st.solved()
        .then(|| (0..n).map(|u| (st.t[u], st.slot[u], st.swap[u])).collect())
}

/// Moves per op the repair makes before it gives up.
const MOVES_PER_OP: usize = 400;
/// The fraction of the moves after which a hopeless search gives up.
const SETTLE: usize = 32;
/// Moves between refreshes of the list of troubled ops.
const REFRESH: usize = 64;
/// How far from its dependence window's ends an op looks for a place, in cycles.
const WINDOW: i64 = 24;
/// Candidates per move evaluated in full, after the quick estimate.
const SHORTLIST: usize = 6;
/// The annealing temperature, in cost units, at the first and last move: a broken
/// constraint costs [`SCALE`] × [`HARD`] = 800, an entry over an LRF's capacity 96.
const START_TEMPERATURE: f64 = 2000.0;
const END_TEMPERATURE: f64 = 40.0;
/// How far, in cycles, an ejection chain's ops may move, and how many ops it may visit.
const CHAIN_SPAN: i64 = 64;
const CHAIN_LIMIT: usize = 400;
/// How many ops a push may move, and how many cycles past where it must each may go.
const PUSH_LIMIT: usize = 40;
const PUSH_SLACK: i64 = 3;
/// How many cycles before its reader a rematerialised constant may go.
const CONSTANT_LEAD: i64 = 32;
/// Entries of each LRF the search leaves free: every pass's copy of a value takes an entry
/// of its own round the unrolled body (see [`super::alloc`]), which needs a little more
/// than the values live at once.
const LRF_MARGIN: i32 = 2;

/// A move's candidate place: its quick estimate, a random tie-break, and (cycle, slot, swap).
type Candidate = (i64, u64, i64, usize, bool);

/// The [`SHORTLIST`] least candidates offered, in order: what sorting them all and taking
/// the first would give (the keys are distinct), without keeping the rest.
#[derive(Default)]
struct Shortlist {
    best: [Candidate; SHORTLIST],
    len: usize,
}

impl Shortlist {
    fn offer(&mut self, c: Candidate) {
        if self.len == SHORTLIST && c >= self.best[SHORTLIST - 1] {
            return;
        }
        let at = self.best[..self.len].partition_point(|&b| b < c);
        let end = self.len.min(SHORTLIST - 1);
        self.best.copy_within(at..end, at + 1);
        self.best[at] = c;
        self.len = (self.len + 1).min(SHORTLIST);
    }

    fn best(&self) -> &[Candidate] {
        &self.best[..self.len]
    }

    /// The estimate of the last candidate kept, once the list is full: a candidate of a
    /// greater one is never kept.
    fn worst(&self) -> Option<i64> {
        (self.len == SHORTLIST).then(|| self.best[SHORTLIST - 1].0)
    }
}

/// The cycles of `[lo, hi]` nearest `t` first, the earlier of two as near.
fn nearest_first(t: i64, lo: i64, hi: i64) -> impl Iterator<Item = i64> {
    let nearest = if t < lo {
        lo - t
    } else if t > hi {
        t - hi
    } else {
        0
    };
    let farthest = (t - lo).max(hi - t);
    (nearest..=farthest)
        .flat_map(move |d| [t - d, t + d].into_iter().take(if d == 0 { 1 } else { 2 }))
        .filter(move |c| (lo..=hi).contains(c))
}

/// The ops that break something, or whose values are live where an LRF is over-full.
fn troubled(st: &State) -> Vec<usize> {
    let p = st.p;
    let n = p.ops.len();
    let mut bad = vec![false; n];
    let res = &p.res;
    let over = |row: usize, r: usize| st.usage[row * res.per_row + r] > res.cap[r];
    for u in 0..n {
        let op = &p.ops[u];
        let (t, k) = (st.t[u], st.slot[u]);
        let mut b = match op.kind {
            Kind::Fu(_) => {
                (0..op.issue.min(p.ii)).any(|c| over(p.row(t + c), res.issue(k)))
                    || over(p.row(t + op.lat), res.result(k))
            }
            Kind::SpRead { .. } | Kind::SpWrite { .. } => over(p.row(t), res.sp(k)),
            Kind::Comm(_) => over(p.row(t), res.comm(k)),
            Kind::StreamIn { .. } => over(p.row(t), res.words()),
            Kind::StreamOut { .. } => over(p.row(t), res.words()) || over(p.row(t), res.sout()),
            Kind::Imm(_) => over(p.row(t), res.imm()),
        };
        let w = t + op.lat;
        for &(l, _) in &st.dests[u] {
            if let Loc::Lrf(x) = l {
                b |= over(p.row(w), res.port(x));
            }
        }
        if st.dests[u].len() > 2 {
            b = true;
            for &(r, _) in &p.readers[u] {
                bad[r] = true;
            }
        }
        for &e in &p.incident[u] {
            let (a, bb, lat, dist) = p.edges[e];
            if a != bb && st.t[a] + lat - p.ii * i64::from(dist) > st.t[bb] {
                b = true;
            }
        }
        for &(r, i) in &p.readers[u] {
            if matches!(p.ops[r].args[i].0, Src::Loop { carried: false, .. })
                && st.t[r] > w + p.reach
            {
                b = true;
                bad[r] = true;
            }
        }
        if b {
            bad[u] = true;
        }
    }
    if st.crowd > 0 {
        // Values live in an over-full row, and their readers.
        for u in 0..n {
            if p.ops[u].permanent {
                continue;
            }
            let w = st.t[u] + p.ops[u].lat;
            for &(l, _) in &st.dests[u] {
                let k = p.loc_index(l);
                let cap = p.cap[k] - st.kept[k];
                let r = st.live_end(u, l, w);
                let live = &st.live[k];
                if circle::cycles(w, r, p.ii).any(|run| live[run].iter().any(|&x| x > cap)) {
                    bad[u] = true;
                    for &(x, i) in &p.readers[u] {
                        if p.arg_loc(x, i, st.slot[x], st.swap[x]) == l {
                            bad[x] = true;
                        }
                    }
                }
            }
        }
    }
    (0..n).filter(|&u| bad[u]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Under a plan no two ops of a unit can land at its result port in one row: a long op
    /// at row `r` lands with a short op at `r + gap`, which the plan never makes short.
    #[test]
    fn latency_plans_keep_result_ports_apart() {
        for (units, ii, short, long) in [
            (3, 218, (2, 400), (4, 251)),
            (3, 219, (2, 600), (4, 50)),
            (2, 64, (2, 10), (6, 100)),
            (1, 7, (1, 3), (3, 3)),
        ] {
            let plan = latency_plan(units, ii, short, long).expect("fits");
            let gap = (long.0 - short.0) as usize;
            let rows = ii as usize;
            let mut counts = (0, 0);
            for unit in &plan {
                for r in 0..rows {
                    match unit[r] {
                        Row::Latency(l) if l == long.0 => {
                            counts.1 += 1;
                            assert_ne!(unit[(r + gap) % rows], Row::Latency(short.0));
                        }
                        Row::Latency(_) => counts.0 += 1,
                        Row::Empty => {}
                    }
                }
            }
            assert!(
                counts.0 >= short.1 && counts.1 >= long.1,
                "{counts:?} at II {ii}"
            );
        }
    }

    /// A shortlist keeps what sorting every candidate and taking the first few keeps.
    #[test]
    fn shortlists_keep_the_least_candidates_in_order() {
        let mut rng = Rng(3);
        for count in 0..40 {
            let all: Vec<Candidate> = (0..count)
                .map(|i| {
                    (
                        rng.below(5) as i64,
                        rng.next(),
                        i as i64,
                        rng.below(3),
                        false,
                    )
                })
                .collect();
            let mut list = Shortlist::default();
            for &c in &all {
                list.offer(c);
            }
            let mut sorted = all.clone();
            sorted.sort_unstable();
            sorted.truncate(SHORTLIST);
            assert_eq!(list.best(), &sorted[..], "{count} candidates");
        }
    }

    #[test]
    fn latency_plans_refuse_too_many_ops() {
        assert_eq!(latency_plan(2, 10, (2, 15), (4, 6)), None);
        // One orbit (gap 2, odd interval), every row taken: no empty row ends the long run.
        assert_eq!(latency_plan(1, 7, (2, 3), (4, 4)), None);
        assert!(latency_plan(1, 8, (2, 3), (4, 4)).is_some());
    }
}
