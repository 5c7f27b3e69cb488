//! The stream processor as a whole: the stream controller, the address generators, the
//! clusters and the SRF in the core clock domain, and the SDRAM channels in the DRAM clock
//! domain, joined by synchronising FIFOs (ARCHITECTURE §4).
//!
//! ```text
//!  host ─▶ stream controller ─┬─▶ clusters + SRF (Machine)
//!          (queue, scoreboard)├─▶ AG0, AG1 ◀──▶ SRF stream buffers
//!                             └─▶ microcode loader     │
//!                                   MemPorts ◀─ async FIFOs ─▶ top.mem.chN (DRAM domain)
//! ```
//!
//! The core-domain part is one hdl module, [`Processor`] (its blocks are evaluated in a
//! fixed order within the cycle and each reads only committed state of the others); each
//! channel is its own module. A stream program ([`StreamProgram`]) is a list of stream
//! instructions plus the kernels they name; the host hands all of them to the stream
//! controller before the first cycle and the run ends when every instruction has
//! completed and the channels are idle.
//!
//! Idle time: when nothing in the processor can change before a known core cycle (the
//! clusters held only for the minimum kernel time, the memory system and the channels
//! idle), [`run_until`] jumps to that cycle in one step with exactly the state and
//! counters stepping leaves (see [`idle`]); with a tracer attached it steps.

use std::cell::Cell;
use std::rc::Rc;

use imagine_hdl::{
    ClockDomain, ContractError, Design, Display, DomainId, Module, SignalId, SignalKind, Sim,
    Trace, Violation, bits_for,
};

use crate::desc::MachineDesc;
use crate::dram::replay::report_of;
use crate::dram::{DramChannel, DramParams, Policy, ReplayReport, Reply};
use crate::hwrast::Rasterizer;
use crate::machine::Machine;
use crate::memory::texture_cache::Waiter;
use crate::memory::{AddressGenerator, MemPorts, MemoryConfig, TextureCache, build_memory};
use crate::microcode::Program;
use crate::runner::{OnStart, RunError};
use crate::stream_controller::{InstrRecord, Issue, StreamController, StreamInstr, Unit};

pub mod idle;
pub use idle::run_until;

/// Characters of the text probes `sc.kernel` and `sc.issue` (longer names are cut).
const TEXT_CHARS: u32 = 24;

/// Kernels and the stream instructions that use them.
#[derive(Clone, Debug, Default)]
pub struct StreamProgram {
    pub kernels: Vec<Program>,
    pub instrs: Vec<StreamInstr>,
}

/// How to build the processor.
#[derive(Default)]
pub struct ProcessorOptions {
    /// The scheduling policy (`None`: the machine description's).
    pub policy: Option<Policy>,
    /// Keep every DRAM request, for `--dram-trace`.
    pub record_dram: bool,
    /// Words to place in DRAM before the run: (word address, words).
    pub dram_init: Vec<(u64, Vec<u32>)>,
    /// Words to place in the SRF before the run: (SRF word, words).
    pub srf_init: Vec<(usize, Vec<u32>)>,
    pub on_start: Option<OnStart>,
    /// Step every idle cycle instead of jumping over idle time (the results are the same;
    /// tests compare the two).
    pub step_idle: bool,
}

/// A host interface transfer in progress, done at cycle `done`: a write's words land in
/// the SRF then, a read takes its words then.
struct HostTransfer {
    id: usize,
    done: u64,
    start: usize,
    kind: HostTransferKind,
}

enum HostTransferKind {
    Write(Vec<u32>),
    Read(usize),
}

struct RunningKernel {
    id: usize,
    program: usize,
    started: u64,
}

/// The core-domain part of the processor.
pub struct Processor {
    domain: DomainId,
    machine: Machine,
    ags: Vec<AddressGenerator>,
    ports: MemPorts,
    texture_cache: Option<TextureCache>,
    /// The hardware rasterizer (`[rasterizer]` machines), and the call it runs.
    rasterizer: Option<Rasterizer>,
    raster_op: Option<usize>,
    /// Words the texture cache hands to waiting references this cycle.
    deliveries: Vec<(Waiter, u32)>,
    sc: StreamController,
    cycle: u64,
    issue: Option<Issue>,
    kernel: Option<RunningKernel>,
    /// Microcode load in progress: (instruction, done at cycle).
    loader: Option<(usize, u64)>,
    host_transfer: Option<HostTransfer>,
    ag_ops: Vec<Option<usize>>,
    replies: Vec<Reply>,
    /// An error met at a clock edge, reported by the next `eval`.
    deferred: Option<ContractError>,
    /// Whether [`run_until`] may jump over idle time, and the core cycles it has jumped.
    skip_idle: bool,
    skipped: u64,
    /// Set at each edge when jumping is on and the clusters and the address generators are
    /// idle: the cheap part of the idle test, which [`run_until`] reads every cycle
    /// without looking the processor up among the modules.
    maybe_idle: Rc<Cell<bool>>,
    path: String,
    ids: [SignalId; 5],
    /// `sc.kernel` and `sc.issue`: the running kernel's name and the stream instruction
    /// issued at the last edge, as text.
    text_ids: [SignalId; 2],
    /// The instruction issued at the last edge, for `sc.issue`.
    issued_last: Option<usize>,
}

