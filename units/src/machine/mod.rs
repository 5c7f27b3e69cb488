//! The composed machine (ARCHITECTURE §4): the microcontroller, the clusters (functional
//! units, LRFs, intracluster switch, condition codes, scratchpads, intercluster network,
//! stream ports) and the SRF, built from a [`MachineDesc`] and clocked as one hdl
//! [`Module`] in the core domain.
//!
//! The clusters are lane-batched: each unit object models one unit slot in every cluster,
//! so one microinstruction is executed for all clusters in tight loops over lanes.
//!
//! Each cycle:
//!
//! 1. the microcontroller fetches the instruction (entering or skipping loops) and decides
//!    which software-pipeline stages are live;
//! 2. if a live stream access cannot proceed (an input stream buffer without the words, an
//!    output stream buffer without room), the whole cluster array stalls: no unit advances
//!    and the instruction issues again next cycle; only the SRF keeps moving data;
//! 3. otherwise results due this cycle go through the switch to LRFs, condition codes and
//!    output streams, the live slots read their operands and issue, and the microcontroller
//!    picks the next instruction;
//! 4. at the edge every block commits.
//!
//! After the `Done` instruction the machine waits for every result in flight, then flushes
//! the output stream buffers into the SRF; then the kernel is over.

mod decode;

use std::fmt;
use std::sync::Arc;

use imagine_hdl::{ContractError, DomainId, Module, Scope, Trace, Violation};

use crate::ccfile::CcFile;
use crate::comm::CommUnit;
use crate::delay::{DelayLine, InFlight};
use crate::desc::MachineDesc;
use crate::fu::{Adder, DivSqrt, Multiplier};
use crate::lanes::{copy_lanes, copy_mask, count, count_set};
use crate::lrf::Lrf;
use crate::microcode::{Dest, Dests, ImmValue, Program, StreamDir};
use crate::microcontroller::{LoopEnv, Microcontroller, Phase};
use crate::ops::{Datapath, Op};
use crate::scratchpad::Scratchpad;
use crate::srf::Srf;
use crate::switch::{StreamSink, route};
use decode::{Decoded, DecodedInst, FuUnit, Inputs};

/// Where a kernel's stream lives in the SRF: its first word and its length (inputs) or the
/// room reserved for it (outputs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamBinding {
    pub start: usize,
    pub words: usize,
}

/// A kernel that cannot be started on this machine.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StartError(pub String);

impl fmt::Display for StartError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for StartError {}

/// What a kernel run did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KernelStats {
    /// Cycles from start to the end of the output flush.
    pub cycles: u64,
    /// Cycles the clusters stalled on stream buffers.
    pub stall_cycles: u64,
    /// Instructions issued.
    pub instructions: u64,
    /// Ops issued per FU slot (adders, multipliers, divide/sqrt), counting each slot once
    /// per cycle (an op covers every cluster).
    pub fu_ops: Vec<u64>,
    /// Ops squashed (not issued) in software-pipeline prologues and epilogues.
    pub squashed: u64,
    /// Loop passes ended, every loop's (a loop of `N` iterations and `S` software-pipeline
    /// stages runs `N + S − 1`).
    pub loop_passes: u64,
}

impl KernelStats {
    /// Arithmetic ops per cycle across all clusters.
    pub fn ops_per_cycle(&self, clusters: usize) -> f64 {
        self.fu_ops.iter().sum::<u64>() as f64 * clusters as f64 / self.cycles.max(1) as f64
    }
}

struct Kernel {
    program: Arc<Program>,
    decoded: Arc<Decoded>,
    bindings: Vec<StreamBinding>,
    stats: KernelStats,
    flushing: bool,
}

/// The SRF seen through a kernel's stream bindings (stream `i` uses stream buffer `i`).
struct Streams<'a> {
    srf: &'a mut Srf,
    lanes: usize,
}

impl StreamSink for Streams<'_> {
    fn append(
        &mut self,
        stream: u16,
        values: &[u32],
        mask: Option<&[bool]>,
    ) -> Result<(), ContractError> {
        match mask {
            None => self.srf.write(stream as usize, values),
            Some(m) => {
                let mut packed = [0u32; crate::desc::MAX_CLUSTERS];
                let mut n = 0;
                for c in 0..self.lanes {
                    if m[c] {
                        packed[n] = values[c];
                        n += 1;
                    }
                }
                #[cfg(feature = "inject-bugs")]
                if n == self.lanes
                    && imagine_hdl::inject::active(
                        imagine_hdl::inject::Bug::CondOutputDropsLastWord,
                    )
                {
                    n -= 1;
                }
                self.srf.write_conditional(stream as usize, &packed[..n])
            }
        }
    }
}

struct Env<'a> {
    srf: &'a Srf,
    cc: &'a CcFile,
    lanes: usize,
}

impl LoopEnv for Env<'_> {
    fn rows_left(&self, stream: u16) -> u64 {
        self.srf.remaining(stream as usize).div_ceil(self.lanes) as u64
    }
    fn exhausted(&self, stream: u16) -> bool {
        self.srf.remaining(stream as usize) == 0
    }
    fn cc_all(&self, cc: u16) -> Result<bool, ContractError> {
        self.cc.all(cc)
    }
}

