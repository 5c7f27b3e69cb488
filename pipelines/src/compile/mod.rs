//! The kernel compiler (ARCHITECTURE §5): kernel IR to the machine's microcode.
//!
//! 1. [`graph`] lowers the IR to machine operations with their dependences; the loop's
//!    constants and its scratchpad reads with several readers are then made again just
//!    before each reader, as far as the immediate slot and the scratchpad have room, so
//!    that their values do not wait in the small LRFs;
//! 2. [`schedule`] modulo-schedules the main loop (software pipelining: the hardware squash
//!    supplies prologue and epilogue) and list-schedules the code before and after it,
//!    binding every op to a slot and every operand to the LRF that slot reads;
//! 3. [`alloc`] gives every value its LRF or condition-code entries;
//! 4. [`emit`] writes the instructions, which [`Program::check`] then checks against the
//!    machine description.
//!
//! The initiation interval starts at its lower bound, the larger of the resource bound
//! (ops per unit class over units, stream words over SRF ports, …) and the recurrence bound
//! (the longest dependence cycle through carried values and scratchpad order), and rises
//! until the loop schedules, fits the stage field and its values fit the LRFs (a full LRF
//! first gets copies into the adders' LRFs around the schedule as it is, then a schedule
//! with a copy). Each interval is tried first with every loop value read within the
//! interval, then with values free to wait a few intervals, the body unrolled into as many
//! passes as they need (modulo variable expansion: copies cost unit slots, which a loop
//! near its bound lacks). A kernel that cannot fit fails with a [`CompileError`] naming the
//! kernel and the resource.
//!
//! The schedules the search tries do not depend on each other, so they run on every host
//! core at once; the first in the search's order that succeeds wins, which makes the
//! microcode that of trying them in turn ([`first_in_order`]). A local search, which runs
//! on every core itself, goes alone. The search of a loop with no straight-line fallback
//! counts its schedules against a budget, in order, and so tries them in turn.

pub mod adjacency;
pub mod alloc;
pub mod bind;
pub mod cache;
pub mod circle;
pub mod emit;
pub mod graph;
pub mod last_reads;
pub mod repair;
pub mod report;
pub mod schedule;

use rustc_hash::FxHashMap as HashMap;
use std::fmt;

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{MAX_STAGES, Permutation, Program};
use imagine_units::ops::UnitClass;

use crate::kernel::{Kernel, Region};
pub use cache::CompileCache;
use graph::{Edge, Graph, Kind, Loc, MOp};
pub use report::Report;
use schedule::{Failure, Schedule, Slots, schedule_region};

/// A kernel that does not fit the machine.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CompileError {
    pub kernel: String,
    pub machine: String,
    /// The resource that ran out: `LRF add0.a`, `microcode store`, `kernel streams`, …
    pub resource: String,
    pub message: String,
}

impl fmt::Display for CompileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "kernel `{}` does not fit machine `{}`: {}: {}",
            self.kernel, self.machine, self.resource, self.message
        )
    }
}

impl std::error::Error for CompileError {}

/// A compiled kernel: its microcode and what the compiler learned.
#[derive(Clone, Debug)]
pub struct Compiled {
    pub program: Program,
    pub report: Report,
    /// Index of the hidden `params` stream in the program, if the kernel has parameters.
    pub params_stream: Option<usize>,
}

/// Compiles `kernel` for `desc`.
pub fn compile(kernel: &Kernel, desc: &MachineDesc) -> Result<Compiled, CompileError> {
    crate::kernel::verify::verify(kernel).map_err(|e| CompileError {
        kernel: kernel.name.clone(),
        machine: desc.name.clone(),
        resource: "kernel".into(),
        message: e.message,
    })?;
    let slots = Slots::new(desc);
    let err = |resource: &str, message: String| CompileError {
        kernel: kernel.name.clone(),
        machine: desc.name.clone(),
        resource: resource.into(),
        message,
    };
    let streams = kernel.streams.len() + usize::from(!kernel.params.is_empty());
    if streams > desc.srf.kernel_streams {
        return Err(err(
            "kernel streams",
            format!(
                "it addresses {streams} streams{}; a kernel may address {} \
                 (`srf.kernel_streams`)",
                if kernel.params.is_empty() {
                    ""
                } else {
                    " (with the hidden `params` stream)"
                },
                desc.srf.kernel_streams
            ),
        ));
    }
    let add0_a = slots.shape.lrf("add0", "a").0 as u16;
    let base = graph::lower(kernel, add0_a);
    check_static(kernel, &base, desc).map_err(|(r, m)| err(&r, m))?;
    let has_loop = !base.in_region(Region::Loop).is_empty() || kernel.main_loop.is_some();
    // Constants the loop reads are made again by immediates just before each read instead
    // of each holding an LRF entry for the whole loop, as far as the immediate slot has
    // room in the interval.
    let mut base = base;
    let room = bounds(&base, desc, &slots).res_mii as usize * 3 / 4;
    base.rematerialize_constants(room);
    // Likewise scratchpad reads with several readers, as far as the scratchpad has room
    // without raising the bound.
    let sp_used = base
        .in_region(Region::Loop)
        .iter()
        .filter(|&&o| {
            matches!(base.ops[o].kind, Kind::SpRead { .. } | Kind::SpWrite { .. })
                || base.ops[o].kind.is_conditional_stream()
        })
        .count();
    let sp_room = room.saturating_sub(sp_used);
    base.rematerialize_scratchpad_reads(sp_room);
    let result = search(kernel, &base, desc, &slots, has_loop);
    result.map_err(|(r, m)| err(&r, m))
}

