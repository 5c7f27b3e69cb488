//! The thesis's hardware rasterizer (Owens 2002 §6.6, machine `gold8+hwrast`): a
//! fixed-function unit beside the clusters, attached to the SRF as one more client and run
//! by the stream controller as a *hardware kernel* — a stream instruction like a kernel
//! call ([`crate::stream_controller::StreamInstr::Rasterize`]), ordered against the other
//! instructions by the same scoreboard, on its own unit, so it may overlap a cluster
//! kernel.
//!
//! ```text
//!            ┌──────────── rasterizer ─────────────────────────────────────────┐
//!  window ──▶│ fetch: one row of C      setup + scan      row of C fragments   │──▶ addr
//!  |det|  ──▶│ triangles per stream ──▶ (latency pipe, ──▶ (double-buffered) ──▶│──▶ z
//!  attribs──▶│ (input_words_per_cycle)  triangles_in_     1 word per cycle     │──▶ prim
//!            │                          flight)                                │──▶ colour / varyings
//!            └─────────────────────────────────────────────────────────────────┘
//! ```
//!
//! * **Fetch**: reads each input stream's next row of `C` records (the cluster-row layout
//!   the geometry kernels wrote them in), up to `rasterizer.input_words_per_cycle` words per
//!   stream per cycle, through the SRF's client port (not the clusters' stream bandwidth).
//!   Once the three rows are in, one triangle per cycle enters setup.
//! * **Setup and scan** ([`fragments`]): a triangle entering at cycle `t` has its fragments
//!   ready at `t + rasterizer.latency` (100 in the thesis), or later when the scan of the
//!   earlier triangles' boxes (`rasterizer.pixels_per_cycle` candidates a cycle) is still
//!   busy. At most `rasterizer.triangles_in_flight` triangles are between fetch and output;
//!   a full pipe stops the fetch.
//! * **Output**: the ready triangles' fragments, in order, fill a row of `C` (the layout
//!   the fragment program and the composite read); a full row is written word by word,
//!   `rasterizer.output_words_per_cycle` words a cycle (1 in the thesis) over the four
//!   output streams, while the next row fills. A stream buffer without room stalls the
//!   output (back-pressure). At the end the last row is completed with null fragments,
//!   as the `xyrast` kernel's row of nulls completes its output.
//! * **Overflow**: a row that would not fit in the output streams' regions is not written:
//!   the unit stops, flushes what it wrote and reports the overflow, and the host splits
//!   the scissor tile, as it does when `xyprep` counts too many candidates.
//!
//! **Two phases.** `eval` sees the SRF as committed at the last edge (its stream buffers'
//! words and room) and moves the stages' contents; nothing else reads them within the
//! cycle, and what the rest of the processor sees — whether a call runs, what a finished
//! call wrote — changes only at `commit` (the edge), where the outputs are flushed and the
//! stream buffers released.
//!
//! The thesis gives the interface (four input streams and one output stream), the rate and
//! the latency; the rest — fetch width, pipe depth, scan rate, row buffering, and our
//! three input and four output streams (the records this pipeline's geometry kernels write
//! and its composite reads) — is ours (see the README).

pub mod fragments;
#[cfg(test)]
mod tests;

use std::collections::VecDeque;

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

use crate::arith::fp32::FpMode;
use crate::desc::{MachineDesc, RasterizerDesc};
use crate::machine::StreamBinding;
use crate::srf::Srf;
pub use fragments::RasterState;
use fragments::WINDOW_WORDS;

/// Input streams: window records, `|det|`, attribute records.
pub const INPUTS: usize = 3;
/// Output streams: address, depth, primitive, colour or varyings.
pub const OUTPUTS: usize = 4;

/// One call of the rasterizer: its streams and its state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RasterJob {
    /// `window`, `det`, `attribs`: one record per triangle each.
    pub inputs: [StreamBinding; INPUTS],
    /// `addr`, `z`, `prim` and the values (packed colour or varyings): one record per
    /// fragment each.
    pub outputs: [StreamBinding; OUTPUTS],
    pub state: RasterState,
}

