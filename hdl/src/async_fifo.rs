//! A synchronising FIFO between two clock domains: the classic dual-clock FIFO with its
//! write pointer carried into the read domain, and its read pointer carried into the write
//! domain, through chains of `sync_stages` flip-flops (Cummings, "Simulation and Synthesis
//! Techniques for Asynchronous FIFO Design", SNUG 2002). Hardware passes Gray-coded
//! pointers so each synchroniser sees at most one changing bit; here the pointers are
//! modelled as counts, which gives the same values once synchronised.
//!
//! The writer sees occupancy through the delayed read pointer and the reader through the
//! delayed write pointer, so both are conservative. When both clocks rise at the same
//! instant each synchroniser samples the other side's pointer as it was before that edge.
//!
//! As modelled, each side sees the newest sample of the other's pointer, so a change is
//! visible one edge of the receiving clock later whatever `sync_stages` is; the chain's
//! length only decides when the FIFO counts as settled. Hardware would take `sync_stages`
//! edges. Kept as it is: the latency is part of every cycle count the project has
//! published, and changing it is a model change of its own.
//!
//! The pointers and their synchronisers are held as what their registers are a function
//! of: the edges each clock has committed ([`EdgeCounts`]) and, per push and pop, the edge
//! of the other clock whose sample first includes it. A push in a write-domain cycle lands
//! at that cycle's edge; the reader's next edge strictly after it (so not one at the same
//! instant, which samples the pointer from before) carries it over. So no edge visits the
//! FIFO: it changes only when an end acts, and its state at any edge follows from the
//! counts, exactly as committing its registers at every edge would leave them. An end
//! acts only in a cycle of its own clock (a module of that domain being evaluated).

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use crate::edge_counts::EdgeCounts;
use crate::{ContractError, DomainId, SignalId, Trace, Traced, Violation};

pub(crate) struct AsyncFifoState<T> {
    path: String,
    write_domain: DomainId,
    read_domain: DomainId,
    capacity: usize,
    /// Flip-flops in each pointer synchroniser.
    stages: u64,
    edges: Rc<EdgeCounts>,
    /// Every value pushed and not popped, this cycle's included, each with the count of
    /// committed read-domain edges from which the reader sees it: a value enters at its
    /// push and leaves at its pop. The other side cannot see it early, as each side's view
    /// goes through the synchronised pointers.
    items: VecDeque<(u64, T)>,
    /// Pushes and pops so far (the binary pointers, with this cycle's).
    pushes: u64,
    pops: u64,
    /// The write-domain edges committed when the last push was made (it lands at the next
    /// one), and the read-domain count from which the reader sees it.
    last_push: Option<(u64, u64)>,
    /// The read-domain edges committed when the last pop was made, and the write-domain
    /// count from which the writer sees it.
    last_pop: Option<(u64, u64)>,
    /// The write-domain counts from which the writer sees each recent pop (those it may not
    /// see yet; the ones it sees are dropped as the FIFO is used).
    pops_seen_from: VecDeque<u64>,
    ids: [SignalId; 2],
}

/// The writing end, used in the write clock domain.
pub struct AsyncFifoTx<T>(Rc<RefCell<AsyncFifoState<T>>>);
/// The reading end, used in the read clock domain.
pub struct AsyncFifoRx<T>(Rc<RefCell<AsyncFifoState<T>>>);

pub(crate) fn new_async_fifo<T: 'static>(
    path: String,
    (write_domain, read_domain): (DomainId, DomainId),
    capacity: usize,
    sync_stages: usize,
    ids: [SignalId; 2],
    edges: Rc<EdgeCounts>,
) -> (
    AsyncFifoTx<T>,
    AsyncFifoRx<T>,
    Rc<RefCell<AsyncFifoState<T>>>,
) {
    let state = Rc::new(RefCell::new(AsyncFifoState {
        path,
        write_domain,
        read_domain,
        capacity,
        stages: sync_stages as u64,
        edges,
        items: VecDeque::with_capacity(capacity),
        pushes: 0,
        pops: 0,
        last_push: None,
        last_pop: None,
        pops_seen_from: VecDeque::with_capacity(capacity),
        ids,
    }));
    (
        AsyncFifoTx(state.clone()),
        AsyncFifoRx(state.clone()),
        state,
    )
}

