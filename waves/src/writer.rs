//! The streaming VCD writer.

use std::cell::RefCell;
use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::{SystemTime, UNIX_EPOCH};

use imagine_hdl::{ClockDomain, ProbeRegistry, SignalId, SignalKind, Tracer};
use vcd::{IdCode, ReferenceIndex, TimescaleUnit, VarType};

use crate::filter::ScopeFilter;
use crate::gtkw::{GtkwView, write_gtkw};
use crate::window::CycleWindow;

/// What to dump: a cycle window and scope filters (the `--vcd-window` and `--vcd-scope`
/// options). The default dumps every signal over the whole run.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct VcdOptions {
    /// Core cycles to dump (see [`CycleWindow`]).
    pub window: CycleWindow,
    /// Glob patterns over signal paths (see [`ScopeFilter`] for the matching rule); empty
    /// selects everything. Clocks are always selected.
    pub scopes: Vec<String>,
    /// The most bytes the dump may hold (`--vcd-max-bytes`): see [`VcdWriter`]'s limit.
    pub max_bytes: Option<u64>,
}

impl VcdOptions {
    /// The compiled scope filter; an invalid glob is an error naming it.
    pub fn filter(&self) -> Result<ScopeFilter, String> {
        ScopeFilter::new(&self.scopes)
    }

    /// The scope patterns that select nothing in `probes` (see [`ScopeFilter::unmatched`]).
    pub fn unmatched_scopes(&self, probes: &ProbeRegistry) -> Result<Vec<String>, String> {
        Ok(self.filter()?.unmatched(probes))
    }
}

/// What a writer wrote, known once the run is finished.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct VcdSummary {
    /// Signals in the dump (clocks included).
    pub signals: usize,
    /// Time of the `$dumpvars` that opens the window, picoseconds; `None` if the run never
    /// reached the window.
    pub first_time_ps: Option<u64>,
    /// Last timestamp written, picoseconds.
    pub last_time_ps: Option<u64>,
    /// Value lines written, the `$dumpvars` block included.
    pub values_written: u64,
    /// The GTKWave save file written next to the dump, if any.
    pub gtkw: Option<PathBuf>,
}

/// Where the writer is relative to the cycle window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// `start` not yet called.
    Idle,
    /// Before the window: only the latest value of each selected signal is kept.
    Before,
    /// At the window's first instant: the `$dumpvars` block is written when time moves on.
    Dump,
    /// Inside the window: changes are written.
    In,
    /// After the window, or after an error: nothing more is written.
    Done,
}

/// A selected signal.
#[derive(Clone, Copy, Debug)]
struct Slot {
    /// First word of its value in `cur` and `written`.
    off: u32,
    words: u32,
    width: u32,
    /// Its identifier code in `ids`.
    id_start: u32,
    id_len: u32,
}

const NOT_SELECTED: u32 = u32::MAX;
/// Output is collected in memory and handed to the writer in chunks of about this size.
const CHUNK: usize = 1 << 16;