/// What a finished call did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RasterResult {
    /// Words written per output stream (nulls included).
    pub outputs: Vec<usize>,
    /// Real fragments (nulls not included).
    pub fragments: usize,
    /// Whether the output regions filled before the triangles ended (the output is then
    /// incomplete: the host splits the work).
    pub overflowed: bool,
}

/// Counters over the run.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RasterStats {
    pub calls: u64,
    /// Cycles a call was running.
    pub busy_cycles: u64,
    pub triangles: u64,
    pub fragments: u64,
    pub words_written: u64,
    /// Cycles a ready word waited for room in its stream buffer.
    pub output_stall_cycles: u64,
}

/// A triangle between setup and output.
struct InFlight {
    /// The cycle its first fragment may be written.
    ready: u64,
    /// Its fragments, [`RasterState::fragment_words`] words each.
    words: Vec<u32>,
    /// Fragments already moved to the row buffer.
    taken: usize,
}

struct Job {
    job: RasterJob,
    triangles: usize,
    /// Words of each input's records.
    record_words: [usize; INPUTS],
    /// The current row of records per input, and words of it read.
    rows: [Vec<u32>; INPUTS],
    /// The next triangle to set up; triangles of the current row before it are done.
    next: usize,
    pipe: VecDeque<InFlight>,
    /// The cycle the scan is free from.
    scan_free: u64,
    /// The row being filled (whole fragments) and the row being written: (stream, word).
    filling: Vec<u32>,
    writing: VecDeque<(u8, u32)>,
    /// Rows handed to the writer, real fragments.
    rows_out: usize,
    fragments: usize,
    written: [usize; OUTPUTS],
    overflowed: bool,
    flushing: bool,
}

/// The rasterizer unit.
pub struct Rasterizer {
    path: String,
    params: RasterizerDesc,
    lanes: usize,
    mode: FpMode,
    /// Its stream buffers: inputs, then outputs.
    sbs: [usize; INPUTS + OUTPUTS],
    job: Option<Job>,
    cycle: u64,
    finished: Option<RasterResult>,
    /// Whether a ready word waited for room this cycle.
    stalled: bool,
    stats: RasterStats,
    /// busy, fetched triangle index, in flight, row level, words written, stalled,
    /// overflowed.
    ids: [SignalId; 7],
}

impl Rasterizer {
    /// The unit of `desc` (which must have a `[rasterizer]` table): its stream buffers are
    /// the ones after the kernels'.
    pub fn new(scope: &mut Scope<'_>, desc: &MachineDesc) -> Option<Self> {
        let params = desc.rasterizer.clone()?;
        let first = desc.srf.kernel_streams;
        let word = bits_for(u32::MAX as u64);
        let ids = [
            scope.signal("busy", 1, SignalKind::Reg),
            scope.signal("triangle", word, SignalKind::Reg),
            scope.signal(
                "in_flight",
                bits_for(params.triangles_in_flight as u64),
                SignalKind::Reg,
            ),
            scope.signal(
                "row_level",
                bits_for(desc.cluster.count as u64),
                SignalKind::Reg,
            ),
            scope.signal("words_written", word, SignalKind::Reg),
            scope.signal("stalled", 1, SignalKind::Reg),
            scope.signal("overflowed", 1, SignalKind::Reg),
        ];
        Some(Rasterizer {
            path: scope.path().to_string(),
            params,
            lanes: desc.cluster.count,
            mode: desc.fp_mode(),
            sbs: std::array::from_fn(|i| first + i),
            job: None,
            cycle: 0,
            finished: None,
            stalled: false,
            stats: RasterStats::default(),
            ids,
        })
    }

    pub fn is_busy(&self) -> bool {
        self.job.is_some()
    }

    /// What the call that ended at the last edge did (taken once).
    pub fn take_finished(&mut self) -> Option<RasterResult> {
        self.finished.take()
    }

    pub fn stats(&self) -> &RasterStats {
        &self.stats
    }

    fn error(&self, what: &str, msg: String) -> ContractError {
        ContractError::at(&format!("{}.{what}", self.path), Violation::Other(msg))
    }

