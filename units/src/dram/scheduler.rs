//! The memory access scheduler of one channel (Rixner, Dally, Kapasi, Mattson and Owens,
//! "Memory Access Scheduling", ISCA 2000, §3–4).
//!
//! * **Pending-reference buffer** (`memory.pending_references` entries, 32 on gold8): each
//!   entry holds a reference's load/store bit, bank, row, column, write data and tag, kept
//!   in arrival order (the entry's age).
//! * **Precharge manager** (one per bank): decides when the bank's open row is closed.
//!   Open-row policies close it only when no pending reference hits it and some pending
//!   reference needs another row of the bank; closed-row policies close it as soon as no
//!   pending reference hits it.
//! * **Row arbiter** (one per bank): for an idle bank, picks the row to activate — the row
//!   of the oldest pending reference to the bank (under load-over-store, of the oldest
//!   load if there is one).
//! * **Column arbiter**: picks among the references whose row is open and whose column
//!   access is ready — the oldest (under load-over-store, the oldest load first).
//! * **Address arbiter**: one command per cycle goes on the command bus. Column-first
//!   policies take a ready column access before a ready precharge or activate, row-first
//!   policies the other way round; within a class the operation serving the oldest
//!   reference wins. `in-order` performs only the operations the oldest reference needs;
//!   `first-ready` takes the oldest reference whose next operation is ready.
//!
//! Timing: the scheduler keeps, per bank and per channel, the earliest command-bus cycle at
//! which each command may issue (tRCD, tRP, tRAS, tRC, tRRD, tWR, burst spacing, read→write
//! turnaround, tRFC) and issues nothing early. The timing checker verifies this
//! independently. The scheduler's cycle `t` decides the command driven in bus cycle
//! `t + 1`.
//!
//! Refresh: once `refresh_interval` cycles have passed since the last refresh was due, no
//! row is activated and no column accessed; open banks are precharged as soon as they may
//! be, then AUTO REFRESH issues, and the channel is busy for tRFC.
//!
//! Ordering: a column access waits while an older pending reference addresses the same
//! burst, so reordering never changes what a load sees or what a location finally holds.
//!
//! Probes: `queue_depth`, `decision` (0 none, 1 column, 2 precharge, 3 activate,
//! 4 refresh-precharge, 5 refresh), `decision_entry` (the entry served, its age rank),
//! `refresh_pending`.

use imagine_hdl::bits::{u4, u12};
use imagine_hdl::{Display, Scope, SignalId, SignalKind, Trace, bits_for};

use super::{Command, DramParams, Location, Policy, Request, Tag};

/// A reference waiting in the pending-reference buffer.
#[derive(Clone, Copy, Debug)]
pub struct Entry {
    pub seq: u64,
    pub write: bool,
    pub bank: usize,
    pub row: u16,
    pub column: u16,
    /// Burst-aligned byte address (for same-location ordering).
    pub burst_addr: u64,
    pub data: [u32; 8],
    pub tag: Tag,
    /// DRAM cycle it entered the buffer.
    pub arrival: u64,
}

/// What the address arbiter chose this cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    None,
    /// A column access for the entry at this index of the buffer (in age order).
    Column(usize),
    Precharge(usize),
    Activate(usize, u16),
    RefreshPrecharge(usize),
    Refresh,
}

impl Decision {
    fn code(self) -> u64 {
        match self {
            Decision::None => 0,
            Decision::Column(_) => 1,
            Decision::Precharge(_) => 2,
            Decision::Activate(..) => 3,
            Decision::RefreshPrecharge(_) => 4,
            Decision::Refresh => 5,
        }
    }
}

/// A command the scheduler issues, with what the bus needs to carry for it.
#[derive(Clone, Copy, Debug)]
pub struct Issued {
    pub cmd: Command,
    /// The reference served by a column command.
    pub entry: Option<Entry>,
}

#[derive(Clone, Copy, Debug)]
enum Op {
    Column,
    Precharge,
    Activate,
}