/// Writes probe changes as a Value Change Dump, streaming, in bounded memory.
///
/// * Header: `$date`, `$version`, a `$comment` naming the window and scope filters,
///   `$timescale 1 ps`, and one `$scope module` per level of the dot-separated signal paths
///   (`top.mac.s2.pp_lo` is variable `pp_lo [23:0]` in scopes `top` / `mac` / `s2`).
///   [`SignalKind::Reg`] becomes a `reg`, [`SignalKind::Wire`] and [`SignalKind::Clock`] a
///   `wire`; widths are the declared ones, vectors carry their range `[w-1:0]`.
/// * Body: timestamps in picoseconds, strictly increasing (simulator instants that round to
///   the same picosecond are merged, the later value winning); under each, the signals
///   whose value differs from the last one written: `0!`/`1!` for 1-bit signals, `b1010 "`
///   (every bit, MSB first) for vectors of any width.
/// * Window (see [`CycleWindow`]): before it nothing is written but the latest value of each
///   selected signal is kept, so the window opens with a `$dumpvars` block holding the
///   state at its first instant (after that instant's edge); signals never reported are
///   `x`. After it a final timestamp marks where the window ends and nothing more is
///   written; later calls return at once.
/// * Scopes (see [`ScopeFilter`]): only selected signals are declared and dumped; clocks
///   always are.
/// * Memory: the last value of each selected signal (twice: current and last written) and a
///   64 KiB output chunk, whatever the run's length.
/// * Errors: [`Tracer::change`] and [`Tracer::time`] cannot return one, so the first I/O
///   error is kept, writing stops, and [`Tracer::finish`] returns it.
///
/// [`VcdWriter::create`] writes to a file and, at [`Tracer::finish`], a GTKWave save file
/// next to it (see [`crate::write_gtkw`]); [`VcdWriter::new`] writes to any
/// [`io::Write`], such as a `Vec<u8>`.
pub struct VcdWriter<W: Write> {
    vcd: vcd::Writer<W>,
    window: CycleWindow,
    filter: ScopeFilter,
    /// The dump's path, when a save file is to be written next to it.
    gtkw_for: Option<PathBuf>,
    /// The registry (kept only for the save file) and the core clock period.
    probes: Option<ProbeRegistry>,
    core_period_ps: Option<u64>,
    selected: Vec<SignalId>,
    slot_of: Vec<u32>,
    slots: Vec<Slot>,
    ids: Vec<u8>,
    cur: Vec<u64>,
    cur_known: Vec<bool>,
    written: Vec<u64>,
    written_known: Vec<bool>,
    dirty: Vec<bool>,
    dirty_list: Vec<u32>,
    phase: Phase,
    /// Time of the instant whose changes are being gathered.
    pending_ps: u64,
    summary: VcdSummary,
    shared: Option<Rc<RefCell<VcdSummary>>>,
    buf: Vec<u8>,
    error: Option<io::Error>,
    /// Bytes handed to the output so far.
    bytes: u64,
    max_bytes: Option<u64>,
    /// Core cycle at which the window opened, once it has.
    opened_at: Option<u64>,
    /// Why the run must stop: the dump would pass `max_bytes`.
    over_limit: Option<String>,
}

/// Window cycles after which the dump's size is projected over a bounded window.
const PROJECT_AFTER_CYCLES: u64 = 1_000;

impl VcdWriter<BufWriter<File>> {
    /// Creates (truncates) the dump file at `path`; [`Tracer::finish`] also writes the
    /// GTKWave save file next to it (`out.vcd` → `out.gtkw`). Fails on an invalid scope
    /// glob (as [`io::ErrorKind::InvalidInput`]) or when the file cannot be created.
    pub fn create(path: impl AsRef<Path>, options: &VcdOptions) -> io::Result<Self> {
        let path = path.as_ref();
        let filter = options
            .filter()
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        let file = File::create(path).map_err(|e| {
            io::Error::new(e.kind(), format!("cannot create `{}`: {e}", path.display()))
        })?;
        let mut w = Self::with_filter(BufWriter::with_capacity(CHUNK, file), options, filter);
        w.gtkw_for = Some(path.to_path_buf());
        Ok(w)
    }
}

impl<W: Write> VcdWriter<W> {
    /// A writer to `out` (no save file). Fails on an invalid scope glob.
    pub fn new(out: W, options: &VcdOptions) -> Result<Self, String> {
        let filter = options.filter()?;
        Ok(Self::with_filter(out, options, filter))
    }

    fn with_filter(out: W, options: &VcdOptions, filter: ScopeFilter) -> Self {
        VcdWriter {
            vcd: vcd::Writer::new(out),
            window: options.window,
            filter,
            gtkw_for: None,
            probes: None,
            core_period_ps: None,
            selected: Vec::new(),
            slot_of: Vec::new(),
            slots: Vec::new(),
            ids: Vec::new(),
            cur: Vec::new(),
            cur_known: Vec::new(),
            written: Vec::new(),
            written_known: Vec::new(),
            dirty: Vec::new(),
            dirty_list: Vec::new(),
            phase: Phase::Idle,
            pending_ps: 0,
            summary: VcdSummary::default(),
            shared: None,
            buf: Vec::with_capacity(CHUNK + 4096),
            error: None,
            bytes: 0,
            max_bytes: options.max_bytes,
            opened_at: None,
            over_limit: None,
        }
    }