/// Searches initiation intervals upward from the lower bound.
fn search(
    kernel: &Kernel,
    base: &Graph,
    desc: &MachineDesc,
    slots: &Slots,
    has_loop: bool,
) -> Result<Compiled, (String, String)> {
    let bounds = bounds(base, desc, slots);
    let mii = bounds.res_mii.max(bounds.rec_mii).max(1);
    // Beyond this the body is no longer worth pipelining; give up with the last reason.
    let max_ii = if has_loop { mii * 3 + 64 } else { mii };
    let mut last_error = None;
    let compiled = |(program, g, s, lay, entries): Attempted| {
        let report = report::build(
            kernel, &g, &s, &lay, &entries, slots, desc, &bounds, &program,
        );
        Compiled {
            program,
            report,
            params_stream: base.params_stream.map(usize::from),
        }
    };
    if !has_loop {
        return try_ii(kernel, base.clone(), desc, slots, LoopMode::None)
            .map(compiled)
            .map_err(|e| match e {
                Retry::Fatal(e) | Retry::Larger(e) | Retry::Repair(_, e) => e,
            });
    }
    // Copies that move long-lived values out of a full LRF, then the same mode again.
    // A body that cannot even be list-scheduled one iteration at a time has no fallback,
    // and its search is bounded by a count of schedules tried (not by time, so that whether
    // a kernel compiles never depends on the host). With a fallback the search is bounded
    // by the fallback's interval, as before.
    let attempts = std::cell::Cell::new(0usize);
    let bounded = std::cell::Cell::new(false);
    let spent = || bounded.get() && attempts.get() >= MAX_SCHEDULE_ATTEMPTS;
    let gave_up = |(resource, why): (String, String)| {
        (
            resource,
            format!("{why} (the compiler gave up after {MAX_SCHEDULE_ATTEMPTS} schedules tried)"),
        )
    };
    // Counts a schedule against the budget; false once it is spent.
    let spend = || {
        if spent() {
            return false;
        }
        attempts.set(attempts.get() + 1);
        true
    };
    // The body list-scheduled, one iteration at a time: the interval to beat. Its order is
    // also the order the scheduler places big loops in far from their bound.
    let mut hinted = base.clone();
    let line_try = Try {
        mode: LoopMode::Line,
        graph: base,
        expand: false,
        repairs: MAX_REPAIRS,
    };
    let line = match line_try.run(kernel, desc, slots, spend) {
        Ok(a) => {
            hinted.hint = (0..base.ops.len())
                .map(|o| {
                    if base.ops[o].region == Region::Loop {
                        a.2.place[o].map_or(-1, |p| p.time)
                    } else {
                        -1
                    }
                })
                .collect();
            Some(compiled(a))
        }
        Err(Retry::Fatal(e) | Retry::Larger(e) | Retry::Repair(_, e)) => {
            last_error = Some(e);
            None
        }
    };
    let max_ii = match &line {
        Some(c) => (c.report.ii.unwrap_or(1) - 1).min(max_ii),
        None => max_ii,
    };
    bounded.set(line.is_none());
    attempts.set(0);
    // Big bodies are tried close to their bound first, in the order of their heights, …
    let near = if mii >= 64 {
        max_ii.min(mii + mii / 4)
    } else {
        max_ii
    };
    // (Each interval near the bound with ties between equal priorities broken both ways:
    // in a full reservation table, which op gets the earlier free slots decides whether
    // values outlive the interval.)
    let mut late = base.clone();
    late.late_ties = true;
    let near_attempts = (mii..=near).flat_map(|ii| {
        let late_too = ii <= mii + LATE_TIES_ABOVE_BOUND;
        std::iter::once((ii, base, MAX_REPAIRS)).chain(late_too.then_some((
            ii,
            &late,
            WIDE_REPAIRS,
        )))
    });
    // … then up to the straight-line interval, in the order of the straight-line schedule
    // (which keeps the dense part of the body as the list scheduler packed it, and fills
    // the rest of the interval with the next iteration's serial tail), with fewer repairs.
    let far_attempts = (near + 1..=max_ii)
        .filter(|_| !hinted.hint.is_empty())
        .map(|ii| (ii, &hinted, WIDE_REPAIRS));
    // Each interval is tried with every value read within the interval first, then with
    // the body unrolled so that values may wait longer (see [`schedule::reach`]); both by
    // Rau's scheduler and then by modulo list scheduling, which keeps a big body's values
    // short-lived where Rau's lets it drift through a nearly full table; last, once per
    // interval close to the bound, by local search (see [`repair`]), which binds as it
    // places and so can fill a table where the others leave values waiting beyond the LRFs
    // (it takes seconds for a big body, so it is not tried further out).
    let mut listed = base.clone();
    listed.list = true;
    let mut repaired = base.clone();
    repaired.repair = true;
    let mut searched = None;
    let tries = near_attempts
        .chain(far_attempts)
        .flat_map(|(ii, graph, repairs)| {
            let mode = LoopMode::Modulo(ii as i64);
            let few = repairs.min(WIDE_REPAIRS);
            let search_too = ii <= mii + SEARCH_ABOVE_BOUND && searched.replace(ii) != Some(ii);
            let at = |graph, expand, repairs| Try {
                mode,
                graph,
                expand,
                repairs,
            };
            [
                at(graph, false, repairs),
                at(graph, true, few),
                at(&listed, false, repairs),
                at(&listed, true, few),
            ]
            .into_iter()
            .chain(search_too.then(|| at(&repaired, true, few)))
        });
    let outcomes: Box<dyn Iterator<Item = Result<Attempted, Retry>>> = if bounded.get() {
        // Without a fallback the budget counts schedules in order, so they go in turn.
        Box::new(tries.map(|t| t.run(kernel, desc, slots, spend)))
    } else {
        // Otherwise they go on every core, with the outcome of taking them in turn. A local
        // search runs its seeds on every core itself, so it goes alone, between the runs of
        // the schedules before and after it (beside another schedule it only goes slower).
        let tries: Vec<Try<'_>> = tries.collect();
        let ends = |r: &Result<Attempted, Retry>| matches!(r, Ok(_) | Err(Retry::Fatal(_)));
        let run = |t: &Try<'_>, wanted: Wanted<'_>| t.run(kernel, desc, slots, wanted);
        let mut outcomes = Vec::new();
        for group in tries.chunk_by(|a, b| !a.graph.repair && !b.graph.repair) {
            outcomes.extend(first_in_order(group, run, ends));
            if outcomes.last().is_some_and(ends) {
                break;
            }
        }
        Box::new(outcomes.into_iter())
    };
    for outcome in outcomes {
        match outcome {
            Ok(a) => return Ok(compiled(a)),
            Err(Retry::Fatal(e)) => return Err(e),
            Err(Retry::Larger(e) | Retry::Repair(_, e)) => last_error = Some(e),
        }
        if spent() {
            return Err(gave_up(last_error.expect("a schedule was tried")));
        }
    }
    line.ok_or_else(|| last_error.unwrap_or(("schedule".into(), "no schedule found".into())))
}