/// Per-bank facts gathered once per cycle by the by-class policies (first-ready asks
/// for a bank's row hit only when it considers a precharge, `row_hit`).
#[derive(Clone, Copy, Debug, Default)]
struct BankView {
    /// Some pending reference hits the open row.
    hit: bool,
    /// Age index of the oldest pending reference needing another row than the open one
    /// (for an idle bank: any row), and that row; under load-over-store, the oldest load
    /// if there is one.
    oldest_miss: Option<(usize, u16)>,
}

#[derive(Clone, Debug)]
pub struct Scheduler {
    policy: Policy,
    p: DramParams,
    capacity: usize,
    /// Pending references in arrival order.
    entries: Vec<Entry>,
    next_seq: u64,
    // The scheduler's view of the banks and the bus, in command-bus cycles.
    open: Vec<Option<u16>>,
    ready_act: Vec<u64>,
    ready_col: Vec<u64>,
    ready_pre: Vec<u64>,
    next_act_any: u64,
    next_read: u64,
    next_write: u64,
    busy_until: u64,
    refreshes: u64,
    // Two-phase: this cycle's decision and arriving reference, applied at commit.
    decision: Decision,
    last: Decision,
    last_rank: usize,
    incoming: Option<(Request, Location, u64)>,
    views: Vec<BankView>,
    ids: Probes,
}

#[derive(Clone, Debug)]
struct Probes {
    depth: SignalId,
    decision: SignalId,
    entry: SignalId,
    refresh: SignalId,
}

impl Scheduler {
    /// `p` is the timing the scheduler believes in (normally the machine's; tests may give
    /// it a wrong one to see the checker catch it).
    pub fn new(scope: &mut Scope<'_>, policy: Policy, p: DramParams, capacity: usize) -> Self {
        let banks = p.banks;
        let ids = Probes {
            depth: scope.signal("queue_depth", bits_for(capacity as u64), SignalKind::Reg),
            decision: scope.signal_shown(
                "decision",
                3,
                SignalKind::Reg,
                Display::Names(&[
                    "none",
                    "column",
                    "precharge",
                    "activate",
                    "refresh-precharge",
                    "refresh",
                ]),
            ),
            entry: scope.signal(
                "decision_entry",
                bits_for(capacity.saturating_sub(1) as u64),
                SignalKind::Reg,
            ),
            refresh: scope.signal("refresh_pending", 1, SignalKind::Reg),
        };
        Scheduler {
            policy,
            capacity,
            entries: Vec::with_capacity(capacity),
            next_seq: 0,
            open: vec![None; banks],
            ready_act: vec![0; banks],
            ready_col: vec![0; banks],
            ready_pre: vec![0; banks],
            next_act_any: 0,
            next_read: 0,
            next_write: 0,
            busy_until: 0,
            refreshes: 0,
            decision: Decision::None,
            last: Decision::None,
            last_rank: 0,
            incoming: None,
            views: vec![BankView::default(); banks],
            ids,
            p,
        }
    }

    pub fn policy(&self) -> Policy {
        self.policy
    }

    /// Pending references.
    pub fn depth(&self) -> usize {
        self.entries.len()
    }

    /// Whether a reference can enter this cycle (committed occupancy).
    pub fn has_room(&self) -> bool {
        self.entries.len() < self.capacity
    }

    /// A reference arriving this cycle (call only when [`has_room`](Self::has_room)).
    pub fn accept(&mut self, r: Request, loc: Location, cycle: u64) {
        debug_assert!(self.has_room() && self.incoming.is_none());
        self.incoming = Some((r, loc, cycle));
    }

    /// The timing this scheduler believes in.
    pub fn params(&self) -> &DramParams {
        &self.p
    }

    /// Refreshes issued so far.
    pub fn refreshes(&self) -> u64 {
        self.refreshes
    }