    /// Also writes a GTKWave save file for `vcd_path` at [`Tracer::finish`] (set by
    /// [`VcdWriter::create`]; for writers over other outputs that end up in that file).
    pub fn with_gtkw(mut self, vcd_path: impl Into<PathBuf>) -> Self {
        self.gtkw_for = Some(vcd_path.into());
        self
    }

    /// A handle on the [`VcdSummary`], filled in by [`Tracer::finish`]; it stays readable
    /// after the writer has been handed to a simulator as a `Box<dyn Tracer>`.
    pub fn summary_handle(&mut self) -> Rc<RefCell<VcdSummary>> {
        self.shared
            .get_or_insert_with(|| Rc::new(RefCell::new(VcdSummary::default())))
            .clone()
    }

    /// What has been written so far.
    pub fn summary(&self) -> &VcdSummary {
        &self.summary
    }

    /// The selected signals, in registration order (known after [`Tracer::start`]).
    pub fn selected(&self) -> &[SignalId] {
        &self.selected
    }

    /// The scope patterns that selected no signal (known after [`Tracer::start`]; before,
    /// pass the registry to [`VcdOptions::unmatched_scopes`]).
    pub fn unmatched_scopes(&self) -> Vec<String> {
        self.probes
            .as_ref()
            .map(|p| self.filter.unmatched(p))
            .unwrap_or_default()
    }

    /// The underlying output (flush with [`Tracer::finish`] first).
    pub fn get_ref(&mut self) -> &mut W {
        self.vcd.writer()
    }

