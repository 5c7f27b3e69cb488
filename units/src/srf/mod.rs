//! The stream register file (SRF) and its stream buffers (ARCHITECTURE §4, SRF row).
//!
//! The SRF is the machine's central on-chip stream storage: `srf.words` 32-bit words
//! (gold8: 32K words, 128 KB) in `srf.banks` banks, interleaved by block — block `b`
//! (`srf.block_words` words, 32 on gold8) lives in bank `b % banks`. Streams start on block
//! boundaries. Nothing reaches the SRF array except through a *stream buffer* (SB); the
//! single SRF port moves at most `srf.words_per_cycle` words per cycle (16 on gold8), and an
//! arbiter grants it to one SB per cycle.
//!
//! # Sides
//!
//! * **Host / stream controller** (between cycles, not clocked): [`Srf::load`] and
//!   [`Srf::read_back`] move whole streams in and out of the array (tests, and the memory
//!   system until it has stream buffers of its own); [`Srf::bind_input`],
//!   [`Srf::bind_output`] and [`Srf::unbind`] attach SBs to streams at kernel start and end.
//! * **Clusters** (lane-batched: one call serves every cluster): an input stream is read
//!   `lanes` words at a time, element `i·lanes + c` going to cluster `c`, so a read of `n`
//!   words (a multiple of `lanes`) hands cluster `c` the words `c, lanes + c, …` of the
//!   returned slice. [`Srf::available`] / [`Srf::read`] on input SBs, [`Srf::space`] /
//!   [`Srf::write`] on output SBs, [`Srf::flush`] at kernel end; the `_conditional` variants
//!   are the conditional-stream accesses (any word count, their own bandwidth limit).
//! * **Clock**: [`Srf::eval`] (the arbiter decides this cycle's transfer from committed
//!   state) and [`Srf::commit`] (the clock edge) once per core cycle; [`Srf::trace`] after
//!   the edge when tracing.
//!
//! # Cycle protocol
//!
//! Two-phase, like every `hdl` module. During a cycle the clusters' reads and writes and the
//! arbiter's decision all see the state committed at the last edge, so they may happen in
//! any order:
//!
//! * a read takes words that were visible at the start of the cycle ([`Srf::available`]
//!   counts down as the cycle's reads take them); the room they free is seen by the arbiter
//!   from the next cycle on;
//! * a write fills free room seen at the start of the cycle; the words become drainable
//!   from the next cycle on;
//! * `flush` takes effect at the edge (a write in the same cycle as the flush is part of
//!   the stream, whichever call comes first);
//! * the granted transfer is applied at the edge: words moved into an input SB are visible
//!   to the clusters the next cycle (SRF→SB latency 1; the SB→LRF latency `latency.stream`
//!   belongs to the cluster side).
//!
//! # The arbiter and transfers
//!
//! A transfer moves up to `words_per_cycle` words between one SB and the SRF and never
//! crosses a multiple of `words_per_cycle` in SRF addresses (an aligned *line*; on gold8 a
//! line is half a 32-word block, so a transfer stays inside one block and one bank; where
//! `words_per_cycle > block_words` (gold32: 64 vs 32) a line spans consecutive blocks, which
//! sit in consecutive banks). Requests, from committed state:
//!
//! * an input SB requests the rest of the current line (capped at the stream's end) when it
//!   has room for all of it and words remain to be fetched;
//! * an output SB requests the current line once it holds all of it; once flushing, it
//!   requests whatever it holds (up to the end of the line).
//!
//! One SB is granted per cycle, round robin over SB indices (the SB after the last one
//! granted has the highest priority; see `arbiter`). **Simplification:** bank conflicts
//! are not modelled beyond "one grant per cycle, one line per grant"; a lone SB whose
//! stream starts off a line boundary, or a short stream's last partial line, uses the port
//! for a cycle at less than its width, as the hardware would.
//!
//! # Stream-buffer capacity
//!
//! Each SB holds `2 × max(words_per_cycle, lanes × cluster_words_per_cycle,
//! lanes × conditional_words_per_cycle)` words ([`Srf::sb_capacity`]; gold8: 2 × max(16,
//! 32, 8) = 64, i.e. 8 words per cluster). Reasons: one cluster-side access of the largest
//! legal size must fit, and the buffer is double-buffered — it can hold one such access
//! while the port refills or drains another. With at least two port lines of room a lone
//! input SB requests a line every cycle the clusters drain one, so it streams at the full
//! port rate (16 words/cycle), and an SB read at one row (8 words) per cycle has 48 words
//! (6 cycles) of slack against arbitration delay before its clusters would stall.
//!
//! # Contract errors
//!
//! Every misuse is a [`ContractError`] located under the SRF's scope, raised before any
//! state changes: `<srf>.load` / `<srf>.read_back` (misaligned start, past the end of the
//! array), `<srf>.bind` (no such SB), `<srf>.sbN.bind` (misaligned, out of range, already
//! bound, output region overlapping another output), `<srf>.sbN.read` / `.write` (wrong
//! mode, past the end of the stream, more than available / space, an unconditional access
//! not a multiple of `lanes`, overflowing the bound output region, writing after flush, and
//! the per-cycle cluster bandwidth: all unconditional reads and writes of one cycle
//! together at most `cluster_words_per_cycle × lanes` words, conditional ones at most
//! `conditional_words_per_cycle × lanes`), `<srf>.sbN.flush`, `<srf>.sbN.unbind` (an output
//! stream not yet flushed into the SRF).
//!
//! # Cost
//!
//! No allocation after construction; `eval` and `commit` visit only the bound SBs; the
//! clusters get slices into the SB's ring; probes are only touched by `trace`.