/// The arithmetic units of a cluster, addressed by FU slot (adders, then multipliers, then
/// divide/sqrt units), as the microcode numbers them.
struct Fus {
    adders: Vec<Adder>,
    multipliers: Vec<Multiplier>,
    divsqrts: Vec<DivSqrt>,
}

impl Fus {
    /// Issues a checked op (see [`Pipelined::issue_checked`]) to `unit`.
    ///
    /// [`Pipelined::issue_checked`]: crate::fu::Pipelined::issue_checked
    #[inline(always)]
    fn issue<const L: usize>(
        &mut self,
        unit: FuUnit,
        op: Op,
        operands: [&[u32]; 3],
        tag: u16,
    ) -> Result<(), ContractError> {
        match unit {
            FuUnit::Adder(i) => self.adders[i as usize].issue_checked::<L>(op, operands, tag),
            FuUnit::Multiplier(i) => {
                self.multipliers[i as usize].issue_checked::<L>(op, operands, tag)
            }
            FuUnit::DivSqrt(i) => self.divsqrts[i as usize].issue_checked::<L>(op, operands, tag),
        }
    }

    fn in_flight(&self) -> usize {
        self.adders.iter().map(|u| u.in_flight()).sum::<usize>()
            + self
                .multipliers
                .iter()
                .map(|u| u.in_flight())
                .sum::<usize>()
            + self.divsqrts.iter().map(|u| u.in_flight()).sum::<usize>()
    }

    fn is_quiet(&self) -> bool {
        self.adders.iter().all(|u| u.is_quiet())
            && self.multipliers.iter().all(|u| u.is_quiet())
            && self.divsqrts.iter().all(|u| u.is_quiet())
    }

    fn skip_idle(&mut self, n: u64) {
        self.adders.iter_mut().for_each(|u| u.skip_idle(n));
        self.multipliers.iter_mut().for_each(|u| u.skip_idle(n));
        self.divsqrts.iter_mut().for_each(|u| u.skip_idle(n));
    }

    fn commit(&mut self) {
        self.adders.iter_mut().for_each(|u| u.commit());
        self.multipliers.iter_mut().for_each(|u| u.commit());
        self.divsqrts.iter_mut().for_each(|u| u.commit());
    }

    fn set_datapath(&mut self, datapath: Datapath) {
        self.adders
            .iter_mut()
            .for_each(|u| u.set_datapath(datapath));
        self.multipliers
            .iter_mut()
            .for_each(|u| u.set_datapath(datapath));
        self.divsqrts
            .iter_mut()
            .for_each(|u| u.set_datapath(datapath));
    }

    fn set_tracing(&mut self, on: bool) {
        self.adders.iter_mut().for_each(|u| u.set_tracing(on));
        self.multipliers.iter_mut().for_each(|u| u.set_tracing(on));
        self.divsqrts.iter_mut().for_each(|u| u.set_tracing(on));
    }

    fn trace(&self, t: &mut Trace) {
        self.adders.iter().for_each(|u| u.trace(t));
        self.multipliers.iter().for_each(|u| u.trace(t));
        self.divsqrts.iter().for_each(|u| u.trace(t));
    }
}

/// Every unit whose result port feeds the intracluster switch.
struct Sources<'a> {
    fus: &'a Fus,
    scratchpads: &'a [Scratchpad],
    comms: &'a [CommUnit],
    stream_reads: &'a [DelayLine],
    immediates: &'a DelayLine,
}

/// What takes each result leaving a unit in a cycle: its destinations, one word per
/// cluster, and the clusters that write it (`None`: all).
trait ResultSink<'a> {
    fn take(
        &mut self,
        dests: &'a Dests,
        values: &'a [u32],
        mask: Option<&'a [bool]>,
    ) -> Result<(), ContractError>;
}

impl<'a, F> ResultSink<'a> for F
where
    F: FnMut(&'a Dests, &'a [u32], Option<&'a [bool]>) -> Result<(), ContractError>,
{
    #[inline(always)]
    fn take(
        &mut self,
        dests: &'a Dests,
        values: &'a [u32],
        mask: Option<&'a [bool]>,
    ) -> Result<(), ContractError> {
        self(dests, values, mask)
    }
}

/// The intracluster switch as the cycle's result sink, compiled for `L` lanes
/// (`crate::lanes`): each result goes to its LRF entries, condition codes and output
/// streams. (A trait method that is always inlined, where a closure called from every
/// source's loop was not: this runs for every result.)
struct Switch<'b, const L: usize> {
    lrfs: &'b mut [Lrf],
    cc: &'b mut CcFile,
    all_lanes: &'b [bool],
    streams: Streams<'b>,
}

impl<'a, const L: usize> ResultSink<'a> for Switch<'_, L> {
    #[inline(always)]
    fn take(
        &mut self,
        dests: &'a Dests,
        values: &'a [u32],
        mask: Option<&'a [bool]>,
    ) -> Result<(), ContractError> {
        let all_lanes = self.all_lanes;
        route::<L>(
            dests,
            values,
            mask,
            all_lanes,
            self.lrfs,
            self.cc,
            &mut self.streams,
        )
    }
}