    fn header(&mut self, probes: &ProbeRegistry) -> io::Result<()> {
        let v = &mut self.vcd;
        v.date(&utc_date(header_seconds()))?;
        v.version(&format!("imagine-waves {}", env!("CARGO_PKG_VERSION")))?;
        let scopes = if self.filter.is_empty() {
            "all".to_string()
        } else {
            self.filter.patterns().collect::<Vec<_>>().join(" ")
        };
        let window = if self.window.is_all() {
            "all".to_string()
        } else {
            self.window.to_string()
        };
        v.comment(&format!(
            "core cycles {window} (FROM inclusive, TO exclusive); scopes {scopes}; \
             {} of {} signals",
            self.selected.len(),
            probes.len()
        ))?;
        v.timescale(1, TimescaleUnit::PS)?;

        // The scope tree, children in order of first appearance.
        enum Item {
            Var(usize),
            Scope(usize),
        }
        struct Node<'a> {
            name: &'a str,
            items: Vec<Item>,
        }
        let mut nodes = vec![Node {
            name: "",
            items: Vec::new(),
        }];
        let mut child: HashMap<(usize, &str), usize> = HashMap::new();
        for (slot, &id) in self.selected.iter().enumerate() {
            let path = probes.get(id).path.as_str();
            let mut at = 0;
            let mut parts = path.split('.').peekable();
            while let Some(part) = parts.next() {
                if parts.peek().is_none() {
                    nodes[at].items.push(Item::Var(slot));
                    break;
                }
                at = match child.get(&(at, part)) {
                    Some(&n) => n,
                    None => {
                        nodes.push(Node {
                            name: part,
                            items: Vec::new(),
                        });
                        let n = nodes.len() - 1;
                        nodes[at].items.push(Item::Scope(n));
                        child.insert((at, part), n);
                        n
                    }
                };
            }
        }
        // Depth-first, with an explicit stack of (node, next item).
        let mut stack = vec![(0usize, 0usize)];
        while let Some((n, i)) = stack.pop() {
            let Some(item) = nodes[n].items.get(i) else {
                if n != 0 {
                    v.upscope()?;
                }
                continue;
            };
            stack.push((n, i + 1));
            match *item {
                Item::Scope(c) => {
                    v.add_module(nodes[c].name)?;
                    stack.push((c, 0));
                }
                Item::Var(slot) => {
                    let s = probes.get(self.selected[slot]);
                    let ty = match s.kind {
                        SignalKind::Reg => VarType::Reg,
                        SignalKind::Wire | SignalKind::Clock => VarType::Wire,
                    };
                    let index = (s.width > 1).then(|| ReferenceIndex::Range(s.width as i32 - 1, 0));
                    let code = IdCode::from(slot as u32);
                    if n == 0 {
                        // A signal outside any scope (a path without a dot).
                        let idx = index.map(|i| format!(" {i}")).unwrap_or_default();
                        writeln!(
                            v.writer(),
                            "$var {ty} {} {code} {}{idx} $end",
                            s.width,
                            s.name()
                        )?;
                    } else {
                        v.var_def(ty, s.width, code, s.name(), index)?;
                    }
                }
            }
        }
        v.enddefinitions()
    }

    // ---- value output ----

    fn value_line(&mut self, slot: usize) {
        let s = self.slots[slot];
        let id = &self.ids[s.id_start as usize..(s.id_start + s.id_len) as usize];
        let known = self.cur_known[slot];
        let words = &self.cur[s.off as usize..(s.off + s.words) as usize];
        let buf = &mut self.buf;
        if s.width == 1 {
            buf.push(match (known, words[0] & 1) {
                (false, _) => b'x',
                (true, 0) => b'0',
                _ => b'1',
            });
        } else {
            buf.push(b'b');
            if known {
                push_bits(buf, words, s.width);
            } else {
                buf.push(b'x');
            }
            buf.push(b' ');
        }
        buf.extend_from_slice(id);
        buf.push(b'\n');
        self.summary.values_written += 1;
    }

    fn timestamp(&mut self, t: u64) {
        self.buf.push(b'#');
        push_decimal(&mut self.buf, t);
        self.buf.push(b'\n');
        self.summary.last_time_ps = Some(t);
    }

    /// Writes the `$dumpvars` block at the window's first instant.
    fn dumpvars(&mut self) {
        let t = self.pending_ps;
        self.timestamp(t);
        self.summary.first_time_ps = Some(t);
        self.buf.extend_from_slice(b"$dumpvars\n");
        for slot in 0..self.slots.len() {
            self.value_line(slot);
        }
        self.buf.extend_from_slice(b"$end\n");
        self.written.copy_from_slice(&self.cur);
        self.written_known.copy_from_slice(&self.cur_known);
        self.drain_if_full();
    }

    /// Writes the changes of the pending instant that differ from what was last written.
    fn flush_instant(&mut self) {
        if self.dirty_list.is_empty() {
            return;
        }
        let mut list = std::mem::take(&mut self.dirty_list);
        let mut stamped = false;
        for &slot in &list {
            let slot = slot as usize;
            self.dirty[slot] = false;
            let s = self.slots[slot];
            let r = s.off as usize..(s.off + s.words) as usize;
            if self.written_known[slot] == self.cur_known[slot]
                && self.written[r.clone()] == self.cur[r.clone()]
            {
                continue;
            }
            if !stamped {
                self.timestamp(self.pending_ps);
                stamped = true;
            }
            self.written[r.clone()].copy_from_slice(&self.cur[r]);
            self.written_known[slot] = self.cur_known[slot];
            self.value_line(slot);
        }
        list.clear();
        self.dirty_list = list;
        self.drain_if_full();
    }

    fn drain_if_full(&mut self) {
        if self.buf.len() >= CHUNK {
            self.drain();
        }
    }

    /// Hands the collected output to the writer; on an error, keeps it and stops.
    fn drain(&mut self) {
        if self.buf.is_empty() {
            return;
        }
        if let Err(e) = self.vcd.writer().write_all(&self.buf) {
            self.fail(e);
        }
        self.bytes += self.buf.len() as u64;
        self.buf.clear();
    }

    /// Checks the size limit in core cycle `core_cycle` of the window: past it, or (over a
    /// bounded window, after [`PROJECT_AFTER_CYCLES`]) projected past it, the dump ends and
    /// [`Tracer::abort`] says why.
    fn check_size(&mut self, core_cycle: u64) {
        let Some(max) = self.max_bytes else { return };
        let opened = *self.opened_at.get_or_insert(core_cycle);
        let cycles = core_cycle.saturating_sub(opened).max(1);
        let bytes = self.bytes + self.buf.len() as u64;
        let per_cycle = bytes as f64 / cycles as f64;
        let window = self.window.to.map(|to| to.saturating_sub(opened));
        let projected = window.map(|w| (per_cycle * w as f64) as u64);
        let over =
            bytes > max || (cycles >= PROJECT_AFTER_CYCLES && projected.is_some_and(|p| p > max));
        if !over {
            return;
        }
        let estimate = match (projected, window) {
            (Some(p), Some(w)) => format!("about {} over the window's {w} core cycles", size(p)),
            _ => format!("more than {} (the window runs to the end)", size(max)),
        };
        self.over_limit = Some(format!(
            "the waveform would be {estimate}: {} in its first {cycles} cycles, {} per cycle; \
             --vcd-max-bytes is {}. Narrow it with --vcd-window FROM:TO (`render --timeline` \
             gives each kernel call's cycles), --vcd-scope GLOB or --vcd-kernel NAME, or raise \
             --vcd-max-bytes",
            size(bytes),
            size(per_cycle as u64),
            size(max)
        ));
        self.close_window(None);
    }

    fn fail(&mut self, e: io::Error) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        self.phase = Phase::Done;
    }

    /// Closes the window: the pending instant, then a timestamp where the window ends.
    fn close_window(&mut self, end_ps: Option<u64>) {
        match self.phase {
            Phase::Dump => self.dumpvars(),
            Phase::In => self.flush_instant(),
            _ => return,
        }
        if let Some(t) = end_ps.filter(|&t| self.summary.last_time_ps.is_none_or(|l| t > l)) {
            self.timestamp(t);
        }
        self.phase = Phase::Done;
        self.drain();
    }
}

