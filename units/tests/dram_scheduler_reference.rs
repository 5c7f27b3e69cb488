//! The memory access scheduler against a reference that states each policy as Rixner et
//! al. do, entry by entry: the pending references in a list in arrival order, each
//! arbiter walking it (and, for the same-burst rule, walking the older entries of each
//! candidate). The scheduler keeps age masks instead; both must issue the same command for
//! the same reference in every cycle, under every policy, for buffers of one word of mask
//! and of several, with refreshes, read back-pressure, row hits, bank conflicts and
//! same-burst pairs.

use imagine_hdl::{Design, default_domains};
use imagine_units::desc::MachineDesc;
use imagine_units::dram::scheduler::Scheduler;
use imagine_units::dram::{Command, DramParams, Location, Policy, Request, Tag};

#[derive(Clone, Copy, Debug)]
struct Pending {
    write: bool,
    bank: usize,
    row: u16,
    burst_addr: u64,
    tag: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Decision {
    None,
    Column(usize),
    Precharge(usize),
    Activate(usize, u16),
    Refresh,
}

#[derive(Clone, Copy)]
enum Op {
    Column,
    Precharge,
    Activate,
}

/// The scheduler as a walk over the buffer.
struct Reference {
    policy: Policy,
    p: DramParams,
    entries: Vec<Pending>,
    open: Vec<Option<u16>>,
    ready_act: Vec<u64>,
    ready_col: Vec<u64>,
    ready_pre: Vec<u64>,
    next_act_any: u64,
    next_read: u64,
    next_write: u64,
    busy_until: u64,
    refreshes: u64,
}

impl Reference {
    fn new(policy: Policy, p: &DramParams) -> Self {
        Reference {
            policy,
            p: p.clone(),
            entries: Vec::new(),
            open: vec![None; p.banks],
            ready_act: vec![0; p.banks],
            ready_col: vec![0; p.banks],
            ready_pre: vec![0; p.banks],
            next_act_any: 0,
            next_read: 0,
            next_write: 0,
            busy_until: 0,
            refreshes: 0,
        }
    }

    fn decide(&self, bus: u64, read_room: bool) -> Decision {
        if bus < self.busy_until {
            return Decision::None;
        }
        if bus >= (self.refreshes + 1) * self.p.t_refi {
            // Open banks are precharged as soon as they may be, then REFRESH.
            let mut all_idle = true;
            for b in 0..self.p.banks {
                if self.open[b].is_some() {
                    all_idle = false;
                    if bus >= self.ready_pre[b] {
                        return Decision::Precharge(b);
                    }
                }
            }
            let ready = (0..self.p.banks).all(|b| bus >= self.ready_act[b]);
            return if all_idle && ready {
                Decision::Refresh
            } else {
                Decision::None
            };
        }
        if self.entries.is_empty() {
            return Decision::None;
        }
        match self.policy {
            Policy::InOrder => {
                let op = self.next_op(0);
                if self.ready(op, 0, bus, read_room) {
                    self.decision_for(op, 0)
                } else {
                    Decision::None
                }
            }
            Policy::FirstReady => {
                for i in 0..self.entries.len() {
                    let op = self.next_op(i);
                    if !self.ready(op, i, bus, read_room) {
                        continue;
                    }
                    let allowed = match op {
                        Op::Column => !self.hazard(i),
                        Op::Precharge => !self.row_hit(self.entries[i].bank),
                        Op::Activate => true,
                    };
                    if allowed {
                        return self.decision_for(op, i);
                    }
                }
                Decision::None
            }
            _ => {
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
        }
    }

    fn next_op(&self, i: usize) -> Op {
        let e = &self.entries[i];
        match self.open[e.bank] {
            Some(r) if r == e.row => Op::Column,
            Some(_) => Op::Precharge,
            None => Op::Activate,
        }
    }

    fn hazard(&self, i: usize) -> bool {
        let a = self.entries[i].burst_addr;
        self.entries[..i].iter().any(|e| e.burst_addr == a)
    }

    fn row_hit(&self, b: usize) -> bool {
        self.open[b].is_some_and(|row| self.entries.iter().any(|e| e.bank == b && e.row == row))
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
        }
        best.map(Decision::Column)
    }

