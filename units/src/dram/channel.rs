//! One SDRAM channel in the DRAM clock domain: the memory access scheduler, the command-bus
//! register, the SDRAM part with its data bus, and the timing checker watching the bus.
//!
//! Each DRAM cycle (`eval`):
//!
//! 1. the SDRAM executes the command the bus register holds (decided last cycle) and
//!    drives the data bus; the timing checker checks that command;
//! 2. read data leaving the data bus is gathered into bursts; a finished burst (or a
//!    finished write) becomes a reply in the return queue, and the oldest reply leaves
//!    through the output FIFO when it has room;
//! 3. the scheduler decides the next command (it issues a read only while the return
//!    queue and the reads in flight leave room for its data);
//! 4. one request enters from the input FIFO if the pending-reference buffer has room.
//!
//! A channel with nothing pending, in flight, on its buses or waiting to be returned is
//! *quiet*: until a request arrives or its next refresh comes due, a cycle changes nothing
//! but the cycle count (and the activity samples), so `eval` sees that from the registers
//! and `commit` only counts it. (Quiet cycles are most of a frame's: the memory system
//! waits on the clusters.)
//!
//! Probes under the channel's scope: `cmd` (3 bits, see [`Command::code`]), `cmd_bank`,
//! `cmd_row`, `cmd_column`; the scheduler's `queue_depth`, `decision`, `decision_entry`,
//! `refresh_pending`; `bankN.state`, `bankN.row`; `dq_valid`, `dq`; `return_depth`.

use std::collections::VecDeque;

use imagine_hdl::{
    AsyncFifoRx, AsyncFifoTx, ContractError, Display, DomainId, FifoRx, FifoTx, Module, Scope,
    SignalId, SignalKind, Trace, Violation, bits_for,
};

use super::activity::{Activity, ActivityLog};
use super::scheduler::{Issued, Scheduler};
use super::sdram::Sdram;
use super::timing_check::{TimingChecker, TimingViolation};
use super::{Command, DramParams, Policy, Reply, Request, Tag, TraceKind, TraceRequest};

/// Where a channel's requests come from.
pub enum ChannelInput {
    /// A FIFO in the DRAM domain (trace replay).
    Local(FifoRx<Request>),
    /// A synchronising FIFO from the core domain (the address generators).
    Crossing(AsyncFifoRx<Request>),
}

/// Where a channel's replies go.
pub enum ChannelOutput {
    /// Nowhere: replies are counted and dropped (trace replay).
    Discard,
    /// A synchronising FIFO into the core domain.
    Crossing(AsyncFifoTx<Reply>),
    /// A FIFO in the DRAM domain.
    Local(FifoTx<Reply>),
}

/// Counters of one channel.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ChannelStats {
    pub cycles: u64,
    pub activates: u64,
    pub precharges: u64,
    pub reads: u64,
    pub writes: u64,
    pub refreshes: u64,
    /// Cycles the data bus carried a word.
    pub data_bus_cycles: u64,
    /// Sum over reads of (cycle the last data word is on the bus − cycle the reference
    /// entered the pending-reference buffer).
    pub read_latency_sum: u64,
    /// The last cycle the channel did anything for a reference (its last data word).
    pub last_busy: u64,
    /// References accepted.
    pub accepted: u64,
}

/// A read burst coming out of the SDRAM: whom it answers, and the words so far.
#[derive(Clone, Debug)]
struct Pending {
    tag: Tag,
    arrival: u64,
    words: usize,
    data: [u32; 8],
}

pub struct DramChannel {
    domain: DomainId,
    path: String,
    index: usize,
    p: DramParams,
    input: ChannelInput,
    output: ChannelOutput,
    scheduler: Scheduler,
    sdram: Sdram,
    checker: TimingChecker,
    /// The command-bus register: the command and, for a column command, the reference
    /// it serves.
    bus_q: Option<Issued>,
    bus_d: Option<Issued>,
    reads: VecDeque<Pending>,
    returns: VecDeque<Reply>,
    return_capacity: usize,
    /// Replies leaving this cycle and requests entering (applied at commit).
    popped_return: bool,
    /// Whether the channel is quiet (see the module doc), and the first cycle at which a
    /// quiet channel acts of its own accord: the scheduler's next refresh, or the timing
    /// checker's next refresh deadline.
    quiet: bool,
    quiet_until: u64,
    /// This cycle is a quiet one in which no request arrives (from `eval` to `commit`).
    idle_cycle: bool,
    cycle: u64,
    stats: ChannelStats,
    record: Option<Vec<TraceRequest>>,
    arriving: Option<TraceRequest>,
    /// Cycles the data bus carried a word, and cycles references waited on row switches
    /// (see [`Activity`]); with `stats`, sampled over time.
    transfer_cycles: u64,
    row_switch_cycles: u64,
    activity_log: ActivityLog,
    /// The first cycle after the last precharge, activate or refresh is done, and after the
    /// last write's data has left the bus.
    row_switch_until: u64,
    write_data_until: u64,
    ids: Probes,
}