    /// Whether, from cycle `cycle` on and as long as no reference arrives, the only
    /// commands this scheduler can issue are its refreshes, each exactly when due (bus
    /// cycle `k · refresh_interval`): no reference pending, every bank closed, no refresh
    /// overdue and no timing constraint still running.
    pub fn idle_skippable(&self, cycle: u64) -> bool {
        let bus = cycle + 1;
        self.entries.is_empty()
            && self.incoming.is_none()
            && matches!(self.decision, Decision::None)
            && self.open.iter().all(Option::is_none)
            && self.busy_until <= bus
            && self.ready_act.iter().all(|&r| r <= bus)
            && !self.refresh_due(bus)
            // One refresh's tRFC ends before the next is due (the machine description
            // guarantees it; a hand-made DramParams might not).
            && self.p.t_rfc < self.p.t_refi
    }

    /// Brings the scheduler to the state `n` idle cycles from `cycle` leave (only when
    /// [`idle_skippable`](Self::idle_skippable)): the refreshes due in bus cycles
    /// `cycle + 1 ..= cycle + n` issued on time. Returns how many, and the bus cycle of
    /// the last one.
    pub fn skip_idle(&mut self, cycle: u64, n: u64) -> (u64, Option<u64>) {
        debug_assert!(self.idle_skippable(cycle));
        let end_bus = cycle + n;
        let issued = (end_bus / self.p.t_refi).saturating_sub(self.refreshes);
        self.last = Decision::None;
        self.last_rank = 0;
        if issued == 0 {
            return (0, None);
        }
        // The same effects as the commit of each of those refreshes; the later ones
        // supersede the earlier ones' deadlines.
        self.refreshes += issued;
        let last_bus = self.refreshes * self.p.t_refi;
        self.busy_until = last_bus + self.p.t_rfc;
        for r in self.ready_act.iter_mut() {
            *r = (*r).max(last_bus + self.p.t_rfc);
        }
        if last_bus == end_bus {
            self.last = Decision::Refresh;
        }
        (issued, Some(last_bus))
    }

    fn refresh_due(&self, bus: u64) -> bool {
        bus >= (self.refreshes + 1) * self.p.t_refi
    }

    /// Decides the command for bus cycle `cycle + 1`. `read_room`: whether the channel can
    /// take one more read burst's data.
    pub fn eval(&mut self, cycle: u64, read_room: bool) -> Option<Issued> {
        let bus = cycle + 1;
        self.decision = if bus < self.busy_until {
            Decision::None
        } else if self.refresh_due(bus) {
            self.refresh_decision(bus)
        } else if self.entries.is_empty() {
            Decision::None
        } else {
            match self.policy {
                Policy::InOrder => self.in_order(bus, read_room),
                Policy::FirstReady => self.first_ready(bus, read_room),
                _ => {
                    self.gather();
                    self.by_class(bus, read_room)
                }
            }
        };
        self.issued()
    }

    fn issued(&self) -> Option<Issued> {
        let e = |i: usize| self.entries[i];
        let bank = |b: usize| u4::new(b as u8);
        match self.decision {
            Decision::None => None,
            Decision::Column(i) => {
                let en = e(i);
                let column = u12::new(en.column);
                let cmd = if en.write {
                    Command::Write {
                        bank: bank(en.bank),
                        column,
                    }
                } else {
                    Command::Read {
                        bank: bank(en.bank),
                        column,
                    }
                };
                Some(Issued {
                    cmd,
                    entry: Some(en),
                })
            }
            Decision::Precharge(b) | Decision::RefreshPrecharge(b) => Some(Issued {
                cmd: Command::Precharge { bank: bank(b) },
                entry: None,
            }),
            Decision::Activate(b, row) => Some(Issued {
                cmd: Command::Activate { bank: bank(b), row },
                entry: None,
            }),
            Decision::Refresh => Some(Issued {
                cmd: Command::Refresh,
                entry: None,
            }),
        }
    }

    fn refresh_decision(&self, bus: u64) -> Decision {
        let mut all_idle = true;
        for b in 0..self.p.banks {
            if self.open[b].is_some() {
                all_idle = false;
                if bus >= self.ready_pre[b] {
                    return Decision::RefreshPrecharge(b);
                }
            }
        }
        if all_idle && (0..self.p.banks).all(|b| bus >= self.ready_act[b]) {
            Decision::Refresh
        } else {
            Decision::None
        }
    }

