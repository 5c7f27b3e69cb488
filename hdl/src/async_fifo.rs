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

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::rc::Rc;

use crate::{Channel, ContractError, DomainId, DomainSet, SignalId, Trace, Violation};

pub(crate) struct AsyncFifoState<T> {
    path: String,
    write_domain: DomainId,
    read_domain: DomainId,
    capacity: usize,
    /// Every value pushed and not popped, this cycle's included: a value enters at its push
    /// and leaves at its pop, so a commit moves only the pointers. The other side cannot
    /// see it early, as each side's view goes through the synchronised pointers.
    items: VecDeque<T>,
    /// Total pushes and pops committed so far (the binary pointers).
    write_ptr: u64,
    read_ptr: u64,
    /// The synchroniser chains carrying each pointer into the other domain.
    write_ptr_sync: Synchroniser,
    read_ptr_sync: Synchroniser,
    pushed: bool,
    popped: bool,
    /// Raised by a push or a pop: the simulator commits this FIFO again (it stops
    /// committing it once an edge would change nothing, see [`Channel::commit`]).
    wake: Rc<Cell<bool>>,
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
    wake: Rc<Cell<bool>>,
) -> (AsyncFifoTx<T>, AsyncFifoRx<T>, Rc<RefCell<dyn Channel>>) {
    let state = Rc::new(RefCell::new(AsyncFifoState {
        path,
        write_domain,
        read_domain,
        capacity,
        items: VecDeque::with_capacity(capacity),
        write_ptr: 0,
        read_ptr: 0,
        write_ptr_sync: Synchroniser::new(sync_stages),
        read_ptr_sync: Synchroniser::new(sync_stages),
        pushed: false,
        popped: false,
        wake,
        ids,
    }));
    (
        AsyncFifoTx(state.clone()),
        AsyncFifoRx(state.clone()),
        state,
    )
}

/// A chain of `stages` flip-flops sampling a pointer at each edge of the receiving clock,
/// held as what the chain's contents are a function of: the newest sample (the value the
/// receiving side sees) and how many of the newest samples equal it, up to `stages` (all
/// of them do once it reaches `stages`). Shifting a chain each edge cost more than the
/// rest of the FIFO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Synchroniser {
    stages: usize,
    newest: u64,
    equal: usize,
}

impl Synchroniser {
    fn new(stages: usize) -> Self {
        Synchroniser {
            stages,
            newest: 0,
            equal: stages,
        }
    }

    /// An edge: the chain shifts in `pointer`.
    #[inline]
    fn sample(&mut self, pointer: u64) {
        if pointer == self.newest {
            self.equal = (self.equal + 1).min(self.stages);
        } else {
            self.newest = pointer;
            self.equal = 1;
        }
    }

    /// Whether every stage holds `pointer`.
    #[inline]
    fn holds_only(&self, pointer: u64) -> bool {
        self.newest == pointer && self.equal == self.stages
    }
}

impl<T> AsyncFifoState<T> {
    fn write_level(&self) -> usize {
        (self.write_ptr - self.read_ptr_sync.newest) as usize
    }
    fn read_level(&self) -> usize {
        #[cfg(feature = "inject-bugs")]
        if crate::inject::active(crate::inject::Bug::CdcZeroStageSynchroniser) {
            return (self.write_ptr - self.read_ptr) as usize;
        }
        (self.write_ptr_sync.newest - self.read_ptr) as usize
    }
    /// Nothing pushed or popped this cycle and every synchroniser stage holding the
    /// pointer it samples: edges of either clock change nothing until an end acts.
    fn is_static(&self) -> bool {
        !self.pushed
            && !self.popped
            && self.write_ptr_sync.holds_only(self.write_ptr)
            && self.read_ptr_sync.holds_only(self.read_ptr)
    }
    /// Empty, nothing pushed or popped this cycle, and every synchroniser stage holding
    /// the pointer it samples: an edge of either clock changes nothing.
    fn is_settled(&self) -> bool {
        self.items.is_empty() && self.is_static()
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
        !s.pushed && s.write_level() < s.capacity
    }

    /// Pushes one value (one per write-domain cycle).
    #[inline]
    pub fn push(&mut self, v: T) -> Result<(), ContractError> {
        let mut s = self.0.borrow_mut();
        if s.pushed {
            return Err(ContractError::over_bandwidth(&s.path, 1));
        }
        if s.write_level() >= s.capacity {
            let capacity = s.capacity;
            return Err(ContractError::at(&s.path, Violation::Overflow { capacity }));
        }
        s.items.push_back(v);
        s.pushed = true;
        s.wake.set(true);
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
        !s.popped && s.read_level() > 0
    }

