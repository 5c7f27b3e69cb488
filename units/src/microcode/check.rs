//! Does a [`Program`] fit a machine? [`Program::check`] finds the first way it does not and
//! names the kernel, the instruction and the slot or field in a [`MicrocodeError`].
//!
//! What is checked (everything that can be decided from the program text alone):
//!
//! * **shape** — one slot per unit as the machine counts them: `fu` has one per adder,
//!   multiplier and divide/sqrt unit, `sp` one per scratchpad, `comm` one per
//!   communication unit, `sin` `srf.cluster_words_per_cycle`;
//! * **units** — every [`FuSlot`]'s op runs on that slot's unit class;
//! * **registers** — LRF entries are below the size of the LRF they name (the inputs of a
//!   slot `addN` are `addN.a`/`addN.b`, of `spN` `spN.addr`/`spN.data`, of `commN`
//!   `commN.data`/`commN.perm`, of `sout` `sout.data`); a [`Dest`]'s LRF exists and its
//!   entry, condition code or stream is in range; condition codes are below
//!   `cluster.condition_codes`; scratchpad bases below `scratchpad.words`; permutation
//!   constants name a cluster (and `xor k` maps every cluster to a cluster);
//! * **canonical form** — fields a slot does not use are 0 (`b` of a one-operand op, `cc` of
//!   anything but `select`, `data` of a scratchpad read, the destinations of a scratchpad
//!   write), a second destination only after a first, no destination twice, and not two
//!   destinations in one LRF (one write port, and both land in the same cycle). Encoding and
//!   the assembler rely on this to be exact;
//! * **streams** — at most `srf.kernel_streams` declared, names are identifiers and unique;
//!   `sin` and stream loops read `In` streams, `sout` and [`Dest::Stream`] write `Out`
//!   streams; per instruction at most `srf.cluster_words_per_cycle` stream words (`sin`
//!   slots used + `sout`) and at most `srf.conditional_words_per_cycle` conditional ones,
//!   which occupy the intercluster network (`comm0`) and the scratchpad (`sp0`) in their
//!   instruction;
//! * **control** — loops properly nested (each [`Control`] `end` closes the innermost open
//!   loop; an instruction with both `begin` and `end` is a one-instruction loop body) and at
//!   most `microcontroller.loop_depth` deep, `stages` in `1..=`[`MAX_STAGES`], `until cc`
//!   loops have one stage, every slot's stage is below its innermost loop's `stages` (0
//!   outside loops); `pass_end` (a pass of a body unrolled for modulo variable expansion
//!   ends there) only inside a loop, never with `end` (the body's last pass would be empty)
//!   nor with `done`; `begin` with `pass_end` is allowed: a first pass of one instruction.
//!   In a loop over a stream every pass reads the same number of unconditional words of
//!   that stream, counting the instructions of nested loops as the microcontroller does
//!   (its iteration count is the stream's rows divided by the first pass's words). The
//!   program ends with exactly one `done`, as its last instruction, outside any loop, and
//!   that instruction neither begins nor ends a loop; the code fits
//!   `microcontroller.store_words`.
//!
//! Not checked here, because it depends on timing: two results landing in one LRF (or on one
//! unit's result port) in the same cycle, the divide/sqrt issue interval, scratchpad
//! addresses `base + offset` beyond the scratchpad, and [`Dest::Stream`] words competing with
//! `sin`/`sout` for stream bandwidth. The machine reports those when it runs.

use std::fmt;

use crate::desc::MachineDesc;
use crate::ops::{Op, UnitClass};

use super::{
    CommSlot, Control, Dest, Dests, FuSlot, ImmValue, Instruction, LoopBegin, LoopKind,
    Permutation, Program, SpSlot, StreamDir, StreamIn, StreamOut,
};

/// Software-pipeline stages a loop may have: the `stage` field of a slot is 4 bits wide
/// (short loops of long-latency ops, at an initiation interval of 1 or 2, need more than 8).
pub const MAX_STAGES: u8 = 16;