impl<'a> Sources<'a> {
    /// Hands `sink` the destinations, words and cluster mask of every result leaving a unit
    /// this cycle, in port order. A result's destinations are those its slot had in the
    /// instruction that issued it (its tag).
    #[inline(always)]
    fn for_each_due(
        &self,
        decoded: &'a Decoded,
        sink: &mut impl ResultSink<'a>,
    ) -> Result<(), ContractError> {
        let ports = decoded.ports_of;
        let mask = |r: &'a InFlight| r.masked.then_some(&r.mask[..]);
        // The FU slots: adders, multipliers, divide/sqrt units, by loops rather than a
        // chained iterator, which did not inline.
        let mut slot = 0;
        for u in &self.fus.adders {
            if let Some(c) = u.completed() {
                sink.take(decoded.route(c.tag, slot), c.values, None)?;
            }
            slot += 1;
        }
        for u in &self.fus.multipliers {
            if let Some(c) = u.completed() {
                sink.take(decoded.route(c.tag, slot), c.values, None)?;
            }
            slot += 1;
        }
        for u in &self.fus.divsqrts {
            if let Some(c) = u.completed() {
                sink.take(decoded.route(c.tag, slot), c.values, None)?;
            }
            slot += 1;
        }
        for (i, sp) in self.scratchpads.iter().enumerate() {
            if let Some(r) = sp.completed() {
                sink.take(decoded.route(r.tag, ports.sp + i), &r.values, mask(r))?;
            }
        }
        for (i, cu) in self.comms.iter().enumerate() {
            if let Some(r) = cu.completed() {
                sink.take(decoded.route(r.tag, ports.comm + i), &r.values, None)?;
            }
        }
        for (i, line) in self.stream_reads.iter().enumerate() {
            if let Some(r) = line.current() {
                sink.take(decoded.route(r.tag, ports.sin + i), &r.values, mask(r))?;
            }
        }
        if let Some(r) = self.immediates.current() {
            sink.take(decoded.route(r.tag, ports.imm), &r.values, None)?;
        }
        Ok(())
    }
}

/// Programs kept in issue form (a frame's pipeline has a few dozen kernels at most; a
/// caller that starts copies of programs, as `Machine::start` makes, does not grow the set).
const DECODED_PROGRAMS: usize = 64;

/// The machine.
pub struct Machine {
    desc: MachineDesc,
    lanes: usize,
    path: String,
    fus: Fus,
    lrfs: Vec<Lrf>,
    cc: CcFile,
    scratchpads: Vec<Scratchpad>,
    comms: Vec<CommUnit>,
    stream_reads: Vec<DelayLine>,
    immediates: DelayLine,
    srf: Srf,
    uc: Microcontroller,
    /// Boxed: each cycle takes it out of the machine and puts it back.
    kernel: Option<Box<Kernel>>,
    /// The programs started so far in issue form (a program is decoded the first time it
    /// starts, not on every call). Each entry holds its program, so the program's address
    /// identifies it as long as the entry lives.
    decoded: Vec<(Arc<Program>, Arc<Decoded>)>,
    /// LRF indices of each slot's inputs.
    fu_inputs: Vec<[usize; 2]>,
    sp_inputs: Vec<[usize; 2]>,
    comm_inputs: Vec<[usize; 2]>,
    sout_input: usize,
    stalled: bool,
    /// The clusters are asleep: no kernel runs and nothing is in flight or pending in
    /// them, so a cycle only turns their pipelines' rings. They are brought over the
    /// `idle_cycles` they slept in one step (`wake_clusters`) before anything can change
    /// them (a kernel starts, a tracer is attached) instead of committing each cycle.
    asleep: bool,
    idle_cycles: u64,
    /// A tracer is attached: the clusters commit every cycle, as their probes are read.
    tracing: bool,
    all_lanes: Vec<bool>,
    buf: [Vec<u32>; 3],
    mask: Vec<bool>,
}

