//! Testbench of the DRAM access scheduler (`units::dram::scheduler`) of one channel under
//! every [`Policy`], driven through its ports as the channel drives it: one reference may
//! enter per cycle while the pending-reference buffer has room, the scheduler decides in
//! its cycle `t` the command on the bus in cycle `t + 1`, and the channel tells it each
//! cycle whether the return path has room for a read (here at random). The stimulus
//! favours a few rows per bank (row hits and bank conflicts), reads and writes to the
//! bursts of recent references (same-burst pairs), and arrival rates that change in
//! phases so the buffer fills and drains. The refresh interval is shortened to at most
//! `max(256, 4 · tRFC)` cycles so that every run meets refreshes; the rest of the timing
//! is the machine's.
//!
//! Reference: the references in arrival order and the memory as they would leave it (a
//! load sees the last store that arrived before it to its burst); the memory as the
//! commands on the bus leave it (a write stores its data in its bus cycle, a read returns
//! what is stored in its bus cycle); the SDRAM reference of the `sdram` testbench for
//! bank state and the timing rules. Checked: every column command serves a pending
//! reference at its bank and column, each reference exactly once, each load the value the
//! arrival order gives it, the final memory that of the arrival order; the independent
//! timing checker flags nothing. Policy contracts: `in-order` serves in arrival order;
//! `first-ready` issues a command in every cycle in which some pending reference's next
//! operation is ready (its timing met, a column access with no older reference to its
//! burst and, for a read, room for its data, a precharge of a row no pending reference
//! hits) and no refresh is due.

use std::collections::{HashMap, VecDeque};

use imagine_hdl::bits::{u4, u12};
use imagine_units::desc::MachineDesc;
use imagine_units::dram::scheduler::{Issued, Scheduler};
use imagine_units::dram::{Command, DramParams, Location, Policy, Request, Tag, TimingChecker};
use imagine_waves::VcdSummary;

use super::sdram::RefSdram;
use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "read served",
    "write served",
    "row hit (column access without an ACTIVATE since the last one)",
    "bank conflict (PRECHARGE for another row)",
    "ACTIVATE",
    "REFRESH",
    "read arrives behind a pending write to its burst",
    "write arrives behind a pending read to its burst",
    "write arrives behind a pending write to its burst",
    "reference served out of arrival order",
    "pending-reference buffer full",
    "read held back: no room for its data",
    "idle with references pending",
];

/// One reference as the stimulus made it.
#[derive(Clone, Copy)]
struct Ref {
    write: bool,
    location: Location,
    burst_addr: u64,
    data: [u32; 8],
    /// For a load: the burst's words as the arrival order leaves them when it arrives.
    expected: [u32; 8],
}

/// Everything one policy's run keeps.
struct Run<'a> {
    p: &'a DramParams,
    policy: Policy,
    rng: &'a mut Rng,
    sb: &'a mut Scoreboard,
    cov: &'a mut Coverage,
    refs: Vec<Ref>,
    served: Vec<bool>,
    /// Sequence numbers of the pending references (accepted, not yet decided), oldest first.
    pending: VecDeque<usize>,
    /// Memory as the arrival order leaves it, and as the bus leaves it, by burst address.
    arrival_memory: HashMap<u64, [u32; 8]>,
    bus_memory: HashMap<u64, [u32; 8]>,
    sdram: RefSdram,
    checker: TimingChecker,
    /// Column accesses to each bank since its ACTIVATE.
    accesses: Vec<u32>,
    next_in_order: usize,
    refreshes: u64,
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let mut p = DramParams::of(desc);
    p.t_refi = p.t_refi.min(256.max(4 * p.t_rfc));
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let bins: Vec<String> = BINS
        .iter()
        .map(|b| b.to_string())
        .chain(Policy::ALL.iter().map(|p| format!("{p}: reference served")))
        .collect();
    let mut cov = Coverage::new(&bins);
    let per_policy = config
        .transactions
        .div_ceil(Policy::ALL.len() as u64)
        .max(1);
    let mut waves = Ok(None);
    for policy in Policy::ALL {
        let mut run = Run {
            p: &p,
            policy,
            rng: &mut rng,
            sb: &mut sb,
            cov: &mut cov,
            refs: Vec::new(),
            served: Vec::new(),
            pending: VecDeque::new(),
            arrival_memory: HashMap::new(),
            bus_memory: HashMap::new(),
            sdram: RefSdram::new(&p),
            checker: TimingChecker::new(0, &p),
            accesses: vec![0; p.banks],
            next_in_order: 0,
            refreshes: 0,
        };
        // Each policy's run starts again at cycle 0: the waveform is of the run in which the
        // first mismatch happens (the runs before it rewrite the file and pass).
        let clean = run.sb.mismatches == 0;
        let run_waves = run.drive(desc, per_policy, clean.then_some(config));
        if clean {
            waves = run_waves;
        }
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves,
    }
}