#[derive(Clone, Debug)]
struct Probes {
    cmd: SignalId,
    bank: SignalId,
    row: SignalId,
    column: SignalId,
    returns: SignalId,
}

/// How to build a channel.
pub struct ChannelConfig {
    pub index: usize,
    pub params: DramParams,
    /// The timing the scheduler believes in; `None`: `params` (tests inject wrong ones).
    pub scheduler_params: Option<DramParams>,
    pub policy: Policy,
    pub pending_references: usize,
    /// Keep every arriving request, for `--dram-trace`.
    pub record: bool,
}

impl DramChannel {
    pub fn new(
        scope: &mut Scope<'_>,
        domain: DomainId,
        cfg: ChannelConfig,
        input: ChannelInput,
        output: ChannelOutput,
    ) -> Self {
        let p = cfg.params;
        let sched_p = cfg.scheduler_params.unwrap_or_else(|| p.clone());
        let ids = Probes {
            cmd: scope.signal_shown(
                "cmd",
                3,
                SignalKind::Reg,
                Display::Names(&["NOP", "ACT", "READ", "WRITE", "PRE", "REF"]),
            ),
            bank: scope.signal("cmd_bank", bits_for(p.banks as u64 - 1), SignalKind::Reg),
            row: scope.signal("cmd_row", bits_for(p.rows as u64 - 1), SignalKind::Reg),
            column: scope.signal(
                "cmd_column",
                bits_for(p.columns as u64 - 1),
                SignalKind::Reg,
            ),
            returns: scope.signal(
                "return_depth",
                bits_for(cfg.pending_references as u64),
                SignalKind::Reg,
            ),
        };
        let mut channel = DramChannel {
            domain,
            path: scope.path().to_string(),
            index: cfg.index,
            input,
            output,
            scheduler: Scheduler::new(scope, cfg.policy, sched_p, cfg.pending_references),
            sdram: Sdram::new(scope, &p),
            checker: TimingChecker::new(cfg.index, &p),
            bus_q: None,
            bus_d: None,
            reads: VecDeque::new(),
            returns: VecDeque::new(),
            return_capacity: cfg.pending_references,
            popped_return: false,
            quiet: false,
            quiet_until: 0,
            idle_cycle: false,
            cycle: 0,
            stats: ChannelStats::default(),
            record: cfg.record.then(Vec::new),
            arriving: None,
            transfer_cycles: 0,
            row_switch_cycles: 0,
            activity_log: ActivityLog::default(),
            row_switch_until: 0,
            write_data_until: 0,
            ids,
            p,
        };
        channel.note_quiet();
        channel
    }

    pub fn index(&self) -> usize {
        self.index
    }

    pub fn policy(&self) -> Policy {
        self.scheduler.policy()
    }

    pub fn stats(&self) -> &ChannelStats {
        &self.stats
    }

    /// What the channel's cycles were spent on, sampled over time.
    pub fn activity_log(&self) -> &ActivityLog {
        &self.activity_log
    }

    /// The activity counters now.
    fn activity(&self) -> Activity {
        Activity {
            transfer_cycles: self.transfer_cycles,
            row_switch_cycles: self.row_switch_cycles,
            columns: self.stats.reads + self.stats.writes,
            activates: self.stats.activates,
        }
    }

    pub fn violations(&self) -> &[TimingViolation] {
        self.checker.violations()
    }

    /// Whether nothing is pending, in flight or waiting to be returned.
    pub fn is_idle(&self) -> bool {
        // A request in the local input FIFO has been handed to the channel: it is pending
        // even though the scheduler has not taken it yet.
        let input_empty = match &self.input {
            ChannelInput::Local(rx) => rx.available() == 0,
            ChannelInput::Crossing(_) => true,
        };
        input_empty
            && self.scheduler.depth() == 0
            && self.reads.is_empty()
            && self.returns.is_empty()
            && self.bus_q.is_none_or(|b| matches!(b.cmd, Command::Refresh))
            && self.bus_d.is_none()
    }