mod arbiter;
mod stream_buffer;

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

use crate::desc::MachineDesc;
use arbiter::RoundRobin;
pub use stream_buffer::SbMode;
use stream_buffer::StreamBuffer;

/// The SRF port's transfer in one cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grant {
    /// The stream buffer served.
    pub sb: usize,
    /// Words moved (1..=`words_per_cycle`).
    pub words: usize,
}

/// Counters of one stream buffer, accumulated over every stream it was bound to.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SbStats {
    /// Streams bound to it.
    pub streams: u64,
    /// Transfers granted to it, and the words they moved through the SRF port.
    pub grants: u64,
    pub srf_words: u64,
    /// Words the clusters read from it or wrote into it.
    pub cluster_words: u64,
    /// Cycles it requested the port (granted or not).
    pub requested_cycles: u64,
    /// Cycles an input SB with words still to deliver could not serve a full row
    /// (`lanes` words, or the rest of the stream) from what it held: the clusters would
    /// have stalled had they wanted it. (Whether they did is the machine's to count, from
    /// [`Srf::available`].)
    pub starved_cycles: u64,
    /// Cycles an output SB (not yet flushing) had room for less than a row.
    pub blocked_cycles: u64,
}

impl SbStats {
    /// Cycles it requested the port and another SB was granted.
    pub fn waited_cycles(&self) -> u64 {
        self.requested_cycles - self.grants
    }
}

/// SRF counters. Everything counts cycles that were committed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SrfStats {
    pub cycles: u64,
    /// Transfers through the SRF port (at most one per cycle).
    pub grants: u64,
    /// Words moved through the SRF port.
    pub words_moved: u64,
    /// `words_histogram[k]`: cycles in which the port moved `k` words.
    pub words_histogram: Vec<u64>,
    /// Per stream buffer.
    pub sb: Vec<SbStats>,
}

impl SrfStats {
    /// Mean words moved through the SRF port per cycle.
    pub fn words_per_cycle(&self) -> f64 {
        if self.cycles == 0 {
            0.0
        } else {
            self.words_moved as f64 / self.cycles as f64
        }
    }
}

/// Probe handles: per SB `level` and `mode`, and the arbiter's last grant.
#[derive(Clone, Debug)]
struct Probes {
    sb: Vec<(SignalId, SignalId)>,
    grant: SignalId,
    grant_valid: SignalId,
    words: SignalId,
}

