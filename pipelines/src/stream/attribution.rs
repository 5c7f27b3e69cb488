//! Where a run's cycles went (ARCHITECTURE §7): every core cycle of a window, from the
//! clusters' point of view, in exactly one category, worked out after the run from the
//! stream controller's records (entered, issued, completed cycle of every stream
//! instruction), so attribution costs the simulation nothing.
//!
//! * **kernel NAME** — a kernel runs: the cycles its statistics count, from its start to the
//!   end of its output flush, stalls included.
//! * **kernel dispatch** — the rest of a kernel call's time on the clusters, from the issue
//!   of the instruction to its completion: the minimum kernel time (the host's dispatch
//!   overhead, `stream_controller.min_kernel_cycles`) and the cycles between the last flush
//!   and the clusters' release.
//! * **waiting: load / store / gather / scatter / host transfer / microcode load** — no kernel
//!   runs and the next kernel waits for an older stream instruction to complete. The cycles
//!   up to the completion of the last older instruction to complete before the kernel issues
//!   go to that instruction's kind: it is the one the kernel waited for (a dependence, a
//!   full scoreboard or the microcode the kernel needs).
//! * **issue** — from that completion to the kernel's issue: the scoreboard seeing the
//!   dependence resolved and the controller issuing.
//! * **host** — no kernel runs and no older instruction completes before the next kernel
//!   issues: the host had not yet handed the kernel over (it waited on a result first).
//! * **drain** — after the window's last kernel: waiting on the last instruction to
//!   complete (under its kind, as above), then the cycles until the window ends.
//!
//! What the clusters waited on ([`WaitingOn`]), for every waiting cycle: before the
//! instruction waited for had issued, **the scoreboard** (it waited there for a dependence
//! or a free unit); after, for a memory operation, what DRAM did meanwhile — **DRAM
//! bandwidth** (the data bus carried words), **bank conflicts** (references waited while
//! banks were precharged, activated or refreshed: row misses, conflicts, refresh) or
//! neither, **memory latency** (address generation, the clock crossings, CAS latency, SRF
//! writes) — and for a host transfer or a microcode load, **the unit at work**. DRAM's side
//! comes from the channels' activity counters ([`ActivityLog`]), sampled every
//! [`SAMPLE_CYCLES`](imagine_units::dram::activity::SAMPLE_CYCLES) DRAM cycles: a stretch
//! of waiting is split in proportion to the busiest channel's transfer and row-switch
//! cycles over it (the busiest, because one saturated channel limits a stream however
//! idle the others are).

use std::ops::Range;

use imagine_units::dram::activity::{ActivityLog, ActivitySpan};
use imagine_units::memory::{MemOpKind, Pattern};
use imagine_units::stream_controller::{InstrRecord, StreamInstr};
use serde::Serialize;

/// A category of cycles.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Category {
    /// Program index of the kernel.
    Kernel(usize),
    KernelDispatch,
    Waiting(Wait),
    Issue,
    Host,
    Drain,
}

/// What the clusters waited for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Wait {
    Load,
    Store,
    Gather,
    Scatter,
    HostTransfer,
    MicrocodeLoad,
    /// A call of the hardware rasterizer (a hardware kernel beside the clusters).
    Rasterizer,
}

impl Wait {
    pub fn name(self) -> &'static str {
        match self {
            Wait::Load => "load",
            Wait::Store => "store",
            Wait::Gather => "gather",
            Wait::Scatter => "scatter",
            Wait::HostTransfer => "host transfer",
            Wait::MicrocodeLoad => "microcode load",
            Wait::Rasterizer => "hardware rasterizer",
        }
    }

    fn of(instr: &StreamInstr) -> Option<Wait> {
        Some(match instr {
            StreamInstr::Memory(op) => match (op.kind, op.pattern) {
                (MemOpKind::Load, Pattern::Indexed { .. }) => Wait::Gather,
                (MemOpKind::Store, Pattern::Indexed { .. }) => Wait::Scatter,
                (MemOpKind::Load, _) => Wait::Load,
                (MemOpKind::Store, _) => Wait::Store,
            },
            StreamInstr::WriteSrf { .. } | StreamInstr::ReadSrf { .. } => Wait::HostTransfer,
            StreamInstr::LoadMicrocode { .. } => Wait::MicrocodeLoad,
            StreamInstr::Rasterize(_) => Wait::Rasterizer,
            StreamInstr::Kernel { .. } => return None,
        })
    }
}