    /// Whether the cycles from now until the next request arrives can be skipped with
    /// [`skip_idle`](Self::skip_idle): nothing pending, in flight or on the buses, every
    /// bank closed, no timing constraint running, and the scheduler timed like the part (so
    /// the checker has nothing to flag); a crossing FIFO to or from the core domain empty
    /// with its synchronisers settled (so that no edge of either clock changes it). Idle
    /// cycles then only count and refresh.
    pub fn can_skip_idle(&self) -> bool {
        let input_empty = match &self.input {
            ChannelInput::Local(rx) => rx.available() == 0,
            ChannelInput::Crossing(rx) => rx.is_settled(),
        };
        let output_settled = match &self.output {
            ChannelOutput::Crossing(tx) => tx.is_settled(),
            ChannelOutput::Discard | ChannelOutput::Local(_) => true,
        };
        input_empty
            && output_settled
            && self.reads.is_empty()
            && self.returns.is_empty()
            && self.bus_q.is_none()
            && self.bus_d.is_none()
            && self.arriving.is_none()
            && self.scheduler.params() == &self.p
            && self.sdram.is_quiet()
            && self.scheduler.idle_skippable(self.cycle)
            && self
                .checker
                .idle_skippable(self.cycle, self.scheduler.refreshes())
    }

    /// Advances the channel over `n` idle cycles (only when
    /// [`can_skip_idle`](Self::can_skip_idle) and no request arrives in them), leaving it
    /// exactly as stepping them would: the refreshes due in them issued on time, counted
    /// and checked, the one decided in the last cycle on the command bus.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.can_skip_idle());
        if n == 0 {
            return;
        }
        let c = self.cycle;
        let (issued, last_bus) = self.scheduler.skip_idle(c, n);
        // The scheduler's cycle t drives bus cycle t + 1: a refresh on the bus in cycle
        // c + n has been decided but not executed yet.
        let pending = last_bus == Some(c + n);
        let executed = issued - pending as u64;
        let last_executed = match (pending, last_bus) {
            (true, Some(b)) if executed > 0 => Some(b - self.p.t_refi),
            (true, _) => None,
            (false, b) => b,
        };
        self.checker.skip_idle(executed, last_executed);
        self.stats.refreshes += executed;
        if let Some(b) = last_executed {
            self.row_switch_until = self.row_switch_until.max(b + self.p.t_rfc);
        }
        // Nothing waits while idle: the counters stay as they are.
        self.activity_log.sample_over(c, n, self.activity());
        self.bus_q = pending.then_some(Issued {
            cmd: Command::Refresh,
            entry: None,
        });
        self.sdram.skip_idle();
        self.popped_return = false;
        self.cycle += n;
        self.stats.cycles = self.cycle;
        self.note_quiet();
    }

    /// Notes, between cycles, whether the channel is quiet (see the module doc) and until
    /// when. Every reply, read burst, bus command and column write's data is over; a
    /// scheduler with nothing pending decides nothing before its next refresh, and the
    /// checker flags nothing before its next refresh deadline.
    fn note_quiet(&mut self) {
        self.quiet = self.bus_q.is_none()
            && self.bus_d.is_none()
            && self.reads.is_empty()
            && self.returns.is_empty()
            && self.arriving.is_none()
            && self.sdram.dq_now().is_none()
            && self.sdram.reads_in_flight() == 0
            && self.cycle >= self.write_data_until
            && self.scheduler.is_quiet();
        if self.quiet {
            self.quiet_until = self
                .scheduler
                .next_refresh_cycle()
                .min(self.checker.next_refresh_deadline());
        }
    }

    /// Whether a request waits in the input FIFO.
    fn request_waiting(&self) -> bool {
        match &self.input {
            ChannelInput::Local(rx) => rx.available() > 0,
            ChannelInput::Crossing(rx) => rx.can_pop(),
        }
    }

    /// Everything that evolves (tests compare a run that skipped idle cycles with one
    /// that stepped them).
    #[cfg(test)]
    pub(crate) fn debug_state(&self) -> String {
        let input = match &self.input {
            ChannelInput::Local(rx) => rx.available(),
            ChannelInput::Crossing(rx) => rx.can_pop() as usize,
        };
        format!(
            "input {input}\nscheduler {:?}\nsdram {}\nchecker {:?}\nbus {:?} {:?}\n\
             reads {:?}\nreturns {:?} {}\ncycle {} {:?}\nrecord {:?} {:?}\n\
             activity {:?} {:?} {} {}",
            self.scheduler,
            self.sdram.debug_state(),
            self.checker,
            self.bus_q,
            self.bus_d,
            self.reads,
            self.returns,
            self.popped_return,
            self.cycle,
            self.stats,
            self.record,
            self.arriving,
            (self.transfer_cycles, self.row_switch_cycles),
            self.activity_log,
            self.row_switch_until,
            self.write_data_until
        )
    }

    /// Starts keeping the requests that enter this channel (between cycles).
    pub fn start_recording(&mut self) {
        self.record.get_or_insert_with(Vec::new);
    }

    /// The requests that entered this channel (when recording), in order.
    pub fn recorded(&self) -> &[TraceRequest] {
        self.record.as_deref().unwrap_or(&[])
    }

    /// The stored word at a byte address of this channel (host view, between cycles).
    pub fn peek(&self, byte_addr: u64) -> Option<u32> {
        let l = self.p.map(byte_addr)?;
        debug_assert_eq!(l.channel, self.index);
        let word = (byte_addr / 4) as usize % self.p.burst;
        Some(self.sdram.peek(
            l.bank.value() as usize,
            l.row,
            l.column.value() as usize + word,
        ))
    }

    /// Writes a word at a byte address of this channel (host, before a run).
    pub fn poke(&mut self, byte_addr: u64, v: u32) -> Option<()> {
        let l = self.p.map(byte_addr)?;
        let word = (byte_addr / 4) as usize % self.p.burst;
        self.sdram.poke(
            l.bank.value() as usize,
            l.row,
            l.column.value() as usize + word,
            v,
        );
        Some(())
    }

    fn error(&self, what: &str, msg: String) -> ContractError {
        ContractError::at(&format!("{}.{what}", self.path), Violation::Other(msg))
    }
}