impl<W: Write> Tracer for VcdWriter<W> {
    fn start(&mut self, probes: &ProbeRegistry, clocks: &[ClockDomain]) -> io::Result<()> {
        self.selected = self.filter.select(probes);
        self.slot_of = vec![NOT_SELECTED; probes.len()];
        self.slots.clear();
        self.ids.clear();
        let mut words = 0u32;
        for (slot, &id) in self.selected.iter().enumerate() {
            let s = probes.get(id);
            self.slot_of[id.0 as usize] = slot as u32;
            let code = IdCode::from(slot as u32).to_string();
            self.slots.push(Slot {
                off: words,
                words: s.words() as u32,
                width: s.width,
                id_start: self.ids.len() as u32,
                id_len: code.len() as u32,
            });
            self.ids.extend_from_slice(code.as_bytes());
            words += s.words() as u32;
        }
        let (n, w) = (self.slots.len(), words as usize);
        self.cur = vec![0; w];
        self.written = vec![0; w];
        self.cur_known = vec![false; n];
        self.written_known = vec![false; n];
        self.dirty = vec![false; n];
        self.dirty_list = Vec::with_capacity(n);
        self.summary = VcdSummary {
            signals: n,
            ..VcdSummary::default()
        };
        self.core_period_ps = clocks
            .first()
            .filter(|c| c.freq_hz > 0)
            .map(|c| 1_000_000_000_000 / c.freq_hz);
        if self.gtkw_for.is_some() || !self.filter.is_empty() {
            self.probes = Some(probes.clone());
        }
        self.phase = Phase::Before;
        if let Err(e) = self.header(probes) {
            self.fail(e);
            return Err(self.error.take().expect("just failed"));
        }
        Ok(())
    }

    #[inline]
    fn time(&mut self, time_ps: u64, core_cycle: u64) {
        let ended = self.window.to.is_some_and(|to| core_cycle >= to);
        match self.phase {
            Phase::Idle | Phase::Done => {}
            Phase::Before => {
                if core_cycle >= self.window.from {
                    if ended {
                        self.phase = Phase::Done;
                    } else {
                        self.phase = Phase::Dump;
                        self.pending_ps = time_ps;
                    }
                }
            }
            Phase::Dump | Phase::In => {
                // Never backwards; the same picosecond continues the pending instant.
                let t = time_ps.max(self.pending_ps);
                if ended {
                    self.close_window(Some(t));
                } else if t != self.pending_ps {
                    if self.phase == Phase::Dump {
                        self.dumpvars();
                        self.phase = Phase::In;
                    } else {
                        self.flush_instant();
                    }
                    self.pending_ps = t;
                    self.check_size(core_cycle);
                }
            }
        }
    }