impl Processor {
    pub fn controller(&self) -> &StreamController {
        &self.sc
    }

    pub fn machine(&self) -> &Machine {
        &self.machine
    }

    /// The machine, for a host that writes kernel parameters into the SRF between cycles
    /// (the microcontroller's scalar registers, which the host sets over its interface).
    pub fn machine_mut(&mut self) -> &mut Machine {
        &mut self.machine
    }

    pub fn texture_cache(&self) -> Option<&TextureCache> {
        self.texture_cache.as_ref()
    }

    pub fn rasterizer(&self) -> Option<&Rasterizer> {
        self.rasterizer.as_ref()
    }

    fn rasterizer_busy(&self) -> bool {
        self.rasterizer.as_ref().is_some_and(Rasterizer::is_busy)
    }

    pub fn address_generators(&self) -> &[AddressGenerator] {
        &self.ags
    }

    /// The host appends a stream instruction (between cycles); returns its index in
    /// [`StreamController::records`].
    pub fn push(&mut self, instr: StreamInstr) -> usize {
        self.sc.push(instr)
    }

    /// Adds a kernel compiled after the processor was built (checked against the machine
    /// as [`build`] checks its programs); returns its program index.
    pub fn add_program(&mut self, desc: &MachineDesc, program: Program) -> Result<usize, String> {
        program
            .check(desc)
            .map_err(|e| format!("kernel `{}`: {e}", program.name))?;
        Ok(self.sc.add_program(program))
    }

    /// Core cycles [`run_until`] has jumped over as idle time (0 when stepping).
    pub fn skipped_cycles(&self) -> u64 {
        self.skipped
    }

    /// What computes the clusters' fp32 ops without a tracer ([`Machine::set_datapath`]).
    pub fn set_datapath(&mut self, datapath: crate::ops::Datapath) {
        self.machine.set_datapath(datapath);
    }

    /// Whether [`run_until`] may jump over idle time (`false`: step every cycle).
    pub fn set_skip_idle(&mut self, on: bool) {
        self.skip_idle = on;
    }

    /// Whether every stream instruction has completed.
    pub fn is_done(&self) -> bool {
        self.sc.is_done() && self.issue.is_none()
    }

    fn error(&self, what: &str, msg: String) -> ContractError {
        ContractError::at(&format!("{}.{what}", self.path), Violation::Other(msg))
    }

    fn start(&mut self, is: &Issue) -> Result<(), ContractError> {
        let cycle = self.cycle;
        match (&is.instr, is.unit) {
            (StreamInstr::Memory(op), Unit::AddressGenerator(a)) => {
                self.ags[a].start(*op, self.machine.srf_mut())?;
                self.ag_ops[a] = Some(is.id);
            }
            (StreamInstr::Kernel { program, bindings }, Unit::Clusters) => {
                let p = &self.sc.programs()[*program];
                if !self.sc.is_resident(*program) {
                    return Err(self.error(
                        "issue",
                        format!("kernel `{}` issued before its microcode was loaded", p.name),
                    ));
                }
                let p = p.clone();
                self.machine
                    .start_checked(p, bindings)
                    .map_err(|e| self.error("issue", e.to_string()))?;
                self.kernel = Some(RunningKernel {
                    id: is.id,
                    program: *program,
                    started: cycle,
                });
            }
            (StreamInstr::LoadMicrocode { program }, Unit::MicrocodeLoader) => {
                let in_use = self.kernel.as_ref().map(|k| k.program);
                self.sc
                    .load_microcode(*program, in_use)
                    .map_err(|e| self.error("issue", e))?;
                let len = self.sc.programs()[*program].code.len() as u64;
                self.loader = Some((is.id, cycle + len.max(1)));
            }
            (StreamInstr::WriteSrf { start, words }, Unit::HostInterface) => {
                self.host_transfer = Some(HostTransfer {
                    id: is.id,
                    done: cycle + self.sc.host_transfer_cycles(words.len()),
                    start: *start,
                    kind: HostTransferKind::Write(words.clone()),
                });
            }
            (StreamInstr::ReadSrf { start, len }, Unit::HostInterface) => {
                self.host_transfer = Some(HostTransfer {
                    id: is.id,
                    done: cycle + self.sc.host_transfer_cycles(*len),
                    start: *start,
                    kind: HostTransferKind::Read(*len),
                });
            }
            (StreamInstr::Rasterize(job), Unit::Rasterizer) => {
                let Some(r) = self.rasterizer.as_mut() else {
                    return Err(self.error(
                        "issue",
                        "a hardware rasterizer call on a machine without a rasterizer \
                         ([rasterizer] in its description)"
                            .into(),
                    ));
                };
                r.start((**job).clone(), self.machine.srf_mut())?;
                self.raster_op = Some(is.id);
            }
            _ => unreachable!("the controller picks a unit of the instruction's kind"),
        }
        Ok(())
    }

