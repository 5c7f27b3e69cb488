//! Local register files (ARCHITECTURE §4): one per functional-unit input in every cluster,
//! each with one read port and one write port per cycle. Sizes come from the machine
//! description (`[lrf]`; 2×32 + 15×16 entries per cluster on gold8).
//!
//! Lane-batched: one [`Lrf`] models the same register file in every cluster; a read or a
//! write moves one word per cluster. A second read or a second write in one cycle is a
//! port conflict, reported as a [`ContractError`] naming the register file.
//! Reads see the state committed at the last edge; writes land at the edge.

use std::cell::Cell;

use crate::lanes::{copy_lanes, copy_mask, count, count_set};
use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

/// A port not used this cycle.
const IDLE: u32 = u32::MAX;

/// The entry a port uses this cycle, if any.
fn port(entry: u32) -> Option<u16> {
    (entry != IDLE).then_some(entry as u16)
}

pub struct Lrf {
    path: String,
    entries: usize,
    lanes: usize,
    /// Entry-major: `data[entry * lanes + lane]`.
    data: Vec<u32>,
    /// The entry the read port reads this cycle (a `Cell`, so reads share the file) and the
    /// entry the write port writes, or [`IDLE`]: one word each rather than an
    /// `Option<u16>`, which is stored as two halves and read back whole (the processor then
    /// waits for the store to reach the cache: a stall per access).
    read_entry: Cell<u32>,
    write_entry: u32,
    write_values: Vec<u32>,
    write_mask: Vec<bool>,
    /// The pending write goes only to the clusters `write_mask` selects.
    write_masked: bool,
    /// Words read and written so far, over all clusters (for bandwidth statistics).
    words_read: Cell<u64>,
    words_written: u64,
    /// A tracer is attached: the ports' use is latched for the probes each cycle. Without
    /// one the cluster's reads (of a program that passed the microcode check, which reads
    /// each file from its one slot, so the port cannot be asked twice) leave the port alone,
    /// and a cycle's commit has something to do only where a write lands.
    tracing: bool,
    probes: LrfProbes,
}

#[derive(Debug)]
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
    last_masked: bool,
}

