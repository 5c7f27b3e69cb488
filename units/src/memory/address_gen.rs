//! An address generator (ARCHITECTURE §4: 2 on gold8): runs one stream memory operation at
//! a time, between SDRAM and the SRF, through SRF stream buffers.
//!
//! * **Patterns**: strided (`base + i·stride + j` for word `j` of record `i`), record
//!   (the same with `record_words > 1`: several consecutive words per element), and
//!   indexed gather/scatter (`base + index[i]·scale + j`, the indices read from an index
//!   stream in the SRF through a second stream buffer).
//! * **Loads** (memory → SRF): up to `memory.ag_words_per_cycle` word references issue per
//!   core cycle, in stream order, each to the request FIFO of the channel its address maps
//!   to (a reference waits while that FIFO is full or already took one this cycle, and holds
//!   back the ones behind it). Replies come back in any order; the reorder buffer
//!   (`memory.ag_reorder_words` words, which also bounds the references outstanding) puts
//!   them back in stream order, and up to `ag_words_per_cycle` words per cycle enter the
//!   data stream buffer through the SRF's memory port. When every word is in, the stream
//!   buffer is flushed into the SRF; the operation is over once it has drained.
//! * **Stores** (SRF → memory): each reference takes its word from the data stream buffer
//!   (which the SRF fills ahead); the operation is over when every write has been
//!   acknowledged by its channel (performed by the SDRAM).
//!
//! Stream buffers: address generator `k` uses SB `n − 1 − 2k` for data and `n − 2 − 2k` for
//! indices (`n` = `srf.stream_buffers`), clear of the kernel's SBs `0..kernel_streams`.
//!
//! * **Cacheable loads** (with a [`TextureCache`]): each reference first looks in the
//!   cache. A hit (or a word already on its way) takes none of the generator's
//!   `ag_words_per_cycle` DRAM references, only the cache's hit bandwidth, and enters the
//!   reorder buffer at once; a miss is a DRAM reference and queues the rest of its line as
//!   fills, which issue ahead of the next references. Retiring into the stream buffer may
//!   then run at the cache's hit rate. Fills still queued when the operation ends keep the
//!   generator busy until they have issued (another generator may be waiting for them).
//!
//! The address path assumes a one-word burst (`dram.burst_words = 1`, the default): each
//! reference is one column access. Probes: `busy`, `issued`, `retired`, `outstanding`.

use std::collections::VecDeque;

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

use super::MemPorts;
use super::texture_cache::{Probe, TextureCache, Waiter};
use crate::dram::{Location, Reply, Request, Tag};
use crate::srf::Srf;

/// A line fill's reference tag: this bit set, the word address in the bits below.
const FILL_BIT: u32 = 1 << 31;
/// DRAM words a line fill's tag can address.
pub const FILL_ADDRESS_LIMIT: u64 = FILL_BIT as u64;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemOpKind {
    /// Memory → SRF.
    Load,
    /// SRF → memory.
    Store,
}

/// How a stream's element addresses are formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// Record `i` starts at `base + i·stride` words.
    Strided { stride: u64 },
    /// Record `i` starts at `base + index[i]·scale` words; the `records` indices are a
    /// stream at SRF word `index_start`. With a `bound` (a bounds register), every index
    /// must be below it — one at or past it stops the operation with an error — and the
    /// stream touches only the records below it, which the stream controller's scoreboard
    /// then tells apart from streams elsewhere in memory; without one it may touch any word.
    Indexed {
        index_start: usize,
        scale: u64,
        bound: Option<u64>,
    },
}

/// A stream memory operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemOp {
    pub kind: MemOpKind,
    /// DRAM word address of record 0 (byte address / 4).
    pub base: u64,
    pub pattern: Pattern,
    /// Words per record (1: a plain strided or indexed stream).
    pub record_words: usize,
    pub records: usize,
    /// First SRF word of the stream (a block boundary).
    pub srf_start: usize,
    /// How records are laid out in the SRF: 1 for one record after another; `C` (the
    /// cluster count) for the layout kernels read, where each row of `C` records is stored
    /// word by word (record `i`'s word `j` at `(i / C)·k·C + j·C + i mod C`, `k` words per
    /// record), so that each cluster receives whole records. `records` must then be a
    /// multiple of `C`. The generator simply issues its references in that order.
    pub row_records: usize,
    /// A load the texture cache may serve (the stream program marks read-only data only).
    pub cacheable: bool,
}

impl MemOp {
    /// Words the operation moves.
    pub fn words(&self) -> usize {
        self.records * self.record_words
    }

