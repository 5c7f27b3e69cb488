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
//! What the memory operations waited on in turn (DRAM bandwidth, bank conflicts) is not
//! split further here; the DRAM statistics give row hits and bandwidth.

use std::ops::Range;

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

/// Cycles `start..end` in one category.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment {
    pub cycles: Range<u64>,
    pub category: Category,
}

/// Every cycle of `window` in one category, as consecutive segments covering it exactly.
pub fn attribute(records: &[InstrRecord], window: Range<u64>) -> Vec<Segment> {
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

    let mut out = Vec::new();
    let mut push = |cycles: Range<u64>, category: Category| {
        let cycles = cycles.start.max(window.start)..cycles.end.min(window.end);
        if cycles.is_empty() {
            return;
        }
        match out.last_mut() {
            Some(Segment {
                cycles: last,
                category: c,
            }) if *c == category && last.end == cycles.start => {
                last.end = cycles.end;
            }
            _ => out.push(Segment { cycles, category }),
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
            .map(|&(c, _, w)| (c, w))
    };
    let mut now = window.start;
    for &(id, issued, completed, program, ran) in &calls {
        if issued > now {
            match last_done(now, issued, id) {
                Some((c, w)) => {
                    push(now..c, Category::Waiting(w));
                    push(c..issued, Category::Issue);
                }
                None => push(now..issued, Category::Host),
            }
        }
        let start = issued.max(now);
        let kernel_end = (start + ran).min(completed);
        push(start..kernel_end, Category::Kernel(program));
        push(kernel_end..completed, Category::KernelDispatch);
        now = now.max(completed);
    }
    if now < window.end {
        match last_done(now, window.end, usize::MAX) {
            Some((c, w)) => {
                push(now..c, Category::Waiting(w));
                push(c..window.end, Category::Drain);
            }
            None => push(now..window.end, Category::Drain),
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
    pub issue: u64,
    pub host: u64,
    pub drain: u64,
}

impl Attribution {
    /// The part of `segments` inside `window`.
    pub fn of(segments: &[Segment], window: Range<u64>) -> Self {
        let mut a = Attribution::default();
        for s in segments {
            let from = s.cycles.start.max(window.start);
            let overlap = s.cycles.end.min(window.end).saturating_sub(from);
            *a.slot(&s.category) += overlap;
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
            Category::Issue => &mut self.issue,
            Category::Host => &mut self.host,
            Category::Drain => &mut self.drain,
        }
    }

    /// Every category with its cycles, named as [`Category::name`] names them (kernels as
    /// `kernels running`), in a fixed order.
    pub fn rows(&self) -> [(&'static str, u64); 11] {
        [
            ("kernels running", self.kernel_running),
            ("kernel dispatch", self.kernel_dispatch),
            ("waiting: load", self.waiting_load),
            ("waiting: store", self.waiting_store),
            ("waiting: gather", self.waiting_gather),
            ("waiting: scatter", self.waiting_scatter),
            ("waiting: host transfer", self.waiting_host_transfer),
            ("waiting: microcode load", self.waiting_microcode_load),
            ("issue", self.issue),
            ("host", self.host),
            ("drain", self.drain),
        ]
    }

    /// The cycles of every category together.
    pub fn total(&self) -> u64 {
        self.rows().iter().map(|(_, c)| c).sum()
    }
}