    fn edge(&mut self) -> Result<(), ContractError> {
        let cycle = self.cycle;
        for ag in &mut self.ags {
            ag.commit(self.machine.srf_mut())?;
        }
        self.ports.commit();
        if let Some(c) = &mut self.texture_cache {
            c.commit();
        }
        for a in 0..self.ags.len() {
            if self.ags[a].just_finished()
                && let Some(id) = self.ag_ops[a].take()
            {
                self.sc.complete(id, cycle);
            }
        }
        if let Some(k) = &self.kernel
            && self.machine.is_idle()
            && cycle >= k.started + self.sc.min_kernel_cycles()
        {
            let id = k.id;
            let streams = &self.sc.programs()[k.program].streams;
            let outputs = streams
                .iter()
                .enumerate()
                .map(|(i, d)| match d.dir {
                    crate::microcode::StreamDir::Out => self.machine.output_len(i),
                    crate::microcode::StreamDir::In => 0,
                })
                .collect();
            let stats = self.machine.stats().cloned().unwrap_or_default();
            self.sc.record_kernel(id, outputs, stats);
            self.machine.release_streams()?;
            self.sc.complete(id, cycle);
            self.kernel = None;
        }
        if let Some(r) = &mut self.rasterizer {
            r.commit(self.machine.srf_mut())?;
            if let Some(result) = r.take_finished()
                && let Some(id) = self.raster_op.take()
            {
                self.sc.record_raster(id, result);
                self.sc.complete(id, cycle);
            }
        }
        if let Some((id, done)) = self.loader
            && cycle >= done
        {
            self.sc.complete(id, cycle);
            self.loader = None;
        }
        if let Some(t) = self.host_transfer.take_if(|t| cycle >= t.done) {
            match t.kind {
                HostTransferKind::Write(words) => self.machine.srf_mut().load(t.start, &words)?,
                HostTransferKind::Read(len) => {
                    let words = self.machine.srf().read_back(t.start, len)?;
                    self.sc.record_read(t.id, words);
                }
            }
            self.sc.complete(t.id, cycle);
        }
        let issue = self.issue.take();
        self.issued_last = issue.as_ref().map(|is| is.id);
        if let Some(is) = &issue {
            self.start(is)?;
        }
        self.sc.commit(cycle, issue.as_ref());
        Ok(())
    }
}