    /// The DRAM words it may touch, `[lo, hi)`; `None` for an indexed stream without a
    /// bound (anywhere).
    pub fn mem_range(&self) -> Option<(u64, u64)> {
        match self.pattern {
            Pattern::Strided { stride } if self.records > 0 => Some((
                self.base,
                self.base + (self.records as u64 - 1) * stride + self.record_words as u64,
            )),
            Pattern::Strided { .. } => Some((self.base, self.base)),
            Pattern::Indexed {
                scale,
                bound: Some(bound),
                ..
            } if self.records > 0 && bound > 0 => Some((
                self.base,
                self.base + (bound - 1) * scale + self.record_words as u64,
            )),
            Pattern::Indexed { bound: Some(_), .. } => Some((self.base, self.base)),
            Pattern::Indexed { bound: None, .. } => None,
        }
    }

    /// Record and word of the stream's `n`-th reference (in SRF order).
    pub fn reference(&self, n: usize) -> (usize, usize) {
        let (k, r) = (self.record_words, self.row_records.max(1));
        let (row, within) = (n / (k * r), n % (k * r));
        (row * r + within % r, within / r)
    }

    /// The SRF index stream `[start, start + records)`, for an indexed stream.
    pub fn index_region(&self) -> Option<(usize, usize)> {
        match self.pattern {
            Pattern::Indexed { index_start, .. } => Some((index_start, self.records)),
            Pattern::Strided { .. } => None,
        }
    }
}

/// Counters of one address generator.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AgStats {
    pub ops: u64,
    pub words: u64,
    pub busy_cycles: u64,
}

#[derive(Debug)]
pub struct AddressGenerator {
    id: u8,
    path: String,
    sb: usize,
    isb: usize,
    width: usize,
    window: usize,
    op: Option<MemOp>,
    issued: usize,
    retired: usize,
    rob: Vec<Option<u32>>,
    /// The DRAM word each reorder slot waits for (cacheable loads: its reply fills the
    /// cache).
    rob_words: Vec<u64>,
    /// Line fills waiting for a DRAM port (word addresses).
    fills: VecDeque<u64>,
    /// Indices of the current row's records (indexed streams).
    indices: Vec<u64>,
    indices_row: Option<usize>,
    /// The last byte address mapped and its location: a reference that waits for a port
    /// is mapped once, not in every cycle it waits.
    mapped: Option<(u64, Location)>,
    flushing: bool,
    /// The operation ended at the last edge.
    finished: bool,
    buf: Vec<u32>,
    stats: AgStats,
    ids: [SignalId; 4],
}

impl AddressGenerator {
    /// Address generator `id` of a machine with `stream_buffers` SBs.
    pub fn new(
        scope: &mut Scope<'_>,
        id: usize,
        stream_buffers: usize,
        width: usize,
        window: usize,
    ) -> Self {
        let count = bits_for(u32::MAX as u64);
        AddressGenerator {
            id: id as u8,
            path: scope.path().to_string(),
            sb: stream_buffers - 1 - 2 * id,
            isb: stream_buffers - 2 - 2 * id,
            width,
            window,
            op: None,
            issued: 0,
            retired: 0,
            rob: vec![None; window],
            rob_words: vec![0; window],
            fills: VecDeque::new(),
            indices: Vec::new(),
            indices_row: None,
            mapped: None,
            flushing: false,
            finished: false,
            buf: Vec::with_capacity(width),
            stats: AgStats::default(),
            ids: [
                scope.signal("busy", 1, SignalKind::Reg),
                scope.signal("issued", count, SignalKind::Reg),
                scope.signal("retired", count, SignalKind::Reg),
                scope.signal("outstanding", bits_for(window as u64), SignalKind::Reg),
            ],
        }
    }

    /// Running an operation, or still issuing the line fills of one.
    pub fn is_busy(&self) -> bool {
        self.op.is_some() || !self.fills.is_empty()
    }

