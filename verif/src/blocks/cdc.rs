//! Testbench of the synchronising FIFO (`hdl::async_fifo`) across the machine's two clocks:
//! one crossing each way (core → DRAM, DRAM → core) with the machine's `crossing_entries`
//! and `sync_stages`, run by the real simulator, a writer and a reader module on each
//! side whose rates change in phases so the FIFOs fill and drain.
//!
//! Reference, from the edge times alone (writer cycle `k` at `k / f_write`): a word pushed
//! in writer cycle `k` may be popped in reader cycle `j` once a reader edge has passed
//! strictly after it (the first reader edge after `k / f_write` comes before `j`); a pop
//! frees room for the writer in the same way. This is the behaviour as implemented: the
//! synchroniser makes a pointer visible after one edge of the receiving clock, whatever
//! `sync_stages` says. Every word must arrive once, in order; the occupancy never passes
//! the capacity; a push into a full FIFO or a pop from an empty one is refused.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use imagine_hdl::{
    AsyncFifoRx, AsyncFifoTx, ClockDomain, ContractError, Design, DomainId, Module, Sim,
};
use imagine_units::desc::MachineDesc;

use super::{Config, Coverage, Outcome, Rng, Scoreboard, Waves};

const BINS: &[&str] = &[
    "push",
    "pop",
    "back-to-back pushes",
    "back-to-back pops",
    "writer sees full",
    "reader sees empty",
    "push refused when full",
    "pop refused when empty",
    "occupancy at capacity",
    "more words than the capacity crossed",
];

/// The reference model of one crossing.
struct RefCrossing {
    label: &'static str,
    capacity: usize,
    f_write: u64,
    f_read: u64,
    /// Writer cycles of the pushes, reader cycles of the pops, so far.
    pushes: Vec<u64>,
    pops: Vec<u64>,
    /// Pushes the reader sees, pops the writer sees.
    seen_pushes: usize,
    seen_pops: usize,
    queue: VecDeque<u32>,
    /// Percent chances of a push and of a pop in this phase.
    push_rate: u64,
    pop_rate: u64,
}

impl RefCrossing {
    fn new(label: &'static str, capacity: usize, f_write: u64, f_read: u64) -> Self {
        RefCrossing {
            label,
            capacity,
            f_write,
            f_read,
            pushes: Vec::new(),
            pops: Vec::new(),
            seen_pushes: 0,
            seen_pops: 0,
            queue: VecDeque::new(),
            push_rate: 50,
            pop_rate: 50,
        }
    }

    /// The first cycle of a clock of `f_to` whose edge is strictly after cycle `k` of a
    /// clock of `f_from`.
    fn first_edge_after(k: u64, f_from: u64, f_to: u64) -> u64 {
        (u128::from(k) * u128::from(f_to) / u128::from(f_from)) as u64 + 1
    }

    /// Whether the writer may push in its cycle `k`.
    fn room(&mut self, k: u64) -> bool {
        while self.seen_pops < self.pops.len()
            && Self::first_edge_after(self.pops[self.seen_pops], self.f_read, self.f_write) < k
        {
            self.seen_pops += 1;
        }
        self.pushes.len() - self.seen_pops < self.capacity
    }

    /// Whether the reader may pop in its cycle `j`.
    fn ready(&mut self, j: u64) -> bool {
        while self.seen_pushes < self.pushes.len()
            && Self::first_edge_after(self.pushes[self.seen_pushes], self.f_write, self.f_read) < j
        {
            self.seen_pushes += 1;
        }
        self.seen_pushes > self.pops.len()
    }

    fn bin(&self, b: &str) -> String {
        format!("{}: {b}", self.label)
    }
}

/// Everything both sides share: stimulus, references, scoreboard, coverage.
struct Bench {
    rng: Rng,
    sb: Scoreboard,
    cov: Coverage,
    crossings: [RefCrossing; 2],
    transactions: u64,
    next_value: u32,
}

