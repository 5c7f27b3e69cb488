//! Replaying a request trace through the channels: the back end of `imagine dram`.
//!
//! The design is the channels alone, in the DRAM clock domain (the only domain, so the
//! simulator's cycle count is DRAM cycles), fed by a trace source: at each cycle it
//! presents the requests whose cycle has come, in trace order, each through its channel's
//! request FIFO (4 entries, up to [`FRONT_END_PER_CHANNEL`] pushes per cycle; the channel
//! takes one reference per cycle from it); a request that finds its FIFO full waits and
//! holds back the ones behind it (as a trace-driven front end does). Probes:
//! `top.trace.presented` and everything under `top.mem.chN`.
//!
//! Metrics (see [`ReplayReport`]): the finish cycle is the last cycle a data word was on a
//! data bus; bandwidth is bytes moved over that time; read latency runs from a reference
//! entering its channel's pending-reference buffer to its last data word.

use std::fmt;

use imagine_hdl::{
    ClockDomain, ContractError, Design, DomainId, FifoTx, Module, SignalId, SignalKind, Sim, Trace,
    bits_for,
};

use super::channel::{ChannelConfig, ChannelInput, ChannelOutput, ChannelStats, DramChannel};
use super::timing_check::TimingViolation;
use super::{DramParams, Policy, Request, Tag, TraceKind, TraceRequest};
use crate::desc::MachineDesc;
use crate::runner::OnStart;

/// How to replay a trace.
pub struct ReplayOptions {
    pub policy: Policy,
    /// The timing the schedulers believe in (`None`: the machine's); for tests that inject
    /// a violation.
    pub scheduler_params: Option<DramParams>,
    /// Keep the requests as the channels received them.
    pub record: bool,
    /// Give up after this many DRAM cycles.
    pub max_cycles: u64,
    pub on_start: Option<OnStart>,
}

impl ReplayOptions {
    pub fn new(policy: Policy) -> Self {
        ReplayOptions {
            policy,
            scheduler_params: None,
            record: false,
            max_cycles: 1 << 32,
            on_start: None,
        }
    }
}

/// A replay that could not run.
#[derive(Debug)]
pub enum ReplayError {
    Setup(String),
    Contract(ContractError),
    Timeout(u64),
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::Setup(s) => f.write_str(s),
            ReplayError::Contract(e) => e.fmt(f),
            ReplayError::Timeout(c) => write!(f, "the trace did not finish within {c} DRAM cycles"),
        }
    }
}

impl std::error::Error for ReplayError {}

impl From<ContractError> for ReplayError {
    fn from(e: ContractError) -> Self {
        ReplayError::Contract(e)
    }
}

/// What a replay measured.
#[derive(Clone, Debug)]
pub struct ReplayReport {
    pub policy: Policy,
    pub requests: u64,
    pub bytes: u64,
    /// The last DRAM cycle with a data word on a bus (0 for an empty trace).
    pub finish_cycle: u64,
    pub dram_hz: u64,
    pub peak_gbs: f64,
    pub gbs: f64,
    pub data_bus_utilisation: f64,
    pub row_hit_rate: f64,
    pub activates: u64,
    pub precharges: u64,
    pub reads: u64,
    pub writes: u64,
    pub refreshes: u64,
    /// Mean DRAM cycles from buffer entry to the last data word, over reads.
    pub avg_read_latency: f64,
    pub violations: Vec<TimingViolation>,
    /// Requests as the channels received them (when recording), by cycle then channel.
    pub recorded: Vec<TraceRequest>,
    pub channels: Vec<ChannelStats>,
}

impl ReplayReport {
    /// Bandwidth as a fraction of the peak.
    pub fn fraction_of_peak(&self) -> f64 {
        self.gbs / self.peak_gbs
    }

    /// Summarises the channels' counters.
    pub fn from_channels(
        policy: Policy,
        p: &DramParams,
        channels: Vec<ChannelStats>,
        violations: Vec<TimingViolation>,
        recorded: Vec<TraceRequest>,
    ) -> Self {
        let sum = |f: fn(&ChannelStats) -> u64| channels.iter().map(f).sum::<u64>();
        let (reads, writes) = (sum(|c| c.reads), sum(|c| c.writes));
        let activates = sum(|c| c.activates);
        let busy = sum(|c| c.data_bus_cycles);
        let requests = reads + writes;
        let finish = channels.iter().map(|c| c.last_busy).max().unwrap_or(0);
        let span = if requests == 0 { 0 } else { finish + 1 };
        let bytes = requests * p.burst_bytes();
        let secs = span as f64 / p.freq_hz as f64;
        ReplayReport {
            policy,
            requests,
            bytes,
            finish_cycle: finish,
            dram_hz: p.freq_hz,
            peak_gbs: p.peak_bytes_per_s() / 1e9,
            gbs: if span == 0 {
                0.0
            } else {
                bytes as f64 / secs / 1e9
            },
            data_bus_utilisation: if span == 0 {
                0.0
            } else {
                busy as f64 / (span * p.channels as u64) as f64
            },
            row_hit_rate: if requests == 0 {
                0.0
            } else {
                (1.0 - activates as f64 / requests as f64).max(0.0)
            },
            activates,
            precharges: sum(|c| c.precharges),
            reads,
            writes,
            refreshes: sum(|c| c.refreshes),
            avg_read_latency: if reads == 0 {
                0.0
            } else {
                sum(|c| c.read_latency_sum) as f64 / reads as f64
            },
            violations,
            recorded,
            channels,
        }
    }
}

