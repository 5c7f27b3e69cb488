//! Registers: a `q` output that holds the value committed at the last clock edge and a `d`
//! input that `eval` sets. Reading `q` and writing `d` is what makes evaluation order
//! irrelevant.

use crate::{Bits, Scope, SignalId, SignalKind, Trace};

/// A register of a [`Bits`] type, registered as a probe of the type's width.
#[derive(Clone, Debug)]
pub struct Reg<T> {
    q: T,
    d: T,
    id: SignalId,
}

impl<T: Bits> Reg<T> {
    pub fn new(scope: &mut Scope<'_>, name: &str, init: T) -> Self {
        let id = scope.signal(name, T::WIDTH, SignalKind::Reg);
        Reg {
            q: init,
            d: init,
            id,
        }
    }

    /// The value committed at the last edge.
    #[inline]
    pub fn q(&self) -> T {
        self.q
    }

    /// Sets the value to commit at the next edge (a register holds unless set).
    #[inline]
    pub fn set(&mut self, d: T) {
        self.d = d;
    }

    /// The value that will be committed.
    #[inline]
    pub fn d(&self) -> T {
        self.d
    }

    #[inline]
    pub fn commit(&mut self) {
        self.q = self.d;
    }

    #[inline]
    pub fn trace(&self, t: &mut Trace) {
        t.bits(self.id, self.q);
    }

    pub fn id(&self) -> SignalId {
        self.id
    }
}
