//! The scratchpad (ARCHITECTURE §4): a small indexed memory in every cluster (256 words on
//! gold8), addressed by an instruction base plus a per-cluster register offset, one access
//! (read or write) per cycle. Reads return after `scratchpad_read` cycles, writes are
//! visible `scratchpad_write` cycles after issue. An address outside the memory in an
//! active cluster is a [`ContractError`] naming the cluster and the address.

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

use crate::delay::{DelayLine, InFlight};
use crate::lanes::{copy_lanes, count};

pub struct Scratchpad {
    path: String,
    words: usize,
    lanes: usize,
    /// Word-major: `data[addr * lanes + lane]`.
    data: Vec<u32>,
    read_latency: u32,
    write_latency: u32,
    reads: DelayLine,
    /// Writes in flight: the address per lane is kept in `values` of a second delay line.
    write_addrs: DelayLine,
    write_data: DelayLine,
    accessed: bool,
    /// Words at the top of the memory that hold conditional stream buffers.
    reserved: usize,
    addr_scratch: Vec<u32>,
    probes: SpProbes,
}

struct SpProbes {
    access: SignalId,
    write: SignalId,
    lane_addr: Vec<SignalId>,
    lane_data: Vec<SignalId>,
    last: Option<bool>,
    /// A tracer is attached: the last access's addresses and data are latched.
    tracing: bool,
    last_addr: Vec<u32>,
    last_data: Vec<u32>,
}

/// The scratchpad's state: its words and the accesses on their way (not the probes'
/// latches, which only a tracer reads).
impl std::fmt::Debug for Scratchpad {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scratchpad")
            .field("path", &self.path)
            .field("data", &self.data)
            .field("reads", &self.reads)
            .field("write_addrs", &self.write_addrs)
            .field("write_data", &self.write_data)
            .field("accessed", &self.accessed)
            .field("reserved", &self.reserved)
            .field("last_access", &self.probes.last)
            .finish()
    }
}

impl Scratchpad {
    /// Scratchpad `name` (e.g. `sp0`) in every cluster.
    pub fn new(
        scope: &mut Scope<'_>,
        name: &str,
        words: usize,
        lanes: usize,
        read_latency: u32,
        write_latency: u32,
    ) -> Self {
        let path = format!("{}.cluster*.{name}", scope.path());
        let addr_bits = bits_for(words as u64 - 1);
        let mut unit = scope.child(name);
        let access = unit.signal("access", 1, SignalKind::Wire);
        let write = unit.signal("write", 1, SignalKind::Wire);
        drop(unit);
        let mut lane_addr = Vec::new();
        let mut lane_data = Vec::new();
        for c in 0..lanes {
            let mut s = scope.child(&format!("cluster{c}"));
            let mut s = s.child(name);
            lane_addr.push(s.signal("addr", addr_bits, SignalKind::Wire));
            lane_data.push(s.signal("data", 32, SignalKind::Wire));
        }
        Scratchpad {
            reads: DelayLine::new(format!("{path}.read"), lanes, read_latency),
            write_addrs: DelayLine::new(format!("{path}.write"), lanes, write_latency),
            write_data: DelayLine::new(format!("{path}.write"), lanes, write_latency),
            path,
            words,
            lanes,
            data: vec![0; words * lanes],
            read_latency,
            write_latency,
            accessed: false,
            reserved: 0,
            addr_scratch: vec![0; lanes],
            probes: SpProbes {
                access,
                write,
                lane_addr,
                lane_data,
                last: None,
                tracing: true,
                last_addr: vec![0; lanes],
                last_data: vec![0; lanes],
            },
        }
    }

    #[inline(always)]
    fn addresses<const L: usize>(
        &mut self,
        base: u16,
        offsets: Option<&[u32]>,
        mask: &[bool],
    ) -> Result<(), ContractError> {
        if std::mem::replace(&mut self.accessed, true) {
            return Err(ContractError::over_bandwidth(
                &format!("{}.port", self.path),
                1,
            ));
        }
        let n = count::<L>(self.lanes);
        let (mask, limit) = (&mask[..n], self.words - self.reserved);
        let addrs = &mut self.addr_scratch[..n];
        match offsets {
            Some(o) => {
                for (a, &o) in addrs.iter_mut().zip(&o[..n]) {
                    *a = (base as u32).wrapping_add(o);
                }
            }
            None => addrs.fill(base as u32),
        }
        // One test over every cluster; which one is out of range only matters for the error.
        let bad =
            (addrs.iter().zip(mask)).fold(false, |bad, (&a, &m)| bad | (m & (a as usize >= limit)));
        if bad {
            let c = (addrs.iter().zip(mask))
                .position(|(&a, &m)| m && a as usize >= limit)
                .expect("found above");
            return Err(self.address_error(c, self.addr_scratch[c]));
        }
        Ok(())
    }

    #[cold]
    #[inline(never)]
    fn address_error(&self, cluster: usize, addr: u32) -> ContractError {
        let problem = if (addr as usize) < self.words {
            format!(
                "address {addr} is in the top {} words, which buffer conditional streams",
                self.reserved
            )
        } else {
            format!("address {addr} is outside the {} words", self.words)
        };
        let path = self.path.replace("cluster*", &format!("cluster{cluster}"));
        ContractError::at(&format!("{path}.addr"), Violation::Other(problem))
    }

    /// Sets aside the top `words` words of every cluster's scratchpad for conditional
    /// stream buffers (2 per conditional word per cycle, as on Imagine).
    pub fn reserve_for_conditional_streams(&mut self, words: usize) {
        self.reserved = words.min(self.words);
    }