/// Requests the trace front end may present to one channel's FIFO per cycle.
pub const FRONT_END_PER_CHANNEL: usize = 2;

/// Presents a trace's requests to the channels.
struct TraceSource {
    domain: DomainId,
    reqs: Vec<TraceRequest>,
    p: DramParams,
    next: usize,
    next_d: usize,
    cycle: u64,
    txs: Vec<FifoTx<Request>>,
    id: SignalId,
}

/// Deterministic write data for a trace's write to `byte_addr`.
pub fn trace_write_data(byte_addr: u64) -> [u32; 8] {
    std::array::from_fn(|k| (byte_addr as u32).wrapping_add(k as u32 * 4) ^ 0x5A5A_5A5A)
}

impl Module for TraceSource {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        let mut used = [0usize; 64];
        let mut i = self.next;
        while let Some(r) = self.reqs.get(i) {
            if r.cycle > self.cycle {
                break;
            }
            let ch = self.p.map(r.byte_addr).map_or(0, |l| l.channel);
            if used[ch] == FRONT_END_PER_CHANNEL || self.txs[ch].free() == 0 {
                break;
            }
            used[ch] += 1;
            self.txs[ch].push(Request {
                write: r.kind == TraceKind::Write,
                byte_addr: r.byte_addr,
                data: trace_write_data(r.byte_addr),
                tag: Tag {
                    source: 0,
                    seq: i as u32,
                },
            })?;
            i += 1;
        }
        self.next_d = i;
        Ok(())
    }
    fn commit(&mut self) {
        self.next = self.next_d;
        self.cycle += 1;
    }
    fn trace(&self, t: &mut Trace) {
        t.value(self.id, self.next as u64);
    }
}

/// Replays `reqs` (already checked against the memory's size) on the memory of `desc`.
pub fn replay(
    desc: &MachineDesc,
    reqs: &[TraceRequest],
    opts: ReplayOptions,
) -> Result<ReplayReport, ReplayError> {
    let p = DramParams::of(desc);
    if let Some(r) = reqs.iter().find(|r| p.map(r.byte_addr).is_none()) {
        return Err(ReplayError::Setup(format!(
            "address {:#x} is out of range: the memory has {} bytes",
            r.byte_addr,
            p.capacity_bytes()
        )));
    }
    let setup = |e: imagine_hdl::DesignError| ReplayError::Setup(e.to_string());
    let mut design =
        Design::new("top", vec![ClockDomain::mhz("dram", desc.clocks.dram_mhz)]).map_err(setup)?;
    let dram = design.domain("dram").map_err(setup)?;
    let mut top = design.scope();
    let mut txs = Vec::new();
    let mut channels = Vec::new();
    {
        let mut mem = top.child("mem");
        for c in 0..p.channels {
            let mut s = mem.child(&format!("ch{c}"));
            let (tx, rx) = s
                .fifo("requests", dram, 4, FRONT_END_PER_CHANNEL)
                .map_err(setup)?;
            txs.push(tx);
            channels.push(DramChannel::new(
                &mut s,
                dram,
                ChannelConfig {
                    index: c,
                    params: p.clone(),
                    scheduler_params: opts.scheduler_params.clone(),
                    policy: opts.policy,
                    pending_references: desc.memory.pending_references,
                    record: opts.record,
                },
                ChannelInput::Local(rx),
                ChannelOutput::Discard,
            ));
        }
    }
    let id = top
        .child("trace")
        .signal("presented", bits_for(reqs.len() as u64), SignalKind::Reg);
    design.add(TraceSource {
        domain: dram,
        reqs: reqs.to_vec(),
        p: p.clone(),
        next: 0,
        next_d: 0,
        cycle: 0,
        txs,
        id,
    });
    for ch in channels {
        design.add(ch);
    }
    let mut sim = Sim::new(design);
    if let Some(f) = opts.on_start {
        f(&mut sim).map_err(ReplayError::Setup)?;
    }
    let n = reqs.len();
    let done = |sim: &Sim| {
        sim.modules_of::<TraceSource>().all(|s| s.next == n)
            && sim.modules_of::<DramChannel>().all(DramChannel::is_idle)
    };
    let finished = sim.run_until(opts.max_cycles, done)?;
    sim.finish()
        .map_err(|e| ReplayError::Setup(format!("cannot finish the waveform: {e}")))?;
    if !finished {
        return Err(ReplayError::Timeout(opts.max_cycles));
    }
    Ok(report_of(&sim, opts.policy, &p))
}

/// The report of the channels of a finished design.
pub fn report_of(sim: &Sim, policy: Policy, p: &DramParams) -> ReplayReport {
    let chans: Vec<&DramChannel> = sim.modules_of::<DramChannel>().collect();
    let mut recorded: Vec<(u64, usize, TraceRequest)> = chans
        .iter()
        .flat_map(|c| c.recorded().iter().map(move |r| (r.cycle, c.index(), *r)))
        .collect();
    recorded.sort_by_key(|&(cy, ch, _)| (cy, ch));
    ReplayReport::from_channels(
        policy,
        p,
        chans.iter().map(|c| c.stats().clone()).collect(),
        chans.iter().flat_map(|c| c.violations().to_vec()).collect(),
        recorded.into_iter().map(|(_, _, r)| r).collect(),
    )
}