    /// Fills the per-bank views from the pending references.
    fn gather(&mut self) {
        let los = self.policy == Policy::LoadOverStore;
        for v in self.views.iter_mut() {
            *v = BankView::default();
        }
        for (i, e) in self.entries.iter().enumerate() {
            let v = &mut self.views[e.bank];
            if self.open[e.bank] == Some(e.row) {
                v.hit = true;
            } else {
                let better = match v.oldest_miss {
                    None => true,
                    Some((j, _)) => los && self.entries[j].write && !e.write,
                };
                if better {
                    v.oldest_miss = Some((i, e.row));
                }
            }
        }
    }

    /// The next operation entry `i` needs.
    fn next_op(&self, i: usize) -> Op {
        let e = &self.entries[i];
        match self.open[e.bank] {
            Some(r) if r == e.row => Op::Column,
            Some(_) => Op::Precharge,
            None => Op::Activate,
        }
    }

    /// An older pending reference addresses the same burst.
    fn hazard(&self, i: usize) -> bool {
        #[cfg(feature = "inject-bugs")]
        if imagine_hdl::inject::active(imagine_hdl::inject::Bug::SchedulerIgnoresSameBurstHazard) {
            return false;
        }
        let a = self.entries[i].burst_addr;
        self.entries[..i].iter().any(|e| e.burst_addr == a)
    }

    fn ready(&self, op: Op, i: usize, bus: u64, read_room: bool) -> bool {
        let e = &self.entries[i];
        let b = e.bank;
        match op {
            Op::Column => {
                bus >= self.ready_col[b]
                    && if e.write {
                        bus >= self.next_write
                    } else {
                        read_room && bus >= self.next_read
                    }
            }
            Op::Precharge => bus >= self.ready_pre[b],
            Op::Activate => bus >= self.ready_act[b] && bus >= self.next_act_any,
        }
    }

    fn decision_for(&self, op: Op, i: usize) -> Decision {
        let e = &self.entries[i];
        match op {
            Op::Column => Decision::Column(i),
            Op::Precharge => Decision::Precharge(e.bank),
            Op::Activate => Decision::Activate(e.bank, e.row),
        }
    }

    fn in_order(&self, bus: u64, read_room: bool) -> Decision {
        let op = self.next_op(0);
        if self.ready(op, 0, bus, read_room) {
            self.decision_for(op, 0)
        } else {
            Decision::None
        }
    }

    fn first_ready(&self, bus: u64, read_room: bool) -> Decision {
        for i in 0..self.entries.len() {
            let op = self.next_op(i);
            // Timing first: it is one comparison, the rules below search the buffer.
            if !self.ready(op, i, bus, read_room) {
                continue;
            }
            let allowed = match op {
                Op::Column => !self.hazard(i),
                // Open-row precharging: never close a row someone still hits.
                Op::Precharge => !self.row_hit(self.entries[i].bank),
                Op::Activate => true,
            };
            if allowed {
                return self.decision_for(op, i);
            }
        }
        Decision::None
    }

    /// Some pending reference hits bank `b`'s open row.
    fn row_hit(&self, b: usize) -> bool {
        self.open[b].is_some_and(|row| self.entries.iter().any(|e| e.bank == b && e.row == row))
    }

    /// Column-first or row-first over the column arbiter, the precharge managers and the
    /// row arbiters.
    fn by_class(&self, bus: u64, read_room: bool) -> Decision {
        let column = self.column_arbiter(bus, read_room);
        let row = self.row_candidate(bus);
        let row_first = matches!(self.policy, Policy::RowOpen | Policy::RowClosed);
        let (first, second) = if row_first {
            (row, column)
        } else {
            (column, row)
        };
        first.or(second).unwrap_or(Decision::None)
    }

    fn column_arbiter(&self, bus: u64, read_room: bool) -> Option<Decision> {
        let los = self.policy == Policy::LoadOverStore;
        let mut best: Option<usize> = None;
        for i in 0..self.entries.len() {
            if !matches!(self.next_op(i), Op::Column)
                || !self.ready(Op::Column, i, bus, read_room)
                || self.hazard(i)
            {
                continue;
            }
            match best {
                None => best = Some(i),
                Some(j) if los && self.entries[j].write && !self.entries[i].write => best = Some(i),
                _ => {}
            }
            if !los {
                break;
            }
        }
        best.map(Decision::Column)
    }