impl Bench {
    fn driving(&self) -> bool {
        self.sb.transactions < self.transactions
    }

    /// The writing side of crossing `i` in its cycle `k`, core cycle `now` (the cycle its
    /// checks are reported in).
    fn write(&mut self, i: usize, k: u64, now: u64, tx: &mut AsyncFifoTx<u32>) {
        let driving = self.driving();
        let Bench {
            rng,
            sb,
            cov,
            crossings,
            next_value,
            ..
        } = self;
        let x = &mut crossings[i];
        if k.is_multiple_of(64) {
            x.push_rate = rng.pick(&[95, 60, 10]);
        }
        let room = x.room(k);
        sb.check(
            now,
            || format!("{} can_push in writer cycle {k}", x.label),
            room,
            tx.can_push(),
        );
        let occupancy = x.pushes.len() - x.pops.len();
        sb.assert(now, occupancy <= x.capacity, || {
            format!("{} occupancy within capacity", x.label)
        });
        cov.hit_if(occupancy == x.capacity, &x.bin("occupancy at capacity"));
        cov.hit_if(!room, &x.bin("writer sees full"));
        if !driving {
            return;
        }
        if room && rng.chance(x.push_rate) {
            sb.transaction();
            let value = *next_value;
            *next_value = next_value.wrapping_add(1);
            let ok = tx.push(value).is_ok();
            sb.check(now, || format!("{} push accepted", x.label), true, ok);
            cov.hit(&x.bin("push"));
            cov.hit_if(
                x.pushes.last() == Some(&(k.wrapping_sub(1))),
                &x.bin("back-to-back pushes"),
            );
            cov.hit_if(
                x.pushes.len() == x.capacity + 1,
                &x.bin("more words than the capacity crossed"),
            );
            x.pushes.push(k);
            x.queue.push_back(value);
            if rng.chance(3) {
                sb.transaction();
                let refused = tx.push(0).is_err();
                sb.check(
                    now,
                    || format!("{} second push in a cycle refused", x.label),
                    true,
                    refused,
                );
            }
        } else if !room && rng.chance(20) {
            sb.transaction();
            let refused = tx.push(0).is_err();
            sb.check(
                now,
                || format!("{} push into a full FIFO refused", x.label),
                true,
                refused,
            );
            cov.hit(&x.bin("push refused when full"));
        }
    }

    /// The reading side of crossing `i` in its cycle `j`, core cycle `now`.
    fn read(&mut self, i: usize, j: u64, now: u64, rx: &mut AsyncFifoRx<u32>) {
        let driving = self.driving();
        let Bench {
            rng,
            sb,
            cov,
            crossings,
            ..
        } = self;
        let x = &mut crossings[i];
        if j.is_multiple_of(64) {
            x.pop_rate = rng.pick(&[95, 60, 10]);
        }
        let ready = x.ready(j);
        sb.check(
            now,
            || format!("{} can_pop in reader cycle {j}", x.label),
            ready,
            rx.can_pop(),
        );
        cov.hit_if(!ready, &x.bin("reader sees empty"));
        if ready && (!driving || rng.chance(x.pop_rate)) {
            sb.transaction();
            let got = rx.pop().ok();
            let expected = x.queue.pop_front();
            sb.check(
                now,
                || format!("{} word popped (in order, once)", x.label),
                expected,
                got,
            );
            cov.hit(&x.bin("pop"));
            cov.hit_if(
                x.pops.last() == Some(&(j.wrapping_sub(1))),
                &x.bin("back-to-back pops"),
            );
            x.pops.push(j);
        } else if !ready && driving && rng.chance(20) {
            sb.transaction();
            let refused = rx.pop().is_err();
            sb.check(
                now,
                || format!("{} pop from an empty FIFO refused", x.label),
                true,
                refused,
            );
            cov.hit(&x.bin("pop refused when empty"));
        }
    }