/// A program that does not fit the machine, or a word that is not an instruction. Names
/// where: the kernel, the instruction index and the slot or field (as the instruction
/// layout names them: `add0.a`, `sin1.stream`, `ctl`), whichever apply.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MicrocodeError {
    pub kernel: Option<String>,
    pub instruction: Option<usize>,
    pub field: Option<String>,
    pub message: String,
}

impl MicrocodeError {
    pub(crate) fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        MicrocodeError {
            kernel: None,
            instruction: None,
            field: Some(field.into()),
            message: message.into(),
        }
    }
}

impl fmt::Display for MicrocodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts = Vec::new();
        match &self.kernel {
            Some(k) => parts.push(format!("kernel `{k}`")),
            None if self.instruction.is_none() => parts.push("microcode word".to_string()),
            None => {}
        }
        if let Some(i) = self.instruction {
            parts.push(format!("instruction {i}"));
        }
        if let Some(field) = &self.field {
            parts.push(format!("`{field}`"));
        }
        if self.kernel.is_some() && self.instruction.is_none() && self.field.is_none() {
            // "kernel `x` needs 2100 instructions; …"
            write!(f, "{} {}", parts.join(", "), self.message)
        } else {
            write!(f, "{}: {}", parts.join(", "), self.message)
        }
    }
}

impl std::error::Error for MicrocodeError {}

/// The slots and LRFs of a cluster as a machine description counts them: slot names,
/// unit classes and which LRF each slot input reads.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Shape {
    pub adders: usize,
    pub multipliers: usize,
    pub divsqrt: usize,
    pub scratchpads: usize,
    pub comm_units: usize,
    pub stream_ins: usize,
    pub clusters: usize,
    pub condition_codes: usize,
    pub kernel_streams: usize,
    pub scratchpad_words: usize,
    /// `MachineDesc::lrf_names`, and the entries of each.
    pub lrf_names: Vec<String>,
    pub lrf_sizes: Vec<usize>,
}

impl Shape {
    pub fn new(desc: &MachineDesc) -> Shape {
        let c = &desc.cluster;
        let lrf_names = desc.lrf_names();
        let lrf_sizes = lrf_names.iter().map(|n| desc.lrf_entries(n)).collect();
        Shape {
            adders: c.adders,
            multipliers: c.multipliers,
            divsqrt: c.divsqrt,
            scratchpads: c.scratchpads,
            comm_units: c.comm_units,
            stream_ins: desc.srf.cluster_words_per_cycle,
            clusters: c.count,
            condition_codes: c.condition_codes,
            kernel_streams: desc.srf.kernel_streams,
            scratchpad_words: desc.scratchpad.words,
            lrf_names,
            lrf_sizes,
        }
    }

    /// Arithmetic slots: adders, then multipliers, then divide/sqrt units.
    pub fn fu_count(&self) -> usize {
        self.adders + self.multipliers + self.divsqrt
    }

    /// The unit class of arithmetic slot `i`.
    pub fn fu_class(&self, i: usize) -> UnitClass {
        if i < self.adders {
            UnitClass::Adder
        } else if i < self.adders + self.multipliers {
            UnitClass::Multiplier
        } else {
            UnitClass::DivSqrt
        }
    }

    /// The name of arithmetic slot `i`: `add0`, `mul1`, `dsq0`.
    pub fn fu_name(&self, i: usize) -> String {
        match self.fu_class(i) {
            UnitClass::Adder => format!("add{i}"),
            UnitClass::Multiplier => format!("mul{}", i - self.adders),
            UnitClass::DivSqrt => format!("dsq{}", i - self.adders - self.multipliers),
        }
    }

    /// The arithmetic slot called `name`, if there is one.
    pub fn fu_index(&self, name: &str) -> Option<usize> {
        let (base, n) = if let Some(n) = name.strip_prefix("add") {
            (0, (n, self.adders))
        } else if let Some(n) = name.strip_prefix("mul") {
            (self.adders, (n, self.multipliers))
        } else if let Some(n) = name.strip_prefix("dsq") {
            (self.adders + self.multipliers, (n, self.divsqrt))
        } else {
            return None;
        };
        let i = parse_index(n.0)?;
        (i < n.1).then_some(base + i)
    }