impl Module for DramChannel {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        let cycle = self.cycle;
        self.idle_cycle = self.quiet && cycle < self.quiet_until && !self.request_waiting();
        if self.idle_cycle {
            return Ok(());
        }
        // 1. The SDRAM and the checker act on the command on the bus.
        let cmd = self.bus_q.as_ref().map(|b| b.cmd);
        let served = self.bus_q.as_ref().and_then(|b| b.entry.as_ref());
        let dq = self.sdram.eval(cmd, served.map_or(&[], |e| &e.data), cycle);
        self.checker.observe(cycle, cmd);
        match (cmd, served) {
            (Some(Command::Read { .. }), Some(e)) => self.reads.push_back(Pending {
                tag: e.tag,
                arrival: e.arrival,
                words: 0,
                data: [0; 8],
            }),
            (Some(Command::Write { .. }), Some(e)) => self.returns.push_back(Reply {
                write: true,
                data: [0; 8],
                tag: e.tag,
            }),
            (Some(Command::Read { .. } | Command::Write { .. }), None) => {
                unreachable!("a column command carries its reference")
            }
            _ => {}
        }
        // 2. Read data into bursts, bursts into replies.
        if let Some(w) = dq {
            let Some(head) = self.reads.front_mut() else {
                return Err(self.error("data", "read data with no read in flight".into()));
            };
            head.data[head.words] = w;
            head.words += 1;
            if head.words == self.p.burst {
                let done = self.reads.pop_front().expect("head exists");
                self.stats.read_latency_sum += cycle - done.arrival;
                self.returns.push_back(Reply {
                    write: false,
                    data: done.data,
                    tag: done.tag,
                });
            }
        }
        if let Some(r) = self.returns.front() {
            let r = *r;
            match &mut self.output {
                ChannelOutput::Discard => self.popped_return = true,
                ChannelOutput::Crossing(tx) => {
                    if tx.can_push() {
                        tx.push(r)?;
                        self.popped_return = true;
                    }
                }
                ChannelOutput::Local(tx) => {
                    if tx.free() > 0 {
                        tx.push(r)?;
                        self.popped_return = true;
                    }
                }
            }
        }
        // 3. The scheduler decides the next command.
        let read_room = self.reads.len() + self.returns.len() < self.return_capacity;
        self.bus_d = self.scheduler.eval(cycle, read_room);
        // 4. One request enters.
        self.arriving = None;
        if !self.scheduler.has_room() {
            return Ok(());
        }
        let r = match &mut self.input {
            ChannelInput::Local(rx) if rx.available() > 0 => rx.pop()?,
            ChannelInput::Crossing(rx) => match rx.try_pop()? {
                Some(r) => r,
                None => return Ok(()),
            },
            _ => return Ok(()),
        };
        let Some(loc) = self.p.map(r.byte_addr) else {
            return Err(self.error(
                "request",
                format!(
                    "byte address {:#x} is past the end of memory ({} bytes)",
                    r.byte_addr,
                    self.p.capacity_bytes()
                ),
            ));
        };
        if loc.channel != self.index {
            return Err(self.error(
                "request",
                format!(
                    "byte address {:#x} belongs to channel {}, not {}",
                    r.byte_addr, loc.channel, self.index
                ),
            ));
        }
        self.scheduler.accept(&r, loc, cycle);
        self.arriving = Some(TraceRequest {
            byte_addr: r.byte_addr,
            kind: if r.write {
                TraceKind::Write
            } else {
                TraceKind::Read
            },
            cycle,
        });
        Ok(())
    }

    fn commit(&mut self) {
        let cycle = self.cycle;
        if self.idle_cycle {
            self.cycle += 1;
            self.stats.cycles = self.cycle;
            self.activity_log.sample(self.cycle, self.activity());
            return;
        }
        let cmd = self.bus_q.as_ref().map(|b| b.cmd);
        if let Some(cmd) = cmd {
            match cmd {
                Command::Activate { .. } => {
                    self.stats.activates += 1;
                    self.row_switch_until = self.row_switch_until.max(cycle + self.p.t_rcd);
                }
                Command::Precharge { .. } => {
                    self.stats.precharges += 1;
                    self.row_switch_until = self.row_switch_until.max(cycle + self.p.t_rp);
                }
                Command::Read { .. } => {
                    self.stats.reads += 1;
                    self.stats.last_busy = self
                        .stats
                        .last_busy
                        .max(cycle + self.p.cl + self.p.burst as u64 - 1);
                }
                Command::Write { .. } => {
                    self.stats.writes += 1;
                    self.stats.last_busy =
                        self.stats.last_busy.max(cycle + self.p.burst as u64 - 1);
                    self.write_data_until = cycle + self.p.burst as u64;
                }
                Command::Refresh => {
                    self.stats.refreshes += 1;
                    self.row_switch_until = self.row_switch_until.max(cycle + self.p.t_rfc);
                }
            }
        }
        if self.sdram.dq_now().is_some() || cycle < self.write_data_until {
            self.transfer_cycles += 1;
        } else if cycle < self.row_switch_until && self.scheduler.depth() > 0 {
            self.row_switch_cycles += 1;
        }
        if self.sdram.dq_now().is_some() {
            self.stats.data_bus_cycles += 1;
        }
        if let Some(Command::Write { .. }) = cmd {
            self.stats.data_bus_cycles += self.p.burst as u64;
        }
        if std::mem::take(&mut self.popped_return) {
            self.returns.pop_front();
        }
        if let Some(a) = self.arriving.take() {
            self.stats.accepted += 1;
            if let Some(rec) = &mut self.record {
                rec.push(a);
            }
        }
        self.scheduler.commit(cycle);
        self.sdram.commit();
        self.bus_q = self.bus_d.take();
        self.cycle += 1;
        self.stats.cycles = self.cycle;
        self.activity_log.sample(self.cycle, self.activity());
        self.note_quiet();
    }

    fn trace(&self, t: &mut Trace) {
        match self.bus_q {
            None => t.value(self.ids.cmd, 0),
            Some(b) => {
                t.value(self.ids.cmd, b.cmd.code());
                if let Some(bank) = b.cmd.bank() {
                    t.value(self.ids.bank, bank as u64);
                }
                match b.cmd {
                    Command::Activate { row, .. } => t.value(self.ids.row, row as u64),
                    Command::Read { column, .. } | Command::Write { column, .. } => {
                        t.value(self.ids.column, column.value() as u64)
                    }
                    _ => {}
                }
            }
        }
        self.scheduler.trace(t, self.cycle);
        self.sdram.trace(t);
        t.value(self.ids.returns, self.returns.len() as u64);
    }
}