impl Machine {
    /// Builds the machine of `desc` under `scope` (probes `scope.cluster3.add0.result`, …).
    pub fn new(scope: &mut Scope<'_>, desc: &MachineDesc) -> Self {
        let lanes = desc.cluster.count;
        let c = &desc.cluster;
        let l = &desc.latency;
        let names = desc.lrf_names();
        let index = |n: String| {
            names
                .iter()
                .position(|m| *m == n)
                .expect("LRF names are complete")
        };
        let units = |prefix: &str, n: usize, inputs: [&str; 2]| -> Vec<[usize; 2]> {
            (0..n)
                .map(|i| inputs.map(|inp| index(format!("{prefix}{i}.{inp}"))))
                .collect()
        };
        let mut fu_inputs = units("add", c.adders, ["a", "b"]);
        fu_inputs.extend(units("mul", c.multipliers, ["a", "b"]));
        fu_inputs.extend(units("dsq", c.divsqrt, ["a", "b"]));
        let sp_inputs = units("sp", c.scratchpads, ["addr", "data"]);
        let comm_inputs = units("comm", c.comm_units, ["data", "perm"]);
        let path = scope.path().to_string();
        let max_latency = l.stream.max(1);
        Machine {
            fus: Fus {
                adders: (0..c.adders)
                    .map(|i| Adder::new(scope, &format!("add{i}"), lanes, desc))
                    .collect(),
                multipliers: (0..c.multipliers)
                    .map(|i| Multiplier::new(scope, &format!("mul{i}"), lanes, desc))
                    .collect(),
                divsqrts: (0..c.divsqrt)
                    .map(|i| DivSqrt::new(scope, &format!("dsq{i}"), lanes, desc))
                    .collect(),
            },
            lrfs: names
                .iter()
                .map(|n| Lrf::new(scope, n, desc.lrf_entries(n), lanes))
                .collect(),
            cc: CcFile::new(scope, c.condition_codes, lanes),
            scratchpads: (0..c.scratchpads)
                .map(|i| {
                    Scratchpad::new(
                        scope,
                        &format!("sp{i}"),
                        desc.scratchpad.words,
                        lanes,
                        l.scratchpad_read,
                        l.scratchpad_write,
                    )
                })
                .collect(),
            comms: (0..c.comm_units)
                .map(|i| CommUnit::new(scope, &format!("comm{i}"), lanes, l.comm))
                .collect(),
            stream_reads: (0..desc.srf.cluster_words_per_cycle)
                .map(|i| DelayLine::new(format!("{path}.sin{i}"), lanes, max_latency))
                .collect(),
            immediates: DelayLine::new(format!("{path}.imm"), lanes, 1),
            srf: Srf::new(&mut scope.child("srf"), desc),
            uc: Microcontroller::new(
                scope,
                desc.microcontroller.store_words,
                desc.microcontroller.loop_depth,
            ),
            kernel: None,
            decoded: Vec::new(),
            fu_inputs,
            sp_inputs,
            comm_inputs,
            sout_input: index("sout.data".into()),
            stalled: false,
            asleep: false,
            idle_cycles: 0,
            // As every block: a machine outside a simulator is traced until told otherwise.
            tracing: true,
            all_lanes: vec![true; lanes],
            buf: [vec![0; lanes], vec![0; lanes], vec![0; lanes]],
            mask: vec![true; lanes],
            lanes,
            path,
            desc: desc.clone(),
        }
    }

    pub fn desc(&self) -> &MachineDesc {
        &self.desc
    }

    /// What computes the fp32 ops of the adders, multipliers and divide/sqrt units while no
    /// tracer is attached: the host fast path unless told otherwise (the same words and
    /// flags; with a tracer the bit-level datapath, the model of record, always does).
    pub fn set_datapath(&mut self, datapath: Datapath) {
        self.fus.set_datapath(datapath);
    }

    pub fn lanes(&self) -> usize {
        self.lanes
    }

    pub fn srf(&self) -> &Srf {
        &self.srf
    }

    pub fn srf_mut(&mut self) -> &mut Srf {
        &mut self.srf
    }

    /// Words all LRFs have read and written so far, over all clusters: `(read, written)`.
    pub fn lrf_words_moved(&self) -> (u64, u64) {
        self.lrfs
            .iter()
            .map(Lrf::words_moved)
            .fold((0, 0), |(r, w), (a, b)| (r + a, w + b))
    }

    pub fn lrf(&self, name: &str) -> Option<&Lrf> {
        self.desc
            .lrf_names()
            .iter()
            .position(|n| n == name)
            .map(|i| &self.lrfs[i])
    }

    pub fn scratchpad(&self, i: usize) -> &Scratchpad {
        &self.scratchpads[i]
    }

    /// Starts `program` with its streams bound to SRF regions (stream `i` on stream buffer
    /// `i`). The program must fit this machine.
    pub fn start(
        &mut self,
        program: &Program,
        bindings: &[StreamBinding],
    ) -> Result<(), StartError> {
        program
            .check(&self.desc)
            .map_err(|e| StartError(e.to_string()))?;
        self.start_checked(Arc::new(program.clone()), bindings)
    }

    /// [`start`](Self::start) for a program already checked against this machine (the
    /// stream controller checks its programs once, when they are loaded), shared rather
    /// than copied.
    pub(crate) fn start_checked(
        &mut self,
        program: Arc<Program>,
        bindings: &[StreamBinding],
    ) -> Result<(), StartError> {
        if let Some(k) = &self.kernel
            && self.uc.phase() != Phase::Idle
        {
            return Err(StartError(format!(
                "kernel `{}` is still running",
                k.program.name
            )));
        }
        if bindings.len() != program.streams.len() {
            return Err(StartError(format!(
                "kernel `{}` has {} streams, {} bound",
                program.name,
                program.streams.len(),
                bindings.len()
            )));
        }
        self.wake_clusters();
        if self.kernel.take().is_some() {
            self.release_streams()
                .map_err(|e| StartError(e.to_string()))?;
        }
        for (i, (s, b)) in program.streams.iter().zip(bindings).enumerate() {
            let bound = match s.dir {
                StreamDir::In => {
                    if b.words % self.lanes != 0 {
                        return Err(StartError(format!(
                            "kernel `{}`: input stream `{}` has {} words, not a multiple of the {} clusters",
                            program.name, s.name, b.words, self.lanes
                        )));
                    }
                    self.srf.bind_input(i, b.start, b.words)
                }
                StreamDir::Out => self.srf.bind_output(i, b.start, b.words),
            };
            bound.map_err(|e| {
                StartError(format!(
                    "kernel `{}`, stream `{}`: {e}",
                    program.name, s.name
                ))
            })?;
        }
        self.uc
            .start(&program.code)
            .map_err(|e| StartError(e.to_string()))?;
        let decoded = self.decoded_form(&program);
        // Conditional streams keep two scratchpad words per conditional word per cycle
        // for their buffers (ARCHITECTURE §4).
        let buffers = if decoded.conditional_streams {
            2 * self.desc.srf.conditional_words_per_cycle
        } else {
            0
        };
        self.scratchpads[0].reserve_for_conditional_streams(buffers);
        let fu_slots = self.fu_inputs.len();
        self.kernel = Some(Box::new(Kernel {
            program,
            decoded,
            bindings: bindings.to_vec(),
            stats: KernelStats {
                fu_ops: vec![0; fu_slots],
                ..KernelStats::default()
            },
            flushing: false,
        }));
        Ok(())
    }

