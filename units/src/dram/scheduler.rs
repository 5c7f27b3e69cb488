//! The memory access scheduler of one channel (Rixner, Dally, Kapasi, Mattson and Owens,
//! "Memory Access Scheduling", ISCA 2000, §3–4).
//!
//! * **Pending-reference buffer** (`memory.pending_references` entries, 32 on gold8; see
//!   [`pending`](super::pending)): each entry holds a reference's load/store bit, bank,
//!   row, column, write data and tag, kept in arrival order (the entry's age).
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

pub use super::pending::Entry;
use super::pending::{AgeMask, PendingBuffer};
use super::{Command, DramParams, Location, Policy, Request, div_rem};

/// What the address arbiter chose this cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    None,
    /// A column access for the entry at this position of the buffer.
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

/// The scheduler's view of one bank, in command-bus cycles.
#[derive(Clone, Copy, Debug, Default)]
struct BankView {
    open: Option<u16>,
    /// The earliest cycles an ACTIVATE, a READ or WRITE, and a PRECHARGE may issue.
    ready_act: u64,
    ready_col: u64,
    ready_pre: u64,
}

#[derive(Clone, Debug)]
pub struct Scheduler {
    policy: Policy,
    p: DramParams,
    buffer: PendingBuffer,
    // The scheduler's view of the banks and the bus, in command-bus cycles.
    banks: Vec<BankView>,
    next_act_any: u64,
    next_read: u64,
    next_write: u64,
    busy_until: u64,
    refreshes: u64,
    // Two-phase: this cycle's decision and arriving reference, applied at commit.
    decision: Decision,
    last: Decision,
    last_rank: usize,
    incoming: Option<Entry>,
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
            buffer: PendingBuffer::new(capacity, p.banks),
            banks: vec![BankView::default(); p.banks],
            next_act_any: 0,
            next_read: 0,
            next_write: 0,
            busy_until: 0,
            refreshes: 0,
            decision: Decision::None,
            last: Decision::None,
            last_rank: 0,
            incoming: None,
            ids,
            p,
        }
    }

    pub fn policy(&self) -> Policy {
        self.policy
    }

    /// Pending references.
    pub fn depth(&self) -> usize {
        self.buffer.len()
    }

    /// Whether a reference can enter this cycle (committed occupancy).
    pub fn has_room(&self) -> bool {
        !self.buffer.is_full()
    }

    /// A reference arriving this cycle (call only when [`has_room`](Self::has_room)).
    #[inline]
    pub fn accept(&mut self, r: &Request, loc: Location, cycle: u64) {
        debug_assert!(self.has_room() && self.incoming.is_none());
        self.incoming = Some(Entry {
            write: r.write,
            bank: loc.bank.value(),
            row: loc.row,
            column: loc.column.value(),
            burst_addr: div_rem(r.byte_addr, self.p.burst_bytes()).0,
            data: r.data,
            tag: r.tag,
            arrival: cycle,
        });
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
        self.is_quiet()
            && self
                .banks
                .iter()
                .all(|b| b.open.is_none() && b.ready_act <= bus)
            && self.busy_until <= bus
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
        for b in self.banks.iter_mut() {
            b.ready_act = b.ready_act.max(last_bus + self.p.t_rfc);
        }
        if last_bus == end_bus {
            self.last = Decision::Refresh;
        }
        (issued, Some(last_bus))
    }

    /// Whether nothing is pending or arriving and nothing decided: until its next refresh
    /// the scheduler decides nothing.
    pub fn is_quiet(&self) -> bool {
        self.buffer.is_empty() && self.incoming.is_none() && self.decision == Decision::None
    }

    /// The cycle in which the scheduler decides for the bus cycle its next refresh is due
    /// in (the refresh, or a precharge before it).
    pub fn next_refresh_cycle(&self) -> u64 {
        ((self.refreshes + 1) * self.p.t_refi).saturating_sub(1)
    }

    fn refresh_due(&self, bus: u64) -> bool {
        bus >= (self.refreshes + 1) * self.p.t_refi
    }

    /// Decides the command for bus cycle `cycle + 1`. `read_room`: whether the channel can
    /// take one more read burst's data.
    #[inline]
    pub fn eval(&mut self, cycle: u64, read_room: bool) -> Option<Issued> {
        let bus = cycle + 1;
        self.decision = if bus < self.busy_until {
            Decision::None
        } else if self.refresh_due(bus) {
            self.refresh_decision(bus)
        } else if self.buffer.is_empty() {
            Decision::None
        } else {
            match self.policy {
                Policy::InOrder => self.in_order(bus, read_room),
                Policy::FirstReady => self.first_ready(bus, read_room),
                _ => self.by_class(bus, read_room),
            }
        };
        self.issued()
    }

    fn issued(&self) -> Option<Issued> {
        let bank = |b: usize| u4::new(b as u8);
        let (cmd, entry) = match self.decision {
            Decision::None => return None,
            Decision::Column(p) => {
                let e = self.buffer.entry(p);
                let (bank, column) = (u4::new(e.bank), u12::new(e.column));
                let cmd = if e.write {
                    Command::Write { bank, column }
                } else {
                    Command::Read { bank, column }
                };
                (cmd, Some(*e))
            }
            Decision::Precharge(b) | Decision::RefreshPrecharge(b) => {
                (Command::Precharge { bank: bank(b) }, None)
            }
            Decision::Activate(b, row) => (Command::Activate { bank: bank(b), row }, None),
            Decision::Refresh => (Command::Refresh, None),
        };
        Some(Issued { cmd, entry })
    }

    fn refresh_decision(&self, bus: u64) -> Decision {
        let mut all_idle = true;
        for (b, bank) in self.banks.iter().enumerate() {
            if bank.open.is_some() {
                all_idle = false;
                if bus >= bank.ready_pre {
                    return Decision::RefreshPrecharge(b);
                }
            }
        }
        if all_idle && self.banks.iter().all(|b| bus >= b.ready_act) {
            Decision::Refresh
        } else {
            Decision::None
        }
    }

    /// The entries an older pending reference to the same burst holds back.
    fn held(&self) -> AgeMask {
        #[cfg(feature = "inject-bugs")]
        if imagine_hdl::inject::active(imagine_hdl::inject::Bug::SchedulerIgnoresSameBurstHazard) {
            return AgeMask::EMPTY;
        }
        self.buffer.held()
    }

    /// Of the entries of the banks in `banks` (those whose tRCD is met), the ones whose
    /// column access may issue: their row open, the data bus's spacing met, room for a
    /// read's data, no older entry to their burst.
    fn ready_columns(&self, banks: AgeMask, bus: u64, read_room: bool) -> AgeMask {
        let writes = self.buffer.writes();
        let kinds = match (bus >= self.next_write, read_room && bus >= self.next_read) {
            (true, true) => AgeMask::ALL,
            (true, false) => writes,
            (false, true) => !writes,
            (false, false) => return AgeMask::EMPTY,
        };
        self.buffer.hits() & !self.held() & banks & kinds
    }

    /// The oldest entry's next operation and the decision performing it, if its timing is
    /// met (and, for a read, there is room for its data).
    fn oldest_ready(&self, bus: u64, read_room: bool) -> Option<(Op, Decision)> {
        let p = self.buffer.oldest()?;
        let e = self.buffer.entry(p);
        let b = e.bank as usize;
        let bank = &self.banks[b];
        match bank.open {
            Some(r) if r == e.row => (bus >= bank.ready_col
                && if e.write {
                    bus >= self.next_write
                } else {
                    read_room && bus >= self.next_read
                })
            .then_some((Op::Column, Decision::Column(p))),
            Some(_) => (bus >= bank.ready_pre).then_some((Op::Precharge, Decision::Precharge(b))),
            None => (bus >= bank.ready_act && bus >= self.next_act_any)
                .then_some((Op::Activate, Decision::Activate(b, e.row))),
        }
    }

    /// Only the oldest pending reference may have operations performed for it.
    fn in_order(&self, bus: u64, read_room: bool) -> Decision {
        self.oldest_ready(bus, read_room)
            .map_or(Decision::None, |(_, d)| d)
    }

    /// The oldest entry whose next operation is ready: a column access (see
    /// [`ready_columns`](Self::ready_columns)), a precharge of a row nobody hits
    /// (open-row precharging), an activate.
    fn first_ready(&self, bus: u64, read_room: bool) -> Decision {
        // Nothing older holds the oldest entry back: when its operation is ready (a
        // precharge, of a row nobody hits) it is the one. Most cycles end here.
        match self.oldest_ready(bus, read_room) {
            Some((Op::Precharge, Decision::Precharge(b))) if self.buffer.banks()[b].hit() => {}
            Some((_, d)) => return d,
            None => {}
        }
        let activate_any = bus >= self.next_act_any;
        let (mut column_banks, mut row_ready) = (AgeMask::EMPTY, AgeMask::EMPTY);
        for (bank, refs) in self.banks.iter().zip(self.buffer.banks()) {
            if !refs.wanted() {
                continue;
            }
            if bus >= bank.ready_col {
                column_banks |= refs.refs;
            }
            // An open bank's misses need a precharge, a closed bank's entries an activate.
            let ready = match bank.open {
                Some(_) => bus >= bank.ready_pre && !refs.hit(),
                None => activate_any && bus >= bank.ready_act,
            };
            if ready {
                row_ready |= refs.refs;
            }
        }
        let ready = self.ready_columns(column_banks, bus, read_room) | row_ready;
        let Some(p) = ready.first() else {
            return Decision::None;
        };
        let e = self.buffer.entry(p);
        let b = e.bank as usize;
        match self.banks[b].open {
            Some(r) if r == e.row => Decision::Column(p),
            Some(_) => Decision::Precharge(b),
            None => Decision::Activate(b, e.row),
        }
    }

    /// The oldest of `among`; under load-over-store, the oldest load if there is one.
    fn oldest(&self, among: AgeMask) -> Option<usize> {
        if self.policy == Policy::LoadOverStore {
            let loads = among & !self.buffer.writes();
            loads.first().or_else(|| among.first())
        } else {
            among.first()
        }
    }

    /// Column-first or row-first over the column arbiter, the precharge managers and the
    /// row arbiters.
    fn by_class(&self, bus: u64, read_room: bool) -> Decision {
        let row_first = matches!(self.policy, Policy::RowOpen | Policy::RowClosed);
        // Column-first: a ready column access for the oldest entry is the column arbiter's
        // choice (under load-over-store, if it is a load).
        if !row_first
            && let Some((Op::Column, d @ Decision::Column(p))) = self.oldest_ready(bus, read_room)
            && !(self.policy == Policy::LoadOverStore && self.buffer.entry(p).write)
        {
            return d;
        }
        let hits = self.buffer.hits();
        let closed = self.policy.closed_row();
        let activate_any = bus >= self.next_act_any;
        let mut column_banks = AgeMask::EMPTY;
        // The ready precharge or activate serving the oldest reference: (its position,
        // none after every position; the decision).
        let mut row: Option<(usize, Decision)> = None;
        for (b, (bank, refs)) in self.banks.iter().zip(self.buffer.banks()).enumerate() {
            // A bank nobody wants matters only to a closed-row policy, if it is open.
            if !(refs.wanted() || (closed && bank.open.is_some())) {
                continue;
            }
            if bus >= bank.ready_col {
                column_banks |= refs.refs;
            }
            // The row arbiter's choice: the oldest reference needing another row than the
            // open one (for an idle bank: any row).
            let oldest_miss = self.oldest(refs.refs & !hits);
            let candidate = match bank.open {
                Some(_) => {
                    let hit = refs.hit();
                    let wanted = !hit && (closed || oldest_miss.is_some());
                    (wanted && bus >= bank.ready_pre)
                        .then(|| (oldest_miss.unwrap_or(usize::MAX), Decision::Precharge(b)))
                }
                None => match oldest_miss {
                    Some(p) if activate_any && bus >= bank.ready_act => {
                        Some((p, Decision::Activate(b, self.buffer.entry(p).row)))
                    }
                    _ => None,
                },
            };
            if let Some((age, d)) = candidate
                && row.is_none_or(|(a, _)| age < a)
            {
                row = Some((age, d));
            }
        }
        let column = self
            .oldest(self.ready_columns(column_banks, bus, read_room))
            .map(Decision::Column);
        let row = row.map(|(_, d)| d);
        let (first, second) = if row_first {
            (row, column)
        } else {
            (column, row)
        };
        first.or(second).unwrap_or(Decision::None)
    }

    /// The clock edge: applies this cycle's decision to the scheduler's view and takes in
    /// the arriving reference.
    #[inline]
    pub fn commit(&mut self, cycle: u64) {
        let bus = cycle + 1;
        let p = &self.p;
        let burst = p.burst as u64;
        self.last_rank = 0;
        match self.decision {
            Decision::None => {}
            Decision::Column(position) => {
                self.last_rank = self.buffer.rank(position);
                let e = self.buffer.entry(position);
                let (write, bank) = (e.write, &mut self.banks[e.bank as usize]);
                self.buffer.remove(position);
                if write {
                    self.next_write = bus + burst;
                    self.next_read = self.next_read.max(bus + burst);
                    // Write recovery: tWR after the last data word.
                    bank.ready_pre = bank.ready_pre.max(bus + burst - 1 + p.t_wr);
                } else {
                    self.next_read = bus + burst;
                    // The next write's data must follow this read's data and a turnaround.
                    self.next_write = self.next_write.max(bus + p.cl + burst + p.turnaround);
                    // Precharge only after the whole burst has been read out.
                    bank.ready_pre = bank.ready_pre.max(bus + burst);
                }
            }
            Decision::Precharge(b) | Decision::RefreshPrecharge(b) => {
                let bank = &mut self.banks[b];
                bank.open = None;
                bank.ready_act = bank.ready_act.max(bus + p.t_rp);
                self.buffer.closed(b);
            }
            Decision::Activate(b, row) => {
                self.banks[b] = BankView {
                    open: Some(row),
                    ready_col: bus + p.t_rcd,
                    ready_pre: bus + p.t_ras,
                    ready_act: bus + p.t_rc,
                };
                self.next_act_any = bus + p.t_rrd;
                self.buffer.opened(b, row);
            }
            Decision::Refresh => {
                self.refreshes += 1;
                self.busy_until = bus + p.t_rfc;
                for b in self.banks.iter_mut() {
                    b.ready_act = b.ready_act.max(bus + p.t_rfc);
                }
            }
        }
        self.last = self.decision;
        self.decision = Decision::None;
        if let Some(e) = self.incoming.take() {
            let open = self.banks[e.bank as usize].open;
            self.buffer.push(e, open);
        }
    }

    pub fn trace(&self, t: &mut Trace, cycle: u64) {
        t.value(self.ids.depth, self.buffer.len() as u64);
        t.value(self.ids.decision, self.last.code());
        t.value(self.ids.entry, self.last_rank as u64);
        t.value(self.ids.refresh, self.refresh_due(cycle + 1) as u64);
    }
}