impl Run<'_> {
    /// Drives `count` references; writes the waveform `config` asks for, if any.
    fn drive(
        &mut self,
        desc: &MachineDesc,
        count: u64,
        config: Option<&Config>,
    ) -> Result<Option<VcdSummary>, String> {
        let p = self.p;
        let capacity = desc.memory.pending_references;
        let mut d = design();
        let mut scheduler = Scheduler::new(&mut d.scope(), self.policy, p.clone(), capacity);
        let mut waves = match config {
            Some(config) => Waves::new(d.probes(), desc, BlockClock::Dram, config),
            None => Waves::none(),
        };
        let mut bus: Option<Issued> = None;
        let mut rate = 50;
        let mut cycle = 0u64;
        // Every reference takes far fewer cycles than this, even one behind a full buffer.
        let limit = (count + 8) * 64 + 4 * p.t_refi;
        loop {
            let done = self.refs.len() as u64 >= count && self.pending.is_empty() && bus.is_none();
            if done || cycle > limit {
                break;
            }
            // The command on the bus this cycle.
            let before = self.checker.violations().len();
            self.checker.observe(cycle, bus.map(|b| b.cmd));
            if let Some(v) = self.checker.violations().get(before) {
                let v = v.to_string();
                self.sb
                    .check(cycle, || "timing checker".into(), String::new(), v);
            }
            if let Some(issued) = bus.take() {
                self.on_bus(cycle, issued);
            }
            // The decision for the next cycle.
            let read_room = self.rng.chance(90);
            let ready = self.some_ready(cycle + 1, read_room);
            let issued = scheduler.eval(cycle, read_room);
            let refresh_due = cycle + 1 >= (self.refreshes + 1) * p.t_refi;
            if self.policy == Policy::FirstReady && !refresh_due {
                self.sb.check(
                    cycle,
                    || "first-ready: a command while a reference's next operation is ready".into(),
                    ready,
                    issued.is_some(),
                );
            }
            if let Some(i) = issued
                && let Some(e) = i.entry
            {
                let seq = e.tag.seq as usize;
                self.pending.retain(|&s| s != seq);
            }
            self.cov.hit_if(
                issued.is_none() && !self.pending.is_empty(),
                "idle with references pending",
            );
            self.cov.hit_if(
                !read_room && self.pending.iter().any(|&s| !self.refs[s].write),
                "read held back: no room for its data",
            );
            // A reference arriving.
            if cycle.is_multiple_of(32) {
                rate = self.rng.pick(&[90, 60, 25, 5]);
            }
            if (self.refs.len() as u64) < count && self.rng.chance(rate) {
                if scheduler.has_room() {
                    let (r, loc) = self.stimulus();
                    scheduler.accept(&r, loc, cycle);
                    self.sb.transaction();
                } else {
                    self.cov.hit("pending-reference buffer full");
                }
            }
            scheduler.commit(cycle);
            waves.cycle(cycle, |t| scheduler.trace(t, cycle));
            bus = issued;
            cycle += 1;
        }
        let unserved = self.served.iter().filter(|s| !**s).count();
        self.sb.check(
            cycle,
            || format!("{}: references never served", self.policy),
            0,
            unserved,
        );
        let mut expected: Vec<_> = self.arrival_memory.iter().collect();
        expected.sort_unstable();
        let mut got: Vec<_> = self.bus_memory.iter().collect();
        got.sort_unstable();
        self.sb.check(
            cycle,
            || format!("{}: memory after every reference", self.policy),
            expected,
            got,
        );
        waves.finish(None)
    }

    /// A new reference, recorded in the reference model.
    fn stimulus(&mut self) -> (Request, Location) {
        let p = self.p;
        let rng = &mut *self.rng;
        let write = rng.chance(45);
        let location = if !self.refs.is_empty() && rng.chance(35) {
            // The burst of a recent reference: same-burst pairs.
            let back = rng.index(self.refs.len().min(8)) + 1;
            self.refs[self.refs.len() - back].location
        } else {
            let bursts = (p.columns / p.burst) as u64;
            Location {
                channel: 0,
                bank: u4::new(rng.below(p.banks as u64) as u8),
                row: rng.pick(&[0, 1, 2, (p.rows - 1) as u16]),
                column: u12::new((rng.below(bursts.min(8)) * p.burst as u64) as u16),
            }
        };
        let byte_addr = p.unmap(&location);
        let burst_addr = byte_addr / p.burst_bytes();
        let mut data = [0u32; 8];
        for w in data.iter_mut().take(p.burst) {
            *w = rng.corner_word();
        }
        for &s in &self.pending {
            let older = &self.refs[s];
            if older.burst_addr == burst_addr {
                let bin = match (older.write, write) {
                    (true, false) => "read arrives behind a pending write to its burst",
                    (false, true) => "write arrives behind a pending read to its burst",
                    (true, true) => "write arrives behind a pending write to its burst",
                    (false, false) => continue,
                };
                self.cov.hit(bin);
            }
        }
        let expected = self
            .arrival_memory
            .get(&burst_addr)
            .copied()
            .unwrap_or([0; 8]);
        if write {
            self.arrival_memory.insert(burst_addr, data);
        }
        let seq = self.refs.len();
        self.refs.push(Ref {
            write,
            location,
            burst_addr,
            data,
            expected,
        });
        self.served.push(false);
        self.pending.push_back(seq);
        let tag = Tag {
            source: 0,
            seq: seq as u32,
        };
        (
            Request {
                write,
                byte_addr,
                data,
                tag,
            },
            location,
        )
    }

    /// The command the bus carries in `cycle`.
    fn on_bus(&mut self, cycle: u64, issued: Issued) {
        let policy = self.policy;
        let cmd = issued.cmd;
        match cmd {
            Command::Activate { bank, .. } => {
                self.cov.hit("ACTIVATE");
                self.accesses[bank.value() as usize] = 0;
            }
            Command::Precharge { bank } => {
                let b = bank.value() as usize;
                let open = self.sdram.open_row(b);
                let wanted_elsewhere = self.pending.iter().any(|&s| {
                    let l = self.refs[s].location;
                    l.bank == bank && Some(l.row) != open
                });
                self.cov.hit_if(
                    open.is_some() && wanted_elsewhere,
                    "bank conflict (PRECHARGE for another row)",
                );
            }
            Command::Refresh => {
                self.cov.hit("REFRESH");
                self.refreshes += 1;
            }
            Command::Read { bank, column } | Command::Write { bank, column } => {
                let Some(e) = issued.entry else {
                    self.sb
                        .assert(cycle, false, || format!("{cmd:?} carries its reference"));
                    return;
                };
                let seq = e.tag.seq as usize;
                let Some(r) = self.refs.get(seq).copied() else {
                    self.sb
                        .assert(cycle, false, || format!("{cmd:?} serves a reference made"));
                    return;
                };
                self.sb.check(
                    cycle,
                    || format!("reference {seq} served once"),
                    false,
                    self.served[seq],
                );
                self.served[seq] = true;
                self.sb.check(
                    cycle,
                    || format!("bus command of reference {seq}"),
                    (r.write, r.location.bank, r.location.column),
                    (matches!(cmd, Command::Write { .. }), bank, column),
                );
                let b = bank.value() as usize;
                self.cov.hit_if(
                    self.accesses[b] > 0,
                    "row hit (column access without an ACTIVATE since the last one)",
                );
                self.accesses[b] += 1;
                self.cov.hit(&format!("{policy}: reference served"));
                self.sb.check(
                    cycle,
                    || format!("data carried by reference {seq}"),
                    &r.data[..self.p.burst],
                    &e.data[..self.p.burst],
                );
                if r.write {
                    self.cov.hit("write served");
                    self.bus_memory.insert(r.burst_addr, e.data);
                } else {
                    self.cov.hit("read served");
                    let got = self
                        .bus_memory
                        .get(&r.burst_addr)
                        .copied()
                        .unwrap_or([0; 8]);
                    let words = self.p.burst;
                    self.sb.check(
                        cycle,
                        || format!("{policy}: load {seq} sees the last store to its burst"),
                        &r.expected[..words],
                        &got[..words],
                    );
                }
                self.cov.hit_if(
                    seq != self.next_in_order,
                    "reference served out of arrival order",
                );
                if policy == Policy::InOrder {
                    self.sb.check(
                        cycle,
                        || "in-order: references served in arrival order".into(),
                        self.next_in_order,
                        seq,
                    );
                }
                while self.served.get(self.next_in_order) == Some(&true) {
                    self.next_in_order += 1;
                }
            }
        }
        self.sdram
            .apply(cycle, cmd, &issued.entry.map_or([0; 8], |e| e.data));
        self.sdram.forget_data_bus();
    }

    /// Whether some pending reference's next operation may go on the bus in cycle `bus`.
    fn some_ready(&self, bus: u64, read_room: bool) -> bool {
        self.pending.iter().enumerate().any(|(age, &s)| {
            let r = &self.refs[s];
            let (bank, b) = (r.location.bank, r.location.bank.value() as usize);
            let open = self.sdram.open_row(b);
            let cmd = match open {
                Some(row) if row == r.location.row => {
                    let column = r.location.column;
                    let older_same_burst = self
                        .pending
                        .iter()
                        .take(age)
                        .any(|&o| self.refs[o].burst_addr == r.burst_addr);
                    if older_same_burst || (!r.write && !read_room) {
                        return false;
                    }
                    if r.write {
                        Command::Write { bank, column }
                    } else {
                        Command::Read { bank, column }
                    }
                }
                Some(row) => {
                    let hit = self.pending.iter().any(|&o| {
                        let l = self.refs[o].location;
                        l.bank == bank && l.row == row
                    });
                    if hit {
                        return false;
                    }
                    Command::Precharge { bank }
                }
                None => Command::Activate {
                    bank,
                    row: r.location.row,
                },
            };
            self.sdram.broken(bus, cmd).is_empty()
        })
    }
}