/// Static limits: scratchpad addresses that can never fit.
fn check_static(kernel: &Kernel, g: &Graph, desc: &MachineDesc) -> Result<(), (String, String)> {
    let words = crate::kernel::interp::scratchpad_words(kernel, desc);
    let clusters = desc.cluster.count;
    for op in &g.ops {
        if let Kind::Comm(Permutation::Xor(k) | Permutation::Broadcast(k)) = op.kind
            && usize::from(k) >= clusters
        {
            return Err((
                "intercluster network".into(),
                format!(
                    "{} names cluster {k}; the machine has {clusters}",
                    op.ir.map_or("a permutation".into(), |v| kernel.describe(v))
                ),
            ));
        }
        if let Kind::SpRead { base } | Kind::SpWrite { base } = op.kind
            && usize::from(base) >= words
        {
            return Err((
                "scratchpad".into(),
                format!(
                    "{} uses base address {base}; the scratchpad has {words} usable words",
                    op.ir.map_or("an access".into(), |v| kernel.describe(v))
                ),
            ));
        }
    }
    Ok(())
}

/// How the main loop is scheduled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LoopMode {
    /// No loop.
    None,
    /// Software-pipelined at this initiation interval.
    Modulo(i64),
    /// One iteration at a time, list-scheduled.
    Line,
}