impl Category {
    /// The name a person reads; kernels by `names[program]`.
    pub fn name(&self, names: &[String]) -> String {
        match self {
            Category::Kernel(p) => format!("kernel {}", names[*p]),
            Category::KernelDispatch => "kernel dispatch".into(),
            Category::Waiting(w) => format!("waiting: {}", w.name()),
            Category::Issue => "issue".into(),
            Category::Host => "host".into(),
            Category::Drain => "drain".into(),
        }
    }
}

/// What waiting cycles were spent on (see the module's documentation); the fields sum to
/// the waiting cycles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WaitingOn {
    /// The instruction waited for had not yet issued.
    pub scoreboard: u64,
    /// A memory operation had issued and DRAM's data bus carried words.
    pub dram_bandwidth: u64,
    /// It had issued and references waited on precharges, activates and refreshes.
    pub bank_conflicts: u64,
    /// It had issued and DRAM neither moved data nor switched rows.
    pub memory_latency: u64,
    /// A host transfer or microcode load was at work.
    pub unit_busy: u64,
}

impl WaitingOn {
    /// Every field with its name, in a fixed order.
    pub fn rows(&self) -> [(&'static str, u64); 5] {
        [
            ("scoreboard", self.scoreboard),
            ("dram bandwidth", self.dram_bandwidth),
            ("bank conflicts", self.bank_conflicts),
            ("memory latency", self.memory_latency),
            ("unit busy", self.unit_busy),
        ]
    }

    pub fn total(&self) -> u64 {
        self.rows().iter().map(|(_, c)| c).sum()
    }

    fn add(&mut self, o: &WaitingOn) {
        self.scoreboard += o.scoreboard;
        self.dram_bandwidth += o.dram_bandwidth;
        self.bank_conflicts += o.bank_conflicts;
        self.memory_latency += o.memory_latency;
        self.unit_busy += o.unit_busy;
    }

    /// The share `part / whole` of these cycles, rounded so that the fields sum to `part`.
    fn part(&self, part: u64, whole: u64) -> WaitingOn {
        if part >= whole {
            return *self;
        }
        let (mut cum, mut taken) = (0u128, 0u64);
        let mut share = |c: u64| {
            cum += c as u128;
            let upto = (cum * part as u128 / whole.max(1) as u128) as u64;
            let mine = upto - taken;
            taken = upto;
            mine
        };
        WaitingOn {
            scoreboard: share(self.scoreboard),
            dram_bandwidth: share(self.dram_bandwidth),
            bank_conflicts: share(self.bank_conflicts),
            memory_latency: share(self.memory_latency),
            unit_busy: share(self.unit_busy),
        }
    }

    /// The waiting cycles of `segments` (as [`attribute`] makes them) inside `window`.
    pub fn of(segments: &[Segment], window: Range<u64>) -> Self {
        let mut on = WaitingOn::default();
        for s in Segment::meeting(segments, &window) {
            let overlap = s.overlap(&window);
            if overlap > 0 {
                on.add(&s.waiting_on.part(overlap, s.cycles.end - s.cycles.start));
            }
        }
        on
    }
}

/// What DRAM did over a run: each channel's activity, and the clocks to map core cycles to
/// DRAM cycles.
#[derive(Clone, Debug, Default)]
pub struct DramActivity<'a> {
    /// In channel order (the first of equally busy channels is taken).
    pub channels: Vec<&'a ActivityLog>,
    /// DRAM cycles per core cycle.
    pub dram_per_core: f64,
}

