//! The stream controller (ARCHITECTURE §4): takes stream instructions from the host,
//! tracks their dependencies in a scoreboard and issues them to the address generators
//! (loads, stores), the clusters (kernels) and the microcode store (microcode loads).
//!
//! * **Queue**: the host writes instructions into a queue of
//!   `stream_controller.queue_entries`; one instruction per cycle moves from the queue into
//!   a free scoreboard entry.
//! * **Scoreboard** (`stream_controller.scoreboard_entries`, 32 on gold8): an entry may
//!   issue when no older entry still in the scoreboard conflicts with it and its unit is
//!   free. Two instructions conflict when one writes what the other reads or writes: SRF
//!   words (a load writes its SRF stream, a store reads it, a kernel reads its inputs and
//!   writes its outputs, an indexed stream also reads its index stream), DRAM words (a
//!   store writes its range, a load reads it; an indexed stream may touch any word unless
//!   it has a bound, and then only the records below it), or a
//!   kernel's microcode (a microcode load writes it, a kernel reads it). Of the entries
//!   that may issue, the oldest issues, one per cycle; an entry leaves the scoreboard when
//!   its operation completes.
//! * **Units**: the address generators (`memory.address_generators`), the clusters (one
//!   kernel at a time), and the microcode loader (one program at a time, one VLIW
//!   instruction per cycle (A), into a store of `microcontroller.store_words`
//!   instructions; the oldest programs not in use are evicted to make room).
//! * **Host interface**: moves `stream_controller.host_words_per_cycle` words per core
//!   cycle between the host and the SRF, one transfer at a time. A host write (kernel
//!   parameters) lands in the SRF when it completes (the scoreboard keeps every reader of
//!   those words waiting until then, so the write needs no SRF port arbitration); a host
//!   read (a count a kernel computed) takes its words when it completes, after every
//!   older writer of them (and before any younger one).
//! * **Host dispatch overhead**: a kernel holds the clusters for at least
//!   `stream_controller.min_kernel_cycles` core cycles (300 on gold8; Owens 2002 measured
//!   200–500), however short its microcode run.
//!
//! The controller is pure decision logic: [`StreamController::select`] picks from
//! committed state; the processor starts the chosen operation at the clock edge and
//! reports completions back with [`StreamController::complete`].

use std::collections::VecDeque;
use std::sync::Arc;

use crate::desc::MachineDesc;
use crate::hwrast::{RasterJob, RasterResult};
use crate::machine::{KernelStats, StreamBinding};

/// The name the hardware rasterizer's calls go by in records, breakdowns and waveforms.
pub const RASTERIZER_KERNEL: &str = "hwrast";
use crate::memory::{MemOp, MemOpKind};
use crate::microcode::{Program, StreamDir};

/// A stream instruction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StreamInstr {
    /// A stream memory operation (load or store) on an address generator.
    Memory(MemOp),
    /// Run program `program` (an index into the stream program's kernels) with its
    /// streams bound to these SRF regions, in declaration order.
    Kernel {
        program: usize,
        bindings: Vec<StreamBinding>,
    },
    /// Load program `program`'s microcode into the microcode store.
    LoadMicrocode { program: usize },
    /// Write `words`, sent by the host with the instruction, into the SRF from word
    /// `start`: scalar values for kernels (parameters), as Imagine's host interface
    /// carried them.
    WriteSrf { start: usize, words: Vec<u32> },
    /// Read `len` SRF words from word `start` back to the host (the words are in the
    /// instruction's [`InstrRecord::read`] once it completes): how the host learns a
    /// number the machine computed, such as an iteration count.
    ReadSrf { start: usize, len: usize },
    /// Run the hardware rasterizer ([`crate::hwrast`]) as a hardware kernel: its input
    /// streams routed from the SRF into it, its outputs back (thesis §6.6).
    Rasterize(Box<RasterJob>),
}

/// The unit an instruction runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    AddressGenerator(usize),
    Clusters,
    MicrocodeLoader,
    HostInterface,
    Rasterizer,
}

/// When an instruction went through the controller (core cycles).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InstrRecord {
    pub instr: StreamInstr,
    /// Entered the scoreboard.
    pub entered: Option<u64>,
    pub issued: Option<u64>,
    pub unit: Option<Unit>,
    pub completed: Option<u64>,
    /// A kernel's words written per stream (0 for inputs) and statistics, once completed.
    pub outputs: Vec<usize>,
    pub kernel_stats: Option<KernelStats>,
    /// The words a host read brought back, once completed.
    pub read: Vec<u32>,
    /// What a hardware rasterizer call did, once completed.
    pub raster: Option<RasterResult>,
}

