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
//! Idle time: when nothing is pending or in flight in any channel and the next request
//! arrives later, the replay jumps to that request's cycle in one step. Idle channels only
//! count cycles and refresh every `refresh_interval` cycles, so the jump applies the
//! refreshes due in the gap in closed form (see [`DramChannel::skip_idle`]); the result is
//! the one stepping every cycle gives, which the tests check. With a tracer attached
//! (`--vcd`) the gap is stepped, so the waveform shows every cycle.
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
use super::trace::MAX_TRACE_CYCLE;
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
    /// Give up when the replay runs this many DRAM cycles past the last request's
    /// arrival.
    pub max_cycles: u64,
    /// Jump over idle gaps in the trace (see the module doc); `false` steps every cycle,
    /// for tests that compare the two.
    pub skip_idle: bool,
    pub on_start: Option<OnStart>,
}

impl ReplayOptions {
    pub fn new(policy: Policy) -> Self {
        ReplayOptions {
            policy,
            scheduler_params: None,
            record: false,
            max_cycles: 1 << 32,
            skip_idle: true,
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
    /// The replay ended without serving every request (a model error, never a result).
    Incomplete {
        requests: usize,
        served: u64,
    },
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::Setup(s) => f.write_str(s),
            ReplayError::Contract(e) => e.fmt(f),
            ReplayError::Timeout(c) => write!(f, "the trace did not finish by DRAM cycle {c}"),
            ReplayError::Incomplete { requests, served } => write!(
                f,
                "the replay served {served} of the trace's {requests} requests (a model error)"
            ),
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
    /// Idle DRAM cycles jumped over rather than stepped (see the module doc); the other
    /// figures are the same either way.
    pub skipped_cycles: u64,
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
            skipped_cycles: 0,
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

impl TraceSource {
    /// The cycle of the next request not yet presented, if any.
    fn next_arrival(&self) -> Option<u64> {
        self.reqs.get(self.next).map(|r| r.cycle)
    }
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

/// Replays `reqs` (already checked against the memory's size and
/// [`MAX_TRACE_CYCLE`]) on the memory of `desc`.
pub fn replay(
    desc: &MachineDesc,
    reqs: &[TraceRequest],
    mut opts: ReplayOptions,
) -> Result<ReplayReport, ReplayError> {
    let p = DramParams::of(desc);
    if let Some(r) = reqs.iter().find(|r| p.map(r.byte_addr).is_none()) {
        return Err(ReplayError::Setup(format!(
            "address {:#x} is out of range: the memory has {} bytes",
            r.byte_addr,
            p.capacity_bytes()
        )));
    }
    if let Some(r) = reqs.iter().find(|r| r.cycle > MAX_TRACE_CYCLE) {
        return Err(ReplayError::Setup(format!(
            "cycle {} is past the latest a trace may name, {MAX_TRACE_CYCLE}",
            r.cycle
        )));
    }
    let (mut sim, dram) = build(desc, reqs, &opts)?;
    if let Some(f) = opts.on_start.take() {
        f(&mut sim).map_err(ReplayError::Setup)?;
    }
    let n = reqs.len();
    let limit = reqs
        .last()
        .map_or(0, |r| r.cycle)
        .saturating_add(opts.max_cycles);
    let mut skipped = 0;
    let finished = loop {
        if sim.core_cycles() >= limit {
            break false;
        }
        // With a tracer, falling edges come too; state changes only on rising ones.
        if !sim.step()?.rising.contains(dram) {
            continue;
        }
        if done(&sim, n) {
            break true;
        }
        if opts.skip_idle {
            skipped += skip_idle_time(&mut sim);
        }
    };
    sim.finish()
        .map_err(|e| ReplayError::Setup(format!("cannot finish the waveform: {e}")))?;
    if !finished {
        return Err(ReplayError::Timeout(limit));
    }
    let mut report = report_of(&sim, opts.policy, &p);
    report.skipped_cycles = skipped;
    if report.requests != n as u64 {
        return Err(ReplayError::Incomplete {
            requests: n,
            served: report.requests,
        });
    }
    Ok(report)
}

/// The design: the trace source and the channels, in the DRAM domain (returned too).
fn build(
    desc: &MachineDesc,
    reqs: &[TraceRequest],
    opts: &ReplayOptions,
) -> Result<(Sim, DomainId), ReplayError> {
    let p = DramParams::of(desc);
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
    Ok((Sim::new(design), dram))
}

/// Every one of the `n` requests presented, and every channel idle (its input FIFO too).
fn done(sim: &Sim, n: usize) -> bool {
    sim.modules_of::<TraceSource>().all(|s| s.next == n)
        && sim.modules_of::<DramChannel>().all(DramChannel::is_idle)
}

/// Between cycles: when every channel is idle and the next request arrives later, jumps
/// to its cycle (see the module doc). Returns the cycles skipped.
fn skip_idle_time(sim: &mut Sim) -> u64 {
    let now = sim.core_cycles();
    let Some(arrival) = sim
        .modules_of::<TraceSource>()
        .next()
        .and_then(TraceSource::next_arrival)
    else {
        return 0;
    };
    if arrival <= now
        || !sim.can_skip_cycles()
        || !sim
            .modules_of::<DramChannel>()
            .all(DramChannel::can_skip_idle)
    {
        return 0;
    }
    let n = arrival - now;
    for c in sim.modules_of_mut::<DramChannel>() {
        c.skip_idle(n);
    }
    for s in sim.modules_of_mut::<TraceSource>() {
        debug_assert_eq!(s.cycle, now);
        s.cycle += n;
    }
    let skipped = sim.skip_cycles(n);
    debug_assert!(skipped, "checked by can_skip_cycles");
    n
}

/// The report of the channels of a finished design.
pub fn report_of(sim: &Sim, policy: Policy, p: &DramParams) -> ReplayReport {
    let chans: Vec<&DramChannel> = sim.modules_of::<DramChannel>().collect();
    ReplayReport::from_channels(
        policy,
        p,
        chans.iter().map(|c| c.stats().clone()).collect(),
        chans.iter().flat_map(|c| c.violations().to_vec()).collect(),
        recorded(sim),
    )
}

/// The requests every recording channel of `sim` received, in DRAM-cycle order (channel
/// order within a cycle).
pub fn recorded(sim: &Sim) -> Vec<TraceRequest> {
    let mut recorded: Vec<(u64, usize, TraceRequest)> = sim
        .modules_of::<DramChannel>()
        .flat_map(|c| c.recorded().iter().map(move |r| (r.cycle, c.index(), *r)))
        .collect();
    recorded.sort_by_key(|&(cy, ch, _)| (cy, ch));
    recorded.into_iter().map(|(_, _, r)| r).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(sim: &Sim) -> String {
        let s = sim.modules_of::<TraceSource>().next().unwrap();
        let mut out = format!(
            "cycle {} source {} {}\n",
            sim.core_cycles(),
            s.next,
            s.cycle
        );
        for c in sim.modules_of::<DramChannel>() {
            out += &c.debug_state();
            out.push('\n');
        }
        out
    }

    /// Runs `reqs` twice, stepping and skipping; after every skip, steps the other run to
    /// the same cycle and compares every channel's whole state.
    fn compare(desc: &MachineDesc, reqs: &[TraceRequest], policy: Policy) -> usize {
        let opts = ReplayOptions::new(policy);
        let (mut fast, _) = build(desc, reqs, &opts).unwrap();
        let (mut slow, _) = build(desc, reqs, &opts).unwrap();
        let mut skips = 0;
        while !done(&fast, reqs.len()) {
            fast.step().unwrap();
            slow.step().unwrap();
            assert_eq!(state(&fast), state(&slow));
            if skip_idle_time(&mut fast) > 0 {
                skips += 1;
                while slow.core_cycles() < fast.core_cycles() {
                    slow.step().unwrap();
                }
                let (f, s) = (state(&fast), state(&slow));
                assert!(
                    f == s,
                    "after a skip to cycle {}:\n{f}\n{s}",
                    fast.core_cycles()
                );
            }
        }
        assert!(done(&slow, reqs.len()));
        skips
    }

    fn rd(byte_addr: u64, cycle: u64) -> TraceRequest {
        TraceRequest {
            byte_addr,
            kind: TraceKind::Read,
            cycle,
        }
    }

    fn wr(byte_addr: u64, cycle: u64) -> TraceRequest {
        TraceRequest {
            byte_addr,
            kind: TraceKind::Write,
            cycle,
        }
    }

    #[test]
    fn after_a_skip_every_channel_is_in_the_state_stepping_leaves() {
        let mut desc = MachineDesc::gold8();
        // The shortest refresh interval allowed, so that gaps cross several.
        desc.dram.refresh_interval = 4 * (desc.dram.t_rc + desc.dram.t_rfc);
        let p = DramParams::of(&desc);
        let (refi, rfc) = (p.t_refi, p.t_rfc);
        let row = (p.columns * p.channels * p.banks) as u64 * 4;
        let mut reqs = vec![rd(0, 0), wr(row + 0x44, 0), rd(2 * row + 0x8, 1)];
        let mut t = 1;
        // Each burst lands at another phase of the refresh: before, on and after a refresh,
        // during its tRFC, and several intervals on.
        for (k, d) in [
            (1, 0),
            (3, -1),
            (6, 1),
            (8, 0),
            (10, rfc as i64),
            (14, -2),
            (19, 3),
            (25, 7),
            (31, 0),
        ] {
            t = (k * refi).checked_add_signed(d).unwrap().max(t + 1);
            reqs.push(rd((k * 0x44) % (3 * row), t));
            reqs.push(wr(row + k * 8, t));
        }
        let mut skips = 0;
        for policy in Policy::ALL {
            skips += compare(&desc, &reqs, policy);
        }
        assert!(skips >= 7 * 7, "only {skips} skips");
    }
}