    /// Pops one value (one per read-domain cycle).
    #[inline]
    pub fn pop(&mut self) -> Result<T, ContractError> {
        let mut s = self.0.borrow_mut();
        if s.popped {
            return Err(ContractError::at(
                &s.path,
                Violation::OverRead { bandwidth: 1 },
            ));
        }
        if s.read_level() == 0 {
            return Err(ContractError::at(&s.path, Violation::Underflow));
        }
        s.popped = true;
        s.wake.set(true);
        Ok(s.items
            .pop_front()
            .expect("a value the reader sees is held"))
    }
}

impl<T> Channel for AsyncFifoState<T> {
    fn commit(&mut self, rising: DomainSet) -> Result<bool, ContractError> {
        // Sample both pointers before either side updates them. (A synchroniser holding only
        // the pointer it samples stays as it is, so a side with nothing to do changes
        // nothing, without a test of its own.)
        let (write_ptr, read_ptr) = (self.write_ptr, self.read_ptr);
        if rising.contains(self.write_domain) {
            if std::mem::take(&mut self.pushed) {
                self.write_ptr += 1;
            }
            self.read_ptr_sync.sample(read_ptr);
        }
        if rising.contains(self.read_domain) {
            if std::mem::take(&mut self.popped) {
                self.read_ptr += 1;
            }
            self.write_ptr_sync.sample(write_ptr);
        }
        Ok(self.is_static())
    }

    fn domain(&self) -> DomainId {
        self.write_domain
    }

    fn trace(&self, t: &mut Trace) {
        t.value(self.ids[0], self.write_level() as u64);
        t.value(self.ids[1], self.read_level() as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A FIFO of four entries from domain 0 (writes, `DomainSet(1)`) to domain 1 (reads,
    /// `DomainSet(2)`), with two synchroniser stages.
    fn core_to_dram() -> (AsyncFifoTx<u8>, AsyncFifoRx<u8>, Rc<RefCell<dyn Channel>>) {
        let domains = (DomainId(0), DomainId(1));
        let ids = [SignalId(0), SignalId(1)];
        new_async_fifo("f".into(), domains, 4, 2, ids, Rc::default())
    }

    #[test]
    fn settled_once_both_synchronisers_have_caught_up() {
        let (mut tx, mut rx, ch) = core_to_dram();
        let (write, read) = (DomainSet(1), DomainSet(2));
        let edge = |d: DomainSet| ch.borrow_mut().commit(d).unwrap();
        assert!(tx.is_settled() && rx.is_settled());
        tx.push(7).unwrap();
        assert!(!tx.is_settled(), "pushed this cycle");
        edge(write);
        // The value crosses two read-domain flip-flops, and is popped.
        edge(read);
        edge(read);
        assert!(!rx.is_settled() && rx.can_pop());
        assert_eq!(rx.pop().unwrap(), 7);
        edge(read);
        // Empty, but the writer has not yet seen the pop.
        assert!(!rx.is_settled());
        edge(write);
        assert!(!tx.is_settled());
        edge(write);
        assert!(tx.is_settled() && rx.is_settled());
        // Settled: edges of either clock change nothing.
        for d in [write, read, DomainSet(3)] {
            edge(d);
            assert!(tx.is_settled() && tx.can_push() && !rx.can_pop());
        }
    }

    #[test]
    fn a_value_is_seen_at_the_readers_first_edge_after_its_push_lands_in_order() {
        let (mut tx, mut rx, ch) = core_to_dram();
        let (write, read, both) = (DomainSet(1), DomainSet(2), DomainSet(3));
        let edge = |d: DomainSet| ch.borrow_mut().commit(d).unwrap();
        tx.push(1).unwrap();
        assert!(!rx.can_pop(), "the push has not landed");
        // Both clocks rise at once: the reader samples the pointer from before the edge.
        edge(both);
        assert!(
            !rx.can_pop(),
            "the reader's synchroniser sampled the old pointer"
        );
        tx.push(2).unwrap();
        edge(write);
        assert!(!rx.can_pop(), "no read edge since the first push landed");
        edge(read);
        assert_eq!(rx.pop().unwrap(), 1);
        assert!(!rx.can_pop(), "one pop per read cycle");
        edge(read);
        assert_eq!(rx.pop().unwrap(), 2);
        edge(read);
        assert!(!rx.can_pop());
        assert_eq!(rx.pop(), Err(ContractError::at("f", Violation::Underflow)));
    }
}