    /// Index of the LRF called `name` in `lrf_names`.
    pub fn lrf_index(&self, name: &str) -> Option<usize> {
        self.lrf_names.iter().position(|n| n == name)
    }

    /// Index and size of the LRF `slot.input` (e.g. `add0`, `a`).
    ///
    /// # Panics
    /// If the machine has no such LRF.
    pub fn lrf(&self, slot: &str, input: &str) -> (usize, usize) {
        let name = format!("{slot}.{input}");
        let i = self
            .lrf_index(&name)
            .unwrap_or_else(|| panic!("the machine has no LRF `{name}`"));
        (i, self.lrf_sizes[i])
    }

    /// Entries of the largest LRF.
    pub fn max_lrf_entries(&self) -> usize {
        self.lrf_sizes.iter().copied().max().unwrap_or(1)
    }

    /// Counts in words for errors: "3 adders, 2 multipliers, 1 divide/sqrt unit".
    fn fu_counts(&self) -> String {
        format!(
            "{} adder{}, {} multiplier{}, {} divide/sqrt unit{}",
            self.adders,
            plural(self.adders),
            self.multipliers,
            plural(self.multipliers),
            self.divsqrt,
            plural(self.divsqrt)
        )
    }
}

/// A decimal index without sign or leading zeros (`0`, `12`).
pub(crate) fn parse_index(s: &str) -> Option<usize> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) || (s.len() > 1 && s.starts_with('0'))
    {
        return None;
    }
    s.parse().ok()
}

/// "an adder", "a multiplier".
fn a_unit(class: UnitClass) -> String {
    match class {
        UnitClass::Adder => format!("an {class}"),
        _ => format!("a {class}"),
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// True for names the assembler can spell: a letter or `_`, then letters, digits, `_`, `.`.
pub fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
}

impl Instruction {
    /// An instruction shaped for `desc` with every slot empty (a `nop`).
    pub fn empty(desc: &MachineDesc) -> Instruction {
        let sh = Shape::new(desc);
        Instruction {
            control: Control::NEXT,
            fu: vec![None; sh.fu_count()],
            sp: vec![None; sh.scratchpads],
            comm: vec![None; sh.comm_units],
            sin: vec![None; sh.stream_ins],
            sout: None,
            imm: None,
        }
    }

    /// True if no slot issues (the control field aside).
    pub fn is_empty(&self) -> bool {
        self.fu.iter().all(Option::is_none)
            && self.sp.iter().all(Option::is_none)
            && self.comm.iter().all(Option::is_none)
            && self.sin.iter().all(Option::is_none)
            && self.sout.is_none()
            && self.imm.is_none()
    }

    /// Unconditional words of kernel stream `stream` this instruction reads per cluster
    /// (what a pass of a loop over the stream consumes).
    pub fn unconditional_reads(&self, stream: u16) -> usize {
        self.sin
            .iter()
            .flatten()
            .filter(|r| r.stream == stream && r.cond.is_none())
            .count()
    }
}

impl Program {
    /// Checks that the program fits `desc` (see the [module documentation](self)); the
    /// first problem found is returned.
    pub fn check(&self, desc: &MachineDesc) -> Result<(), MicrocodeError> {
        check(self, desc)
    }
}

/// [`Program::check`].
pub fn check(program: &Program, desc: &MachineDesc) -> Result<(), MicrocodeError> {
    Checker {
        program,
        desc,
        shape: Shape::new(desc),
    }
    .run()
}

struct Checker<'a> {
    program: &'a Program,
    desc: &'a MachineDesc,
    shape: Shape,
}

/// An open loop during the walk.
struct Open {
    begin: usize,
    stages: u8,
    kind: LoopKind,
    /// First instruction of the current pass.
    pass_begin: usize,
    /// Unconditional words of the loop's stream (stream loops) read so far in this pass.
    reads: usize,
    /// The first pass's last instruction and words read, once it has ended.
    first: Option<(usize, usize)>,
}