    /// The ready precharge or activate serving the oldest reference.
    fn row_candidate(&self, bus: u64) -> Option<Decision> {
        let closed = self.policy.closed_row();
        let mut best: Option<(u64, Decision)> = None;
        for b in 0..self.p.banks {
            let v = self.views[b];
            let cand = match self.open[b] {
                Some(_) => {
                    let wanted = !v.hit && (closed || v.oldest_miss.is_some());
                    if wanted && bus >= self.ready_pre[b] {
                        let age = v.oldest_miss.map_or(u64::MAX, |(i, _)| self.entries[i].seq);
                        Some((age, Decision::Precharge(b)))
                    } else {
                        None
                    }
                }
                None => match v.oldest_miss {
                    Some((i, row)) if bus >= self.ready_act[b] && bus >= self.next_act_any => {
                        Some((self.entries[i].seq, Decision::Activate(b, row)))
                    }
                    _ => None,
                },
            };
            if let Some((age, d)) = cand
                && best.is_none_or(|(a, _)| age < a)
            {
                best = Some((age, d));
            }
        }
        best.map(|(_, d)| d)
    }

    /// The clock edge: applies this cycle's decision to the scheduler's view and takes in
    /// the arriving reference.
    pub fn commit(&mut self, cycle: u64) {
        let bus = cycle + 1;
        let p = &self.p;
        let burst = p.burst as u64;
        self.last_rank = 0;
        match self.decision {
            Decision::None => {}
            Decision::Column(i) => {
                self.last_rank = i;
                let e = self.entries.remove(i);
                let b = e.bank;
                if e.write {
                    self.next_write = bus + burst;
                    self.next_read = self.next_read.max(bus + burst);
                    // Write recovery: tWR after the last data word.
                    self.ready_pre[b] = self.ready_pre[b].max(bus + burst - 1 + p.t_wr);
                } else {
                    self.next_read = bus + burst;
                    // The next write's data must follow this read's data and a turnaround.
                    self.next_write = self.next_write.max(bus + p.cl + burst + p.turnaround);
                    // Precharge only after the whole burst has been read out.
                    self.ready_pre[b] = self.ready_pre[b].max(bus + burst);
                }
            }
            Decision::Precharge(b) | Decision::RefreshPrecharge(b) => {
                self.open[b] = None;
                self.ready_act[b] = self.ready_act[b].max(bus + p.t_rp);
            }
            Decision::Activate(b, row) => {
                self.open[b] = Some(row);
                self.ready_col[b] = bus + p.t_rcd;
                self.ready_pre[b] = bus + p.t_ras;
                self.ready_act[b] = bus + p.t_rc;
                self.next_act_any = bus + p.t_rrd;
            }
            Decision::Refresh => {
                self.refreshes += 1;
                self.busy_until = bus + p.t_rfc;
                for b in 0..p.banks {
                    self.ready_act[b] = self.ready_act[b].max(bus + p.t_rfc);
                }
            }
        }
        self.last = self.decision;
        self.decision = Decision::None;
        if let Some((r, loc, cycle)) = self.incoming.take() {
            self.entries.push(Entry {
                seq: self.next_seq,
                write: r.write,
                bank: loc.bank.value() as usize,
                row: loc.row,
                column: loc.column.value(),
                burst_addr: r.byte_addr / self.p.burst_bytes(),
                data: r.data,
                tag: r.tag,
                arrival: cycle,
            });
            self.next_seq += 1;
        }
    }

    pub fn trace(&self, t: &mut Trace, cycle: u64) {
        t.value(self.ids.depth, self.entries.len() as u64);
        t.value(self.ids.decision, self.last.code());
        t.value(self.ids.entry, self.last_rank as u64);
        t.value(self.ids.refresh, self.refresh_due(cycle + 1) as u64);
    }
}