impl InstrRecord {
    fn new(instr: StreamInstr) -> Self {
        InstrRecord {
            instr,
            entered: None,
            issued: None,
            unit: None,
            completed: None,
            outputs: Vec::new(),
            kernel_stats: None,
            read: Vec::new(),
            raster: None,
        }
    }

    /// A short name: `load`, `store`, `kernel NAME`, `microcode NAME`.
    pub fn kind(&self, programs: &[Arc<Program>]) -> String {
        match &self.instr {
            StreamInstr::Memory(m) if m.kind == MemOpKind::Load => "load".into(),
            StreamInstr::Memory(_) => "store".into(),
            StreamInstr::Kernel { program, .. } => format!("kernel {}", programs[*program].name),
            StreamInstr::LoadMicrocode { program } => {
                format!("microcode {}", programs[*program].name)
            }
            StreamInstr::WriteSrf { .. } => "host write".into(),
            StreamInstr::ReadSrf { .. } => "host read".into(),
            StreamInstr::Rasterize(_) => format!("kernel {RASTERIZER_KERNEL}"),
        }
    }
}

/// What an instruction reads and writes, for the scoreboard.
#[derive(Clone, Debug, Default)]
struct Footprint {
    srf_reads: Vec<(usize, usize)>,
    srf_writes: Vec<(usize, usize)>,
    /// DRAM words `[lo, hi)`; `None` inside means the whole memory.
    mem_reads: Vec<Option<(u64, u64)>>,
    mem_writes: Vec<Option<(u64, u64)>>,
    code_read: Option<usize>,
    code_write: Option<usize>,
}

fn overlap(a: (usize, usize), b: (usize, usize)) -> bool {
    a.1 > 0 && b.1 > 0 && a.0 < b.0 + b.1 && b.0 < a.0 + a.1
}

fn mem_overlap(a: Option<(u64, u64)>, b: Option<(u64, u64)>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => a.0 < b.1 && b.0 < a.1,
        _ => true,
    }
}

impl Footprint {
    fn of(instr: &StreamInstr, programs: &[Arc<Program>]) -> Self {
        let mut f = Footprint::default();
        match instr {
            StreamInstr::Memory(m) => {
                let region = (m.srf_start, m.words());
                if let Some(ix) = m.index_region() {
                    f.srf_reads.push(ix);
                }
                match m.kind {
                    MemOpKind::Load => {
                        f.srf_writes.push(region);
                        f.mem_reads.push(m.mem_range());
                    }
                    MemOpKind::Store => {
                        f.srf_reads.push(region);
                        f.mem_writes.push(m.mem_range());
                    }
                }
            }
            StreamInstr::Kernel { program, bindings } => {
                for (s, b) in programs[*program].streams.iter().zip(bindings) {
                    match s.dir {
                        StreamDir::In => f.srf_reads.push((b.start, b.words)),
                        StreamDir::Out => f.srf_writes.push((b.start, b.words)),
                    }
                }
                f.code_read = Some(*program);
            }
            StreamInstr::LoadMicrocode { program } => f.code_write = Some(*program),
            StreamInstr::WriteSrf { start, words } => f.srf_writes.push((*start, words.len())),
            StreamInstr::ReadSrf { start, len } => f.srf_reads.push((*start, *len)),
            StreamInstr::Rasterize(job) => {
                f.srf_reads
                    .extend(job.inputs.iter().map(|b| (b.start, b.words)));
                f.srf_writes
                    .extend(job.outputs.iter().map(|b| (b.start, b.words)));
            }
        }
        f
    }

    /// Whether `later` must wait for `self` (an older instruction).
    fn blocks(&self, later: &Footprint) -> bool {
        let srf = |w: &[(usize, usize)], r: &[(usize, usize)]| {
            w.iter().any(|&a| r.iter().any(|&b| overlap(a, b)))
        };
        let mem = |w: &[Option<(u64, u64)>], r: &[Option<(u64, u64)>]| {
            w.iter().any(|&a| r.iter().any(|&b| mem_overlap(a, b)))
        };
        srf(&self.srf_writes, &later.srf_reads)
            || srf(&self.srf_writes, &later.srf_writes)
            || (srf(&later.srf_writes, &self.srf_reads) && !war_ignored())
            || mem(&self.mem_writes, &later.mem_reads)
            || mem(&self.mem_writes, &later.mem_writes)
            || mem(&later.mem_writes, &self.mem_reads)
            || (self.code_write.is_some()
                && (self.code_write == later.code_read || self.code_write == later.code_write))
            || (later.code_write.is_some() && later.code_write == self.code_read)
    }
}

