//! Condition-code register file (ARCHITECTURE §4): `condition_codes` one-bit registers in
//! every cluster (16 on gold8), written by compares through the switch and read by
//! `select`, conditional streams and loop tests. Any number of reads per cycle; one write
//! per register per cycle.

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation};

#[derive(Debug)]
pub struct CcFile {
    path: String,
    entries: usize,
    lanes: usize,
    /// Entry-major: `bits[entry * lanes + lane]`.
    bits: Vec<bool>,
    /// Writes of this cycle: the entries, and their new rows in `rows[..entries.len()]`
    /// (rows are reused from cycle to cycle).
    pending: Vec<u16>,
    rows: Vec<Vec<bool>>,
    /// Per cluster, all codes as one probe word.
    probes: Vec<SignalId>,
}

impl CcFile {
    pub fn new(scope: &mut Scope<'_>, entries: usize, lanes: usize) -> Self {
        let probes = (0..lanes)
            .map(|c| {
                scope
                    .child(&format!("cluster{c}"))
                    .signal("cc", entries as u32, SignalKind::Reg)
            })
            .collect();
        CcFile {
            path: format!("{}.cluster*.cc", scope.path()),
            entries,
            lanes,
            bits: vec![false; entries * lanes],
            pending: Vec::new(),
            rows: Vec::new(),
            probes,
        }
    }

    fn check(&self, entry: u16) -> Result<usize, ContractError> {
        if entry as usize >= self.entries {
            return Err(ContractError::at(
                &self.path,
                Violation::Other(format!(
                    "condition code {entry} is outside the {} codes",
                    self.entries
                )),
            ));
        }
        Ok(entry as usize)
    }

    /// Committed value of code `entry` in every cluster.
    #[inline]
    pub fn read(&self, entry: u16) -> Result<&[bool], ContractError> {
        let e = self.check(entry)?;
        Ok(&self.bits[e * self.lanes..(e + 1) * self.lanes])
    }

    /// Whether code `entry` is set in every cluster.
    pub fn all(&self, entry: u16) -> Result<bool, ContractError> {
        Ok(self.read(entry)?.iter().all(|&b| b))
    }

    /// Sets code `entry` to bit 0 of `values` at the edge, in the clusters `mask` selects.
    pub fn write(
        &mut self,
        entry: u16,
        values: &[u32],
        mask: &[bool],
    ) -> Result<(), ContractError> {
        let e = self.check(entry)?;
        if self.pending.contains(&entry) {
            return Err(ContractError::at(
                &self.path,
                Violation::Other(format!("condition code {entry} written twice in one cycle")),
            ));
        }
        let n = self.pending.len();
        if self.rows.len() == n {
            self.rows.push(vec![false; self.lanes]);
        }
        let row = &mut self.rows[n];
        row.copy_from_slice(&self.bits[e * self.lanes..(e + 1) * self.lanes]);
        for ((r, &v), &m) in row.iter_mut().zip(values).zip(mask) {
            #[cfg(feature = "inject-bugs")]
            let m =
                m || imagine_hdl::inject::active(imagine_hdl::inject::Bug::CcFileIgnoresWriteMask);
            if m {
                *r = v & 1 != 0;
            }
        }
        self.pending.push(entry);
        Ok(())
    }

    pub fn commit(&mut self) {
        for (&e, row) in self.pending.iter().zip(&self.rows) {
            let e = e as usize;
            self.bits[e * self.lanes..(e + 1) * self.lanes].copy_from_slice(row);
        }
        self.pending.clear();
    }

    pub fn trace(&self, t: &mut Trace) {
        for (c, &id) in self.probes.iter().enumerate() {
            let mut word = vec![0u64; self.entries.div_ceil(64)];
            for e in 0..self.entries {
                if self.bits[e * self.lanes + c] {
                    word[e / 64] |= 1 << (e % 64);
                }
            }
            t.wide(id, &word);
        }
    }
}