/// How far below its size [`schedule::relieve`] may take an LRF's peak of live values for
/// the allocation (first fit, round the interval) to succeed.
const RELIEF_SLACK: usize = 4;

/// Repairs of a full LRF tried at one initiation interval before a larger one.
const MAX_REPAIRS: usize = 96;

/// Software-pipelined schedules a loop with no straight-line fallback may be tried with
/// (each interval, variant and LRF repair counts one) before the compiler gives up on it.
/// Of the library's and the pipelines' kernels on gold1, gold8, gold8+F, gold16 and gold32
/// only `merge` on gold1 takes this path, and it needs 21; a kernel the machine cannot
/// serve (e.g. `turbulence` with two condition codes) would otherwise try every interval up
/// to three times its bound, for minutes.
const MAX_SCHEDULE_ATTEMPTS: usize = 64;

/// Intervals above the lower bound at which the local search is tried (see [`search`]).
const SEARCH_ABOVE_BOUND: u32 = 1;

/// Intervals above the lower bound at which the modulo scheduler also breaks ties the
/// other way (see [`search`]).
const LATE_TIES_ABOVE_BOUND: u32 = 3;

/// Repairs tried at each interval far from the bound, and with ties broken late (see
/// [`search`]).
const WIDE_REPAIRS: usize = 16;

enum Retry {
    /// Try a larger initiation interval.
    Larger((String, String)),
    /// Try the same interval again with this graph (a copy moves a long-lived value out
    /// of a full LRF).
    Repair(Box<Graph>, (String, String)),
    /// No interval helps.
    Fatal((String, String)),
}

type Attempted = (Program, Graph, Schedule, emit::Layout, alloc::Entries);

/// Whether the search still wants a job's outcome: a job stops early once it does not (its
/// outcome is then dropped).
type Wanted<'a> = &'a (dyn Fn() -> bool + Sync);

/// One schedule of the search: `graph` (unrolled if `expand`) in `mode`, with up to
/// `repairs` LRF repairs (each a schedule again with a copy).
#[derive(Clone, Copy)]
struct Try<'a> {
    mode: LoopMode,
    graph: &'a Graph,
    expand: bool,
    repairs: usize,
}

impl Try<'_> {
    /// Schedules, repairing a full LRF while `spend` allows another schedule (the budget
    /// lasts, or the search still wants this one).
    fn run(
        &self,
        kernel: &Kernel,
        desc: &MachineDesc,
        slots: &Slots,
        mut spend: impl FnMut() -> bool,
    ) -> Result<Attempted, Retry> {
        let mut work = self.graph.clone();
        work.expand |= self.expand;
        let mut last = None;
        for _repair in 0..=self.repairs {
            if !spend() {
                break;
            }
            match try_ii(kernel, work, desc, slots, self.mode) {
                Err(Retry::Repair(g, e)) => {
                    work = *g;
                    last = Some(e);
                }
                other => return other,
            }
        }
        // (Nothing tried: the search no longer wants this one; its outcome is dropped.)
        Err(Retry::Larger(last.unwrap_or_else(|| {
            ("schedule".into(), "not tried: no longer wanted".into())
        })))
    }
}

/// Runs `jobs` on the host's cores, taken in order, until one gives a result that `ends`
/// the search; returns the results in order up to and including that one (or all). The
/// results are those of running the jobs in turn: every job before the first that ends is
/// run (a job is started only while no earlier one has ended), and the ones after it that
/// were already started are dropped. A job is given a test of whether it is still wanted
/// (no earlier job has ended), so that it can stop early once it is not.
fn first_in_order<J: Sync, R: Send>(
    jobs: &[J],
    run: impl Fn(&J, Wanted<'_>) -> R + Sync,
    ends: impl Fn(&R) -> bool + Sync,
) -> Vec<R> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    let first_end = AtomicUsize::new(usize::MAX);
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs.len())
        .max(1);
    let worker = || {
        let mut mine = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= jobs.len() || i > first_end.load(Ordering::Relaxed) {
                return mine;
            }
            let r = run(&jobs[i], &|| first_end.load(Ordering::Relaxed) > i);
            if ends(&r) {
                first_end.fetch_min(i, Ordering::Relaxed);
            }
            mine.push((i, r));
        }
    };
    let mut done: Vec<(usize, R)> = std::thread::scope(|scope| {
        let others: Vec<_> = (1..threads).map(|_| scope.spawn(worker)).collect();
        let mut done = worker();
        for w in others {
            done.extend(w.join().expect("a compiler thread panicked"));
        }
        done
    });
    done.sort_by_key(|&(i, _)| i);
    let last = first_end.into_inner();
    done.into_iter()
        .take_while(|&(i, _)| i <= last)
        .map(|(_, r)| r)
        .collect()
}