/// Whether the injected bug that drops write-after-read hazards is on (never without the
/// `inject-bugs` feature).
#[inline(always)]
fn war_ignored() -> bool {
    #[cfg(feature = "inject-bugs")]
    {
        imagine_hdl::inject::active(imagine_hdl::inject::Bug::ScoreboardIgnoresWriteAfterRead)
    }
    #[cfg(not(feature = "inject-bugs"))]
    {
        false
    }
}

#[derive(Clone, Debug)]
struct Entry {
    /// Index into the instruction list (program order).
    id: usize,
    footprint: Footprint,
    running: bool,
}

/// Counters of the controller.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ScStats {
    /// Cycles some scoreboard entry was ready but its unit was busy.
    pub unit_busy_cycles: u64,
    /// Cycles the scoreboard was full while the queue held instructions.
    pub scoreboard_full_cycles: u64,
    /// Most entries in the scoreboard at once.
    pub max_occupancy: usize,
}

pub struct StreamController {
    /// Shared with the clusters while a kernel runs (no copy per call).
    programs: Vec<Arc<Program>>,
    records: Vec<InstrRecord>,
    /// Instructions the host has not yet written into the queue, and the queue.
    host: VecDeque<usize>,
    queue: VecDeque<usize>,
    queue_cap: usize,
    scoreboard: Vec<Entry>,
    /// Per scoreboard entry, whether no older entry blocks it; `None` once the scoreboard
    /// has changed. (Footprints are fixed, so this changes only when entries come or go:
    /// the host model need not compare every pair of entries every cycle.)
    unblocked: Option<Vec<bool>>,
    /// The last [`pick`](Self::pick): the units it saw free and its answer, kept while the
    /// scoreboard stays as it was (most cycles nothing comes, goes or issues).
    last_pick: Option<(UnitsFree, Picked)>,
    sb_cap: usize,
    min_kernel: u64,
    host_words_per_cycle: usize,
    store_words: usize,
    /// Programs in the microcode store, oldest first.
    resident: Vec<usize>,
    stats: ScStats,
}

/// The units an instruction could issue on this cycle (address generator `a` free: bit
/// `a` of `ags`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct UnitsFree {
    ags: u64,
    clusters: bool,
    loader: bool,
    host: bool,
    rasterizer: bool,
}

/// The oldest entry that may issue (its instruction and unit), and whether some entry was
/// ready with its unit busy.
type Picked = (Option<(usize, Unit)>, bool);

/// What an [`idle`](StreamController::idle) controller counts each cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdleCounts {
    /// An entry is ready but its unit is busy ([`ScStats::unit_busy_cycles`]).
    pub unit_busy: bool,
    /// The scoreboard is full and the queue holds instructions
    /// ([`ScStats::scoreboard_full_cycles`]).
    pub scoreboard_full: bool,
}

/// The operation the controller wants started this cycle.
#[derive(Clone, Debug)]
pub struct Issue {
    pub id: usize,
    pub unit: Unit,
    pub instr: StreamInstr,
}

impl StreamController {
    pub fn new(desc: &MachineDesc, programs: Vec<Program>, instrs: Vec<StreamInstr>) -> Self {
        let n = instrs.len();
        StreamController {
            programs: programs.into_iter().map(Arc::new).collect(),
            records: instrs.into_iter().map(InstrRecord::new).collect(),
            host: (0..n).collect(),
            queue: VecDeque::new(),
            queue_cap: desc.stream_controller.queue_entries,
            scoreboard: Vec::new(),
            unblocked: None,
            last_pick: None,
            sb_cap: desc.stream_controller.scoreboard_entries,
            min_kernel: desc.stream_controller.min_kernel_cycles,
            host_words_per_cycle: desc.stream_controller.host_words_per_cycle,
            store_words: desc.microcontroller.store_words,
            resident: Vec::new(),
            stats: ScStats::default(),
        }
    }

    pub fn programs(&self) -> &[Arc<Program>] {
        &self.programs
    }

    /// Adds a program the host compiled after the run began (a kernel the frame reached
    /// late); returns its index for [`StreamInstr::Kernel`] and
    /// [`StreamInstr::LoadMicrocode`].
    pub fn add_program(&mut self, program: Program) -> usize {
        self.programs.push(Arc::new(program));
        self.programs.len() - 1
    }

    /// The host appends an instruction (between cycles); returns its index.
    pub fn push(&mut self, instr: StreamInstr) -> usize {
        self.records.push(InstrRecord::new(instr));
        self.host.push_back(self.records.len() - 1);
        self.records.len() - 1
    }

