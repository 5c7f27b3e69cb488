//! Fixed-latency pipes with a bandwidth, one writer and one reader (ARCHITECTURE §3, after
//! ATTILA's signals).
//!
//! A value written in cycle `t` is visible to the reader in cycle `t + latency` and only
//! then; the reader must take it in that cycle. Writing more than `bandwidth` values in a
//! cycle, or leaving an arrived value unread, is a [`ContractError`] naming the pipe.
//! One writer and one reader are enforced by construction: [`PipeTx`] and [`PipeRx`] are
//! the only handles and neither can be cloned.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use crate::{Channel, ContractError, DomainId, DomainSet, SignalId, Trace, Traced, Violation};

pub(crate) struct PipeState<T> {
    path: String,
    domain: DomainId,
    bandwidth: usize,
    /// `stages[0]` is visible to the reader; the last stage receives next cycle's writes.
    stages: VecDeque<VecDeque<T>>,
    incoming: VecDeque<T>,
    error: Option<ContractError>,
    valid_id: SignalId,
}

/// The writing end of a pipe.
pub struct PipeTx<T>(Rc<RefCell<PipeState<T>>>);
/// The reading end of a pipe.
pub struct PipeRx<T>(Rc<RefCell<PipeState<T>>>);

pub(crate) fn new_pipe<T: 'static>(
    path: String,
    domain: DomainId,
    latency: usize,
    bandwidth: usize,
    valid_id: SignalId,
) -> (PipeTx<T>, PipeRx<T>, Rc<RefCell<PipeState<T>>>) {
    let state = Rc::new(RefCell::new(PipeState {
        path,
        domain,
        bandwidth,
        stages: (0..latency)
            .map(|_| VecDeque::with_capacity(bandwidth))
            .collect(),
        incoming: VecDeque::with_capacity(bandwidth),
        error: None,
        valid_id,
    }));
    (PipeTx(state.clone()), PipeRx(state.clone()), state)
}

impl<T> PipeTx<T> {
    /// Writes a value; it arrives `latency` cycles later.
    pub fn write(&mut self, v: T) -> Result<(), ContractError> {
        let mut s = self.0.borrow_mut();
        if s.incoming.len() == s.bandwidth {
            return Err(ContractError::over_bandwidth(&s.path, s.bandwidth));
        }
        s.incoming.push_back(v);
        Ok(())
    }
}

impl<T> PipeRx<T> {
    /// Takes the next value that arrived this cycle, if any.
    pub fn read(&mut self) -> Option<T> {
        self.0.borrow_mut().stages[0].pop_front()
    }

    /// Number of values that arrived this cycle and are not yet read.
    pub fn available(&self) -> usize {
        self.0.borrow().stages[0].len()
    }
}

impl<T> Channel for PipeState<T> {
    fn commit(&mut self, rising: DomainSet) -> Result<bool, ContractError> {
        if !rising.contains(self.domain) {
            return Ok(false);
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let lost = self.stages[0].len();
        if lost > 0 {
            return Err(ContractError::at(&self.path, Violation::Unread { lost }));
        }
        let mut visible = self.stages.pop_front().expect("latency >= 1");
        std::mem::swap(&mut visible, &mut self.incoming);
        self.stages.push_back(visible);
        Ok(false)
    }

    fn domain(&self) -> DomainId {
        self.domain
    }
}

impl<T> Traced for PipeState<T> {
    fn trace(&self, t: &mut Trace) {
        t.value(self.valid_id, self.stages[0].len() as u64);
    }
}