    /// Brings an idle generator over `n ≥ 1` cycles with no operation started, as their
    /// edges would: only the end-of-operation flag clears.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(!self.is_busy() && n > 0);
        self.finished = false;
    }

    /// Whether an operation ended at the last edge (and it is free again).
    pub fn just_finished(&self) -> bool {
        self.finished
    }

    pub fn stats(&self) -> &AgStats {
        &self.stats
    }

    /// Starts `op` (between cycles): binds its stream buffers.
    pub fn start(&mut self, op: MemOp, srf: &mut Srf) -> Result<(), ContractError> {
        if self.op.is_some() {
            return Err(self.error("start", "an operation is already running".into()));
        }
        if op.row_records > 1 && !op.records.is_multiple_of(op.row_records) {
            return Err(self.error(
                "start",
                format!(
                    "{} records do not fill rows of {} (a cluster-row layout needs whole rows)",
                    op.records, op.row_records
                ),
            ));
        }
        match op.kind {
            MemOpKind::Load => srf.bind_output(self.sb, op.srf_start, op.words())?,
            MemOpKind::Store => srf.bind_input(self.sb, op.srf_start, op.words())?,
        }
        if let Some((start, len)) = op.index_region() {
            srf.bind_input(self.isb, start, len)?;
        }
        self.op = Some(op);
        self.issued = 0;
        self.retired = 0;
        self.indices.clear();
        self.indices_row = None;
        self.flushing = false;
        self.stats.ops += 1;
        Ok(())
    }

    /// A reply for this generator (read data or a write acknowledgement). Returns the DRAM
    /// word and its value when the word belongs in the texture cache (a cacheable load's
    /// word or a line fill, which may arrive after its operation ended).
    pub fn accept(&mut self, r: &Reply) -> Result<Option<(u64, u32)>, ContractError> {
        if r.tag.seq & FILL_BIT != 0 {
            return Ok(Some(((r.tag.seq & !FILL_BIT) as u64, r.data[0])));
        }
        let Some(op) = self.op else {
            return Err(self.error("reply", "a reply arrived with no operation running".into()));
        };
        match op.kind {
            MemOpKind::Load => {
                let slot = r.tag.seq as usize % self.window;
                self.deliver(slot, r.data[0])?;
                Ok(op.cacheable.then_some((self.rob_words[slot], r.data[0])))
            }
            MemOpKind::Store => {
                self.retired += 1;
                Ok(None)
            }
        }
    }

    /// Puts a loaded word into reorder slot `slot` (from DRAM, or from the texture cache
    /// for a reference that waited for a line on its way).
    pub fn deliver(&mut self, slot: usize, word: u32) -> Result<(), ContractError> {
        if self.rob[slot].is_some() {
            return Err(self.error("reply", format!("reorder slot {slot} taken twice")));
        }
        self.rob[slot] = Some(word);
        Ok(())
    }

    fn error(&self, what: &str, msg: String) -> ContractError {
        ContractError::at(&format!("{}.{what}", self.path), Violation::Other(msg))
    }

    /// One core cycle: retire load data into the stream buffer, issue line fills, then
    /// references (looking cacheable loads up in `cache` first).
    pub fn eval(
        &mut self,
        srf: &mut Srf,
        ports: &mut MemPorts,
        mut cache: Option<&mut TextureCache>,
    ) -> Result<(), ContractError> {
        let mut port_slots = self.width;
        self.issue_fills(ports, &mut port_slots)?;
        let Some(op) = self.op else { return Ok(()) };
        self.stats.busy_cycles += 1;
        let words = op.words();
        let cached = op.cacheable && op.kind == MemOpKind::Load && cache.is_some();
        if op.kind == MemOpKind::Load {
            let width = match &cache {
                Some(c) if cached => self.width.max(c.hit_words_per_cycle()),
                _ => self.width,
            };
            self.buf.clear();
            let room = srf.space(self.sb).min(width);
            while self.buf.len() < room && self.retired + self.buf.len() < words {
                let slot = (self.retired + self.buf.len()) % self.window;
                match self.rob[slot].take() {
                    Some(w) => self.buf.push(w),
                    None => break,
                }
            }
            if !self.buf.is_empty() {
                srf.memory_write(self.sb, &self.buf)?;
                self.retired += self.buf.len();
                self.stats.words += self.buf.len() as u64;
            }
            if self.retired == words && !self.flushing {
                srf.flush(self.sb)?;
                self.flushing = true;
            }
        }
        // Each pass issues one reference or stops: DRAM references are bounded by the
        // generator's width, cache hits by the cache's bandwidth.
        loop {
            if self.issued == words || self.issued - self.retired >= self.window {
                break;
            }
            let (rec, j) = op.reference(self.issued);
            let start = match op.pattern {
                Pattern::Strided { stride } => op.base + rec as u64 * stride,
                Pattern::Indexed { scale, bound, .. } => {
                    // A row's indices arrive in its first word's pass, one per record.
                    let rows = op.row_records.max(1);
                    let (row, in_row) = (rec / rows, rec % rows);
                    if self.indices_row != Some(row) {
                        self.indices.clear();
                        self.indices_row = Some(row);
                    }
                    if j == 0 && self.indices.len() == in_row {
                        if srf.available(self.isb) == 0 {
                            break;
                        }
                        let index = srf.memory_read(self.isb, 1)?[0] as u64;
                        if let Some(bound) = bound
                            && index >= bound
                        {
                            return Err(self.error(
                                "index",
                                format!(
                                    "record {rec} of the stream has index {index}, past its \
                                     bound {bound}"
                                ),
                            ));
                        }
                        self.indices.push(index);
                    }
                    op.base + self.indices[in_row] * scale
                }
            };
            let j = j as u64;
            #[cfg(feature = "inject-bugs")]
            let j =
                if imagine_hdl::inject::active(imagine_hdl::inject::Bug::AgDropsRecordWordOffset) {
                    0
                } else {
                    j
                };
            let word = start + j;
            let byte = word * 4;
            let loc = match self.mapped {
                Some((b, loc)) if b == byte => loc,
                _ => {
                    let Some(loc) = ports.params().map(byte) else {
                        return Err(self.error(
                            "address",
                            format!(
                                "word {} of the stream is at byte address {byte:#x}, past the end of memory ({} bytes)",
                                self.issued,
                                ports.params().capacity_bytes()
                            ),
                        ));
                    };
                    self.mapped = Some((byte, loc));
                    loc
                }
            };
            let slot = self.issued % self.window;
            if let Some(c) = cache.as_deref_mut().filter(|_| cached) {
                match c.probe(word) {
                    Probe::Miss => {}
                    probe => {
                        if !c.claim_hit() {
                            break;
                        }
                        match probe {
                            Probe::Hit(v) => self.rob[slot] = Some(v),
                            _ => c.wait(Waiter {
                                ag: self.id as usize,
                                slot,
                                word,
                            }),
                        }
                        self.issued += 1;
                        continue;
                    }
                }
            }
            if port_slots == 0 || !ports.can_push(loc.channel) {
                break;
            }
            let mut data = [0u32; 8];
            if op.kind == MemOpKind::Store {
                if srf.available(self.sb) == 0 {
                    break;
                }
                data[0] = srf.memory_read(self.sb, 1)?[0];
                self.stats.words += 1;
                if let Some(c) = cache.as_deref_mut() {
                    c.invalidate(word);
                }
            }
            ports.push(
                loc.channel,
                Request {
                    write: op.kind == MemOpKind::Store,
                    byte_addr: byte,
                    data,
                    tag: Tag {
                        source: self.id,
                        seq: self.issued as u32,
                    },
                },
            )?;
            if let Some(c) = cache.as_deref_mut().filter(|_| cached) {
                self.rob_words[slot] = word;
                // The rest of the line, as far as the stream may touch and memory goes.
                let (lo, hi) = op.mem_range().unwrap_or((0, u64::MAX));
                let first = word - word % c.line_words();
                let line = (first..first + c.line_words())
                    .filter(|&w| (lo..hi).contains(&w) && ports.params().map(w * 4).is_some());
                c.miss(word, line.clone());
                self.fills.extend(line.filter(|&w| w != word));
            }
            port_slots -= 1;
            self.issued += 1;
        }
        Ok(())
    }

    /// Issues queued line fills, each taking one of this cycle's DRAM references.
    fn issue_fills(
        &mut self,
        ports: &mut MemPorts,
        port_slots: &mut usize,
    ) -> Result<(), ContractError> {
        while *port_slots > 0
            && let Some(&word) = self.fills.front()
        {
            let loc = ports
                .params()
                .map(word * 4)
                .expect("fills are queued in memory");
            if !ports.can_push(loc.channel) {
                break;
            }
            ports.push(
                loc.channel,
                Request {
                    write: false,
                    byte_addr: word * 4,
                    data: [0; 8],
                    tag: Tag {
                        source: self.id,
                        seq: FILL_BIT | word as u32,
                    },
                },
            )?;
            self.fills.pop_front();
            *port_slots -= 1;
        }
        Ok(())
    }

    /// The clock edge (after the SRF's): ends a finished operation and frees its stream
    /// buffers.
    pub fn commit(&mut self, srf: &mut Srf) -> Result<(), ContractError> {
        self.finished = false;
        let Some(op) = self.op else { return Ok(()) };
        let done = match op.kind {
            MemOpKind::Load => self.flushing && srf.flushed(self.sb),
            MemOpKind::Store => self.retired == op.words(),
        };
        if done {
            srf.unbind(self.sb)?;
            if op.index_region().is_some() {
                srf.unbind(self.isb)?;
            }
            self.op = None;
            self.finished = true;
        }
        Ok(())
    }

    pub fn trace(&self, t: &mut Trace) {
        t.value(self.ids[0], self.op.is_some() as u64);
        t.value(self.ids[1], self.issued as u64 & 0xFFFF_FFFF);
        t.value(self.ids[2], self.retired as u64 & 0xFFFF_FFFF);
        t.value(self.ids[3], (self.issued - self.retired) as u64);
    }
}