fn try_ii(
    kernel: &Kernel,
    mut g: Graph,
    desc: &MachineDesc,
    slots: &Slots,
    mode: LoopMode,
) -> Result<Attempted, Retry> {
    let mut s = Schedule::new(g.ops.len());
    let describe = |g: &Graph, f: &Failure| -> String {
        let (op, why) = match f {
            Failure::NoSlot { op, why } => (*op, why.clone()),
            Failure::Copies { op } => (*op, "too many register copies needed".into()),
        };
        let what = g.ops[op]
            .ir
            .map_or_else(|| "a copy".to_string(), |v| kernel.describe(v));
        format!("{what} {} cannot be placed: {why}", g.ops[op].region.name())
    };
    let ii = match mode {
        LoopMode::None => None,
        LoopMode::Modulo(ii) => Some(ii),
        LoopMode::Line => {
            // The body as straight-line code; the next iteration starts when every result
            // has landed.
            schedule_region(&mut g, &mut s, Region::Loop, None, slots, desc)
                .map_err(|f| Retry::Fatal(("schedule".into(), describe(&g, &f))))?;
            let len = g
                .in_region(Region::Loop)
                .iter()
                .filter_map(|&u| s.place[u].map(|p| p.time + g.latency(u, desc) + 1))
                .max()
                .unwrap_or(1);
            Some(len.max(1))
        }
    };
    if let (LoopMode::Modulo(_), Some(ii)) = (mode, ii) {
        schedule_region(&mut g, &mut s, Region::Loop, Some(ii), slots, desc).map_err(|f| {
            Retry::Larger((
                "schedule".into(),
                format!("at initiation interval {ii}, {}", describe(&g, &f)),
            ))
        })?;
        let last = g
            .in_region(Region::Loop)
            .iter()
            .filter_map(|&u| s.place[u].map(|p| p.time))
            .max()
            .unwrap_or(0);
        let stages = last / ii + 1;
        if stages > i64::from(MAX_STAGES) {
            return Err(Retry::Larger((
                "software-pipeline stages".into(),
                format!(
                    "the loop needs {stages} stages at initiation interval {ii}; the stage \
                     field holds {MAX_STAGES}"
                ),
            )));
        }
    }
    let after_loop = g.clone();
    schedule_region(&mut g, &mut s, Region::Post, None, slots, desc)
        .map_err(|f| Retry::Fatal(("schedule".into(), describe(&g, &f))))?;
    let providers = fan_out(&mut g, &mut s);
    schedule_region(&mut g, &mut s, Region::Pre, None, slots, desc)
        .map_err(|f| Retry::Fatal(("schedule".into(), describe(&g, &f))))?;
    // A full LRF in the loop first gets copies that move its long-waiting values to the
    // adders' LRFs, the schedule kept (see [`schedule::relieve`]); then, if that is not
    // enough, it is repaired by rescheduling with a copy.
    let mut lowered = vec![0usize; slots.lrfs()];
    let mut allocated = alloc::allocate(&g, &s, slots, ii, desc);
    while let (Err(o), Some(ii), LoopMode::Modulo(_)) = (&allocated, ii, mode) {
        let (Some(Region::Loop), Loc::Lrf(l)) = (o.region, o.loc) else {
            break;
        };
        let l = l as usize;
        let cap = slots.shape.lrf_sizes[l];
        if lowered[l] > RELIEF_SLACK {
            break;
        }
        let peak = alloc::Liveness::new(&g, &s, slots, ii, desc).peak(l);
        let target = if peak > cap {
            cap - lowered[l]
        } else {
            peak - 1
        };
        lowered[l] = cap - target + 1;
        if !schedule::relieve(&mut g, &mut s, ii, o.loc, target, slots, desc) {
            break;
        }
        allocated = alloc::allocate(&g, &s, slots, Some(ii), desc);
    }
    let entries = allocated.map_err(|o| {
        let name = match o.loc {
            Loc::Lrf(l) => format!("LRF {}", slots.shape.lrf_names[l as usize]),
            Loc::Cc => "condition codes".into(),
        };
        let message = format!(
            "more than its {} entries hold live values at once{}",
            o.entries,
            match o.region {
                Some(r) => format!(" ({})", r.name()),
                None => " (values kept across the loop)".into(),
            }
        );
        if o.region == Some(Region::Loop) {
            match longest_read(&after_loop, &s, slots, desc, o.loc) {
                Some((user, arg, deadline)) => {
                    let mut g = after_loop.clone();
                    g.insert_lifetime_copy(user, arg, deadline);
                    Retry::Repair(Box::new(g), (name, message))
                }
                None => Retry::Larger((name, message)),
            }
        } else {
            Retry::Fatal((name, message))
        }
    })?;
    let lay = emit::layout(&g, &s, ii, entries.unroll, desc);
    if lay.len > desc.microcontroller.store_words {
        // (An unrolled body may fit at a larger interval, with fewer passes.)
        let retry = if lay.unroll > 1 {
            Retry::Larger
        } else {
            Retry::Fatal
        };
        return Err(retry((
            "microcode store".into(),
            format!(
                "it needs {} instructions; the store holds {} (`microcontroller.store_words`)",
                lay.len, desc.microcontroller.store_words
            ),
        )));
    }
    let program = emit::emit(kernel, &g, &s, &entries, &lay, slots, desc, &providers);
    program
        .check(desc)
        .map_err(|e| Retry::Fatal(("microcode".into(), format!("internal error: {e}"))))?;
    Ok((program, g, s, lay, entries))
}

