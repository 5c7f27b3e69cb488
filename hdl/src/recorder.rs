//! A tracer for testbenches: it keeps the probe registry and every change it is sent, so a
//! test can ask which values a signal took.

use std::cell::{Ref, RefCell};
use std::io;
use std::rc::Rc;

use crate::{ClockDomain, ProbeRegistry, SignalId, Tracer};

/// What a [`Recorder`] has seen.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    pub probes: ProbeRegistry,
    /// `(time in ps, signal, value words)`, in the order the changes arrived.
    pub changes: Vec<(u64, SignalId, Vec<u64>)>,
    now_ps: u64,
}

impl Recording {
    /// The values (their first 64-bit word) that the signal at `path` took, in order; `None`
    /// if there is no such signal.
    pub fn values(&self, path: &str) -> Option<Vec<u64>> {
        let id = self.probes.find(path)?;
        Some(
            self.changes
                .iter()
                .filter(|(_, s, _)| *s == id)
                .map(|(_, _, v)| v[0])
                .collect(),
        )
    }
}

/// A [`Tracer`] that records; clones share one [`Recording`], so a test keeps a clone and
/// hands another to the simulator.
#[derive(Clone, Debug, Default)]
pub struct Recorder(Rc<RefCell<Recording>>);

impl Recorder {
    pub fn recording(&self) -> Ref<'_, Recording> {
        self.0.borrow()
    }
}

impl Tracer for Recorder {
    fn start(&mut self, probes: &ProbeRegistry, _: &[ClockDomain]) -> io::Result<()> {
        self.0.borrow_mut().probes = probes.clone();
        Ok(())
    }
    fn time(&mut self, time_ps: u64, _: u64) {
        self.0.borrow_mut().now_ps = time_ps;
    }
    fn change(&mut self, id: SignalId, value: &[u64]) {
        let mut r = self.0.borrow_mut();
        let now = r.now_ps;
        r.changes.push((now, id, value.to_vec()));
    }
    fn finish(&mut self) -> io::Result<()> {
        Ok(())
    }
}