impl DramActivity<'_> {
    /// The (fractional) DRAM cycles the core cycles `cycles` span.
    fn dram_cycles(&self, cycles: &Range<u64>) -> (f64, f64) {
        (
            cycles.start as f64 * self.dram_per_core,
            cycles.end as f64 * self.dram_per_core,
        )
    }

    /// Column accesses and activates of all channels over the core cycles `cycles`.
    pub fn accesses(&self, cycles: &Range<u64>) -> (f64, f64) {
        let (from, to) = self.dram_cycles(cycles);
        self.channels.iter().fold((0.0, 0.0), |(c, a), log| {
            let s = log.between(from, to);
            (c + s.columns, a + s.activates)
        })
    }

    /// Of the core cycles `cycles`, those when the busiest channel carried data and those
    /// when it switched rows with references waiting, in proportion to its cycles.
    fn split(&self, cycles: &Range<u64>) -> (u64, u64) {
        let (from, to) = self.dram_cycles(cycles);
        let span = to - from;
        // The first of the busiest (`max_by` would take the last).
        let busiest = self
            .channels
            .iter()
            .map(|log| log.between(from, to))
            .reduce(|best, c| {
                let busy = |s: &ActivitySpan| s.transfer_cycles + s.row_switch_cycles;
                if busy(&c) > busy(&best) { c } else { best }
            });
        let (Some(b), true) = (busiest, span > 0.0) else {
            return (0, 0);
        };
        let n = (cycles.end - cycles.start) as f64;
        let transfer = (b.transfer_cycles / span).clamp(0.0, 1.0);
        let rows = (b.row_switch_cycles / span).clamp(0.0, 1.0 - transfer);
        let transfer = (n * transfer).round() as u64;
        let rows = ((n * rows).round() as u64).min(cycles.end - cycles.start - transfer);
        (transfer, rows)
    }
}

/// Cycles `start..end` in one category, and for a wait what it waited on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment {
    pub cycles: Range<u64>,
    pub category: Category,
    pub waiting_on: WaitingOn,
}

impl Segment {
    /// Its cycles inside `window`.
    fn overlap(&self, window: &Range<u64>) -> u64 {
        let from = self.cycles.start.max(window.start);
        self.cycles.end.min(window.end).saturating_sub(from)
    }

    /// The segments of `segments` (consecutive, in cycle order, as [`attribute`] makes
    /// them) that meet `window`: found by bisection, as a frame's batches each ask for
    /// their window of a frame's segments.
    fn meeting<'s>(segments: &'s [Segment], window: &Range<u64>) -> &'s [Segment] {
        let first = segments.partition_point(|s| s.cycles.end <= window.start);
        let rest = &segments[first..];
        &rest[..rest.partition_point(|s| s.cycles.start < window.end)]
    }
}

/// Every cycle of `window` in one category, as consecutive segments covering it exactly.
pub fn attribute(
    records: &[InstrRecord],
    dram: &DramActivity<'_>,
    window: Range<u64>,
) -> Vec<Segment> {
    // Kernel calls on the clusters, in issue order (the clusters run one at a time).
    let mut calls: Vec<(usize, u64, u64, usize, u64)> = records
        .iter()
        .enumerate()
        .filter_map(|(id, r)| match (&r.instr, r.issued, r.completed) {
            (StreamInstr::Kernel { program, .. }, Some(i), Some(c)) => {
                let ran = r.kernel_stats.as_ref().map_or(0, |s| s.cycles);
                Some((id, i, c, *program, ran))
            }
            _ => None,
        })
        .filter(|&(_, i, c, ..)| c > window.start && i < window.end)
        .collect();
    calls.sort_by_key(|&(_, i, ..)| i);
    // Completions of the other instructions, in time order: (cycle, id, kind).
    let mut done: Vec<(u64, usize, Wait)> = records
        .iter()
        .enumerate()
        .filter_map(|(id, r)| Some((r.completed?, id, Wait::of(&r.instr)?)))
        .collect();
    done.sort_unstable();

    // What waiting `cycles` for instruction `id` were spent on.
    let waiting_on = |cycles: &Range<u64>, id: usize| {
        let r = &records[id];
        let issued = r
            .issued
            .unwrap_or(cycles.end)
            .clamp(cycles.start, cycles.end);
        let mut on = WaitingOn {
            scoreboard: issued - cycles.start,
            ..WaitingOn::default()
        };
        let at_work = issued..cycles.end;
        let n = at_work.end - at_work.start;
        if matches!(r.instr, StreamInstr::Memory(_)) {
            let (transfer, rows) = dram.split(&at_work);
            on.dram_bandwidth = transfer;
            on.bank_conflicts = rows;
            on.memory_latency = n - transfer - rows;
        } else {
            on.unit_busy = n;
        }
        on
    };
    let mut out: Vec<Segment> = Vec::new();
    // `waited_for`: the instruction a wait waited for.
    let mut push = |cycles: Range<u64>, category: Category, waited_for: Option<usize>| {
        let cycles = cycles.start.max(window.start)..cycles.end.min(window.end);
        if cycles.is_empty() {
            return;
        }
        let on = waited_for.map_or_else(WaitingOn::default, |id| waiting_on(&cycles, id));
        match out.last_mut() {
            Some(last) if last.category == category && last.cycles.end == cycles.start => {
                last.cycles.end = cycles.end;
                last.waiting_on.add(&on);
            }
            _ => out.push(Segment {
                cycles,
                category,
                waiting_on: on,
            }),
        }
    };
    // The last completion in `(from, to]` of an instruction older than `older_than`.
    let last_done = |from: u64, to: u64, older_than: usize| {
        let end = done.partition_point(|&(c, ..)| c <= to);
        done[..end]
            .iter()
            .rev()
            .take_while(|&&(c, ..)| c > from)
            .find(|&&(_, id, _)| id < older_than)
            .copied()
    };
    let mut now = window.start;
    for &(id, issued, completed, program, ran) in &calls {
        if issued > now {
            match last_done(now, issued, id) {
                Some((c, waited, w)) => {
                    push(now..c, Category::Waiting(w), Some(waited));
                    push(c..issued, Category::Issue, None);
                }
                None => push(now..issued, Category::Host, None),
            }
        }
        let start = issued.max(now);
        let kernel_end = (start + ran).min(completed);
        push(start..kernel_end, Category::Kernel(program), None);
        push(kernel_end..completed, Category::KernelDispatch, None);
        now = now.max(completed);
    }
    if now < window.end {
        match last_done(now, window.end, usize::MAX) {
            Some((c, waited, w)) => {
                push(now..c, Category::Waiting(w), Some(waited));
                push(c..window.end, Category::Drain, None);
            }
            None => push(now..window.end, Category::Drain, None),
        }
    }
    out
}