    /// Claims the port for a conditional stream access this cycle.
    pub fn claim_for_conditional_stream(&mut self) -> Result<(), ContractError> {
        if std::mem::replace(&mut self.accessed, true) {
            return Err(ContractError::at(
                &format!("{}.port", self.path),
                Violation::Busy {
                    detail: "a conditional stream access buffers its words here this cycle".into(),
                },
            ));
        }
        Ok(())
    }

    /// Reads `base + offset` in the clusters `mask` selects; the words leave
    /// `scratchpad_read` cycles later with `tag`.
    pub fn read(
        &mut self,
        base: u16,
        offsets: Option<&[u32]>,
        mask: &[bool],
        tag: u16,
    ) -> Result<(), ContractError> {
        self.read_for::<0>(base, offsets, mask, tag)
    }

    /// [`read`](Self::read) compiled for `L` lanes ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn read_for<const L: usize>(
        &mut self,
        base: u16,
        offsets: Option<&[u32]>,
        mask: &[bool],
        tag: u16,
    ) -> Result<(), ContractError> {
        self.addresses::<L>(base, offsets, mask)?;
        let n = count::<L>(self.lanes);
        let (data, addrs, mask) = (&self.data, &self.addr_scratch[..n], &mask[..n]);
        let masked = mask.iter().any(|&m| !m).then_some(mask);
        self.reads
            .insert_for::<L>(self.read_latency, tag, masked, |v| {
                for (c, (v, (&a, &m))) in v.iter_mut().zip(addrs.iter().zip(mask)).enumerate() {
                    *v = if m { data[a as usize * n + c] } else { 0 };
                }
            })?;
        self.probes.last = Some(false);
        if self.probes.tracing {
            self.probes.last_addr.copy_from_slice(&self.addr_scratch);
        }
        Ok(())
    }

    /// Writes `values` to `base + offset` in the clusters `mask` selects.
    pub fn write(
        &mut self,
        base: u16,
        offsets: Option<&[u32]>,
        values: &[u32],
        mask: &[bool],
    ) -> Result<(), ContractError> {
        self.write_for::<0>(base, offsets, values, mask)
    }

    /// [`write`](Self::write) compiled for `L` lanes ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn write_for<const L: usize>(
        &mut self,
        base: u16,
        offsets: Option<&[u32]>,
        values: &[u32],
        mask: &[bool],
    ) -> Result<(), ContractError> {
        self.addresses::<L>(base, offsets, mask)?;
        let addrs = &self.addr_scratch;
        self.write_addrs
            .insert_for::<L>(self.write_latency, 0, Some(mask), |v| {
                copy_lanes::<L>(v, addrs)
            })?;
        self.write_data
            .insert_for::<L>(self.write_latency, 0, None, |v| copy_lanes::<L>(v, values))?;
        self.probes.last = Some(true);
        if self.probes.tracing {
            self.probes.last_addr.copy_from_slice(&self.addr_scratch);
            self.probes.last_data.copy_from_slice(values);
        }
        Ok(())
    }

    /// The read result leaving this cycle.
    #[inline]
    pub fn completed(&self) -> Option<&InFlight> {
        self.reads.current()
    }

    /// Accesses still in flight.
    pub fn in_flight(&self) -> usize {
        self.reads.in_flight() + self.write_addrs.in_flight()
    }

    /// Brings a scratchpad with nothing in flight and no access this cycle over `n ≥ 1`
    /// cycles, as `n` commits would: the delay lines turn, the probe latch clears.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.in_flight() == 0 && self.write_data.in_flight() == 0 && n > 0);
        debug_assert!(!self.accessed);
        self.reads.skip_idle(n);
        self.write_addrs.skip_idle(n);
        self.write_data.skip_idle(n);
        self.probes.last = None;
    }

    pub fn commit(&mut self) {
        // A write issued with latency L becomes visible to reads L cycles after its issue, so
        // it lands at the edge before the cycle in which its delay line releases it.
        #[cfg(feature = "inject-bugs")]
        let landing =
            if imagine_hdl::inject::active(imagine_hdl::inject::Bug::ScratchpadWriteLandsLate) {
                (self.write_addrs.current(), self.write_data.current())
            } else {
                (self.write_addrs.due_next(), self.write_data.due_next())
            };
        #[cfg(not(feature = "inject-bugs"))]
        let landing = (self.write_addrs.due_next(), self.write_data.due_next());
        if let (Some(a), Some(d)) = landing {
            for c in 0..self.lanes {
                if a.mask[c] {
                    self.data[a.values[c] as usize * self.lanes + c] = d.values[c];
                }
            }
        }
        self.reads.commit();
        self.write_addrs.commit();
        self.write_data.commit();
        if !std::mem::take(&mut self.accessed) {
            self.probes.last = None;
        }
    }

    /// The committed word at `addr` in cluster `lane` (for inspection and tests).
    /// Whether a tracer is attached (see [`imagine_hdl::Module::set_tracing`]): without one
    /// the addresses and data of each access are not latched for the probes.
    pub fn set_tracing(&mut self, on: bool) {
        self.probes.tracing = on;
    }

    pub fn peek(&self, addr: usize, lane: usize) -> u32 {
        self.data[addr * self.lanes + lane]
    }

    pub fn trace(&self, t: &mut Trace) {
        let p = &self.probes;
        t.value(p.access, p.last.is_some() as u64);
        t.value(p.write, (p.last == Some(true)) as u64);
        for c in 0..self.lanes {
            t.value(
                p.lane_addr[c],
                p.last_addr[c] as u64 & ((1 << bits_for(self.words as u64 - 1)) - 1),
            );
            t.value(p.lane_data[c], p.last_data[c] as u64);
        }
    }
}