impl<T> AsyncFifoState<T> {
    /// Write- and read-domain edges committed.
    #[inline]
    fn counts(&self) -> (u64, u64) {
        (
            self.edges.committed(self.write_domain),
            self.edges.committed(self.read_domain),
        )
    }
    /// A push in this write-domain cycle (it lands at the cycle's edge).
    #[inline]
    fn pushed(&self, write_edges: u64) -> bool {
        self.last_push.is_some_and(|(at, _)| at == write_edges)
    }
    /// A pop in this read-domain cycle.
    #[inline]
    fn popped(&self, read_edges: u64) -> bool {
        self.last_pop.is_some_and(|(at, _)| at == read_edges)
    }
    /// Occupancy as the writer sees it: its committed pointer less the read pointer its
    /// synchroniser holds.
    #[inline]
    fn write_level(&self) -> usize {
        let w = self.edges.committed(self.write_domain);
        let mut unseen = 0;
        for &from in self.pops_seen_from.iter().rev() {
            if from <= w {
                break;
            }
            unseen += 1;
        }
        (self.pushes - self.pushed(w) as u64 - (self.pops - unseen)) as usize
    }
    /// Occupancy as the reader sees it: the write pointer its synchroniser holds less its
    /// committed pointer (a value popped this cycle is still counted).
    fn read_level(&self) -> usize {
        let r = self.edges.committed(self.read_domain);
        #[cfg(feature = "inject-bugs")]
        if crate::inject::active(crate::inject::Bug::CdcZeroStageSynchroniser) {
            let w = self.edges.committed(self.write_domain);
            return (self.pushes - self.pushed(w) as u64 - self.pops + self.popped(r) as u64)
                as usize;
        }
        let seen = self.items.iter().take_while(|(from, _)| *from <= r).count();
        seen + self.popped(r) as usize
    }
    /// Whether the reader sees a value to pop (its synchronised view is not empty).
    #[inline]
    fn sees_a_value(&self, read_edges: u64) -> bool {
        #[cfg(feature = "inject-bugs")]
        if crate::inject::active(crate::inject::Bug::CdcZeroStageSynchroniser) {
            return self.read_level() > 0;
        }
        self.items
            .front()
            .is_some_and(|(from, _)| *from <= read_edges)
    }
    /// Whether the reader, with `read_edges` committed, may pop: it has not this cycle and
    /// it sees a value.
    #[inline]
    fn may_pop(&self, read_edges: u64) -> bool {
        !self.popped(read_edges) && self.sees_a_value(read_edges)
    }
    /// Nothing pushed or popped this cycle and every synchroniser stage holding the
    /// pointer it samples: edges of either clock change nothing until an end acts. (A
    /// stage samples the value last seen from a count on: all hold it `stages − 1` edges
    /// later.)
    fn is_static(&self) -> bool {
        let (w, r) = self.counts();
        let settled = |last: Option<(u64, u64)>, edges: u64| {
            last.is_none_or(|(_, from)| edges + 1 >= from + self.stages)
        };
        !self.pushed(w)
            && !self.popped(r)
            && settled(self.last_push, r)
            && settled(self.last_pop, w)
    }
    /// Empty, nothing pushed or popped this cycle, and every synchroniser stage holding
    /// the pointer it samples: an edge of either clock changes nothing.
    fn is_settled(&self) -> bool {
        self.items.is_empty() && self.is_static()
    }
    /// The count of `to`'s committed edges from which it sees what `from` did in its
    /// cycle under way: `to`'s next edge after the edge that ends that cycle; when both
    /// clocks rise at that instant, `to` samples what was there before, so one more.
    #[inline]
    fn seen_from(&self, to: DomainId, committed: u64) -> u64 {
        committed + 1 + self.edges.rising(to) as u64
    }
    /// The reader pops the value it sees first, in a cycle with `read_edges` committed.
    #[inline]
    fn take(&mut self, read_edges: u64) -> Result<T, ContractError> {
        if !self.edges.rising(self.read_domain) {
            return Err(self.outside_its_cycle("reader", self.read_domain));
        }
        let w = self.edges.committed(self.write_domain);
        let from = self.seen_from(self.write_domain, w);
        self.pops += 1;
        self.last_pop = Some((read_edges, from));
        self.forget_seen_pops(w);
        self.pops_seen_from.push_back(from);
        Ok(self
            .items
            .pop_front()
            .expect("a value the reader sees is held")
            .1)
    }
    /// Pops the writer sees, with `write_edges` committed, are counted in `pops`: only
    /// those it may not see yet are kept.
    #[inline]
    fn forget_seen_pops(&mut self, write_edges: u64) {
        while self
            .pops_seen_from
            .front()
            .is_some_and(|&f| f <= write_edges)
        {
            self.pops_seen_from.pop_front();
        }
    }
    #[cold]
    fn outside_its_cycle(&self, end: &str, domain: DomainId) -> ContractError {
        ContractError::at(
            &self.path,
            Violation::Other(format!(
                "the {end} acted outside a cycle of its clock (domain {})",
                domain.0
            )),
        )
    }
}

