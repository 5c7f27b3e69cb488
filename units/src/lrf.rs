//! Local register files (ARCHITECTURE §4): one per functional-unit input in every cluster,
//! each with one read port and one write port per cycle. Sizes come from the machine
//! description (`[lrf]`; 2×32 + 15×16 entries per cluster on gold8).
//!
//! Lane-batched: one [`Lrf`] models the same register file in every cluster; a read or a
//! write moves one word per cluster. A second read or a second write in one cycle is a
//! port conflict, reported as a [`ContractError`] naming the register file.
//! Reads see the state committed at the last edge; writes land at the edge.

use std::cell::Cell;

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

pub struct Lrf {
    path: String,
    entries: usize,
    lanes: usize,
    /// Entry-major: `data[entry * lanes + lane]`.
    data: Vec<u32>,
    /// The read port's use this cycle (a `Cell`, so reads share the file).
    read_entry: Cell<Option<u16>>,
    write_entry: Option<u16>,
    write_values: Vec<u32>,
    write_mask: Vec<bool>,
    probes: LrfProbes,
}

struct LrfProbes {
    read_valid: SignalId,
    read_addr: SignalId,
    write_valid: SignalId,
    write_addr: SignalId,
    /// Per cluster: write enable (after the lane mask) and write data.
    lane_we: Vec<SignalId>,
    lane_wdata: Vec<SignalId>,
    last_read: Option<u16>,
    last_write: Option<u16>,
    last_values: Vec<u32>,
    last_mask: Vec<bool>,
}

impl Lrf {
    /// An LRF `name` (e.g. `add0.a`) in every cluster; probes go under
    /// `<scope>.lrf.<name>` and `<scope>.cluster<c>.lrf.<name>`.
    pub fn new(scope: &mut Scope<'_>, name: &str, entries: usize, lanes: usize) -> Self {
        let addr = bits_for(entries as u64 - 1);
        let file = name.replace('.', "_");
        let mut s = scope.child("lrf");
        let mut s = s.child(&file);
        let probes = LrfProbes {
            read_valid: s.signal("read_valid", 1, SignalKind::Wire),
            read_addr: s.signal("read_addr", addr, SignalKind::Wire),
            write_valid: s.signal("write_valid", 1, SignalKind::Wire),
            write_addr: s.signal("write_addr", addr, SignalKind::Wire),
            lane_we: Vec::new(),
            lane_wdata: Vec::new(),
            last_read: None,
            last_write: None,
            last_values: vec![0; lanes],
            last_mask: vec![false; lanes],
        };
        let path = s.path().to_string();
        drop(s);
        let mut probes = probes;
        for c in 0..lanes {
            let mut cs = scope.child(&format!("cluster{c}"));
            let mut ls = cs.child("lrf");
            let mut ls = ls.child(&file);
            probes.lane_we.push(ls.signal("we", 1, SignalKind::Wire));
            probes
                .lane_wdata
                .push(ls.signal("wdata", 32, SignalKind::Wire));
        }
        Lrf {
            path,
            entries,
            lanes,
            data: vec![0; entries * lanes],
            read_entry: Cell::new(None),
            write_entry: None,
            write_values: vec![0; lanes],
            write_mask: vec![true; lanes],
            probes,
        }
    }

    pub fn entries(&self) -> usize {
        self.entries
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    #[inline]
    fn check_entry(&self, entry: u16, port: &str) -> Result<usize, ContractError> {
        let e = entry as usize;
        if e >= self.entries {
            return Err(ContractError::at(
                &format!("{}.{port}", self.path),
                Violation::Other(format!("entry {e} is outside the {} entries", self.entries)),
            ));
        }
        Ok(e)
    }

    /// Reads `entry` in every cluster (the read port, once per cycle).
    #[inline]
    pub fn read(&self, entry: u16) -> Result<&[u32], ContractError> {
        if let Some(prev) = self.read_entry.get() {
            return Err(ContractError::at(
                &format!("{}.read", self.path),
                Violation::Other(format!(
                    "read port conflict: entries {prev} and {entry} read in the same cycle"
                )),
            ));
        }
        let e = self.check_entry(entry, "read")?;
        self.read_entry.set(Some(entry));
        Ok(&self.data[e * self.lanes..(e + 1) * self.lanes])
    }

    /// Writes `values` (one per cluster) to `entry` at the edge, in the clusters whose
    /// `mask` bit is set (`None`: all).
    #[inline]
    pub fn write(
        &mut self,
        entry: u16,
        values: &[u32],
        mask: Option<&[bool]>,
    ) -> Result<(), ContractError> {
        if let Some(prev) = self.write_entry {
            return Err(ContractError::at(
                &format!("{}.write", self.path),
                Violation::Other(format!(
                    "write port conflict: entries {prev} and {entry} written in the same cycle"
                )),
            ));
        }
        self.check_entry(entry, "write")?;
        self.write_entry = Some(entry);
        self.write_values.copy_from_slice(values);
        match mask {
            Some(m) => self.write_mask.copy_from_slice(m),
            None => self.write_mask.fill(true),
        }
        Ok(())
    }

    /// The committed contents of `entry`, one word per cluster (for inspection and tests).
    pub fn peek(&self, entry: usize) -> &[u32] {
        &self.data[entry * self.lanes..(entry + 1) * self.lanes]
    }

    /// Sets the committed contents of `entry` directly (for tests).
    pub fn poke(&mut self, entry: usize, values: &[u32]) {
        self.data[entry * self.lanes..(entry + 1) * self.lanes].copy_from_slice(values);
    }

    /// Ends the cycle: the write lands; the ports' use is kept for the probes.
    #[inline]
    pub fn commit(&mut self) {
        let p = &mut self.probes;
        p.last_read = self.read_entry.take();
        p.last_write = self.write_entry.take();
        if let Some(e) = p.last_write {
            let row = &mut self.data[e as usize * self.lanes..(e as usize + 1) * self.lanes];
            for ((d, &v), &m) in row.iter_mut().zip(&self.write_values).zip(&self.write_mask) {
                if m {
                    *d = v;
                }
            }
            // The write buffers become the probe's copy; the next write refills the others.
            std::mem::swap(&mut p.last_values, &mut self.write_values);
            std::mem::swap(&mut p.last_mask, &mut self.write_mask);
        }
    }

    pub fn trace(&self, t: &mut Trace) {
        let p = &self.probes;
        t.value(p.read_valid, p.last_read.is_some() as u64);
        t.value(p.read_addr, p.last_read.unwrap_or(0) as u64);
        t.value(p.write_valid, p.last_write.is_some() as u64);
        t.value(p.write_addr, p.last_write.unwrap_or(0) as u64);
        for c in 0..self.lanes {
            t.value(
                p.lane_we[c],
                (p.last_write.is_some() && p.last_mask[c]) as u64,
            );
            t.value(p.lane_wdata[c], p.last_values[c] as u64);
        }
    }
}
