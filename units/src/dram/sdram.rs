//! The SDRAM part of one channel: its banks, the words it stores, and the data bus.
//!
//! It executes the command on the command bus in the cycle the bus drives it:
//! `ACTIVATE` opens a row, `PRECHARGE` closes it, `READ` puts the burst's words on the data
//! bus `CL` cycles later (one word per cycle), `WRITE` takes its words from the bus in the
//! command's cycle and the next `burst − 1` (the words are stored at the command: nothing
//! can read them earlier), `REFRESH` changes nothing visible. Storage is sparse: a row is
//! allocated the first time it is written, and unwritten words read as 0.
//!
//! A column command to a bank whose open row is not the one addressed reads the addressed
//! row all the same (the model stays deterministic); the timing checker flags it.
//!
//! Probes: `bankN.state`, `bankN.row` (see `bank`), `dq_valid` and `dq` (the data bus).

use std::collections::VecDeque;

use imagine_hdl::{Scope, SignalId, SignalKind, Trace};

use super::Command;
use super::bank::Bank;

#[derive(Clone, Debug)]
pub struct Sdram {
    banks: Vec<Bank>,
    rows: usize,
    columns: usize,
    burst: usize,
    cl: u64,
    /// Per (bank, row), its words once written: indexed, not hashed (each word read or
    /// written looks its row up).
    store: Vec<Option<Box<[u32]>>>,
    /// Read words due on the data bus: (cycle, word), in cycle order.
    due: VecDeque<(u64, u32)>,
    /// The bank given a command this cycle: the only one whose state can change at the
    /// edge.
    commanded: Option<usize>,
    /// The data bus this cycle and at the last edge (for probes).
    dq: Option<u32>,
    dq_q: Option<u32>,
    ids: (SignalId, SignalId),
}

impl Sdram {
    pub fn new(scope: &mut Scope<'_>, p: &super::DramParams) -> Self {
        Sdram {
            banks: (0..p.banks)
                .map(|b| Bank::new(&mut scope.child(&format!("bank{b}")), p.rows))
                .collect(),
            rows: p.rows,
            columns: p.columns,
            burst: p.burst,
            cl: p.cl,
            store: vec![None; p.banks * p.rows],
            due: VecDeque::new(),
            commanded: None,
            dq: None,
            dq_q: None,
            ids: (
                scope.signal("dq_valid", 1, SignalKind::Wire),
                scope.signal("dq", 32, SignalKind::Wire),
            ),
        }
    }

    pub fn bank(&self, b: usize) -> &Bank {
        &self.banks[b]
    }

    fn key(&self, bank: usize, row: u16) -> usize {
        bank * self.rows + row as usize
    }

    /// The word at (bank, row, column), as stored now.
    pub fn peek(&self, bank: usize, row: u16, column: usize) -> u32 {
        self.store[self.key(bank, row)]
            .as_ref()
            .map_or(0, |r| r[column])
    }

    /// Writes a word directly (the host preloading memory before a run).
    pub fn poke(&mut self, bank: usize, row: u16, column: usize, v: u32) {
        let key = self.key(bank, row);
        let columns = self.columns;
        self.store[key].get_or_insert_with(|| vec![0; columns].into_boxed_slice())[column] = v;
    }

    /// Executes the command on the bus in `cycle` (write data in `data`); returns the word on
    /// the data bus this cycle for a read burst, if any.
    #[inline]
    pub fn eval(&mut self, cmd: Option<Command>, data: &[u32], cycle: u64) -> Option<u32> {
        match cmd {
            Some(Command::Activate { bank, row }) => {
                let b = bank.value() as usize;
                self.banks[b].activate(row);
                self.commanded = Some(b);
            }
            Some(Command::Precharge { bank }) => {
                let b = bank.value() as usize;
                self.banks[b].precharge();
                self.commanded = Some(b);
            }
            Some(Command::Read { bank, column }) => {
                let b = bank.value() as usize;
                let row = self.row_for(b);
                for k in 0..self.burst {
                    let w = self.peek(b, row, column.value() as usize + k);
                    self.due.push_back((cycle + self.cl + k as u64, w));
                }
            }
            Some(Command::Write { bank, column }) => {
                let b = bank.value() as usize;
                let row = self.row_for(b);
                for (k, &w) in data.iter().enumerate().take(self.burst) {
                    self.poke(b, row, column.value() as usize + k, w);
                }
            }
            Some(Command::Refresh) | None => {}
        }
        self.dq = match self.due.front() {
            Some(&(c, w)) if c == cycle => {
                self.due.pop_front();
                Some(w)
            }
            _ => None,
        };
        self.dq
    }

    /// The row a column command addresses: the open one (row 0 of an idle bank, a
    /// violation the checker reports).
    fn row_for(&self, bank: usize) -> u16 {
        self.banks[bank].open_row().unwrap_or(0)
    }

    /// The data bus in the current cycle (after `eval`).
    pub fn dq_now(&self) -> Option<u32> {
        self.dq
    }

    /// Read words still to come out on the data bus.
    pub fn reads_in_flight(&self) -> usize {
        self.due.len()
    }

    /// Whether idle cycles change nothing here: no read data due, every bank closed.
    pub fn is_quiet(&self) -> bool {
        self.due.is_empty()
            && self
                .banks
                .iter()
                .all(|b| b.state() == super::bank::BankState::Idle)
    }

    /// The state idle cycles leave (only when [`is_quiet`](Self::is_quiet)): an empty data
    /// bus.
    pub fn skip_idle(&mut self) {
        debug_assert!(self.is_quiet());
        self.dq = None;
        self.dq_q = None;
    }

    /// Everything that evolves, with the sparse store in a fixed order (tests compare two
    /// runs' states).
    #[cfg(test)]
    pub(crate) fn debug_state(&self) -> String {
        let rows: Vec<_> = self
            .store
            .iter()
            .enumerate()
            .filter(|(_, r)| r.is_some())
            .collect();
        format!(
            "{:?} {:?} {:?} {:?} {rows:?}",
            self.banks, self.due, self.dq, self.dq_q
        )
    }

    #[inline]
    pub fn commit(&mut self) {
        if let Some(b) = self.commanded.take() {
            self.banks[b].commit();
        }
        self.dq_q = self.dq;
    }

    pub fn trace(&self, t: &mut Trace) {
        self.banks.iter().for_each(|b| b.trace(t));
        t.value(self.ids.0, self.dq_q.is_some() as u64);
        if let Some(w) = self.dq_q {
            t.value(self.ids.1, w as u64);
        }
    }
}