    /// `program` in issue form, decoded the first time it starts.
    fn decoded_form(&mut self, program: &Arc<Program>) -> Arc<Decoded> {
        if let Some((_, d)) = self.decoded.iter().find(|(p, _)| Arc::ptr_eq(p, program)) {
            return d.clone();
        }
        let c = &self.desc.cluster;
        let d = Arc::new(Decoded::new(
            program,
            &Inputs {
                fu: &self.fu_inputs,
                sp: &self.sp_inputs,
                comm: &self.comm_inputs,
                sout: self.sout_input,
                sin: self.stream_reads.len(),
                adders: c.adders,
                multipliers: c.multipliers,
            },
        ));
        if self.decoded.len() == DECODED_PROGRAMS {
            self.decoded.remove(0);
        }
        self.decoded.push((program.clone(), d.clone()));
        d
    }

    /// Unbinds the stream buffers of the last kernel (once it is idle), so the memory
    /// system may bind their SRF regions; its statistics stay. Streams already released
    /// are skipped.
    pub fn release_streams(&mut self) -> Result<(), ContractError> {
        if let Some(k) = &self.kernel {
            for i in 0..k.program.streams.len() {
                if self.srf.mode(i) != crate::srf::SbMode::Idle {
                    self.srf.unbind(i)?;
                }
            }
        }
        Ok(())
    }

    /// Whether no kernel is running.
    pub fn is_idle(&self) -> bool {
        self.uc.phase() == Phase::Idle
    }

    /// Whether the cycles ahead change nothing but counters and ring positions: no kernel
    /// is running (none started, or the last one has finished and flushed), nothing is in
    /// flight in any unit, and the SRF's stream buffers ask nothing of its port (see
    /// [`Srf::idle_skippable`]). The stream controller may still hold a finished kernel
    /// for its minimum time; the memory system's own stream buffers must be idle too.
    pub fn idle_skippable(&self) -> bool {
        !self.stalled && self.clusters_quiet() && self.srf.idle_skippable()
    }

    /// No kernel runs and nothing is issued or in flight in the clusters.
    fn clusters_quiet(&self) -> bool {
        self.uc.phase() == Phase::Idle && self.fus.is_quiet() && self.in_flight() == 0
    }