    /// Starts `job` (between cycles): binds its stream buffers.
    pub fn start(&mut self, job: RasterJob, srf: &mut Srf) -> Result<(), ContractError> {
        if self.job.is_some() {
            return Err(self.error("start", "a call is already running".into()));
        }
        let c = self.lanes;
        let record_words = [WINDOW_WORDS, 1, job.state.attrib_words()];
        let triangles = job.inputs[1].words;
        for (k, (b, w)) in job.inputs.iter().zip(record_words).enumerate() {
            if b.words != triangles * w || !triangles.is_multiple_of(c) {
                return Err(self.error(
                    "start",
                    format!(
                        "input {k}: {} words for {triangles} triangles of {w}-word records \
                         (whole rows of {c})",
                        b.words
                    ),
                ));
            }
        }
        let value_words = job.state.value_words();
        for (k, b) in job.outputs.iter().enumerate() {
            let w = if k == 3 { value_words } else { 1 };
            if !b.words.is_multiple_of(w * c) {
                return Err(self.error(
                    "start",
                    format!(
                        "output {k}: {} words are not whole rows of {w}-word records",
                        b.words
                    ),
                ));
            }
        }
        for (k, b) in job.inputs.iter().enumerate() {
            srf.bind_input(self.sbs[k], b.start, b.words)?;
        }
        for (k, b) in job.outputs.iter().enumerate() {
            srf.bind_output(self.sbs[INPUTS + k], b.start, b.words)?;
        }
        self.stats.calls += 1;
        self.job = Some(Job {
            job,
            triangles,
            record_words,
            rows: std::array::from_fn(|k| Vec::with_capacity(record_words[k] * c)),
            next: 0,
            pipe: VecDeque::new(),
            scan_free: 0,
            filling: Vec::new(),
            writing: VecDeque::new(),
            rows_out: 0,
            fragments: 0,
            written: [0; OUTPUTS],
            overflowed: false,
            flushing: false,
        });
        Ok(())
    }

    /// Fragments the output regions hold.
    fn capacity(job: &RasterJob) -> usize {
        let v = job.state.value_words();
        (0..OUTPUTS)
            .map(|k| job.outputs[k].words / if k == 3 { v } else { 1 })
            .min()
            .unwrap_or(0)
    }