/// The stream register file with its stream buffers and port arbiter.
#[derive(Clone, Debug)]
pub struct Srf {
    path: String,
    machine: String,
    lanes: usize,
    banks: usize,
    block_words: usize,
    /// Port width, words per cycle (the transfer line).
    line: usize,
    sb_cap: usize,
    /// Per-cycle cluster-side limits (all SBs together), and what this cycle used.
    uncond_limit: usize,
    cond_limit: usize,
    uncond_used: usize,
    cond_used: usize,
    cluster_words_per_cycle: usize,
    conditional_words_per_cycle: usize,
    storage: Vec<u32>,
    sbs: Vec<StreamBuffer>,
    /// Indices of the bound SBs, ascending.
    active: Vec<usize>,
    rr: RoundRobin,
    /// This cycle's grant, decided by `eval`.
    grant: Option<Grant>,
    /// The grant of the cycle that ended at the last edge (for probes).
    last: Option<Grant>,
    stats: SrfStats,
    probes: Probes,
}

impl Srf {
    /// The SRF of `desc` (`srf` section, `cluster.count` lanes) with its probes under
    /// `scope` (e.g. `top.srf`): `sbN.level`, `sbN.mode` for every SB, and
    /// `arbiter.grant`, `arbiter.grant_valid`, `arbiter.words`.
    pub fn new(scope: &mut Scope<'_>, desc: &MachineDesc) -> Self {
        let s = &desc.srf;
        let lanes = desc.cluster.count;
        let uncond_limit = s.cluster_words_per_cycle * lanes;
        let cond_limit = s.conditional_words_per_cycle * lanes;
        let sb_cap = 2 * s.words_per_cycle.max(uncond_limit).max(cond_limit);
        let level_bits = bits_for(sb_cap as u64);
        let sb = (0..s.stream_buffers)
            .map(|i| {
                let mut c = scope.child(&format!("sb{i}"));
                (
                    c.signal("level", level_bits, SignalKind::Reg),
                    c.signal("mode", 2, SignalKind::Reg),
                )
            })
            .collect();
        let mut arb = scope.child("arbiter");
        let probes = Probes {
            sb,
            grant: arb.signal("grant", bits_for(s.stream_buffers as u64), SignalKind::Reg),
            grant_valid: arb.signal("grant_valid", 1, SignalKind::Reg),
            words: arb.signal("words", bits_for(s.words_per_cycle as u64), SignalKind::Reg),
        };
        Srf {
            path: scope.path().to_string(),
            machine: desc.name.clone(),
            lanes,
            banks: s.banks,
            block_words: s.block_words,
            line: s.words_per_cycle,
            sb_cap,
            uncond_limit,
            cond_limit,
            uncond_used: 0,
            cond_used: 0,
            cluster_words_per_cycle: s.cluster_words_per_cycle,
            conditional_words_per_cycle: s.conditional_words_per_cycle,
            storage: vec![0; s.words],
            sbs: (0..s.stream_buffers)
                .map(|_| StreamBuffer::new(sb_cap))
                .collect(),
            active: Vec::with_capacity(s.stream_buffers),
            rr: RoundRobin::new(s.stream_buffers),
            grant: None,
            last: None,
            stats: SrfStats {
                words_histogram: vec![0; s.words_per_cycle + 1],
                sb: vec![SbStats::default(); s.stream_buffers],
                ..SrfStats::default()
            },
            probes,
        }
    }

    // ---- parameters ----------------------------------------------------------------------

    /// The scope path the probes and errors are under.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Clusters served by one access.
    pub fn lanes(&self) -> usize {
        self.lanes
    }

    /// Capacity of the SRF array in words.
    pub fn words(&self) -> usize {
        self.storage.len()
    }

    pub fn block_words(&self) -> usize {
        self.block_words
    }

    pub fn stream_buffers(&self) -> usize {
        self.sbs.len()
    }

    /// Words one stream buffer holds (see the module doc for the choice).
    pub fn sb_capacity(&self) -> usize {
        self.sb_cap
    }

    /// The SRF port's words per cycle (also the largest transfer).
    pub fn words_per_cycle(&self) -> usize {
        self.line
    }

    /// The bank holding SRF word `addr` (blocks are interleaved across banks).
    pub fn bank_of(&self, addr: usize) -> usize {
        (addr / self.block_words) % self.banks
    }

    // ---- host / stream-controller side --------------------------------------------------

    /// Writes `data` into the SRF array from word `start` (a block boundary).
    pub fn load(&mut self, start: usize, data: &[u32]) -> Result<(), ContractError> {
        self.check_region("load", start, data.len())?;
        self.storage[start..start + data.len()].copy_from_slice(data);
        Ok(())
    }