    fn drained(&self) -> bool {
        !self.driving() && self.crossings.iter().all(|x| x.queue.is_empty())
    }
}

/// One clock domain's side: it writes crossing `side` and reads crossing `1 - side`.
struct Side {
    domain: DomainId,
    side: usize,
    cycle: u64,
    /// This side's clock and the core clock: checks are reported in core cycles, the
    /// cycles a waveform window counts.
    mhz: u64,
    core_mhz: u64,
    tx: AsyncFifoTx<u32>,
    rx: AsyncFifoRx<u32>,
    bench: Rc<RefCell<Bench>>,
}

impl Module for Side {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        let mut b = self.bench.borrow_mut();
        let now = self.cycle * self.core_mhz / self.mhz;
        b.write(self.side, self.cycle, now, &mut self.tx);
        b.read(1 - self.side, self.cycle, now, &mut self.rx);
        Ok(())
    }
    fn commit(&mut self) {
        self.cycle += 1;
    }
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let (core_mhz, dram_mhz) = (desc.clocks.core_mhz, desc.clocks.dram_mhz);
    let (capacity, stages) = (desc.memory.crossing_entries, desc.memory.sync_stages);
    let labels = ["core to dram", "dram to core"];
    let names: Vec<String> = labels
        .iter()
        .flat_map(|l| BINS.iter().map(move |b| format!("{l}: {b}")))
        .collect();
    let bench = Rc::new(RefCell::new(Bench {
        rng: Rng::new(config.seed),
        sb: Scoreboard::default(),
        cov: Coverage::new(&names),
        crossings: [
            RefCrossing::new(labels[0], capacity, core_mhz, dram_mhz),
            RefCrossing::new(labels[1], capacity, dram_mhz, core_mhz),
        ],
        transactions: config.transactions,
        next_value: 0,
    }));
    let domains = vec![
        ClockDomain::mhz("core", core_mhz),
        ClockDomain::mhz("dram", dram_mhz),
    ];
    let mut d = Design::new("top", domains).expect("a validated machine has valid clocks");
    let (core, dram) = (DomainId(0), DomainId(1));
    let mut top = d.scope();
    let (to_dram_tx, to_dram_rx) = top
        .async_fifo::<u32>("to_dram", (core, dram), capacity, stages)
        .expect("a validated machine has a valid crossing");
    let (to_core_tx, to_core_rx) = top
        .async_fifo::<u32>("to_core", (dram, core), capacity, stages)
        .expect("a validated machine has a valid crossing");
    d.add(Side {
        domain: core,
        side: 0,
        cycle: 0,
        mhz: core_mhz,
        core_mhz,
        tx: to_dram_tx,
        rx: to_core_rx,
        bench: bench.clone(),
    });
    d.add(Side {
        domain: dram,
        side: 1,
        cycle: 0,
        mhz: dram_mhz,
        core_mhz,
        tx: to_core_tx,
        rx: to_dram_rx,
        bench: bench.clone(),
    });
    let mut sim = Sim::new(d);
    let waves = Waves::attach(&mut sim, config);
    // Generous: every transaction is at most a few core cycles apart, plus the drain.
    let limit = 64 * config.transactions + 10_000;
    let mut drained = false;
    while sim.core_cycles() < limit {
        if let Err(e) = sim.step() {
            let mut b = bench.borrow_mut();
            let cycle = sim.core_cycles();
            b.sb.check(
                cycle,
                || "no contract error".into(),
                String::new(),
                e.to_string(),
            );
            break;
        }
        if bench.borrow().drained() {
            drained = true;
            break;
        }
    }
    let waves = waves.finish(Some(&mut sim));
    drop(sim);
    let Bench { mut sb, cov, .. } = Rc::into_inner(bench)
        .expect("the simulator is gone")
        .into_inner();
    sb.assert(limit, drained, || {
        "every pushed word arrives (no loss)".into()
    });
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves,
    }
}