    fn row_candidate(&self, bus: u64) -> Option<Decision> {
        let los = self.policy == Policy::LoadOverStore;
        let closed = self.policy.closed_row();
        let mut best: Option<(usize, Decision)> = None;
        for b in 0..self.p.banks {
            let mut hit = false;
            let mut oldest_miss: Option<usize> = None;
            for (i, e) in self.entries.iter().enumerate() {
                if e.bank != b {
                    continue;
                }
                if self.open[b] == Some(e.row) {
                    hit = true;
                } else if oldest_miss.is_none_or(|j| los && self.entries[j].write && !e.write) {
                    oldest_miss = Some(i);
                }
            }
            let cand = match self.open[b] {
                Some(_) => ((!hit && (closed || oldest_miss.is_some()))
                    && bus >= self.ready_pre[b])
                    .then(|| (oldest_miss.unwrap_or(usize::MAX), Decision::Precharge(b))),
                None => match oldest_miss {
                    Some(i) if bus >= self.ready_act[b] && bus >= self.next_act_any => {
                        Some((i, Decision::Activate(b, self.entries[i].row)))
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

    fn commit(&mut self, bus: u64, d: Decision, incoming: Option<Pending>) {
        let p = &self.p;
        let burst = p.burst as u64;
        match d {
            Decision::None => {}
            Decision::Column(i) => {
                let e = self.entries.remove(i);
                let b = e.bank;
                if e.write {
                    self.next_write = bus + burst;
                    self.next_read = self.next_read.max(bus + burst);
                    self.ready_pre[b] = self.ready_pre[b].max(bus + burst - 1 + p.t_wr);
                } else {
                    self.next_read = bus + burst;
                    self.next_write = self.next_write.max(bus + p.cl + burst + p.turnaround);
                    self.ready_pre[b] = self.ready_pre[b].max(bus + burst);
                }
            }
            Decision::Precharge(b) => {
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
        if let Some(e) = incoming {
            self.entries.push(e);
        }
    }

    /// The command a decision puts on the bus, with the tag of the reference it serves.
    fn command(&self, d: Decision) -> Option<(u64, Option<u32>)> {
        match d {
            Decision::None => None,
            Decision::Column(i) => {
                let e = &self.entries[i];
                Some((if e.write { 3 } else { 2 }, Some(e.tag)))
            }
            Decision::Precharge(_) => Some((4, None)),
            Decision::Activate(..) => Some((1, None)),
            Decision::Refresh => Some((5, None)),
        }
    }
}

/// SplitMix64.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        ((self.next() as u128 * n as u128) >> 64) as u64
    }

    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
}

/// Runs `count` references through both and compares every cycle's command.
fn compare(p: &DramParams, policy: Policy, capacity: usize, count: u32, seed: u64) {
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut scheduler = Scheduler::new(&mut design.scope(), policy, p.clone(), capacity);
    let mut reference = Reference::new(policy, p);
    let mut rng = Rng(seed);
    let mut made: Vec<Location> = Vec::new();
    let mut rate = 50;
    let mut served = 0;
    let mut cycle = 0u64;
    while served < count {
        assert!(
            cycle < 64 * (count as u64 + 64),
            "{policy}: stuck at cycle {cycle}"
        );
        let read_room = rng.chance(85);
        let issued = scheduler.eval(cycle, read_room);
        let decision = reference.decide(cycle + 1, read_room);
        let got = issued.map(|i| {
            let code = match i.cmd {
                Command::Activate { .. } => 1,
                Command::Read { .. } => 2,
                Command::Write { .. } => 3,
                Command::Precharge { .. } => 4,
                Command::Refresh => 5,
            };
            (code, i.entry.map(|e| e.tag.seq))
        });
        assert_eq!(
            got,
            reference.command(decision),
            "{policy}, capacity {capacity}, seed {seed}: cycle {cycle}, {decision:?}"
        );
        if let Some(i) = issued {
            served += i.entry.is_some() as u32;
            assert_eq!(
                i.cmd.bank(),
                match decision {
                    Decision::Column(k) => Some(reference.entries[k].bank),
                    Decision::Precharge(b) | Decision::Activate(b, _) => Some(b),
                    _ => None,
                }
            );
            if let (Command::Activate { row, .. }, Decision::Activate(_, r)) = (i.cmd, decision) {
                assert_eq!(row, r);
            }
        }
        if cycle.is_multiple_of(40) {
            rate = [95, 70, 30, 3][rng.below(4) as usize];
        }
        let mut incoming = None;
        if (made.len() as u32) < count && scheduler.has_room() && rng.chance(rate) {
            let write = rng.chance(40);
            let loc = if !made.is_empty() && rng.chance(30) {
                made[made.len() - 1 - rng.below(made.len().min(6) as u64) as usize]
            } else {
                Location {
                    channel: 0,
                    bank: imagine_hdl::bits::u4::new(rng.below(p.banks as u64) as u8),
                    row: [0, 1, 2, 7][rng.below(4) as usize],
                    column: imagine_hdl::bits::u12::new((rng.below(8) * p.burst as u64) as u16),
                }
            };
            let byte_addr = p.unmap(&loc);
            let tag = made.len() as u32;
            made.push(loc);
            scheduler.accept(
                &Request {
                    write,
                    byte_addr,
                    data: [tag; 8],
                    tag: Tag {
                        source: 0,
                        seq: tag,
                    },
                },
                loc,
                cycle,
            );
            incoming = Some(Pending {
                write,
                bank: loc.bank.value() as usize,
                row: loc.row,
                burst_addr: byte_addr / p.burst_bytes(),
                tag,
            });
        }
        scheduler.commit(cycle);
        reference.commit(cycle + 1, decision, incoming);
        cycle += 1;
    }
}

fn params(banks: usize) -> DramParams {
    let mut p = DramParams::of(&MachineDesc::gold8());
    p.banks = banks;
    p.t_refi = 300;
    p
}

#[test]
fn the_age_masks_choose_as_the_walk_over_the_buffer_does() {
    for (banks, capacity, count) in [
        (4, 32, 3000),
        (4, 1, 300),
        (4, 5, 1000),
        (2, 64, 3000),
        (4, 65, 3000),
        (16, 130, 3000),
        (4, 256, 4000),
    ] {
        let p = params(banks);
        for (k, policy) in Policy::ALL.into_iter().enumerate() {
            compare(&p, policy, capacity, count, 17 * k as u64 + capacity as u64);
        }
    }
}