impl<T> AsyncFifoTx<T> {
    /// Whether the FIFO is empty with both synchronisers settled, so that clock edges of
    /// either domain change nothing (idle time may then be jumped over).
    pub fn is_settled(&self) -> bool {
        self.0.borrow().is_settled()
    }

    /// Whether the writer may push this cycle (its synchronised view shows room and it has
    /// not pushed yet this cycle).
    #[inline]
    pub fn can_push(&self) -> bool {
        let s = self.0.borrow();
        !s.pushed(s.edges.committed(s.write_domain)) && s.write_level() < s.capacity
    }

    /// Pushes one value (one per write-domain cycle, in one).
    #[inline]
    pub fn push(&mut self, v: T) -> Result<(), ContractError> {
        let mut s = self.0.borrow_mut();
        let (w, r) = s.counts();
        if s.pushed(w) {
            return Err(ContractError::over_bandwidth(&s.path, 1));
        }
        if s.write_level() >= s.capacity {
            let capacity = s.capacity;
            return Err(ContractError::at(&s.path, Violation::Overflow { capacity }));
        }
        if !s.edges.rising(s.write_domain) {
            return Err(s.outside_its_cycle("writer", s.write_domain));
        }
        let from = s.seen_from(s.read_domain, r);
        s.items.push_back((from, v));
        s.pushes += 1;
        s.last_push = Some((w, from));
        s.forget_seen_pops(w);
        Ok(())
    }
}

impl<T> AsyncFifoRx<T> {
    /// Whether the FIFO is empty with both synchronisers settled (see
    /// [`AsyncFifoTx::is_settled`]).
    pub fn is_settled(&self) -> bool {
        self.0.borrow().is_settled()
    }
}

impl<T> AsyncFifoRx<T> {
    /// Whether the reader may pop this cycle.
    #[inline]
    pub fn can_pop(&self) -> bool {
        let s = self.0.borrow();
        s.may_pop(s.edges.committed(s.read_domain))
    }

    /// Pops a value if the reader may ([`can_pop`](Self::can_pop)), in one look at the
    /// FIFO.
    #[inline]
    pub fn try_pop(&mut self) -> Result<Option<T>, ContractError> {
        let mut s = self.0.borrow_mut();
        let r = s.edges.committed(s.read_domain);
        if !s.may_pop(r) {
            return Ok(None);
        }
        s.take(r).map(Some)
    }

    /// Pops one value (one per read-domain cycle, in one).
    #[inline]
    pub fn pop(&mut self) -> Result<T, ContractError> {
        let mut s = self.0.borrow_mut();
        let r = s.edges.committed(s.read_domain);
        if s.popped(r) {
            return Err(ContractError::at(
                &s.path,
                Violation::OverRead { bandwidth: 1 },
            ));
        }
        if !s.sees_a_value(r) {
            return Err(ContractError::at(&s.path, Violation::Underflow));
        }
        s.take(r)
    }
}