/// The loop operand read from `loc` that waits longest after its value lands (if it waits
/// long enough for a copy elsewhere to help).
fn longest_read(
    g: &Graph,
    s: &Schedule,
    slots: &Slots,
    desc: &MachineDesc,
    loc: Loc,
) -> Option<(usize, usize, i64)> {
    let mut best = None;
    let mut longest = 3;
    for u in g.in_region(Region::Loop) {
        let Some(pl) = s.place[u] else { continue };
        if g.ops[u].copy_kind == Some(graph::CopyKind::Lifetime) {
            continue;
        }
        for (i, a) in g.ops[u].args.iter().enumerate() {
            let graph::Source::Local(p) = a.src else {
                continue;
            };
            let Some(pp) = s.place[p] else { continue };
            if slots.operand_loc(g.ops[u].kind, pl.slot, pl.swap, a) != loc {
                continue;
            }
            let wait = pl.time - (pp.time + g.latency(p, desc));
            if wait > longest {
                longest = wait;
                best = Some((u, i, pl.time - i64::from(desc.latency.int) - 1));
            }
        }
    }
    best
}

/// Values computed before the loop and read later must be written where their readers
/// read them: up to two places directly, more through extra immediates or `mov` copies.
/// Returns, for each (value, location), the op that writes it there.
fn fan_out(g: &mut Graph, s: &mut Schedule) -> HashMap<(usize, Loc), usize> {
    let mut providers = HashMap::default();
    let pre = g.in_region(Region::Pre);
    for &p in &pre {
        if let Some(m) = g.ops[p].tie {
            g.ops[p].seeded = s.dests[m].clone();
        }
    }
    for &p in &pre {
        let mut need: Vec<Loc> = s.required[p].iter().map(|&(l, _)| l).collect();
        need.sort();
        need.dedup();
        if need.is_empty() {
            continue;
        }
        let local_readers = g.ops.iter().any(|o| {
            o.region == Region::Pre && o.args.iter().any(|a| a.src == graph::Source::Local(p))
        });
        let is_imm = matches!(g.ops[p].kind, Kind::Imm(_));
        if need.len() <= 2 && !local_readers {
            g.ops[p].seeded = need.clone();
            for l in need {
                providers.insert((p, l), p);
            }
            continue;
        }
        for chunk in need.chunks(2) {
            let q = g.ops.len();
            let (kind, args) = if is_imm {
                (g.ops[p].kind, graph::Args::new())
            } else {
                (
                    Kind::Fu(imagine_units::ops::Op::Mov),
                    graph::operands(&[graph::Arg {
                        src: graph::Source::Local(p),
                        input: graph::Input::A,
                    }]),
                )
            };
            g.ops.push(MOp {
                copy: !is_imm,
                seeded: chunk.to_vec(),
                ..MOp::new(kind, args, Region::Pre, g.ops[p].ir)
            });
            for &l in chunk {
                providers.insert((p, l), q);
            }
        }
    }
    s.grow(g.ops.len());
    providers
}

/// Lower bounds on the initiation interval.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Bounds {
    /// Resource bound and the resource that sets it.
    pub res_mii: u32,
    pub res_limit: String,
    /// Recurrence bound.
    pub rec_mii: u32,
}