impl Module for Processor {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        if let Some(e) = self.deferred.take() {
            return Err(e);
        }
        let rasterizer_free = !self.rasterizer_busy();
        let ags = &self.ags;
        self.issue = self.sc.select(
            |a| !ags[a].is_busy(),
            ags.len(),
            self.kernel.is_none(),
            self.loader.is_none(),
            self.host_transfer.is_none(),
            rasterizer_free,
        );
        self.replies.clear();
        self.ports.pop_replies(&mut self.replies)?;
        for r in &self.replies {
            let Some(ag) = self.ags.get_mut(r.tag.source as usize) else {
                return Err(self.error(
                    "replies",
                    format!("a reply for address generator {}", r.tag.source),
                ));
            };
            if let Some((word, value)) = ag.accept(r)?
                && let Some(c) = &mut self.texture_cache
            {
                c.fill(word, value, &mut self.deliveries);
            }
        }
        for (w, value) in self.deliveries.drain(..) {
            self.ags[w.ag].deliver(w.slot, value)?;
        }
        // The address generators take turns at offering references first (round robin).
        let n = self.ags.len();
        // (An idle generator's evaluation does nothing: it is not called.)
        for k in 0..n {
            let ag = &mut self.ags[(self.cycle as usize + k) % n];
            if ag.is_busy() {
                ag.eval(
                    self.machine.srf_mut(),
                    &mut self.ports,
                    self.texture_cache.as_mut(),
                )?;
            }
        }
        if let Some(r) = &mut self.rasterizer {
            r.eval(self.machine.srf_mut())?;
        }
        self.machine.eval()
    }

    fn commit(&mut self) {
        self.machine.commit();
        if let Err(e) = self.edge() {
            self.deferred = Some(e);
        }
        self.cycle += 1;
        self.maybe_idle.set(
            self.skip_idle
                && self.machine.is_idle()
                && !self.ags.iter().any(|a| a.is_busy())
                && !self.rasterizer_busy(),
        );
    }

    fn set_tracing(&mut self, on: bool) {
        self.machine.set_tracing(on);
    }

    fn trace(&self, t: &mut Trace) {
        self.machine.trace(t);
        self.ags.iter().for_each(|a| a.trace(t));
        if let Some(c) = &self.texture_cache {
            c.trace(t);
        }
        if let Some(r) = &self.rasterizer {
            r.trace(t);
        }
        t.value(self.ids[0], self.sc.occupancy() as u64);
        t.value(self.ids[1], self.kernel.is_some() as u64);
        t.value(self.ids[2], self.loader.is_some() as u64);
        t.value(
            self.ids[3],
            self.ags.iter().filter(|a| a.is_busy()).count() as u64,
        );
        t.value(self.ids[4], self.host_transfer.is_some() as u64);
        let programs = self.sc.programs();
        let kernel = self
            .kernel
            .as_ref()
            .map_or("", |k| &programs[k.program].name);
        t.text(self.text_ids[0], kernel);
        let issued = self
            .issued_last
            .map(|id| self.sc.records()[id].kind(programs))
            .unwrap_or_default();
        t.text(self.text_ids[1], &issued);
    }
}

/// Builds the processor of `desc` running `program`.
pub fn build(
    desc: &MachineDesc,
    program: StreamProgram,
    mut opts: ProcessorOptions,
) -> Result<Sim, RunError> {
    let setup = |e: String| RunError::Setup(e);
    if desc.dram.burst_words != 1 {
        return Err(setup(format!(
            "machine `{}`: the address generators issue one-word references and need \
             dram.burst_words = 1, not {}",
            desc.name, desc.dram.burst_words
        )));
    }
    for (i, k) in program.kernels.iter().enumerate() {
        k.check(desc)
            .map_err(|e| setup(format!("kernel {i} (`{}`): {e}", k.name)))?;
    }
    for (i, instr) in program.instrs.iter().enumerate() {
        let bad = match instr {
            StreamInstr::Kernel { program: p, .. } | StreamInstr::LoadMicrocode { program: p } => {
                *p >= program.kernels.len()
            }
            StreamInstr::Memory(m) => m.record_words == 0,
            StreamInstr::WriteSrf { start, words } => {
                words.is_empty() || start + words.len() > desc.srf.words
            }
            StreamInstr::ReadSrf { start, len } => *len == 0 || start + len > desc.srf.words,
            StreamInstr::Rasterize(_) => desc.rasterizer.is_none(),
        };
        if bad {
            return Err(setup(format!(
                "stream instruction {i} names a kernel that is not in the program, has \
                 0-word records, moves no words or words past the end of the SRF, or calls a \
                 rasterizer the machine does not have"
            )));
        }
    }
    let domains = vec![
        ClockDomain::mhz("core", desc.clocks.core_mhz),
        ClockDomain::mhz("dram", desc.clocks.dram_mhz),
    ];
    let mut design = Design::new("top", domains).map_err(|e| setup(e.to_string()))?;
    let core = design.domain("core").map_err(|e| setup(e.to_string()))?;
    let policy = match opts.policy {
        Some(p) => p,
        None => Policy::parse(&desc.memory.policy).expect("validated"),
    };
    let ports = build_memory(
        &mut design,
        desc,
        MemoryConfig {
            policy,
            record: opts.record_dram,
            init: std::mem::take(&mut opts.dram_init),
        },
    )
    .map_err(|e| setup(e.to_string()))?;
    let mut top = design.scope();
    let mut machine = Machine::new(&mut top, desc);
    for (start, words) in &opts.srf_init {
        machine.srf_mut().load(*start, words)?;
    }
    let m = &desc.memory;
    let ags = (0..m.address_generators)
        .map(|k| {
            AddressGenerator::new(
                &mut top.child(&format!("ag{k}")),
                k,
                desc.srf.stream_buffers,
                m.ag_words_per_cycle,
                m.ag_reorder_words,
            )
        })
        .collect::<Vec<_>>();
    let texture_cache = desc
        .texture_cache
        .as_ref()
        .map(|d| TextureCache::new(&mut top.child("texture_cache"), d));
    let rasterizer = Rasterizer::new(&mut top.child("rasterizer"), desc);
    let mut s = top.child("sc");
    let ids = [
        s.signal(
            "scoreboard",
            bits_for(desc.stream_controller.scoreboard_entries as u64),
            SignalKind::Reg,
        ),
        s.signal("kernel_busy", 1, SignalKind::Reg),
        s.signal("loader_busy", 1, SignalKind::Reg),
        s.signal(
            "ags_busy",
            bits_for(m.address_generators as u64),
            SignalKind::Reg,
        ),
        s.signal("host_busy", 1, SignalKind::Reg),
    ];
    let text_ids = [
        s.signal_shown("kernel", 8 * TEXT_CHARS, SignalKind::Reg, Display::Text),
        s.signal_shown("issue", 8 * TEXT_CHARS, SignalKind::Wire, Display::Text),
    ];
    let path = s.path().to_string();
    let n_ags = ags.len();
    design.add(Processor {
        domain: core,
        machine,
        ags,
        ports,
        texture_cache,
        rasterizer,
        raster_op: None,
        deliveries: Vec::new(),
        sc: StreamController::new(desc, program.kernels, program.instrs),
        cycle: 0,
        issue: None,
        kernel: None,
        loader: None,
        host_transfer: None,
        ag_ops: vec![None; n_ags],
        replies: Vec::new(),
        deferred: None,
        skip_idle: !opts.step_idle,
        skipped: 0,
        maybe_idle: Rc::default(),
        path,
        ids,
        text_ids,
        issued_last: None,
    });
    let mut sim = Sim::new(design);
    if let Some(f) = opts.on_start.take() {
        f(&mut sim).map_err(RunError::Setup)?;
    }
    Ok(sim)
}