/// Cycles per category (kernels together) over a window; the fields sum to its cycles.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Attribution {
    pub kernel_running: u64,
    pub kernel_dispatch: u64,
    pub waiting_load: u64,
    pub waiting_store: u64,
    pub waiting_gather: u64,
    pub waiting_scatter: u64,
    pub waiting_host_transfer: u64,
    pub waiting_microcode_load: u64,
    /// Clusters idle while the hardware rasterizer runs (machines with one).
    pub waiting_rasterizer: u64,
    pub issue: u64,
    pub host: u64,
    pub drain: u64,
}

impl Attribution {
    /// The part of `segments` (as [`attribute`] makes them) inside `window`.
    pub fn of(segments: &[Segment], window: Range<u64>) -> Self {
        let mut a = Attribution::default();
        for s in Segment::meeting(segments, &window) {
            *a.slot(&s.category) += s.overlap(&window);
        }
        a
    }

    fn slot(&mut self, c: &Category) -> &mut u64 {
        match c {
            Category::Kernel(_) => &mut self.kernel_running,
            Category::KernelDispatch => &mut self.kernel_dispatch,
            Category::Waiting(Wait::Load) => &mut self.waiting_load,
            Category::Waiting(Wait::Store) => &mut self.waiting_store,
            Category::Waiting(Wait::Gather) => &mut self.waiting_gather,
            Category::Waiting(Wait::Scatter) => &mut self.waiting_scatter,
            Category::Waiting(Wait::HostTransfer) => &mut self.waiting_host_transfer,
            Category::Waiting(Wait::MicrocodeLoad) => &mut self.waiting_microcode_load,
            Category::Waiting(Wait::Rasterizer) => &mut self.waiting_rasterizer,
            Category::Issue => &mut self.issue,
            Category::Host => &mut self.host,
            Category::Drain => &mut self.drain,
        }
    }