    /// The `len` words of the SRF array from word `start` (a block boundary).
    pub fn read_back(&self, start: usize, len: usize) -> Result<Vec<u32>, ContractError> {
        self.check_region("read_back", start, len)?;
        Ok(self.storage[start..start + len].to_vec())
    }

    fn check_region(&self, what: &str, start: usize, len: usize) -> Result<(), ContractError> {
        let problem = self.region_problem(start, len);
        match problem {
            None => Ok(()),
            Some(p) => Err(self.error(
                None,
                what,
                format!("{what} of {len} words at word {start}: {p}"),
            )),
        }
    }

    /// Why the region `[start, start + len)` cannot hold a stream, if it cannot.
    fn region_problem(&self, start: usize, len: usize) -> Option<String> {
        let words = self.storage.len();
        if !start.is_multiple_of(self.block_words) {
            Some(format!(
                "start {start} is not on a {}-word block boundary",
                self.block_words
            ))
        } else if start.checked_add(len).is_none_or(|end| end > words) {
            Some(format!(
                "[{start}, {start} + {len}) runs past the end of the SRF (capacity {words} \
                 words)"
            ))
        } else {
            None
        }
    }

    /// Binds stream buffer `sb` to the input stream of `len` words at SRF word `start`.
    /// The SB starts fetching at the next `eval`.
    pub fn bind_input(&mut self, sb: usize, start: usize, len: usize) -> Result<(), ContractError> {
        self.bind(sb, SbMode::Input, start, len)
    }

    /// Binds stream buffer `sb` to an output stream written into the region of `capacity`
    /// words at SRF word `start`.
    pub fn bind_output(
        &mut self,
        sb: usize,
        start: usize,
        capacity: usize,
    ) -> Result<(), ContractError> {
        self.bind(sb, SbMode::Output, start, capacity)
    }

    fn bind(
        &mut self,
        sb: usize,
        mode: SbMode,
        start: usize,
        len: usize,
    ) -> Result<(), ContractError> {
        let what = if mode == SbMode::Input {
            "input stream"
        } else {
            "output region"
        };
        if sb >= self.sbs.len() {
            return Err(self.error(
                None,
                "bind",
                format!(
                    "stream buffer {sb} does not exist: `{}` has {} (sb0..sb{})",
                    self.machine,
                    self.sbs.len(),
                    self.sbs.len() - 1
                ),
            ));
        }
        if self.sbs[sb].mode != SbMode::Idle {
            let b = &self.sbs[sb];
            return Err(self.error(
                Some(sb),
                "bind",
                format!(
                    "sb{sb} is already bound ({:?}, {} words at word {}); unbind it first",
                    b.mode, b.len, b.start
                ),
            ));
        }
        if let Some(p) = self.region_problem(start, len) {
            return Err(self.error(
                Some(sb),
                "bind",
                format!("sb{sb}: {what} of {len} words at word {start}: {p}"),
            ));
        }
        if mode == SbMode::Output
            && let Some(&o) = self.active.iter().find(|&&o| {
                let b = &self.sbs[o];
                b.mode.is_output() && start < b.start + b.len && b.start < start + len
            })
        {
            let b = &self.sbs[o];
            return Err(self.error(
                Some(sb),
                "bind",
                format!(
                    "sb{sb}: output region [{start}, {}) overlaps sb{o}'s output region \
                     [{}, {})",
                    start + len,
                    b.start,
                    b.start + b.len
                ),
            ));
        }
        self.sbs[sb].bind(mode, start, len, self.line);
        let at = self.active.partition_point(|&i| i < sb);
        self.active.insert(at, sb);
        self.stats.sb[sb].streams += 1;
        Ok(())
    }

    /// Releases stream buffer `sb`. An input stream may be released with words unread; an
    /// output stream only once flushed into the SRF.
    pub fn unbind(&mut self, sb: usize) -> Result<(), ContractError> {
        let b = self.sb(sb, "unbind")?;
        if b.mode == SbMode::Idle {
            return Err(self.error(Some(sb), "unbind", format!("sb{sb} is not bound")));
        }
        if !b.flushed() {
            let held = b.level + b.pending;
            let msg = if b.mode == SbMode::Output {
                format!(
                    "sb{sb}: output stream not flushed ({held} words still buffered); call \
                     flush and clock until flushed"
                )
            } else {
                format!("sb{sb}: flush still in progress ({held} words not yet in the SRF)")
            };
            return Err(self.error(Some(sb), "unbind", msg));
        }
        self.sbs[sb].unbind();
        self.active.retain(|&i| i != sb);
        if self.grant.is_some_and(|g| g.sb == sb) {
            self.grant = None;
        }
        Ok(())
    }