/// Nothing lands at an edge: the FIFO's registers are a function of the committed edges
/// (see the module doc), so the simulator only traces it.
impl<T> Traced for AsyncFifoState<T> {
    fn trace(&self, t: &mut Trace) {
        t.value(self.ids[0], self.write_level() as u64);
        t.value(self.ids[1], self.read_level() as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DomainSet;

    /// A FIFO of four entries from domain 0 (writes) to domain 1 (reads), with two
    /// synchroniser stages, and the edge counts that time it.
    fn core_to_dram() -> (AsyncFifoTx<u8>, AsyncFifoRx<u8>, Rc<EdgeCounts>) {
        let domains = (DomainId(0), DomainId(1));
        let ids = [SignalId(0), SignalId(1)];
        let edges = Rc::new(EdgeCounts::new(2));
        let (tx, rx, _) = new_async_fifo("f".into(), domains, 4, 2, ids, edges.clone());
        (tx, rx, edges)
    }

    const WRITE: DomainSet = DomainSet(1);
    const READ: DomainSet = DomainSet(2);
    const BOTH: DomainSet = DomainSet(3);

    /// A step of the clocks in `rising`: `cycle` is what the ends do in it.
    fn step(edges: &EdgeCounts, rising: DomainSet, cycle: impl FnOnce()) {
        edges.begin(rising);
        cycle();
        edges.end();
    }

    #[test]
    fn settled_once_both_synchronisers_have_caught_up() {
        let (mut tx, mut rx, edges) = core_to_dram();
        assert!(tx.is_settled() && rx.is_settled());
        step(&edges, WRITE, || {
            tx.push(7).unwrap();
            assert!(!tx.is_settled(), "pushed this cycle");
        });
        // The value crosses two read-domain flip-flops, and is popped.
        step(&edges, READ, || {});
        step(&edges, READ, || {});
        assert!(!rx.is_settled() && rx.can_pop());
        step(&edges, READ, || assert_eq!(rx.pop().unwrap(), 7));
        // Empty, but the writer has not yet seen the pop.
        assert!(!rx.is_settled());
        step(&edges, WRITE, || {});
        assert!(!tx.is_settled());
        step(&edges, WRITE, || {});
        assert!(tx.is_settled() && rx.is_settled());
        // Settled: edges of either clock change nothing.
        for d in [WRITE, READ, BOTH] {
            step(&edges, d, || {});
            assert!(tx.is_settled() && tx.can_push() && !rx.can_pop());
        }
    }

    #[test]
    fn a_value_is_seen_at_the_readers_first_edge_after_its_push_lands_in_order() {
        let (mut tx, mut rx, edges) = core_to_dram();
        // Both clocks rise at once: the reader samples the pointer from before the edge.
        step(&edges, BOTH, || {
            tx.push(1).unwrap();
            assert!(!rx.can_pop(), "the push has not landed");
        });
        assert!(
            !rx.can_pop(),
            "the reader's synchroniser sampled the old pointer"
        );
        step(&edges, WRITE, || tx.push(2).unwrap());
        assert!(!rx.can_pop(), "no read edge since the first push landed");
        step(&edges, READ, || {});
        step(&edges, READ, || {
            assert_eq!(rx.pop().unwrap(), 1);
            assert!(!rx.can_pop(), "one pop per read cycle");
        });
        step(&edges, READ, || assert_eq!(rx.pop().unwrap(), 2));
        step(&edges, READ, || {
            assert!(!rx.can_pop());
            assert_eq!(rx.pop(), Err(ContractError::at("f", Violation::Underflow)));
        });
    }

    #[test]
    fn an_end_acts_only_in_a_cycle_of_its_own_clock() {
        let (mut tx, mut rx, edges) = core_to_dram();
        let outside = |e: ContractError| e.to_string().contains("outside a cycle of its clock");
        assert!(outside(tx.push(1).unwrap_err()), "between steps");
        step(&edges, READ, || assert!(outside(tx.push(1).unwrap_err())));
        step(&edges, WRITE, || tx.push(1).unwrap());
        step(&edges, READ, || {});
        assert!(rx.can_pop());
        step(&edges, WRITE, || assert!(outside(rx.pop().unwrap_err())));
        step(&edges, READ, || assert_eq!(rx.pop().unwrap(), 1));
    }
}