/// What a stream program run did.
#[derive(Clone, Debug)]
pub struct StreamReport {
    pub core_cycles: u64,
    pub dram_cycles: u64,
    /// Per stream instruction: when it entered the scoreboard, issued and completed.
    pub records: Vec<InstrRecord>,
    /// Per instruction, a short name (`load`, `kernel madd`, …).
    pub names: Vec<String>,
    pub dram: ReplayReport,
}

pub fn processor(sim: &Sim) -> &Processor {
    sim.modules_of::<Processor>()
        .next()
        .expect("the design holds a processor")
}

pub fn processor_mut(sim: &mut Sim) -> &mut Processor {
    sim.modules_of_mut::<Processor>()
        .next()
        .expect("the design holds a processor")
}

/// Runs a built processor until the stream program has completed.
pub fn run(
    sim: &mut Sim,
    desc: &MachineDesc,
    max_core_cycles: u64,
) -> Result<StreamReport, RunError> {
    let done = |p: &Processor, sim: &Sim| {
        p.is_done() && sim.modules_of::<DramChannel>().all(DramChannel::is_idle)
    };
    let finished = run_until(sim, max_core_cycles, done)?;
    sim.finish()
        .map_err(|e| RunError::Setup(format!("cannot finish the trace: {e}")))?;
    if !finished {
        return Err(RunError::Timeout {
            kernel: "stream program".into(),
            cycles: max_core_cycles,
        });
    }
    let p = processor(sim);
    let dram = sim.clocks().find("dram").expect("built with a DRAM domain");
    let policy = sim
        .modules_of::<DramChannel>()
        .next()
        .map(DramChannel::policy)
        .unwrap_or(Policy::FirstReady);
    Ok(StreamReport {
        core_cycles: sim.core_cycles(),
        dram_cycles: sim.clocks().cycles(dram),
        names: p
            .sc
            .records()
            .iter()
            .map(|r| r.kind(p.sc.programs()))
            .collect(),
        records: p.sc.records().to_vec(),
        dram: report_of(sim, policy, &DramParams::of(desc)),
    })
}

/// `n` words of DRAM from word address `word` (host view, after a run).
pub fn read_dram(sim: &Sim, desc: &MachineDesc, word: u64, n: usize) -> Vec<u32> {
    let p = DramParams::of(desc);
    let chans: Vec<&DramChannel> = sim.modules_of::<DramChannel>().collect();
    (0..n as u64)
        .map(|k| {
            let byte = (word + k) * 4;
            p.map(byte)
                .and_then(|l| chans.iter().find(|c| c.index() == l.channel))
                .and_then(|c| c.peek(byte))
                .unwrap_or(0)
        })
        .collect()
}