    /// What stream buffer `sb` is bound to.
    pub fn mode(&self, sb: usize) -> SbMode {
        self.sbs[sb].mode
    }

    fn sb(&self, sb: usize, what: &str) -> Result<&StreamBuffer, ContractError> {
        self.sbs.get(sb).ok_or_else(|| {
            self.error(
                None,
                what,
                format!(
                    "stream buffer {sb} does not exist: `{}` has {}",
                    self.machine,
                    self.sbs.len()
                ),
            )
        })
    }

    // ---- cluster side: input -------------------------------------------------------------

    /// Words an input SB can still deliver this cycle (visible at the start of the cycle,
    /// less what this cycle's reads took); 0 for an SB that is not an input.
    #[inline]
    pub fn available(&self, sb: usize) -> usize {
        let b = &self.sbs[sb];
        if b.mode == SbMode::Input {
            b.available()
        } else {
            0
        }
    }

    /// Words of an input stream not yet delivered to the clusters (this cycle's reads
    /// included).
    #[inline]
    pub fn remaining(&self, sb: usize) -> usize {
        let b = &self.sbs[sb];
        if b.mode == SbMode::Input {
            b.len - b.done - b.pending
        } else {
            0
        }
    }

    /// Whether every word of the input stream bound to `sb` has been delivered to the
    /// clusters (as of the last edge).
    #[inline]
    pub fn exhausted(&self, sb: usize) -> bool {
        let b = &self.sbs[sb];
        b.mode == SbMode::Input && b.done == b.len
    }

    /// Reads the next `n` words of the input stream on `sb` (an unconditional access: `n`
    /// a multiple of `lanes`, word `k·lanes + c` for cluster `c`).
    #[inline]
    pub fn read(&mut self, sb: usize, n: usize) -> Result<&[u32], ContractError> {
        self.read_access(sb, n, false)
    }

    /// Reads the next `n` words of the input stream on `sb` for a conditional stream (any
    /// `n`, within the conditional bandwidth).
    #[inline]
    pub fn read_conditional(&mut self, sb: usize, n: usize) -> Result<&[u32], ContractError> {
        self.read_access(sb, n, true)
    }

    #[inline]
    fn read_access(
        &mut self,
        sb: usize,
        n: usize,
        conditional: bool,
    ) -> Result<&[u32], ContractError> {
        let ok = match self.sbs.get(sb) {
            Some(b) => b.mode == SbMode::Input && n <= b.available(),
            None => false,
        };
        if !ok || !self.within_bandwidth(n, conditional) {
            return Err(self.read_error(sb, n, conditional));
        }
        self.charge(n, conditional);
        Ok(self.sbs[sb].take(n))
    }

    #[inline(always)]
    fn within_bandwidth(&self, n: usize, conditional: bool) -> bool {
        if conditional {
            self.cond_used + n <= self.cond_limit
        } else {
            self.uncond_used + n <= self.uncond_limit && self.multiple_of_lanes(n)
        }
    }

    /// `n % lanes == 0`, without a division for the usual power-of-two cluster counts.
    #[inline(always)]
    fn multiple_of_lanes(&self, n: usize) -> bool {
        if self.lanes.is_power_of_two() {
            n & (self.lanes - 1) == 0
        } else {
            n.is_multiple_of(self.lanes)
        }
    }

    #[inline(always)]
    fn charge(&mut self, n: usize, conditional: bool) {
        if conditional {
            self.cond_used += n;
        } else {
            self.uncond_used += n;
        }
    }

    // ---- memory side ---------------------------------------------------------------------