/// The file's state: its words, the pending write and the counts (not the write buffers
/// between writes, which are swapped with the probes' latches while tracing, nor the
/// latches themselves, which only a tracer reads).
impl std::fmt::Debug for Lrf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pending = port(self.write_entry).map(|e| {
            let n = self.lanes;
            (
                e,
                &self.write_values[..n],
                self.write_masked.then(|| &self.write_mask[..n]),
            )
        });
        f.debug_struct("Lrf")
            .field("path", &self.path)
            .field("data", &self.data)
            .field("read_entry", &port(self.read_entry.get()))
            .field("pending_write", &pending)
            .field("words_read", &self.words_read.get())
            .field("words_written", &self.words_written)
            .finish()
    }
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
            last_masked: false,
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
            read_entry: Cell::new(IDLE),
            write_entry: IDLE,
            write_values: vec![0; lanes],
            write_mask: vec![true; lanes],
            write_masked: false,
            words_read: Cell::new(0),
            words_written: 0,
            tracing: true,
            probes,
        }
    }

    pub fn entries(&self) -> usize {
        self.entries
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    /// Words read and written so far over all clusters: `(read, written)`.
    pub fn words_moved(&self) -> (u64, u64) {
        (self.words_read.get(), self.words_written)
    }

    /// Whether a tracer is attached (see the field's doc and
    /// [`imagine_hdl::Module::set_tracing`]).
    pub fn set_tracing(&mut self, on: bool) {
        self.tracing = on;
    }

    /// The error for a bad use of `port`; kept out of line so the ports stay small.
    #[cold]
    #[inline(never)]
    fn port_error(&self, port: &str, entry: u16, previous: Option<u16>) -> ContractError {
        let problem = match previous {
            Some(prev) => {
                format!("{port} port conflict: entries {prev} and {entry} in the same cycle")
            }
            None => format!("entry {entry} is outside the {} entries", self.entries),
        };
        ContractError::at(&format!("{}.{port}", self.path), Violation::Other(problem))
    }

    /// Reads `entry` in every cluster (the read port, once per cycle).
    #[inline]
    pub fn read(&self, entry: u16) -> Result<&[u32], ContractError> {
        self.read_port::<0>(entry)
    }

    /// The cluster's read of an operand of a program that passed the microcode check,
    /// compiled for `L` lanes ([`crate::lanes`]): the port's use is only kept when a tracer
    /// is attached (see the `tracing` field).
    #[inline(always)]
    pub(crate) fn read_for<const L: usize>(&self, entry: u16) -> Result<&[u32], ContractError> {
        if self.tracing || cfg!(feature = "inject-bugs") {
            return self.read_port::<L>(entry);
        }
        let n = count::<L>(self.lanes);
        self.words_read.set(self.words_read.get() + n as u64);
        let start = entry as usize * n;
        Ok(&self.data[start..start + n])
    }

    /// The read port: refuses a second read in a cycle and an entry outside the file.
    #[inline(always)]
    fn read_port<const L: usize>(&self, entry: u16) -> Result<&[u32], ContractError> {
        let previous = self.read_entry.get();
        if previous != IDLE || entry as usize >= self.entries {
            return Err(self.port_error("read", entry, port(previous)));
        }
        self.read_entry.set(u32::from(entry));
        let n = count::<L>(self.lanes);
        self.words_read.set(self.words_read.get() + n as u64);
        let start = entry as usize * n;
        Ok(&self.data[start..start + n])
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
        self.write_for::<0>(entry, values, mask)
    }

    /// [`write`](Self::write) compiled for `L` lanes ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn write_for<const L: usize>(
        &mut self,
        entry: u16,
        values: &[u32],
        mask: Option<&[bool]>,
    ) -> Result<(), ContractError> {
        if self.write_entry != IDLE || entry as usize >= self.entries {
            return Err(self.port_error("write", entry, port(self.write_entry)));
        }
        self.write_entry = u32::from(entry);
        copy_lanes::<L>(&mut self.write_values, values);
        self.write_masked = mask.is_some();
        if let Some(m) = mask {
            copy_mask::<L>(&mut self.write_mask, m);
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

    /// Brings a file with no access pending over idle cycles, as their commits would: the
    /// probe latches of the last access clear.
    pub fn skip_idle(&mut self) {
        debug_assert!(self.read_entry.get() == IDLE && self.write_entry == IDLE);
        self.probes.last_read = None;
        self.probes.last_write = None;
    }

    /// Ends the cycle: the write lands; the ports' use is kept for the probes.
    #[inline]
    pub fn commit(&mut self) {
        self.commit_for::<0>()
    }

    /// [`commit`](Self::commit) compiled for `L` lanes ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn commit_for<const L: usize>(&mut self) {
        if !self.tracing && !cfg!(feature = "inject-bugs") {
            self.commit_untraced::<L>();
            return;
        }
        // Most files see no access in a cycle: leave them after the cheapest test.
        if self.write_entry == IDLE && self.read_entry.get() == IDLE {
            self.probes.last_read = None;
            self.probes.last_write = None;
            return;
        }
        let last_read = port(self.read_entry.replace(IDLE));
        let last_write = port(std::mem::replace(&mut self.write_entry, IDLE));
        (self.probes.last_read, self.probes.last_write) = (last_read, last_write);
        if let Some(e) = last_write {
            #[cfg(feature = "inject-bugs")]
            if last_read == Some(e)
                && imagine_hdl::inject::active(
                    imagine_hdl::inject::Bug::LrfDropsWriteOnSameEntryRead,
                )
            {
                return;
            }
            self.land::<L>(e);
            // The write buffers become the probe's copy; the next write refills the others.
            let p = &mut self.probes;
            std::mem::swap(&mut p.last_values, &mut self.write_values);
            std::mem::swap(&mut p.last_mask, &mut self.write_mask);
            p.last_masked = self.write_masked;
        }
    }

    /// The edge without a tracer (and without injected bugs), where only a write has
    /// anything to do (see the `tracing` field): for a caller that knows it is untraced,
    /// as the machine does for all its files at once.
    #[inline(always)]
    pub(crate) fn commit_untraced<const L: usize>(&mut self) {
        debug_assert!(!self.tracing && !cfg!(feature = "inject-bugs"));
        if self.write_entry != IDLE {
            let e = std::mem::replace(&mut self.write_entry, IDLE);
            self.land::<L>(e as u16);
        }
    }

    /// The pending write to `e` lands.
    #[inline(always)]
    fn land<const L: usize>(&mut self, e: u16) {
        let n = count::<L>(self.lanes);
        self.words_written += if self.write_masked {
            count_set::<L>(&self.write_mask) as u64
        } else {
            n as u64
        };
        let start = e as usize * n;
        let row = &mut self.data[start..start + n];
        if self.write_masked {
            let (values, mask) = (&self.write_values[..n], &self.write_mask[..n]);
            for ((d, &v), &m) in row.iter_mut().zip(values).zip(mask) {
                if m {
                    *d = v;
                }
            }
        } else {
            copy_lanes::<L>(row, &self.write_values);
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
                (p.last_write.is_some() && (!p.last_masked || p.last_mask[c])) as u64,
            );
            t.value(p.lane_wdata[c], p.last_values[c] as u64);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use imagine_hdl::{Design, default_domains};

    fn lrf(entries: usize) -> Lrf {
        let mut d = Design::new("top", default_domains()).unwrap();
        Lrf::new(&mut d.scope(), "add0.a", entries, 4)
    }

    #[test]
    fn writes_land_at_the_edge_with_their_mask() {
        let mut f = lrf(16);
        f.write(3, &[1, 2, 3, 4], None).unwrap();
        assert_eq!(
            f.read(3).unwrap(),
            &[0, 0, 0, 0],
            "a write is visible only after the edge"
        );
        f.commit();
        assert_eq!(f.read(3).unwrap(), &[1, 2, 3, 4]);
        f.write(3, &[9, 9, 9, 9], Some(&[true, false, false, true]))
            .unwrap();
        f.commit();
        assert_eq!(f.peek(3), &[9, 2, 3, 9]);
    }

    #[test]
    fn words_moved_count_clusters_and_write_masks() {
        let mut f = lrf(16);
        f.read(0).unwrap();
        f.write(1, &[1, 2, 3, 4], None).unwrap();
        f.commit();
        f.write(2, &[5, 6, 7, 8], Some(&[false, true, false, true]))
            .unwrap();
        f.commit();
        f.commit();
        assert_eq!(f.words_moved(), (4, 6));
    }

    #[test]
    fn each_port_serves_one_access_per_cycle() {
        let mut f = lrf(16);
        f.read(1).unwrap();
        let e = f.read(2).unwrap_err().to_string();
        assert!(
            e.contains("top.lrf.add0_a") && e.contains("read port conflict"),
            "{e}"
        );
        f.write(1, &[0; 4], None).unwrap();
        let e = f.write(2, &[0; 4], None).unwrap_err().to_string();
        assert!(e.contains("write port conflict"), "{e}");
        f.commit();
        // The next cycle starts with free ports.
        f.read(2).unwrap();
        f.write(2, &[0; 4], None).unwrap();
    }

    #[test]
    fn entries_outside_the_file_are_errors() {
        let mut f = lrf(16);
        assert!(
            f.read(16)
                .unwrap_err()
                .to_string()
                .contains("outside the 16 entries")
        );
        assert!(
            f.write(99, &[0; 4], None)
                .unwrap_err()
                .to_string()
                .contains("entry 99")
        );
    }
}