    #[inline]
    fn wants_changes(&self) -> bool {
        self.phase != Phase::Done
    }

    fn abort(&self) -> Option<String> {
        self.over_limit.clone()
    }

    fn change(&mut self, id: SignalId, value: &[u64]) {
        if self.phase == Phase::Done {
            return;
        }
        let Some(&slot) = self.slot_of.get(id.0 as usize) else {
            return;
        };
        if slot == NOT_SELECTED {
            return;
        }
        let slot = slot as usize;
        let s = self.slots[slot];
        let (off, n) = (s.off as usize, s.words as usize);
        let cur = &mut self.cur[off..off + n];
        if value.len() >= n {
            cur.copy_from_slice(&value[..n]);
        } else {
            // Missing high words are zero.
            cur.fill(0);
            cur[..value.len()].copy_from_slice(value);
        }
        // Bits above the width are not part of the value.
        if !s.width.is_multiple_of(64) {
            cur[n - 1] &= (1u64 << (s.width % 64)) - 1;
        }
        self.cur_known[slot] = true;
        if self.phase == Phase::In && !self.dirty[slot] {
            self.dirty[slot] = true;
            self.dirty_list.push(slot as u32);
        }
    }

    fn finish(&mut self) -> io::Result<()> {
        if self.phase == Phase::Idle {
            return Ok(());
        }
        self.close_window(None);
        self.drain();
        if self.error.is_none()
            && let Err(e) = self.vcd.flush()
        {
            self.fail(e);
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        if let (Some(vcd_path), Some(probes)) = (&self.gtkw_for, &self.probes) {
            let view = GtkwView {
                start_ps: self.summary.first_time_ps.unwrap_or(0),
                end_ps: self.summary.last_time_ps,
                core_period_ps: self.core_period_ps,
            };
            let path = write_gtkw(vcd_path, probes, &self.selected, &view).map_err(|e| {
                io::Error::new(
                    e.kind(),
                    format!(
                        "cannot write the GTKWave save file for `{}`: {e}",
                        vcd_path.display()
                    ),
                )
            })?;
            self.summary.gtkw = Some(path);
        }
        if let Some(shared) = &self.shared {
            *shared.borrow_mut() = self.summary.clone();
        }
        Ok(())
    }
}

impl<W: Write> Drop for VcdWriter<W> {
    /// Hands over whatever was collected, if [`Tracer::finish`] was not called.
    fn drop(&mut self) {
        if self.error.is_none() {
            let _ = self.vcd.writer().write_all(&self.buf);
        }
    }
}

/// `"0"`/`"1"` for each bit of every byte value, MSB first.
static BITS: [[u8; 8]; 256] = {
    let mut t = [[0u8; 8]; 256];
    let mut b = 0;
    while b < 256 {
        let mut i = 0;
        while i < 8 {
            t[b][i] = b'0' + ((b >> (7 - i)) & 1) as u8;
            i += 1;
        }
        b += 1;
    }
    t
};

/// Appends the `width` low bits of the little-endian `words`, MSB first.
fn push_bits(buf: &mut Vec<u8>, words: &[u64], width: u32) {
    let n = words.len();
    buf.reserve(width as usize);
    let top_bits = width - 64 * (n as u32 - 1);
    push_word(buf, words[n - 1], top_bits);
    for &w in words[..n - 1].iter().rev() {
        push_word(buf, w, 64);
    }
}

/// Appends the `bits` (1..=64) low bits of `w`, MSB first.
#[inline]
fn push_word(buf: &mut Vec<u8>, w: u64, bits: u32) {
    let lead = bits % 8;
    for i in (bits - lead..bits).rev() {
        buf.push(b'0' + ((w >> i) & 1) as u8);
    }
    for byte in (0..bits / 8).rev() {
        buf.extend_from_slice(&BITS[((w >> (8 * byte)) & 0xFF) as usize]);
    }
}

fn push_decimal(buf: &mut Vec<u8>, mut v: u64) {
    let mut tmp = [0u8; 20];
    let mut i = tmp.len();
    loop {
        i -= 1;
        tmp[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    buf.extend_from_slice(&tmp[i..]);
}

/// The time the header's `$date` gives, in seconds since 1970: `SOURCE_DATE_EPOCH` when it
/// is set (the reproducible-builds convention, so that the same inputs give the same file
/// byte for byte), else now.
fn header_seconds() -> u64 {
    std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or_else(|| {
            SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
        })
}

/// `secs` since 1970 as a UTC date and time, `2025-01-31 12:34:56 UTC`.
fn utc_date(secs: u64) -> String {
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02} UTC",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// A byte count as a person reads it.
fn size(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 => format!("{:.1} GB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.1} MB", b as f64 / (1u64 << 20) as f64),
        b if b >= 1 << 10 => format!("{:.1} kB", b as f64 / 1024.0),
        b => format!("{b} bytes"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(words: &[u64], width: u32) -> String {
        let mut b = Vec::new();
        push_bits(&mut b, words, width);
        String::from_utf8(b).unwrap()
    }

    #[test]
    fn bit_strings() {
        assert_eq!(bits(&[0b1011], 4), "1011");
        assert_eq!(bits(&[0b1011], 7), "0001011");
        assert_eq!(bits(&[5], 9), "000000101");
        assert_eq!(bits(&[u64::MAX], 64), "1".repeat(64));
        assert_eq!(bits(&[0, 1], 65), format!("1{}", "0".repeat(64)));
        assert_eq!(bits(&[1, 0, 0b10], 130), format!("10{}1", "0".repeat(127)));
    }

    #[test]
    fn signals_outside_any_scope_and_empty_registries() {
        let mut r = ProbeRegistry::new();
        let clk = r.register("clk".into(), 1, SignalKind::Clock);
        let bus = r.register("bus".into(), 3, SignalKind::Wire);
        r.register("top.x".into(), 2, SignalKind::Reg);
        let mut w = VcdWriter::new(Vec::new(), &VcdOptions::default()).unwrap();
        w.start(&r, &[]).unwrap();
        w.time(0, 0);
        w.change(clk, &[1]);
        w.change(bus, &[5]);
        w.finish().unwrap();
        let text = String::from_utf8(std::mem::take(w.get_ref())).unwrap();
        assert!(
            text.contains("$var wire 1 ! clk $end\n$var wire 3 \" bus [2:0] $end\n"),
            "{text}"
        );
        assert!(
            text.ends_with("#0\n$dumpvars\n1!\nb101 \"\nbx #\n$end\n"),
            "{text}"
        );
        let header = vcd::Parser::new(text.as_bytes()).parse_header().unwrap();
        assert_eq!(header.find_var(&["bus"]).unwrap().size, 3);
        assert_eq!(header.find_var(&["top", "x"]).unwrap().size, 2);

        let mut w = VcdWriter::new(Vec::new(), &VcdOptions::default()).unwrap();
        w.start(&ProbeRegistry::new(), &[]).unwrap();
        w.time(0, 0);
        w.time(5, 1);
        w.finish().unwrap();
        let text = String::from_utf8(std::mem::take(w.get_ref())).unwrap();
        assert!(
            text.ends_with("$enddefinitions $end\n#0\n$dumpvars\n$end\n"),
            "{text}"
        );
    }

    #[test]
    fn decimals_and_dates() {
        for v in [0u64, 7, 10, 1234567890, u64::MAX] {
            let mut b = Vec::new();
            push_decimal(&mut b, v);
            assert_eq!(String::from_utf8(b).unwrap(), v.to_string());
        }
        assert_eq!(utc_date(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc_date(951_782_400 + 86_399), "2000-02-29 23:59:59 UTC");
        assert_eq!(utc_date(1_798_675_200), "2026-12-31 00:00:00 UTC");
    }
}