    /// The memory system's port on an input SB (a store stream: SRF → memory): takes the
    /// next `n` words, any count up to [`available`](Self::available). Unlike the
    /// clusters' reads it is not charged to the clusters' stream bandwidth and need not be
    /// a multiple of the cluster count; the address generator's own width limits it.
    pub fn memory_read(&mut self, sb: usize, n: usize) -> Result<&[u32], ContractError> {
        let ok =
            matches!(self.sbs.get(sb), Some(b) if b.mode == SbMode::Input && n <= b.available());
        if !ok {
            return Err(self.read_error(sb, n, false));
        }
        Ok(self.sbs[sb].take(n))
    }

    /// The memory system's port on an output SB (a load stream: memory → SRF): appends
    /// `words`, up to [`space`](Self::space), within the bound region; not charged to the
    /// clusters' stream bandwidth.
    pub fn memory_write(&mut self, sb: usize, words: &[u32]) -> Result<(), ContractError> {
        let n = words.len();
        let ok = matches!(self.sbs.get(sb), Some(b)
            if b.mode == SbMode::Output && n <= b.space() && b.done + b.pending + n <= b.len);
        if !ok {
            return Err(self.write_error(sb, n, false));
        }
        self.sbs[sb].put(words);
        Ok(())
    }

    // ---- cluster side: output ------------------------------------------------------------

    /// Free words an output SB can still accept this cycle; 0 for an SB that is not
    /// writable. This is buffer room only: writing past the bound region's capacity is an
    /// error, not a stall.
    #[inline]
    pub fn space(&self, sb: usize) -> usize {
        let b = &self.sbs[sb];
        if b.mode == SbMode::Output {
            b.space()
        } else {
            0
        }
    }

    /// Appends `words` to the output stream on `sb` (an unconditional access: a multiple of
    /// `lanes` words, word `k·lanes + c` from cluster `c`).
    #[inline]
    pub fn write(&mut self, sb: usize, words: &[u32]) -> Result<(), ContractError> {
        self.write_access(sb, words, false)
    }

    /// Appends `words` to the output stream on `sb` for a conditional stream.
    #[inline]
    pub fn write_conditional(&mut self, sb: usize, words: &[u32]) -> Result<(), ContractError> {
        self.write_access(sb, words, true)
    }

    #[inline]
    fn write_access(
        &mut self,
        sb: usize,
        words: &[u32],
        conditional: bool,
    ) -> Result<(), ContractError> {
        let n = words.len();
        let ok = match self.sbs.get(sb) {
            Some(b) => {
                b.mode == SbMode::Output && n <= b.space() && b.done + b.pending + n <= b.len
            }
            None => false,
        };
        if !ok || !self.within_bandwidth(n, conditional) {
            return Err(self.write_error(sb, n, conditional));
        }
        self.charge(n, conditional);
        self.sbs[sb].put(words);
        Ok(())
    }

    /// Ends the output stream on `sb`: from the next cycle the SB drains everything it
    /// holds, including a last partial line. Writes in this same cycle still count.
    pub fn flush(&mut self, sb: usize) -> Result<(), ContractError> {
        let b = self.sb(sb, "flush")?;
        if !b.mode.is_output() {
            return Err(self.error(
                Some(sb),
                "flush",
                format!("sb{sb} is {}, not an output stream", mode_name(b.mode)),
            ));
        }
        if b.mode == SbMode::Output {
            self.sbs[sb].flush_req = true;
        }
        Ok(())
    }

    /// Whether nothing written to `sb` remains outside the SRF: true unless `sb` is an
    /// output SB not yet flushed, or flushing with words left.
    pub fn flushed(&self, sb: usize) -> bool {
        self.sbs[sb].flushed()
    }

    /// Words the clusters have written to the output stream on `sb` (as of the last edge).
    pub fn output_len(&self, sb: usize) -> usize {
        let b = &self.sbs[sb];
        if b.mode.is_output() { b.done } else { 0 }
    }

    /// Whether every bound output SB has been flushed into the SRF (input SBs may still be
    /// prefetching).
    pub fn idle(&self) -> bool {
        self.active.iter().all(|&i| self.sbs[i].flushed())
    }

    /// Unconditional and conditional words the clusters may still move this cycle.
    pub fn cluster_words_left(&self) -> (usize, usize) {
        (
            self.uncond_limit - self.uncond_used,
            self.cond_limit - self.cond_used,
        )
    }

    // ---- clock ---------------------------------------------------------------------------

