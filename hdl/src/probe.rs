//! Probes: every module registers its signals (hierarchical name, width, kind) when it is
//! built, and reports their values after each clock edge to a [`Trace`], which forwards
//! only the values that changed to a [`Tracer`] (for example a VCD writer).
//!
//! With no tracer attached the simulator never calls a module's `trace`, so probing costs
//! one branch per edge; the `probes` cargo feature (on by default) removes even that.

use std::io;

/// Handle of a registered signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SignalId(pub u32);

/// What a signal is, for waveform viewers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SignalKind {
    /// Combinational value (an output of logic within the cycle).
    Wire,
    /// The output of a register.
    Reg,
    /// A clock.
    Clock,
}

/// How a waveform viewer should show a signal's values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Display {
    /// As a number (binary for one bit, hexadecimal otherwise).
    #[default]
    Number,
    /// As ASCII text, first character in the most significant byte (a name).
    Text,
    /// Value `i` is `names[i]` (a coded field: a command, a state, an opcode).
    Names(&'static [&'static str]),
}

/// A registered signal.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SignalDecl {
    /// Full hierarchical path, dot separated: `top.mac.stage2.product`.
    pub path: String,
    pub width: u32,
    pub kind: SignalKind,
    pub display: Display,
    /// One of the few signals that say what its module is doing (a unit's op in each
    /// cluster): a waveform viewer shows it in an open group of its module's module
    /// (`top.cluster0` for `top.cluster0.add0.op`) ahead of the closed detail groups.
    pub glance: bool,
}

impl SignalDecl {
    /// The enclosing scope's path (`top.mac.stage2`).
    pub fn scope(&self) -> &str {
        self.path.rsplit_once('.').map_or("", |(s, _)| s)
    }
    /// The signal's own name (`product`).
    pub fn name(&self) -> &str {
        self.path.rsplit_once('.').map_or(&self.path, |(_, n)| n)
    }
    /// Number of 64-bit words holding a value.
    pub fn words(&self) -> usize {
        self.width.div_ceil(64) as usize
    }
}

/// All signals of a design, in registration order.
#[derive(Clone, Debug, Default)]
pub struct ProbeRegistry {
    signals: Vec<SignalDecl>,
}

impl ProbeRegistry {
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers a signal at `path`. Widths must be at least 1.
    ///
    /// # Panics
    /// On a zero width or a path registered twice: both are construction bugs of a design.
    pub fn register(&mut self, path: String, width: u32, kind: SignalKind) -> SignalId {
        assert!(width > 0, "signal `{path}` declared with width 0");
        debug_assert!(
            !self.signals.iter().any(|s| s.path == path),
            "signal `{path}` registered twice"
        );
        self.signals.push(SignalDecl {
            path,
            width,
            kind,
            display: Display::Number,
            glance: false,
        });
        SignalId(self.signals.len() as u32 - 1)
    }

    /// Says how a viewer should show signal `id`'s values.
    pub fn set_display(&mut self, id: SignalId, display: Display) {
        self.signals[id.0 as usize].display = display;
    }

    /// Marks signal `id` as one to show at a glance ([`SignalDecl::glance`]).
    pub fn set_glance(&mut self, id: SignalId) {
        self.signals[id.0 as usize].glance = true;
    }

    pub fn signals(&self) -> &[SignalDecl] {
        &self.signals
    }

    pub fn get(&self, id: SignalId) -> &SignalDecl {
        &self.signals[id.0 as usize]
    }

    pub fn find(&self, path: &str) -> Option<SignalId> {
        self.signals
            .iter()
            .position(|s| s.path == path)
            .map(|i| SignalId(i as u32))
    }

    pub fn len(&self) -> usize {
        self.signals.len()
    }

    pub fn is_empty(&self) -> bool {
        self.signals.is_empty()
    }
}

/// Receives signal changes in time order.
pub trait Tracer {
    /// Called once, before any time passes, with the complete registry and the clock
    /// domains (their clock signals are registered as [`SignalKind::Clock`]).
    fn start(&mut self, probes: &ProbeRegistry, clocks: &[crate::ClockDomain]) -> io::Result<()>;
    /// Simulated time moves to `time_ps`; `core_cycle` counts rising edges of domain 0.
    fn time(&mut self, time_ps: u64, core_cycle: u64);
    /// Signal `id` now holds `value` (little-endian 64-bit words, as many as the width needs).
    fn change(&mut self, id: SignalId, value: &[u64]);
    /// The run is over: flush and report any error met while writing.
    fn finish(&mut self) -> io::Result<()>;
    /// False once the tracer ignores every further change (for example past the end of a
    /// cycle window), so the simulator can stop reporting them.
    fn wants_changes(&self) -> bool {
        true
    }
    /// Why the run must stop now (say, a waveform grown past its size limit); the
    /// simulator then returns an error with this text.
    fn abort(&self) -> Option<String> {
        None
    }
}

/// Change detector between modules and a tracer: keeps the last value of every signal and
/// forwards only changes (everything on the first report).
pub struct Trace {
    offsets: Vec<usize>,
    widths: Vec<u32>,
    last: Vec<u64>,
    seen: Vec<bool>,
    tracer: Box<dyn Tracer>,
}