fn bounds(g: &Graph, desc: &MachineDesc, slots: &Slots) -> Bounds {
    let ops = g.in_region(Region::Loop);
    if ops.is_empty() {
        return Bounds::default();
    }
    let sh = &slots.shape;
    let count = |f: &dyn Fn(&MOp) -> bool| ops.iter().filter(|&&o| f(&g.ops[o])).count();
    let class = |c: UnitClass| count(&|o: &MOp| matches!(o.kind, Kind::Fu(op) if op.unit() == c));
    let conditional = count(&|o: &MOp| o.kind.is_conditional_stream());
    let sp = count(&|o: &MOp| matches!(o.kind, Kind::SpRead { .. } | Kind::SpWrite { .. }));
    let comm = count(&|o: &MOp| matches!(o.kind, Kind::Comm(_)));
    let sin = count(&|o: &MOp| matches!(o.kind, Kind::StreamIn { .. }));
    let sout = count(&|o: &MOp| matches!(o.kind, Kind::StreamOut { .. }));
    let imm = count(&|o: &MOp| matches!(o.kind, Kind::Imm(_)));
    let per = |n: usize, units: usize| n.div_ceil(units.max(1));
    let interval = desc.latency.divsqrt_issue_interval.max(1) as usize;
    // (Named for the result ports when they, not the issue slots, set the bound.)
    let landing = |c: UnitClass, units: usize, name: &'static str, ports: &'static str| {
        let mut by_latency: std::collections::BTreeMap<i64, usize> = Default::default();
        for &o in &ops {
            if matches!(g.ops[o].kind, Kind::Fu(op) if op.unit() == c) {
                *by_latency.entry(g.latency(o, desc)).or_default() += 1;
            }
        }
        let n = result_port_mii(&by_latency, units);
        let raised = n > per(by_latency.values().sum(), units);
        (n, if raised { ports } else { name })
    };
    let limits = [
        landing(
            UnitClass::Adder,
            sh.adders,
            "adders",
            "adders' result ports",
        ),
        landing(
            UnitClass::Multiplier,
            sh.multipliers,
            "multipliers",
            "multipliers' result ports",
        ),
        (
            per(class(UnitClass::DivSqrt) * interval, sh.divsqrt),
            "divide/sqrt unit",
        ),
        (sp + conditional, "scratchpad"),
        (
            per(comm + conditional, sh.comm_units).max(conditional),
            "intercluster network",
        ),
        (
            per(sin + sout, desc.srf.cluster_words_per_cycle),
            "stream words",
        ),
        (sout, "stream output slot"),
        (
            per(conditional, desc.srf.conditional_words_per_cycle),
            "conditional streams",
        ),
        (imm, "immediate slot"),
    ];
    let (res, what) = limits
        .iter()
        .max_by_key(|(n, _)| *n)
        .map(|&(n, w)| (n, w))
        .unwrap_or((1, "none"));
    let edges = g.edges(Region::Loop, desc);
    Bounds {
        res_mii: res.max(1) as u32,
        res_limit: what.into(),
        rec_mii: rec_mii(g.ops.len(), &edges),
    }
}