    /// The arbiter: decides this cycle's transfer from committed state. Call once per cycle,
    /// before [`commit`](Self::commit); its order relative to the clusters' accesses does
    /// not matter.
    #[inline]
    pub fn eval(&mut self) {
        let mut best: Option<(usize, Grant)> = None;
        for &i in &self.active {
            let b = &self.sbs[i];
            let st = &mut self.stats.sb[i];
            let (starved, blocked) = Self::waiting(b, self.lanes, self.sb_cap);
            st.starved_cycles += u64::from(starved);
            st.blocked_cycles += u64::from(blocked);
            let words = b.request();
            if words > 0 {
                st.requested_cycles += 1;
                let rank = self.rr.rank(i);
                if best.is_none_or(|(r, _)| rank < r) {
                    best = Some((rank, Grant { sb: i, words }));
                }
            }
        }
        self.grant = best.map(|(_, g)| g);
    }

    /// Whether SB `b` counts a starved cycle (input) or a blocked one (output, not yet
    /// flushing) this cycle.
    #[inline(always)]
    fn waiting(b: &StreamBuffer, lanes: usize, cap: usize) -> (bool, bool) {
        match b.mode {
            SbMode::Input => (b.level < lanes.min(b.len - b.done), false),
            SbMode::Output => (false, cap - b.level < lanes),
            _ => (false, false),
        }
    }

    /// Whether the cycles ahead change nothing but counters while the clusters and the
    /// memory system leave the SRF alone: between cycles, no stream buffer asks for the
    /// port (so none is granted and no level changes).
    pub fn idle_skippable(&self) -> bool {
        self.grant.is_none()
            && self.uncond_used == 0
            && self.cond_used == 0
            && self.active.iter().all(|&i| {
                let b = &self.sbs[i];
                b.request() == 0 && b.pending == 0 && !b.flush_req
            })
    }