    /// Notes what a completed kernel instruction wrote.
    pub fn record_kernel(&mut self, id: usize, outputs: Vec<usize>, stats: KernelStats) {
        let r = &mut self.records[id];
        r.outputs = outputs;
        r.kernel_stats = Some(stats);
    }

    pub fn records(&self) -> &[InstrRecord] {
        &self.records
    }

    pub fn stats(&self) -> &ScStats {
        &self.stats
    }

    /// Notes what a completed rasterizer call wrote.
    pub fn record_raster(&mut self, id: usize, result: RasterResult) {
        let r = &mut self.records[id];
        r.outputs = result.outputs.clone();
        r.raster = Some(result);
    }

    /// Notes the words a completed host read brought back.
    pub fn record_read(&mut self, id: usize, words: Vec<u32>) {
        self.records[id].read = words;
    }

    /// Core cycles the host interface takes to move `words` words.
    pub fn host_transfer_cycles(&self, words: usize) -> u64 {
        words.div_ceil(self.host_words_per_cycle).max(1) as u64
    }

    pub fn min_kernel_cycles(&self) -> u64 {
        self.min_kernel
    }

    /// Whether every instruction has completed.
    pub fn is_done(&self) -> bool {
        self.host.is_empty() && self.queue.is_empty() && self.scoreboard.is_empty()
    }

    /// Entries in the scoreboard.
    pub fn occupancy(&self) -> usize {
        self.scoreboard.len()
    }

    /// Picks the oldest scoreboard entry that may issue on a free unit (`free_ag` gives the
    /// free address generators, `clusters_free`, `loader_free` and `host_free` the other
    /// units), from committed state.
    pub fn select(
        &mut self,
        free_ag: impl Fn(usize) -> bool,
        ags: usize,
        clusters_free: bool,
        loader_free: bool,
        host_free: bool,
        rasterizer_free: bool,
    ) -> Option<Issue> {
        let free = [clusters_free, loader_free, host_free, rasterizer_free];
        match self.pick(free_ag, ags, free) {
            (Some((id, unit)), _) => Some(Issue {
                id,
                unit,
                instr: self.records[id].instr.clone(),
            }),
            (None, unit_busy) => {
                self.stats.unit_busy_cycles += u64::from(unit_busy);
                None
            }
        }
    }

    /// Whether the controller does nothing in the cycles ahead while its units stay as
    /// they are (arguments as for [`select`](Self::select)): nothing may issue, and no
    /// instruction moves from the host into the queue or from the queue into the
    /// scoreboard. Then each such cycle only counts, as [`skip_idle`](Self::skip_idle)
    /// does.
    pub fn idle(
        &mut self,
        free_ag: impl Fn(usize) -> bool,
        ags: usize,
        clusters_free: bool,
        loader_free: bool,
        host_free: bool,
        rasterizer_free: bool,
    ) -> Option<IdleCounts> {
        if !self.host.is_empty() && self.queue.len() < self.queue_cap {
            return None;
        }
        if !self.queue.is_empty() && self.scoreboard.len() < self.sb_cap {
            return None;
        }
        let free = [clusters_free, loader_free, host_free, rasterizer_free];
        match self.pick(free_ag, ags, free) {
            (Some(_), _) => None,
            (None, unit_busy) => Some(IdleCounts {
                unit_busy,
                scoreboard_full: !self.queue.is_empty(),
            }),
        }
    }

    /// Counts `n` cycles in which the controller was [`idle`](Self::idle) with `counts`,
    /// as `n` cycles of `select` and `commit` would.
    pub fn skip_idle(&mut self, n: u64, counts: IdleCounts) {
        self.stats.unit_busy_cycles += n * u64::from(counts.unit_busy);
        self.stats.scoreboard_full_cycles += n * u64::from(counts.scoreboard_full);
        self.stats.max_occupancy = self.stats.max_occupancy.max(self.scoreboard.len());
    }

    /// The oldest entry that may issue (its instruction and unit), and whether some entry
    /// was ready with its unit busy.
    /// `free`: the clusters, the microcode loader, the host interface and the rasterizer.
    fn pick(&mut self, free_ag: impl Fn(usize) -> bool, ags: usize, free: [bool; 4]) -> Picked {
        let [clusters, loader, host, rasterizer] = free;
        let free = UnitsFree {
            ags: (0..ags).fold(0u64, |m, a| m | (u64::from(free_ag(a)) << a)),
            clusters,
            loader,
            host,
            rasterizer,
        };
        if let Some((seen, picked)) = self.last_pick
            && seen == free
        {
            return picked;
        }
        let picked = self.pick_among(free);
        self.last_pick = Some((free, picked));
        picked
    }

