//! One internal bank of an SDRAM part: idle (precharged) or active with one open row.
//!
//! The bank only follows the commands it is given; whether they respect the datasheet's
//! timing is the timing checker's business (see `timing_check`), and which command comes
//! when is the scheduler's. Probes: `state` (1 bit: 0 idle, 1 active) and `row` (the open
//! row, `bits_for(rows - 1)` bits).

use imagine_hdl::{Display, Scope, SignalId, SignalKind, Trace, bits_for};

/// The state of a bank.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BankState {
    /// Precharged: no row open.
    Idle,
    /// The row is open in the sense amplifiers.
    Active { row: u16 },
}

/// A bank with registered state (`q` committed, `d` next).
#[derive(Clone, Debug)]
pub struct Bank {
    q: BankState,
    d: BankState,
    ids: (SignalId, SignalId),
}

impl Bank {
    pub fn new(scope: &mut Scope<'_>, rows: usize) -> Self {
        Bank {
            q: BankState::Idle,
            d: BankState::Idle,
            ids: (
                scope.signal_shown(
                    "state",
                    1,
                    SignalKind::Reg,
                    Display::Names(&["idle", "active"]),
                ),
                scope.signal("row", bits_for(rows as u64 - 1), SignalKind::Reg),
            ),
        }
    }

    pub fn state(&self) -> BankState {
        self.q
    }

    /// The open row, if any.
    pub fn open_row(&self) -> Option<u16> {
        match self.q {
            BankState::Active { row } => Some(row),
            BankState::Idle => None,
        }
    }

    pub fn activate(&mut self, row: u16) {
        self.d = BankState::Active { row };
    }

    pub fn precharge(&mut self) {
        #[cfg(feature = "inject-bugs")]
        if imagine_hdl::inject::active(imagine_hdl::inject::Bug::SdramPrechargeKeepsRowOpen) {
            return;
        }
        self.d = BankState::Idle;
    }

    pub fn commit(&mut self) {
        self.q = self.d;
    }

    pub fn trace(&self, t: &mut Trace) {
        match self.q {
            BankState::Idle => t.value(self.ids.0, 0),
            BankState::Active { row } => {
                t.value(self.ids.0, 1);
                t.value(self.ids.1, row as u64);
            }
        }
    }
}