impl Checker<'_> {
    fn kernel_error(&self, message: String) -> MicrocodeError {
        MicrocodeError {
            kernel: Some(self.program.name.clone()),
            instruction: None,
            field: None,
            message,
        }
    }

    fn error(&self, i: usize, field: impl Into<String>, message: String) -> MicrocodeError {
        MicrocodeError {
            kernel: Some(self.program.name.clone()),
            instruction: Some(i),
            field: Some(field.into()),
            message,
        }
    }

    fn run(&self) -> Result<(), MicrocodeError> {
        let p = self.program;
        if !is_identifier(&p.name) {
            return Err(self.kernel_error(
                "has a name that is not an identifier (a letter or `_`, then letters, digits, \
                 `_` or `.`)"
                    .into(),
            ));
        }
        let max = self.desc.srf.kernel_streams;
        if p.streams.len() > max {
            return Err(self.kernel_error(format!(
                "declares {} streams; a kernel may address at most {max} (`srf.kernel_streams`)",
                p.streams.len()
            )));
        }
        for (i, s) in p.streams.iter().enumerate() {
            if !is_identifier(&s.name) {
                return Err(self.kernel_error(format!(
                    "declares stream {i} as `{}`, which is not an identifier",
                    s.name
                )));
            }
            if p.streams[..i].iter().any(|t| t.name == s.name) {
                return Err(
                    self.kernel_error(format!("declares stream `{}` more than once", s.name))
                );
            }
        }
        let store = self.desc.microcontroller.store_words;
        if p.code.len() > store {
            return Err(self.kernel_error(format!(
                "needs {} instructions; the microcode store holds {store}",
                p.code.len()
            )));
        }
        if p.code.is_empty() {
            return Err(self.kernel_error("has no instructions (it must end with `done`)".into()));
        }

        let mut open: Vec<Open> = Vec::new();
        for (i, ins) in p.code.iter().enumerate() {
            let ctl = ins.control;
            if ctl.done && (ctl.begin.is_some() || ctl.end) {
                return Err(self.error(
                    i,
                    "ctl.done",
                    format!(
                        "`done` on an instruction that also {} a loop; the kernel's last \
                         instruction is outside every loop and carries only `done`",
                        if ctl.begin.is_some() {
                            "begins"
                        } else {
                            "ends"
                        }
                    ),
                ));
            }
            if ctl.done && ctl.pass_end {
                return Err(self.error(
                    i,
                    "ctl.pass",
                    "`pass` on the `done` instruction; the kernel's last instruction is \
                     outside every loop, and a pass ends only inside one"
                        .into(),
                ));
            }
            if ctl.pass_end && ctl.end {
                return Err(self.error(
                    i,
                    "ctl.pass",
                    "`pass` on an instruction that also ends a loop: `end` ends the body's \
                     last pass, so a pass end here too would leave that pass empty; drop \
                     the `pass`"
                        .into(),
                ));
            }
            // Control first: a loop's first instruction's own slots are inside the loop it
            // opens (and a one-instruction body's are inside the loop it both opens and ends).
            if let Some(LoopBegin { kind, stages }) = ctl.begin {
                self.check_loop(i, kind, stages)?;
                if open.len() >= self.desc.microcontroller.loop_depth {
                    return Err(self.error(
                        i,
                        "ctl.begin",
                        format!(
                            "opens a loop nested {} deep; the loop stack holds {} \
                             (`microcontroller.loop_depth`)",
                            open.len() + 1,
                            self.desc.microcontroller.loop_depth
                        ),
                    ));
                }
                open.push(Open {
                    begin: i,
                    stages,
                    kind,
                    pass_begin: i,
                    reads: 0,
                    first: None,
                });
            }
            // With `begin`, `pass_end` ends the first pass (of one instruction) of the loop
            // just opened.
            if ctl.pass_end && open.is_empty() {
                return Err(self.error(
                    i,
                    "ctl.pass",
                    "`pass` outside every loop; it ends a pass of the innermost loop".into(),
                ));
            }
            let stages = open.last().map_or(1, |l| l.stages);
            self.check_instruction(i, ins, stages)?;
            for l in &mut open {
                if let LoopKind::UntilStreamEmpty(s) = l.kind {
                    l.reads += ins.unconditional_reads(s);
                }
            }
            if ctl.ends_pass()
                && let Some(l) = open.last_mut()
            {
                self.check_pass(i, ctl.end, l)?;
            }
            if ctl.end && open.pop().is_none() {
                return Err(self.error(i, "ctl.end", "`end` closes no open loop".into()));
            }
            if ctl.done {
                if let Some(l) = open.last() {
                    return Err(self.error(
                        i,
                        "ctl.done",
                        format!(
                            "`done` inside the loop that begins at instruction {}; a kernel \
                             ends outside every loop",
                            l.begin
                        ),
                    ));
                }
                if i + 1 != p.code.len() {
                    return Err(self.error(
                        i,
                        "ctl.done",
                        format!(
                            "`done` before the last instruction ({}); `done` must be the last \
                             instruction and appear once",
                            p.code.len() - 1
                        ),
                    ));
                }
            }
        }
        let last = p.code.len() - 1;
        if let Some(l) = open.last() {
            return Err(self.error(
                l.begin,
                "ctl.begin",
                "opens a loop that is never closed by an `end`".into(),
            ));
        }
        if !p.code[last].control.done {
            return Err(self.error(
                last,
                "ctl.done",
                "the last instruction is not `done`; a kernel ends with exactly one `done`".into(),
            ));
        }
        Ok(())
    }

    /// Pass `l.pass_begin..=i` of loop `l` has ended (at its `end` if `end`): a loop over a
    /// stream reads as many of its words in every pass as in the first.
    fn check_pass(&self, i: usize, end: bool, l: &mut Open) -> Result<(), MicrocodeError> {
        let reads = std::mem::take(&mut l.reads);
        let pass_begin = std::mem::replace(&mut l.pass_begin, i + 1);
        let Some((first_end, first)) = l.first else {
            l.first = Some((i, reads));
            return Ok(());
        };
        let LoopKind::UntilStreamEmpty(s) = l.kind else {
            return Ok(());
        };
        if reads == first {
            return Ok(());
        }
        let name = &self.program.streams[usize::from(s)].name;
        Err(self.error(
            i,
            if end { "ctl.end" } else { "ctl.pass" },
            format!(
                "the pass of instructions {pass_begin}..={i} reads {reads} unconditional \
                 word{} of stream `{name}` per cluster, but the loop's first pass \
                 (instructions {}..={first_end}) reads {first}; every pass of a loop over a \
                 stream reads as many (its iterations are the stream's rows divided by the \
                 words of one pass)",
                plural(reads),
                l.begin
            ),
        ))
    }

    fn check_loop(&self, i: usize, kind: LoopKind, stages: u8) -> Result<(), MicrocodeError> {
        if !(1..=MAX_STAGES).contains(&stages) {
            return Err(self.error(
                i,
                "ctl.stages",
                format!("a loop has 1..={MAX_STAGES} software-pipeline stages, not {stages}"),
            ));
        }
        match kind {
            LoopKind::Counted(_) => {}
            LoopKind::UntilStreamEmpty(s) => self.check_stream(i, "ctl.value", s, StreamDir::In)?,
            LoopKind::UntilCc(cc) => {
                self.check_cc(i, "ctl.value", cc)?;
                if stages != 1 {
                    return Err(self.error(
                        i,
                        "ctl.stages",
                        format!(
                            "an `until cc` loop cannot be software-pipelined (stages must be 1, \
                             not {stages}): its iteration count is not known in advance"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    fn check_instruction(
        &self,
        i: usize,
        ins: &Instruction,
        stages: u8,
    ) -> Result<(), MicrocodeError> {
        let sh = &self.shape;
        let lengths = [
            ("fu", ins.fu.len(), sh.fu_count(), sh.fu_counts()),
            (
                "sp",
                ins.sp.len(),
                sh.scratchpads,
                format!("{} scratchpad{}", sh.scratchpads, plural(sh.scratchpads)),
            ),
            (
                "comm",
                ins.comm.len(),
                sh.comm_units,
                format!(
                    "{} communication unit{}",
                    sh.comm_units,
                    plural(sh.comm_units)
                ),
            ),
            (
                "sin",
                ins.sin.len(),
                sh.stream_ins,
                format!(
                    "{} stream input{} (`srf.cluster_words_per_cycle`)",
                    sh.stream_ins,
                    plural(sh.stream_ins)
                ),
            ),
        ];
        for (field, have, want, what) in lengths {
            if have != want {
                return Err(self.error(
                    i,
                    field,
                    format!(
                        "has {have} slot{}; machine `{}` has {want} ({what})",
                        plural(have),
                        self.desc.name
                    ),
                ));
            }
        }
        let stage_ok = |slot: &str, stage: u8| -> Result<(), MicrocodeError> {
            if stage < stages {
                return Ok(());
            }
            let why = if stages == 1 {
                "outside a software-pipelined loop every slot is stage 0".to_string()
            } else {
                format!("the loop has {stages} stages (0..={})", stages - 1)
            };
            Err(self.error(
                i,
                format!("{slot}.stage"),
                format!("stage {stage} is out of range: {why}"),
            ))
        };
        for (k, slot) in ins.fu.iter().enumerate() {
            if let Some(s) = slot {
                let name = sh.fu_name(k);
                self.check_fu(i, k, &name, s)?;
                stage_ok(&name, s.stage)?;
            }
        }
        for (k, slot) in ins.sp.iter().enumerate() {
            if let Some(s) = slot {
                let name = format!("sp{k}");
                self.check_sp(i, &name, s)?;
                stage_ok(&name, s.stage)?;
            }
        }
        for (k, slot) in ins.comm.iter().enumerate() {
            if let Some(s) = slot {
                let name = format!("comm{k}");
                self.check_comm(i, &name, s)?;
                stage_ok(&name, s.stage)?;
            }
        }
        for (k, slot) in ins.sin.iter().enumerate() {
            if let Some(s) = slot {
                let name = format!("sin{k}");
                self.check_sin(i, &name, s)?;
                stage_ok(&name, s.stage)?;
            }
        }
        if let Some(s) = &ins.sout {
            self.check_sout(i, s)?;
            stage_ok("sout", s.stage)?;
        }
        if let Some(s) = &ins.imm {
            let _: ImmValue = s.value;
            self.check_dests(i, "imm", &s.dests)?;
            stage_ok("imm", s.stage)?;
        }
        // Stream bandwidth per cluster in this instruction.
        let words = ins.sin.iter().flatten().count() + usize::from(ins.sout.is_some());
        let max = self.desc.srf.cluster_words_per_cycle;
        if words > max {
            return Err(self.error(
                i,
                "sout",
                format!(
                    "moves {words} stream words per cluster (stream inputs and the stream \
                     output); the SRF gives a cluster {max} per cycle \
                     (`srf.cluster_words_per_cycle`)"
                ),
            ));
        }
        let conditional = ins
            .sin
            .iter()
            .flatten()
            .filter(|s| s.cond.is_some())
            .count()
            + usize::from(ins.sout.is_some_and(|s| s.cond.is_some()));
        let max = self.desc.srf.conditional_words_per_cycle;
        if conditional > max {
            let field = match ins.sout {
                Some(StreamOut { cond: Some(_), .. }) => "sout".to_string(),
                _ => format!(
                    "sin{}",
                    ins.sin
                        .iter()
                        .enumerate()
                        .filter(|(_, s)| s.is_some_and(|s| s.cond.is_some()))
                        .nth(max)
                        .map_or(0, |(k, _)| k)
                ),
            };
            return Err(self.error(
                i,
                field,
                format!(
                    "moves {conditional} conditional stream words per cluster; conditional \
                     streams carry {max} per cycle (`srf.conditional_words_per_cycle`)"
                ),
            ));
        }
        // Conditional streams route their words over the intercluster network and buffer
        // them in the scratchpad (Kapasi et al., MICRO 2000), which then serve nothing else
        // that cycle.
        if conditional > 0 && ins.comm.first().is_some_and(Option::is_some) {
            return Err(self.error(
                i,
                "comm0",
                "is busy: a conditional stream access in the same instruction routes its \
                 words over the intercluster network"
                    .to_string(),
            ));
        }
        if conditional > 0 && ins.sp.first().is_some_and(Option::is_some) {
            return Err(self.error(
                i,
                "sp0",
                "is busy: a conditional stream access in the same instruction buffers its \
                 words in the scratchpad"
                    .to_string(),
            ));
        }
        Ok(())
    }

    fn check_entry(
        &self,
        i: usize,
        slot: &str,
        input: &str,
        entry: u16,
    ) -> Result<(), MicrocodeError> {
        let (_, size) = self.shape.lrf(slot, input);
        if usize::from(entry) >= size {
            return Err(self.error(
                i,
                format!("{slot}.{input}"),
                format!("entry {entry} is out of range: LRF `{slot}.{input}` has {size} entries"),
            ));
        }
        Ok(())
    }

    fn check_zero(
        &self,
        i: usize,
        field: String,
        value: u16,
        why: &str,
    ) -> Result<(), MicrocodeError> {
        if value != 0 {
            return Err(self.error(
                i,
                field,
                format!("is {value} but {why}; an unused field must be 0"),
            ));
        }
        Ok(())
    }

    fn check_cc(&self, i: usize, field: &str, cc: u16) -> Result<(), MicrocodeError> {
        let n = self.shape.condition_codes;
        if usize::from(cc) >= n {
            return Err(self.error(
                i,
                field,
                format!(
                    "condition code {cc} is out of range: a cluster has {n} (`cluster.condition_codes`)"
                ),
            ));
        }
        Ok(())
    }

    fn check_stream(
        &self,
        i: usize,
        field: &str,
        s: u16,
        dir: StreamDir,
    ) -> Result<(), MicrocodeError> {
        let streams = &self.program.streams;
        let Some(decl) = streams.get(usize::from(s)) else {
            return Err(self.error(
                i,
                field,
                format!(
                    "stream {s} is not declared (the kernel declares {})",
                    streams.len()
                ),
            ));
        };
        if decl.dir != dir {
            let (want, is) = match dir {
                StreamDir::In => ("reads an input", "an output"),
                StreamDir::Out => ("writes an output", "an input"),
            };
            return Err(self.error(
                i,
                field,
                format!(
                    "{want} stream, but stream {s} `{}` is {is} stream",
                    decl.name
                ),
            ));
        }
        Ok(())
    }

    fn check_fu(&self, i: usize, k: usize, name: &str, s: &FuSlot) -> Result<(), MicrocodeError> {
        let class = self.shape.fu_class(k);
        if s.op.unit() != class {
            return Err(self.error(
                i,
                format!("{name}.op"),
                format!(
                    "`{}` runs on {}, but `{name}` is {}",
                    s.op,
                    a_unit(s.op.unit()),
                    a_unit(class)
                ),
            ));
        }
        self.check_entry(i, name, "a", s.a)?;
        if s.op.arity() >= 2 {
            self.check_entry(i, name, "b", s.b)?;
        } else {
            self.check_zero(
                i,
                format!("{name}.b"),
                s.b,
                &format!("`{}` takes one operand", s.op),
            )?;
        }
        if s.op == Op::Select {
            self.check_cc(i, &format!("{name}.cc"), s.cc)?;
        } else {
            self.check_zero(
                i,
                format!("{name}.cc"),
                s.cc,
                &format!("only `select` reads a condition code, not `{}`", s.op),
            )?;
        }
        self.check_dests(i, name, &s.dests)
    }

    fn check_sp(&self, i: usize, name: &str, s: &SpSlot) -> Result<(), MicrocodeError> {
        let words = self.shape.scratchpad_words;
        if usize::from(s.base) >= words {
            return Err(self.error(
                i,
                format!("{name}.base"),
                format!(
                    "base {} is out of range: the scratchpad has {words} words (`scratchpad.words`)",
                    s.base
                ),
            ));
        }
        if let Some(o) = s.offset {
            self.check_entry(i, name, "addr", o)?;
        }
        if s.write {
            self.check_entry(i, name, "data", s.data)?;
            if s.dests.iter().any(Option::is_some) {
                return Err(self.error(
                    i,
                    format!("{name}.dest0"),
                    "a scratchpad write has no result; its destinations must be empty".into(),
                ));
            }
            Ok(())
        } else {
            self.check_zero(
                i,
                format!("{name}.data"),
                s.data,
                "a scratchpad read writes no data",
            )?;
            self.check_dests(i, name, &s.dests)
        }
    }

    fn check_comm(&self, i: usize, name: &str, s: &CommSlot) -> Result<(), MicrocodeError> {
        self.check_entry(i, name, "data", s.data)?;
        let c = self.shape.clusters;
        let field = format!("{name}.perm");
        let (what, k) = match s.perm {
            Permutation::PerCluster(e) => {
                self.check_entry(i, name, "perm", e)?;
                return self.check_dests(i, name, &s.dests);
            }
            Permutation::Rotate(k) => ("rotate", k),
            Permutation::Xor(k) => ("xor", k),
            Permutation::Broadcast(k) => ("bcast", k),
        };
        if usize::from(k) >= c {
            return Err(self.error(
                i,
                field,
                format!(
                    "`{what} {k}` names cluster {k}, but the machine has {c} cluster{} (0..={})",
                    plural(c),
                    c - 1
                ),
            ));
        }
        let leaves = match s.perm {
            Permutation::Xor(k) => (0..c).find(|&from| from ^ usize::from(k) >= c),
            _ => None,
        };
        if let Some(from) = leaves {
            return Err(self.error(
                i,
                field,
                format!(
                    "`xor {k}` sends cluster {from} to cluster {}, but the machine has {c} clusters",
                    from ^ usize::from(k)
                ),
            ));
        }
        self.check_dests(i, name, &s.dests)
    }

    fn check_sin(&self, i: usize, name: &str, s: &StreamIn) -> Result<(), MicrocodeError> {
        self.check_stream(i, &format!("{name}.stream"), s.stream, StreamDir::In)?;
        if let Some(cc) = s.cond {
            self.check_cc(i, &format!("{name}.cond"), cc)?;
        }
        self.check_dests(i, name, &s.dests)
    }

    fn check_sout(&self, i: usize, s: &StreamOut) -> Result<(), MicrocodeError> {
        self.check_stream(i, "sout.stream", s.stream, StreamDir::Out)?;
        self.check_entry(i, "sout", "data", s.data)?;
        if let Some(cc) = s.cond {
            self.check_cc(i, "sout.cond", cc)?;
        }
        Ok(())
    }

    fn check_dests(&self, i: usize, slot: &str, dests: &Dests) -> Result<(), MicrocodeError> {
        if dests[0].is_none() && dests[1].is_some() {
            return Err(self.error(
                i,
                format!("{slot}.dest1"),
                "a second destination without a first; use dest0 first".into(),
            ));
        }
        for (d, dest) in dests.iter().enumerate() {
            let Some(dest) = dest else { continue };
            let field = format!("{slot}.dest{d}");
            match *dest {
                Dest::Lrf { lrf, entry } => {
                    let sh = &self.shape;
                    let Some(size) = sh.lrf_sizes.get(usize::from(lrf)) else {
                        return Err(self.error(
                            i,
                            field,
                            format!(
                                "LRF {lrf} does not exist: a cluster has {} LRFs",
                                sh.lrf_names.len()
                            ),
                        ));
                    };
                    if usize::from(entry) >= *size {
                        return Err(self.error(
                            i,
                            field,
                            format!(
                                "entry {entry} is out of range: LRF `{}` has {size} entries",
                                sh.lrf_names[usize::from(lrf)]
                            ),
                        ));
                    }
                }
                Dest::Cc { index } => self.check_cc(i, &field, index)?,
                Dest::Stream { stream } => {
                    self.check_stream(i, &field, stream, StreamDir::Out)?;
                }
            }
        }
        if let [Some(a), Some(b)] = dests {
            let clash = match (a, b) {
                (Dest::Lrf { lrf: x, .. }, Dest::Lrf { lrf: y, .. }) if x == y => Some(format!(
                    "both destinations write LRF `{}` in the same cycle; an LRF has one write port",
                    self.shape.lrf_names[usize::from(*x)]
                )),
                _ if a == b => Some("both destinations are the same".into()),
                _ => None,
            };
            if let Some(message) = clash {
                return Err(self.error(i, format!("{slot}.dest1"), message));
            }
        }
        Ok(())
    }
}
