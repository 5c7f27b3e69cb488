//! FIFOs with a capacity, in one clock domain.
//!
//! Pushes made during a cycle become visible after the edge; pops take from what was
//! committed at the last edge, so the writer's view of the occupancy and the reader's view
//! do not depend on who is evaluated first. Pushing into a full FIFO, popping an empty one,
//! or exceeding the per-cycle push/pop bandwidth is a [`ContractError`].

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use crate::{Channel, ContractError, DomainId, DomainSet, SignalId, Trace, Traced, Violation};

pub(crate) struct FifoState<T> {
    path: String,
    domain: DomainId,
    capacity: usize,
    bandwidth: usize,
    items: VecDeque<T>,
    pushed: VecDeque<T>,
    popped: usize,
    level_id: SignalId,
}

/// The writing end of a FIFO.
pub struct FifoTx<T>(Rc<RefCell<FifoState<T>>>);
/// The reading end of a FIFO.
pub struct FifoRx<T>(Rc<RefCell<FifoState<T>>>);

pub(crate) fn new_fifo<T: 'static>(
    path: String,
    domain: DomainId,
    capacity: usize,
    bandwidth: usize,
    level_id: SignalId,
) -> (FifoTx<T>, FifoRx<T>, Rc<RefCell<FifoState<T>>>) {
    let state = Rc::new(RefCell::new(FifoState {
        path,
        domain,
        capacity,
        bandwidth,
        items: VecDeque::with_capacity(capacity),
        pushed: VecDeque::with_capacity(bandwidth),
        popped: 0,
        level_id,
    }));
    (FifoTx(state.clone()), FifoRx(state.clone()), state)
}

impl<T> FifoTx<T> {
    /// Free entries as the writer sees them this cycle (committed occupancy).
    #[inline]
    pub fn free(&self) -> usize {
        let s = self.0.borrow();
        s.capacity - s.items.len() - s.pushed.len()
    }

    #[inline]
    pub fn push(&mut self, v: T) -> Result<(), ContractError> {
        let mut s = self.0.borrow_mut();
        if s.pushed.len() == s.bandwidth {
            return Err(ContractError::over_bandwidth(&s.path, s.bandwidth));
        }
        if s.items.len() + s.pushed.len() == s.capacity {
            let capacity = s.capacity;
            return Err(ContractError::at(&s.path, Violation::Overflow { capacity }));
        }
        s.pushed.push_back(v);
        Ok(())
    }
}

impl<T: Clone> FifoRx<T> {
    /// Entries the reader may still pop this cycle.
    #[inline]
    pub fn available(&self) -> usize {
        let s = self.0.borrow();
        (s.items.len() - s.popped).min(s.bandwidth - s.popped)
    }

    #[inline]
    pub fn pop(&mut self) -> Result<T, ContractError> {
        let mut s = self.0.borrow_mut();
        if s.popped == s.bandwidth {
            let bandwidth = s.bandwidth;
            return Err(ContractError::at(
                &s.path,
                Violation::OverRead { bandwidth },
            ));
        }
        let Some(v) = s.items.get(s.popped).cloned() else {
            return Err(ContractError::at(&s.path, Violation::Underflow));
        };
        s.popped += 1;
        Ok(v)
    }
}

impl<T> Channel for FifoState<T> {
    fn commit(&mut self, rising: DomainSet) -> Result<bool, ContractError> {
        if rising.contains(self.domain) {
            self.items.drain(..self.popped);
            self.popped = 0;
            self.items.append(&mut self.pushed);
        }
        Ok(false)
    }

    fn domain(&self) -> DomainId {
        self.domain
    }
}

impl<T> Traced for FifoState<T> {
    fn trace(&self, t: &mut Trace) {
        t.value(self.level_id, self.items.len() as u64);
    }
}