/// The smallest II at which `units` fully pipelined units can issue ops of the latencies
/// counted in `by_latency`, each unit landing one result a cycle. Above the plain bound
/// (ops over units) when ops of two latencies nearly fill the units: a unit's rows `gap`
/// (the latencies' difference) apart form `gcd(gap, ii)` orbits of `ii / gcd` rows, and
/// results moved by latency land in distinct rows only if each full orbit issues a single
/// latency, whereas an orbit with an empty row may mix them (the long ops just before the
/// empty row). So the ops fit iff the full orbits can be split between the latencies
/// without outnumbering either. (With more than two latencies only the plain bound.)
fn result_port_mii(by_latency: &std::collections::BTreeMap<i64, usize>, units: usize) -> usize {
    let ops: usize = by_latency.values().sum();
    let plain = ops.div_ceil(units.max(1));
    let (2, Some((&short, &n_short)), Some((&long, &n_long)), true) = (
        by_latency.len(),
        by_latency.first_key_value(),
        by_latency.last_key_value(),
        units > 0,
    ) else {
        return plain;
    };
    let gap = (long - short) as usize;
    let fits = |ii: usize| {
        let orbits_per_unit = gcd(gap, ii);
        let orbit = ii / orbits_per_unit;
        let orbits = units * orbits_per_unit;
        let full = orbits - (units * ii - ops).min(orbits);
        (0..=full).any(|long_orbits| {
            long_orbits * orbit <= n_long && (full - long_orbits) * orbit <= n_short
        })
    };
    (plain.max(1)..)
        .find(|&ii| fits(ii))
        .expect("ops + 1 rows a unit always fit")
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The smallest II with no dependence cycle longer than its distance allows: no positive
/// cycle in the graph weighted `latency − II·distance` (Bellman–Ford).
fn rec_mii(n: usize, edges: &[Edge]) -> u32 {
    let feasible = |ii: i64| -> bool {
        let mut dist = vec![0i64; n];
        for _ in 0..=n {
            let mut changed = false;
            for e in edges {
                let w = e.latency - ii * i64::from(e.distance);
                if dist[e.from] + w > dist[e.to] {
                    dist[e.to] = dist[e.from] + w;
                    changed = true;
                }
            }
            if !changed {
                return true;
            }
        }
        false
    };
    let mut hi: i64 = 1 + edges.iter().map(|e| e.latency.max(0)).sum::<i64>();
    let mut lo: i64 = 1;
    if feasible(lo) {
        return 1;
    }
    while lo + 1 < hi {
        let mid = (lo + hi) / 2;
        if feasible(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi as u32
}

#[cfg(test)]
mod tests {
    use super::{first_in_order, result_port_mii};
    use std::collections::{BTreeMap, BTreeSet};

    /// Every (short, long) op count one unit can issue at interval `ii` with each result
    /// landing in its own row, found by trying every assignment of rows.
    fn one_unit(ii: usize, short: usize, long: usize) -> BTreeSet<(usize, usize)> {
        let mut found = BTreeSet::new();
        for code in 0..3usize.pow(ii as u32) {
            let (mut c, mut landed, mut counts, mut clash) = (code, vec![false; ii], (0, 0), false);
            for row in 0..ii {
                let latency = match c % 3 {
                    0 => None,
                    1 => Some(short),
                    _ => Some(long),
                };
                c /= 3;
                if let Some(l) = latency {
                    clash |= std::mem::replace(&mut landed[(row + l) % ii], true);
                    if l == short {
                        counts.0 += 1
                    } else {
                        counts.1 += 1
                    }
                }
            }
            if !clash {
                found.insert(counts);
            }
        }
        found
    }

    #[test]
    fn result_port_bound_matches_exhaustive_search() {
        for (short, long) in [(2, 4), (2, 3), (1, 4)] {
            let feasible: Vec<BTreeSet<(usize, usize)>> =
                (0..=7).map(|ii| one_unit(ii, short, long)).collect();
            for units in 1..=2 {
                for n_short in 0..=7 * units {
                    for n_long in 0..=7 * units {
                        if n_short + n_long == 0 {
                            continue;
                        }
                        // Some split of the ops between the units fits at `ii`.
                        let fits = |ii: usize| {
                            let f = &feasible[ii];
                            match units {
                                1 => f.contains(&(n_short, n_long)),
                                _ => f.iter().any(|&(s, l)| {
                                    s <= n_short
                                        && l <= n_long
                                        && f.contains(&(n_short - s, n_long - l))
                                }),
                            }
                        };
                        let Some(exact) = (1..=7).find(|&ii| fits(ii)) else {
                            continue;
                        };
                        let counts =
                            BTreeMap::from([(short as i64, n_short), (long as i64, n_long)]);
                        let counts: BTreeMap<i64, usize> =
                            counts.into_iter().filter(|&(_, n)| n > 0).collect();
                        assert_eq!(
                            result_port_mii(&counts, units),
                            exact,
                            "{units} unit(s), {n_short} ops of latency {short}, {n_long} of {long}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn result_port_bound_of_a_full_mixed_adder_class() {
        // Three adders full at an odd interval must each issue one latency.
        let counts = BTreeMap::from([(2, 420), (4, 231)]);
        assert_eq!(result_port_mii(&counts, 3), 218);
        assert_eq!(result_port_mii(&BTreeMap::from([(2, 651)]), 3), 217);
        assert_eq!(
            result_port_mii(&BTreeMap::from([(2, 434), (4, 217)]), 3),
            217
        );
    }

    /// The jobs' outcomes in turn, up to and including the first that ends the search.
    fn in_turn(jobs: &[u64], ends: impl Fn(&u64) -> bool) -> Vec<u64> {
        let mut out = Vec::new();
        for &j in jobs {
            out.push(j * 10);
            if ends(&(j * 10)) {
                break;
            }
        }
        out
    }

    #[test]
    fn jobs_on_every_core_give_the_outcomes_taken_in_turn() {
        // Job j sleeps (j % 4) ms, so later jobs often finish first; outcome 10·j ends the
        // search when j is a multiple of 7 (never, for the first list).
        let lists: [Vec<u64>; 3] = [
            vec![1, 2, 3, 5, 6, 9, 3, 2, 1, 5],
            (1..40).collect(),
            vec![14, 1, 2, 3],
        ];
        let ends = |r: &u64| r.is_multiple_of(70);
        for jobs in &lists {
            let got = first_in_order(
                jobs,
                |&j, wanted| {
                    std::thread::sleep(std::time::Duration::from_millis(j % 4));
                    // A job no longer wanted may stop with any result: it is dropped.
                    if wanted() { j * 10 } else { 1 }
                },
                ends,
            );
            assert_eq!(got, in_turn(jobs, ends), "jobs {jobs:?}");
        }
        assert!(first_in_order(&[] as &[u64], |&j, _| j, |_| true).is_empty());
    }
}