impl Trace {
    pub fn new(probes: &ProbeRegistry, tracer: Box<dyn Tracer>) -> Self {
        let mut offsets = Vec::with_capacity(probes.len());
        let mut words = 0;
        for s in probes.signals() {
            offsets.push(words);
            words += s.words();
        }
        Trace {
            offsets,
            widths: probes.signals().iter().map(|s| s.width).collect(),
            last: vec![0; words],
            seen: vec![false; probes.len()],
            tracer,
        }
    }

    /// Whether the tracer still takes changes (see [`Tracer::wants_changes`]).
    pub fn wants_changes(&self) -> bool {
        self.tracer.wants_changes()
    }

    pub fn tracer(&mut self) -> &mut dyn Tracer {
        &mut *self.tracer
    }

    /// Reports a value of up to 64 bits.
    #[inline]
    pub fn value(&mut self, id: SignalId, v: u64) {
        let i = id.0 as usize;
        debug_assert!(
            self.widths[i] >= 64 || v >> self.widths[i] == 0,
            "value {v:#x} does not fit signal {i} of width {}",
            self.widths[i]
        );
        let off = self.offsets[i];
        if self.last[off] != v || !self.seen[i] {
            self.last[off] = v;
            self.seen[i] = true;
            self.tracer.change(id, &[v]);
        }
    }

    /// Reports a value of any width as little-endian words.
    pub fn wide(&mut self, id: SignalId, words: &[u64]) {
        let i = id.0 as usize;
        let off = self.offsets[i];
        let n = (self.widths[i] as usize).div_ceil(64);
        debug_assert!(
            words.len() >= n,
            "signal {i}: {} words for width {}",
            words.len(),
            self.widths[i]
        );
        let words = &words[..n];
        debug_assert!(
            self.widths[i].is_multiple_of(64) || words[n - 1] >> (self.widths[i] % 64) == 0,
            "value does not fit signal {i} of width {}",
            self.widths[i]
        );
        if &self.last[off..off + n] != words || !self.seen[i] {
            self.last[off..off + n].copy_from_slice(words);
            self.seen[i] = true;
            self.tracer.change(id, words);
        }
    }

    /// Reports `text` on a [`Display::Text`] signal as a Verilog string is held: the last
    /// character in the lowest byte, leading bytes zero; a longer text is cut to its first
    /// characters.
    pub fn text(&mut self, id: SignalId, text: &str) {
        let i = id.0 as usize;
        let bytes = (self.widths[i] / 8) as usize;
        let mut words = [0u64; 8];
        let n = (self.widths[i] as usize).div_ceil(64).min(words.len());
        let kept = &text.as_bytes()[..text.len().min(bytes).min(8 * words.len())];
        for (k, &b) in kept.iter().enumerate() {
            let bit = 8 * (kept.len() - 1 - k);
            words[bit / 64] |= u64::from(b) << (bit % 64);
        }
        self.wide(id, &words[..n]);
    }

    /// Reports a typed value of up to 128 bits.
    #[inline]
    pub fn bits<T: crate::Bits>(&mut self, id: SignalId, v: T) {
        let x = v.to_u128();
        if T::WIDTH <= 64 {
            self.value(id, x as u64);
        } else {
            self.wide(id, &[x as u64, (x >> 64) as u64]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Recorder;

    #[test]
    fn only_changes_are_forwarded() {
        let mut reg = ProbeRegistry::new();
        let a = reg.register("top.a".into(), 8, SignalKind::Reg);
        let w = reg.register("top.w".into(), 130, SignalKind::Wire);
        let recorder = Recorder::default();
        let mut t = Trace::new(&reg, Box::new(recorder.clone()));
        t.value(a, 0); // first report always goes out
        t.value(a, 0);
        t.value(a, 5);
        t.wide(w, &[1, 2, 3]);
        t.wide(w, &[1, 2, 3]);
        t.wide(w, &[1, 2, 1]);
        let got: Vec<(u32, Vec<u64>)> = recorder
            .recording()
            .changes
            .iter()
            .map(|(_, id, v)| (id.0, v.clone()))
            .collect();
        assert_eq!(
            got,
            vec![
                (0, vec![0]),
                (0, vec![5]),
                (1, vec![1, 2, 3]),
                (1, vec![1, 2, 1])
            ]
        );
        assert_eq!(reg.get(w).words(), 3);
        assert_eq!(reg.get(a).scope(), "top");
        assert_eq!(reg.get(a).name(), "a");
    }

    #[test]
    fn text_is_held_as_a_verilog_string() {
        let mut reg = ProbeRegistry::new();
        let k = reg.register("top.kernel".into(), 32, SignalKind::Reg);
        let recorder = Recorder::default();
        let mut t = Trace::new(&reg, Box::new(recorder.clone()));
        t.text(k, "ab");
        t.text(k, "xyrast"); // cut to the 4 characters the signal holds
        let values: Vec<u64> = recorder
            .recording()
            .changes
            .iter()
            .map(|(_, _, v)| v[0])
            .collect();
        assert_eq!(values, vec![0x6162, 0x7879_7261]);
    }

    #[test]
    #[should_panic(expected = "does not fit")]
    #[cfg(debug_assertions)]
    fn a_value_wider_than_its_signal_is_caught() {
        let mut reg = ProbeRegistry::new();
        let a = reg.register("top.a".into(), 4, SignalKind::Reg);
        let mut t = Trace::new(&reg, Box::new(Recorder::default()));
        t.value(a, 16);
    }
}