    /// Brings an [`idle_skippable`](Self::idle_skippable) machine over `n ≥ 1` cycles,
    /// leaving it as `n` idle cycles would: the units' pipelines turn with nothing in
    /// them, the probe latches of the last cycle clear, the SRF counts idle cycles.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.idle_skippable() && n > 0);
        self.srf.skip_idle(n);
        if self.asleep {
            self.idle_cycles += n;
            return;
        }
        self.skip_clusters(n);
    }

    /// Brings the quiet clusters over `n ≥ 1` idle cycles, as `n` commits would.
    fn skip_clusters(&mut self, n: u64) {
        self.fus.skip_idle(n);
        // Between idle cycles nothing is pending in an LRF or the condition codes: an
        // LRF's commit only clears its probe latches, the condition codes' does nothing.
        self.lrfs.iter_mut().for_each(|u| u.skip_idle());
        self.scratchpads.iter_mut().for_each(|u| u.skip_idle(n));
        self.comms.iter_mut().for_each(|u| u.skip_idle(n));
        self.stream_reads.iter_mut().for_each(|u| u.skip_idle(n));
        self.immediates.skip_idle(n);
    }

    /// Brings sleeping clusters over the cycles they slept (see the `asleep` field).
    pub(crate) fn wake_clusters(&mut self) {
        if std::mem::take(&mut self.asleep) {
            let n = std::mem::take(&mut self.idle_cycles);
            if n > 0 {
                self.skip_clusters(n);
            }
        }
    }

    /// Everything that evolves (tests compare a run that skipped idle cycles with one that
    /// stepped them).
    #[cfg(test)]
    pub(crate) fn debug_state(&self) -> String {
        let kernel = self
            .kernel
            .as_ref()
            .map(|k| (&k.program.name, &k.bindings, &k.stats, k.flushing));
        format!(
            "srf {:?}\nadders {:?}\nmultipliers {:?}\ndivsqrts {:?}\nlrfs {:?}\ncc {:?}\n\
             scratchpads {:?}\ncomms {:?}\nstream_reads {:?}\nimmediates {:?}\nuc {:?}\n\
             kernel {kernel:?}\nstalled {}",
            self.srf,
            self.fus.adders,
            self.fus.multipliers,
            self.fus.divsqrts,
            self.lrfs,
            self.cc,
            self.scratchpads,
            self.comms,
            self.stream_reads,
            self.immediates,
            self.uc,
            self.stalled
        )
    }

    /// Statistics of the current or last kernel.
    pub fn stats(&self) -> Option<&KernelStats> {
        self.kernel.as_ref().map(|k| &k.stats)
    }

    /// Words the last kernel wrote to its stream `i` (an output stream).
    pub fn output_len(&self, i: usize) -> usize {
        self.srf.output_len(i)
    }

    /// The binding of the current or last kernel's stream `i`.
    pub fn binding(&self, i: usize) -> Option<StreamBinding> {
        self.kernel
            .as_ref()
            .and_then(|k| k.bindings.get(i).copied())
    }

    fn in_flight(&self) -> usize {
        self.fus.in_flight()
            + self
                .scratchpads
                .iter()
                .map(|u| u.in_flight())
                .sum::<usize>()
            + self.comms.iter().map(|u| u.in_flight()).sum::<usize>()
            + self
                .stream_reads
                .iter()
                .map(|u| u.in_flight())
                .sum::<usize>()
            + self.immediates.in_flight()
    }

    /// Whether a live stream access of `inst` cannot proceed this cycle (an error if it can
    /// never proceed: reading past the end of a stream).
    fn must_stall(
        &self,
        kernel: &Kernel,
        inst: &DecodedInst,
        live: crate::microcontroller::Liveness,
    ) -> Result<bool, ContractError> {
        let decoded = &*kernel.decoded;
        if !decoded.switch_writes_streams && !inst.streams {
            return Ok(false);
        }
        // Words per stream this cycle (u32: a cycle moves at most a few words per cluster,
        // and the arrays are cleared every cycle).
        let mut need_in = [0u32; crate::desc::MAX_KERNEL_STREAMS];
        let mut need_out = [0u32; crate::desc::MAX_KERNEL_STREAMS];
        let lanes = self.lanes as u32;
        for s in decoded.sin(inst).iter().filter(|s| live.live(s.stage)) {
            need_in[s.stream as usize] += match s.cond {
                None => lanes,
                Some(cc) => self.cc.read(cc)?.iter().filter(|&&b| b).count() as u32,
            };
        }
        if let Some((s, _)) = inst.sout.filter(|(s, _)| live.live(s.stage)) {
            need_out[s.stream as usize] += match s.cond {
                None => lanes,
                Some(cc) => self.cc.read(cc)?.iter().filter(|&&b| b).count() as u32,
            };
        }
        // Results due this cycle that go to output streams.
        if decoded.switch_writes_streams {
            self.sources().for_each_due(
                decoded,
                &mut |dests: &Dests, _, mask: Option<&[bool]>| {
                    for d in dests.iter().flatten() {
                        if let Dest::Stream { stream } = d {
                            need_out[*stream as usize] +=
                                mask.map_or(lanes, |m| m.iter().filter(|&&b| b).count() as u32);
                        }
                    }
                    Ok(())
                },
            )?;
        }
        for (stream, &need) in need_in
            .iter()
            .enumerate()
            .take(kernel.program.streams.len())
        {
            let need = need as usize;
            if need == 0 {
                continue;
            }
            let remaining = self.srf.remaining(stream);
            if need > remaining {
                return Err(ContractError::at(
                    &format!("{}.sin", self.path),
                    Violation::Other(format!(
                        "kernel `{}` reads {need} words of stream `{}` with only {remaining} left",
                        kernel.program.name, kernel.program.streams[stream].name
                    )),
                ));
            }
            if need > self.srf.available(stream) {
                return Ok(true);
            }
        }
        for (stream, &need) in need_out
            .iter()
            .enumerate()
            .take(kernel.program.streams.len())
        {
            if need > 0 && need as usize > self.srf.space(stream) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Routes every result due this cycle through the switch.
    fn writeback<const L: usize>(&mut self, decoded: &Decoded) -> Result<(), ContractError> {
        // Borrow the sources and the destinations field by field: they are disjoint.
        let sources = Sources {
            fus: &self.fus,
            scratchpads: &self.scratchpads,
            comms: &self.comms,
            stream_reads: &self.stream_reads,
            immediates: &self.immediates,
        };
        let mut switch = Switch::<L> {
            lrfs: &mut self.lrfs,
            cc: &mut self.cc,
            all_lanes: &self.all_lanes,
            streams: Streams {
                srf: &mut self.srf,
                lanes: self.lanes,
            },
        };
        sources.for_each_due(decoded, &mut switch)
    }

    fn sources(&self) -> Sources<'_> {
        Sources {
            fus: &self.fus,
            scratchpads: &self.scratchpads,
            comms: &self.comms,
            stream_reads: &self.stream_reads,
            immediates: &self.immediates,
        }
    }

    /// Issues the live slots of instruction `pc`.
    #[inline(always)]
    fn issue<const L: usize>(
        &mut self,
        kernel: &mut Kernel,
        pc: u16,
        live: crate::microcontroller::Liveness,
    ) -> Result<(), ContractError> {
        let decoded = &*kernel.decoded;
        let inst = decoded.inst(pc);
        let stats = &mut kernel.stats;
        stats.instructions += 1;
        stats.loop_passes += inst.ends_pass as u64;
        for f in decoded.fu(inst) {
            if !live.live(f.stage) {
                stats.squashed += 1;
                continue;
            }
            // Operands go from the LRF read ports straight to the unit's input latches.
            let a = self.lrfs[f.a.lrf as usize].read_for::<L>(f.a.entry)?;
            let b = match f.b {
                Some(b) => self.lrfs[b.lrf as usize].read_for::<L>(b.entry)?,
                None => a,
            };
            let operands = match f.select {
                // select(cond, a, b): the condition code is the first operand.
                Some(cc) => {
                    let n = count::<L>(self.lanes);
                    let cond = &mut self.buf[2][..n];
                    for (dst, &bit) in cond.iter_mut().zip(&self.cc.read(cc)?[..n]) {
                        *dst = bit as u32;
                    }
                    [&cond[..], a, b]
                }
                None => [a, b, a],
            };
            self.fus.issue::<L>(f.unit, f.op, operands, pc)?;
            stats.fu_ops[f.slot as usize] += 1;
        }
        for sp in decoded.sp(inst) {
            if !live.live(sp.stage) {
                stats.squashed += 1;
                continue;
            }
            let i = sp.index as usize;
            let [offsets, data, _] = &mut self.buf;
            let offsets = match sp.offset {
                Some(e) => {
                    copy_lanes::<L>(offsets, self.lrfs[e.lrf as usize].read_for::<L>(e.entry)?);
                    Some(&offsets[..])
                }
                None => None,
            };
            match sp.data {
                Some(e) => {
                    copy_lanes::<L>(data, self.lrfs[e.lrf as usize].read_for::<L>(e.entry)?);
                    self.scratchpads[i].write_for::<L>(sp.base, offsets, data, &self.all_lanes)?;
                }
                None => self.scratchpads[i].read_for::<L>(sp.base, offsets, &self.all_lanes, pc)?,
            }
        }
        for cs in decoded.comm(inst) {
            if !live.live(cs.stage) {
                stats.squashed += 1;
                continue;
            }
            let [data, perm, _] = &mut self.buf;
            copy_lanes::<L>(
                data,
                self.lrfs[cs.data.lrf as usize].read_for::<L>(cs.data.entry)?,
            );
            let regs = match cs.sources {
                Some(e) => {
                    copy_lanes::<L>(perm, self.lrfs[e.lrf as usize].read_for::<L>(e.entry)?);
                    Some(&perm[..])
                }
                None => None,
            };
            self.comms[cs.index as usize].send(data, cs.perm, regs, pc)?;
        }
        let stream_latency = self.desc.latency.stream;
        // The network and the scratchpad carry every conditional access of the instruction
        // (up to `srf.conditional_words_per_cycle`, as the program check allows): claimed
        // once, by the first.
        let mut claimed = false;
        for s in decoded.sin(inst) {
            if !live.live(s.stage) {
                stats.squashed += 1;
                continue;
            }
            let (i, stream) = (s.index as usize, s.stream as usize);
            match s.cond {
                None => {
                    let words = self.srf.read(stream, self.lanes)?;
                    self.stream_reads[i]
                        .insert_for::<L>(stream_latency, pc, None, |v| copy_lanes::<L>(v, words))?;
                }
                Some(cc) => {
                    // Conditional input: clusters whose code is set take the next elements
                    // in cluster order, routed over the intercluster network and buffered
                    // in the scratchpad.
                    self.claim_for_conditional_streams(&mut claimed)?;
                    copy_mask::<L>(&mut self.mask, self.cc.read(cc)?);
                    let n = count_set::<L>(&self.mask);
                    let words = self.srf.read_conditional(stream, n)?;
                    let mask = &self.mask;
                    self.stream_reads[i].insert_for::<L>(stream_latency, pc, Some(mask), |v| {
                        let mut next = words.iter();
                        for (dst, &m) in v.iter_mut().zip(mask) {
                            *dst = if m { *next.next().expect("n words") } else { 0 };
                        }
                    })?;
                }
            }
        }
        if let Some((s, data)) = inst.sout {
            if live.live(s.stage) {
                if s.cond.is_some() {
                    // Conditional output is compacted over the intercluster network and
                    // buffered in the scratchpad.
                    self.claim_for_conditional_streams(&mut claimed)?;
                }
                let data = self.lrfs[data.lrf as usize].read_for::<L>(data.entry)?;
                let mask = match s.cond {
                    Some(cc) => Some(self.cc.read(cc)?),
                    None => None,
                };
                Streams {
                    srf: &mut self.srf,
                    lanes: self.lanes,
                }
                .append(s.stream, data, mask)?;
            } else {
                stats.squashed += 1;
            }
        }
        if let Some(imm) = inst.imm {
            if live.live(imm.stage) {
                self.immediates
                    .insert_for::<L>(1, pc, None, |v| match imm.value {
                        ImmValue::Const(x) => v.fill(x),
                        ImmValue::ClusterId => {
                            v.iter_mut().enumerate().for_each(|(c, x)| *x = c as u32)
                        }
                    })?;
            } else {
                stats.squashed += 1;
            }
        }
        Ok(())
    }

    /// Claims the intercluster network and the scratchpad for this instruction's
    /// conditional stream accesses, unless `claimed` says an earlier one did.
    fn claim_for_conditional_streams(&mut self, claimed: &mut bool) -> Result<(), ContractError> {
        if !std::mem::replace(claimed, true) {
            self.comms[0].reserve()?;
            self.scratchpads[0].claim_for_conditional_stream()?;
        }
        Ok(())
    }

    fn cycle(&mut self) -> Result<(), ContractError> {
        self.stalled = false;
        let Some(mut kernel) = self.kernel.take() else {
            return Ok(());
        };
        // The per-cycle path compiled for this machine's cluster count (`crate::lanes`).
        let result = match self.lanes {
            8 => self.kernel_cycle::<8>(&mut kernel),
            16 => self.kernel_cycle::<16>(&mut kernel),
            32 => self.kernel_cycle::<32>(&mut kernel),
            _ => self.kernel_cycle::<0>(&mut kernel),
        };
        self.kernel = Some(kernel);
        result
    }

    /// The edge, compiled for `L` lanes (`crate::lanes`): every block commits; in a stall
    /// the clusters' units hold.
    #[inline(always)]
    fn commit_for<const L: usize>(&mut self) {
        self.srf.commit();
        self.uc.commit();
        if self.stalled {
            return;
        }
        if self.asleep {
            self.idle_cycles += 1;
            return;
        }
        self.fus.commit();
        if self.tracing || cfg!(feature = "inject-bugs") {
            self.lrfs.iter_mut().for_each(|u| u.commit_for::<L>());
        } else {
            self.lrfs.iter_mut().for_each(|u| u.commit_untraced::<L>());
        }
        self.cc.commit();
        self.scratchpads.iter_mut().for_each(|u| u.commit());
        self.comms.iter_mut().for_each(|u| u.commit());
        self.stream_reads.iter_mut().for_each(|u| u.commit());
        self.immediates.commit();
        // With no kernel, what this edge landed was the last: the clusters can sleep.
        self.asleep = !self.tracing && self.clusters_quiet();
    }

    fn kernel_cycle<const L: usize>(&mut self, kernel: &mut Kernel) -> Result<(), ContractError> {
        match self.uc.phase() {
            Phase::Idle => return Ok(()),
            Phase::Finishing => {
                kernel.stats.cycles += 1;
                self.writeback::<L>(&kernel.decoded)?;
                if self.in_flight() == 0 && !kernel.flushing {
                    kernel.flushing = true;
                    for (i, s) in kernel.program.streams.iter().enumerate() {
                        if s.dir == StreamDir::Out {
                            self.srf.flush(i)?;
                        }
                    }
                }
                // Only the kernel's own output streams: the memory system's stream buffers
                // may be busy at the same time.
                let flushed = kernel
                    .program
                    .streams
                    .iter()
                    .enumerate()
                    .all(|(i, s)| s.dir != StreamDir::Out || self.srf.flushed(i));
                if kernel.flushing && flushed {
                    self.uc.finish();
                }
                return Ok(());
            }
            Phase::Running => {}
        }
        kernel.stats.cycles += 1;
        let env = Env {
            srf: &self.srf,
            cc: &self.cc,
            lanes: self.lanes,
        };
        let Some((pc, live)) = self.uc.fetch(&kernel.program.code, &env)? else {
            return Ok(());
        };
        if self.must_stall(kernel, kernel.decoded.inst(pc), live)? {
            self.uc.discard();
            self.stalled = true;
            kernel.stats.stall_cycles += 1;
            return Ok(());
        }
        self.writeback::<L>(&kernel.decoded)?;
        self.issue::<L>(kernel, pc, live)?;
        let env = Env {
            srf: &self.srf,
            cc: &self.cc,
            lanes: self.lanes,
        };
        self.uc.advance(&kernel.program.code, &env)
    }
}

impl Module for Machine {
    fn domain(&self) -> DomainId {
        DomainId(0)
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        self.cycle()?;
        self.srf.eval();
        Ok(())
    }

    fn commit(&mut self) {
        match self.lanes {
            8 => self.commit_for::<8>(),
            16 => self.commit_for::<16>(),
            32 => self.commit_for::<32>(),
            _ => self.commit_for::<0>(),
        }
    }

    fn set_tracing(&mut self, on: bool) {
        self.wake_clusters();
        self.tracing = on;
        self.fus.set_tracing(on);
        self.lrfs.iter_mut().for_each(|u| u.set_tracing(on));
        self.scratchpads.iter_mut().for_each(|u| u.set_tracing(on));
        self.comms.iter_mut().for_each(|u| u.set_tracing(on));
    }

    fn trace(&self, t: &mut Trace) {
        self.uc.trace(t);
        self.fus.trace(t);
        self.lrfs.iter().for_each(|u| u.trace(t));
        self.cc.trace(t);
        self.scratchpads.iter().for_each(|u| u.trace(t));
        self.comms.iter().for_each(|u| u.trace(t));
        self.srf.trace(t);
    }
}