    /// One cycle, from the state at the last edge: the SRF client port's reads and writes
    /// and the stages' moves (each stage reads what the one after it held at the edge).
    pub fn eval(&mut self, srf: &mut Srf) -> Result<(), ContractError> {
        let (c, now, mode) = (self.lanes, self.cycle, self.mode);
        self.stalled = false;
        let Some(j) = self.job.as_mut() else {
            return Ok(());
        };
        self.stats.busy_cycles += 1;
        if j.flushing {
            return Ok(());
        }
        // Output: up to the rate, in order, each word into its stream's buffer.
        let mut budget = self.params.output_words_per_cycle;
        while budget > 0
            && let Some(&(k, w)) = j.writing.front()
        {
            let sb = self.sbs[INPUTS + k as usize];
            if srf.space(sb) == 0 {
                self.stats.output_stall_cycles += 1;
                self.stalled = true;
                break;
            }
            srf.memory_write(sb, &[w])?;
            j.writing.pop_front();
            j.written[k as usize] += 1;
            self.stats.words_written += 1;
            budget -= 1;
        }
        // Row buffer: the ready triangles' fragments fill it; a full row goes to the
        // writer once the writer has finished the last.
        let fw = j.job.state.fragment_words();
        while j.filling.len() < c * fw
            && let Some(t) = j.pipe.front_mut()
            && t.ready <= now
        {
            let n = t.words.len() / fw;
            if t.taken == n {
                j.pipe.pop_front();
                continue;
            }
            let room = c - j.filling.len() / fw;
            let take = room.min(n - t.taken);
            j.filling
                .extend_from_slice(&t.words[t.taken * fw..(t.taken + take) * fw]);
            t.taken += take;
            if t.taken == n {
                j.pipe.pop_front();
            }
        }
        let inputs_done = j.next == j.triangles && j.pipe.is_empty();
        let real = j.filling.len() / fw;
        if j.writing.is_empty() && (real == c || (inputs_done && real > 0)) {
            if (j.rows_out + 1) * c > Self::capacity(&j.job) {
                j.overflowed = true;
            } else {
                while j.filling.len() < c * fw {
                    j.job.state.null_fragment(&mut j.filling);
                }
                // Stream by stream, each in the cluster-row layout: word k of fragment
                // c of the row at k·C + c.
                let v = j.job.state.value_words();
                for k in 0..3 + v {
                    let stream = k.min(3) as u8;
                    j.writing
                        .extend((0..c).map(|f| (stream, j.filling[f * fw + k])));
                }
                j.filling.clear();
                j.rows_out += 1;
                j.fragments += real;
            }
        }
        // Setup: one triangle a cycle from the fetched row, while the pipe has room.
        let row_start = j.next - j.next % c;
        let fetched = (0..INPUTS).all(|k| j.rows[k].len() == j.record_words[k] * c);
        if fetched && j.next < j.triangles && j.pipe.len() < self.params.triangles_in_flight {
            let i = j.next - row_start;
            let field = |k: usize| -> Vec<u32> {
                (0..j.record_words[k])
                    .map(|w| j.rows[k][w * c + i])
                    .collect()
            };
            let state = &j.job.state;
            let s = fragments::setup(
                state,
                j.next as u32,
                &field(0),
                j.rows[1][i],
                &field(2),
                mode,
            );
            let mut words = Vec::new();
            fragments::rasterize(&s, state, mode, &mut words);
            let scan = s.candidates().div_ceil(self.params.pixels_per_cycle as u64);
            j.scan_free = j.scan_free.max(now) + scan;
            j.pipe.push_back(InFlight {
                ready: (now + self.params.latency).max(j.scan_free),
                words,
                taken: 0,
            });
            self.stats.triangles += 1;
            j.next += 1;
            if j.next.is_multiple_of(c) {
                j.rows.iter_mut().for_each(Vec::clear);
            }
        }
        // Fetch: the current row of each input, up to the width per stream.
        if j.next.is_multiple_of(c) && j.next < j.triangles {
            for k in 0..INPUTS {
                let want = j.record_words[k] * c - j.rows[k].len();
                let n = want
                    .min(self.params.input_words_per_cycle)
                    .min(srf.available(self.sbs[k]));
                if n > 0 {
                    let words = srf.memory_read(self.sbs[k], n)?;
                    j.rows[k].extend_from_slice(words);
                }
            }
        }
        Ok(())
    }

    /// The clock edge: a finished or overflowed call flushes its outputs, and once they
    /// are in the SRF releases its stream buffers.
    pub fn commit(&mut self, srf: &mut Srf) -> Result<(), ContractError> {
        self.cycle += 1;
        let Some(j) = self.job.as_mut() else {
            return Ok(());
        };
        let done = j.overflowed
            || (j.next == j.triangles
                && j.pipe.is_empty()
                && j.filling.is_empty()
                && j.writing.is_empty());
        if done && !j.flushing {
            for k in 0..OUTPUTS {
                srf.flush(self.sbs[INPUTS + k])?;
            }
            j.flushing = true;
            return Ok(());
        }
        if j.flushing && (0..OUTPUTS).all(|k| srf.flushed(self.sbs[INPUTS + k])) {
            for sb in self.sbs {
                srf.unbind(sb)?;
            }
            self.stats.fragments += j.fragments as u64;
            self.finished = Some(RasterResult {
                outputs: j.written.to_vec(),
                fragments: j.fragments,
                overflowed: j.overflowed,
            });
            self.job = None;
        }
        Ok(())
    }

    pub fn trace(&self, t: &mut Trace) {
        let j = self.job.as_ref();
        t.value(self.ids[0], j.is_some() as u64);
        t.value(self.ids[1], j.map_or(0, |j| j.next as u64 & 0xFFFF_FFFF));
        t.value(self.ids[2], j.map_or(0, |j| j.pipe.len() as u64));
        let fw = j.map_or(1, |j| j.job.state.fragment_words());
        t.value(self.ids[3], j.map_or(0, |j| (j.filling.len() / fw) as u64));
        t.value(self.ids[4], self.stats.words_written & 0xFFFF_FFFF);
        t.value(self.ids[5], self.stalled as u64);
        t.value(self.ids[6], j.is_some_and(|j| j.overflowed) as u64);
    }
}