    /// Brings an [`idle_skippable`](Self::idle_skippable) SRF over `n ≥ 1` cycles, counting
    /// what `n` cycles of `eval` and `commit` with no access count.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.idle_skippable() && n > 0);
        for &i in &self.active {
            let (starved, blocked) = Self::waiting(&self.sbs[i], self.lanes, self.sb_cap);
            let st = &mut self.stats.sb[i];
            st.starved_cycles += n * u64::from(starved);
            st.blocked_cycles += n * u64::from(blocked);
        }
        self.stats.words_histogram[0] += n;
        self.stats.cycles += n;
        self.last = None;
    }

    /// The transfer `eval` granted this cycle.
    pub fn grant(&self) -> Option<Grant> {
        self.grant
    }

    /// The clock edge: applies the clusters' accesses and the granted transfer.
    #[inline]
    pub fn commit(&mut self) {
        let grant = self.grant.take();
        for &i in &self.active {
            let b = &mut self.sbs[i];
            self.stats.sb[i].cluster_words += b.pending as u64;
            let words = match grant {
                Some(g) if g.sb == i => g.words,
                _ => 0,
            };
            b.commit(words, self.line, &mut self.storage);
        }
        let moved = grant.map_or(0, |g| g.words);
        if let Some(g) = grant {
            self.rr.granted(g.sb);
            self.stats.grants += 1;
            self.stats.words_moved += g.words as u64;
            let st = &mut self.stats.sb[g.sb];
            st.grants += 1;
            st.srf_words += g.words as u64;
        }
        self.stats.words_histogram[moved] += 1;
        self.stats.cycles += 1;
        self.uncond_used = 0;
        self.cond_used = 0;
        self.last = grant;
    }

    /// Reports every probe (after a commit).
    pub fn trace(&self, t: &mut Trace) {
        for (b, &(level, mode)) in self.sbs.iter().zip(&self.probes.sb) {
            t.value(level, b.level as u64);
            t.value(mode, b.mode.bits());
        }
        t.value(self.probes.grant_valid, self.last.is_some() as u64);
        if let Some(g) = self.last {
            t.value(self.probes.grant, g.sb as u64);
        }
        t.value(self.probes.words, self.last.map_or(0, |g| g.words as u64));
    }

    pub fn stats(&self) -> &SrfStats {
        &self.stats
    }

    /// Zeroes the counters (for example between frames).
    pub fn reset_stats(&mut self) {
        self.stats.cycles = 0;
        self.stats.grants = 0;
        self.stats.words_moved = 0;
        self.stats.words_histogram.fill(0);
        self.stats.sb.fill(SbStats::default());
    }

    // ---- errors --------------------------------------------------------------------------

    #[cold]
    #[inline(never)]
    fn error(&self, sb: Option<usize>, signal: &str, msg: String) -> ContractError {
        let path = match sb {
            Some(sb) => format!("{}.sb{sb}.{signal}", self.path),
            None => format!("{}.{signal}", self.path),
        };
        ContractError::at(&path, Violation::Other(msg))
    }

    /// The error of a read that `read_access` refused.
    #[cold]
    #[inline(never)]
    fn read_error(&self, sb: usize, n: usize, conditional: bool) -> ContractError {
        let b = match self.sb(sb, "read") {
            Ok(b) => b,
            Err(e) => return e,
        };
        let kind = access_kind(conditional);
        let msg = if b.mode != SbMode::Input {
            format!(
                "{kind} read of {n} words from sb{sb}, which is {}, not an input stream",
                mode_name(b.mode)
            )
        } else if b.done + b.pending + n > b.len {
            format!(
                "{kind} read of {n} words from sb{sb} runs past the end of its stream: {} of \
                 {} words already delivered",
                b.done + b.pending,
                b.len
            )
        } else if n > b.available() {
            format!(
                "{kind} read of {n} words from sb{sb}, only {} available this cycle (the \
                 clusters must wait while `available` is short)",
                b.available()
            )
        } else {
            return self.bandwidth_error(sb, "read", n, conditional);
        };
        self.error(Some(sb), "read", msg)
    }

    #[cold]
    #[inline(never)]
    fn write_error(&self, sb: usize, n: usize, conditional: bool) -> ContractError {
        let b = match self.sb(sb, "write") {
            Ok(b) => b,
            Err(e) => return e,
        };
        let kind = access_kind(conditional);
        let msg = if b.mode == SbMode::Flushing {
            format!("{kind} write of {n} words to sb{sb} after its stream was flushed")
        } else if b.mode != SbMode::Output {
            format!(
                "{kind} write of {n} words to sb{sb}, which is {}, not an output stream",
                mode_name(b.mode)
            )
        } else if b.done + b.pending + n > b.len {
            format!(
                "{kind} write of {n} words overflows the output region bound to sb{sb}: {} \
                 words written, capacity {} words",
                b.done + b.pending,
                b.len
            )
        } else if n > b.space() {
            format!(
                "{kind} write of {n} words to sb{sb}, only {} words of space this cycle \
                 (the clusters must wait while `space` is short)",
                b.space()
            )
        } else {
            return self.bandwidth_error(sb, "write", n, conditional);
        };
        self.error(Some(sb), "write", msg)
    }

    #[cold]
    #[inline(never)]
    fn bandwidth_error(&self, sb: usize, op: &str, n: usize, conditional: bool) -> ContractError {
        let msg = if !conditional && !n.is_multiple_of(self.lanes) {
            format!(
                "unconditional {op} of {n} words on sb{sb} is not a multiple of the {} \
                 clusters (one word per cluster per access)",
                self.lanes
            )
        } else {
            let (used, per, limit) = if conditional {
                (
                    self.cond_used,
                    self.conditional_words_per_cycle,
                    self.cond_limit,
                )
            } else {
                (
                    self.uncond_used,
                    self.cluster_words_per_cycle,
                    self.uncond_limit,
                )
            };
            format!(
                "{} {op} of {n} words on sb{sb} after {used} this cycle exceeds the clusters' \
                 {} stream bandwidth of {per} words per cluster per cycle × {} clusters = \
                 {limit} words per cycle",
                access_kind(conditional),
                access_kind(conditional),
                self.lanes
            )
        };
        self.error(Some(sb), op, msg)
    }
}

fn access_kind(conditional: bool) -> &'static str {
    if conditional {
        "conditional"
    } else {
        "unconditional"
    }
}

fn mode_name(m: SbMode) -> &'static str {
    match m {
        SbMode::Idle => "not bound",
        SbMode::Input => "bound to an input stream",
        SbMode::Output => "bound to an output stream",
        SbMode::Flushing => "a flushing output stream",
    }
}