    fn pick_among(&mut self, free: UnitsFree) -> Picked {
        let mut unit_busy = false;
        let board = &self.scoreboard;
        let unblocked = self.unblocked.get_or_insert_with(|| {
            (0..board.len())
                .map(|k| {
                    !board[..k]
                        .iter()
                        .any(|o| o.footprint.blocks(&board[k].footprint))
                })
                .collect()
        });
        for (k, e) in self.scoreboard.iter().enumerate() {
            if e.running || !unblocked[k] {
                continue;
            }
            let instr = &self.records[e.id].instr;
            let unit = match instr {
                StreamInstr::Memory(_) => (free.ags != 0)
                    .then(|| Unit::AddressGenerator(free.ags.trailing_zeros() as usize)),
                StreamInstr::Kernel { .. } => free.clusters.then_some(Unit::Clusters),
                StreamInstr::LoadMicrocode { .. } => free.loader.then_some(Unit::MicrocodeLoader),
                StreamInstr::WriteSrf { .. } | StreamInstr::ReadSrf { .. } => {
                    free.host.then_some(Unit::HostInterface)
                }
                StreamInstr::Rasterize(_) => free.rasterizer.then_some(Unit::Rasterizer),
            };
            match unit {
                Some(unit) => return (Some((e.id, unit)), unit_busy),
                None => unit_busy = true,
            }
        }
        (None, unit_busy)
    }

    /// The clock edge: records the issue of `issue` in `cycle`, and moves one instruction
    /// host → queue and one queue → scoreboard.
    pub fn commit(&mut self, cycle: u64, issue: Option<&Issue>) {
        if let Some(is) = issue {
            let r = &mut self.records[is.id];
            r.issued = Some(cycle);
            r.unit = Some(is.unit);
            if let Some(e) = self.scoreboard.iter_mut().find(|e| e.id == is.id) {
                e.running = true;
                self.last_pick = None;
            }
        }
        if self.scoreboard.len() < self.sb_cap {
            if let Some(id) = self.queue.pop_front() {
                let footprint = Footprint::of(&self.records[id].instr, &self.programs);
                self.records[id].entered = Some(cycle);
                self.scoreboard.push(Entry {
                    id,
                    footprint,
                    running: false,
                });
                self.unblocked = None;
                self.last_pick = None;
            }
        } else if !self.queue.is_empty() {
            self.stats.scoreboard_full_cycles += 1;
        }
        if self.queue.len() < self.queue_cap
            && let Some(id) = self.host.pop_front()
        {
            self.queue.push_back(id);
        }
        self.stats.max_occupancy = self.stats.max_occupancy.max(self.scoreboard.len());
    }

    /// Instruction `id` completed in `cycle`: its entry leaves the scoreboard.
    pub fn complete(&mut self, id: usize, cycle: u64) {
        self.records[id].completed = Some(cycle);
        self.scoreboard.retain(|e| e.id != id);
        self.unblocked = None;
        self.last_pick = None;
    }

    /// Makes room for and records program `p` in the microcode store; `in_use` is the
    /// program the clusters are running. Errors if it cannot fit.
    pub fn load_microcode(&mut self, p: usize, in_use: Option<usize>) -> Result<(), String> {
        let size = |q: usize| self.programs[q].code.len();
        if size(p) > self.store_words {
            return Err(format!(
                "kernel `{}` has {} instructions; the microcode store holds {}",
                self.programs[p].name,
                size(p),
                self.store_words
            ));
        }
        self.resident.retain(|&q| q != p);
        while self.resident.iter().map(|&q| size(q)).sum::<usize>() + size(p) > self.store_words {
            let Some(pos) = self.resident.iter().position(|&q| Some(q) != in_use) else {
                break;
            };
            self.resident.remove(pos);
        }
        self.resident.push(p);
        Ok(())
    }

    /// Everything that evolves but the programs and the memo of unblocked entries (a
    /// function of the scoreboard), for tests that compare a run that skipped idle cycles
    /// with one that stepped them.
    #[cfg(test)]
    pub(crate) fn debug_state(&self) -> String {
        format!(
            "records {:?}\nhost {:?}\nqueue {:?}\nscoreboard {:?}\nresident {:?}\nstats {:?}",
            self.records, self.host, self.queue, self.scoreboard, self.resident, self.stats
        )
    }

    /// Whether program `p`'s microcode is in the store.
    pub fn is_resident(&self, p: usize) -> bool {
        self.resident.contains(&p)
    }
}
