//! The rising edges each clock domain has committed, as the blocks of a design see them
//! while they are evaluated: shared with blocks whose registers are a closed-form function
//! of those counts (the synchronising FIFOs' pointer synchronisers), so that an edge need
//! not visit them. The simulator marks the domains rising in the step under way before it
//! evaluates them, and counts their edges once the step's commits are done.

use std::cell::Cell;

use crate::{Clocks, DomainId, DomainSet};

pub(crate) struct EdgeCounts {
    /// Per domain (of at most 64), the rising edges whose commits are done: held in place,
    /// as every FIFO end reads them at each use.
    committed: [Cell<u64>; 64],
    domains: usize,
    /// The domains rising in the step under way (none between steps).
    rising: Cell<u64>,
}

impl EdgeCounts {
    pub(crate) fn new(domains: usize) -> Self {
        EdgeCounts {
            committed: std::array::from_fn(|_| Cell::new(0)),
            domains,
            rising: Cell::new(0),
        }
    }

    /// The rising edges of `d` whose commits are done.
    #[inline]
    pub(crate) fn committed(&self, d: DomainId) -> u64 {
        self.committed[d.0 as usize].get()
    }

    /// Whether `d` rises in the step under way.
    #[inline]
    pub(crate) fn rising(&self, d: DomainId) -> bool {
        self.rising.get() & (1 << d.0) != 0
    }

    /// A step whose rising domains are `rising` starts (before its evaluations).
    #[inline]
    pub(crate) fn begin(&self, rising: DomainSet) {
        self.rising.set(rising.0);
    }

    /// The step under way has committed: its rising edges count.
    #[inline]
    pub(crate) fn end(&self) {
        let mut rising = self.rising.replace(0);
        while rising != 0 {
            let c = &self.committed[rising.trailing_zeros() as usize];
            rising &= rising - 1;
            c.set(c.get() + 1);
        }
    }

    /// The clocks have jumped between steps: every domain's edges count.
    pub(crate) fn sync(&self, clocks: &Clocks) {
        debug_assert_eq!(self.rising.get(), 0, "a jump between steps");
        for (i, c) in self.committed[..self.domains].iter().enumerate() {
            c.set(clocks.cycles(DomainId(i as u8)));
        }
    }
}