    /// Every category with its cycles, named as [`Category::name`] names them (kernels as
    /// `kernels running`), in a fixed order.
    pub fn rows(&self) -> [(&'static str, u64); 12] {
        [
            ("kernels running", self.kernel_running),
            ("kernel dispatch", self.kernel_dispatch),
            ("waiting: load", self.waiting_load),
            ("waiting: store", self.waiting_store),
            ("waiting: gather", self.waiting_gather),
            ("waiting: scatter", self.waiting_scatter),
            ("waiting: host transfer", self.waiting_host_transfer),
            ("waiting: microcode load", self.waiting_microcode_load),
            ("waiting: hardware rasterizer", self.waiting_rasterizer),
            ("issue", self.issue),
            ("host", self.host),
            ("drain", self.drain),
        ]
    }

    /// The cycles waiting on a stream instruction, of every kind.
    pub fn waiting(&self) -> u64 {
        self.waiting_load
            + self.waiting_store
            + self.waiting_gather
            + self.waiting_scatter
            + self.waiting_host_transfer
            + self.waiting_microcode_load
            + self.waiting_rasterizer
    }

    /// The cycles of every category together.
    pub fn total(&self) -> u64 {
        self.rows().iter().map(|(_, c)| c).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use imagine_units::dram::activity::{Activity, SAMPLE_CYCLES};

    /// A channel whose data bus is busy for `transfer` and switching rows for `rows` of
    /// every sample period.
    fn channel(periods: u64, transfer: u64, rows: u64) -> ActivityLog {
        let mut log = ActivityLog::default();
        for p in 1..=periods {
            let a = Activity {
                transfer_cycles: p * transfer,
                row_switch_cycles: p * rows,
                ..Activity::default()
            };
            log.sample(p * SAMPLE_CYCLES, a);
        }
        log
    }

    #[test]
    fn waits_split_by_the_busiest_channel_in_proportion() {
        let (busy, idle) = (channel(100, 32, 16), channel(100, 0, 0));
        let dram = DramActivity {
            channels: vec![&idle, &busy],
            dram_per_core: 0.5,
        };
        // 1,000 core cycles are 500 DRAM cycles: half transferring, a quarter switching.
        assert_eq!(dram.split(&(2_000..3_000)), (500, 250));
        let saturated = channel(100, SAMPLE_CYCLES, 0);
        let dram = DramActivity {
            channels: vec![&saturated],
            dram_per_core: 1.0,
        };
        assert_eq!(dram.split(&(64..640)), (576, 0));
        assert_eq!(DramActivity::default().split(&(0..100)), (0, 0));
        // Equally busy channels: the first one's split, whatever the others say (the
        // attribution must not depend on the order the design holds its modules in).
        let (transferring, switching) = (channel(100, 32, 0), channel(100, 0, 32));
        let first = |channels| DramActivity {
            channels,
            dram_per_core: 1.0,
        };
        assert_eq!(
            first(vec![&transferring, &switching]).split(&(0..640)),
            (320, 0)
        );
        assert_eq!(
            first(vec![&switching, &transferring]).split(&(0..640)),
            (0, 320)
        );
    }

    #[test]
    fn a_part_of_a_wait_keeps_its_proportions_and_sums_exactly() {
        let on = WaitingOn {
            scoreboard: 3,
            dram_bandwidth: 5,
            bank_conflicts: 1,
            memory_latency: 0,
            unit_busy: 1,
        };
        for part in 0..=10 {
            assert_eq!(on.part(part, 10).total(), part);
        }
        assert_eq!(on.part(5, 10).dram_bandwidth, 3);
        assert_eq!(on.part(10, 10), on);
    }

    #[test]
    fn a_window_counts_the_segments_it_meets_as_a_scan_of_them_all_would() {
        // Consecutive segments of lengths 1..=6, alternating between a kernel and a wait.
        let mut segments = Vec::new();
        let mut start = 10;
        for len in 1..=6u64 {
            let (category, waiting_on) = if len % 2 == 0 {
                (Category::KernelDispatch, WaitingOn::default())
            } else {
                let on = WaitingOn {
                    scoreboard: len,
                    ..WaitingOn::default()
                };
                (Category::Waiting(Wait::Load), on)
            };
            segments.push(Segment {
                cycles: start..start + len,
                category,
                waiting_on,
            });
            start += len;
        }
        let scan = |window: &Range<u64>| {
            let (mut dispatch, mut waiting) = (0, 0);
            for s in &segments {
                let n = s.overlap(window);
                match s.category {
                    Category::KernelDispatch => dispatch += n,
                    _ => waiting += n,
                }
            }
            (dispatch, waiting)
        };
        for from in 0..start + 2 {
            for to in from..start + 3 {
                let window = from..to;
                let a = Attribution::of(&segments, window.clone());
                let on = WaitingOn::of(&segments, window.clone());
                assert_eq!(
                    (a.kernel_dispatch, a.waiting_load),
                    scan(&window),
                    "{window:?}"
                );
                assert_eq!(on.scoreboard, scan(&window).1, "{window:?}");
            }
        }
    }
}
