//! The microcode of the clusters: one VLIW instruction per cycle, issued by the
//! microcontroller to every cluster at once (SIMD).
//!
//! An [`Instruction`] has one slot per unit of a cluster, as the machine description counts
//! them, plus a control field for the microcontroller:
//!
//! | slot | reads | does | result goes |
//! |---|---|---|---|
//! | `addN`, `mulN`, `dsqN` ([`FuSlot`]) | entry of its own input LRFs `unit.a`, `unit.b`; a condition code for `select` | an [`Op`] | through the intracluster switch to up to two [`Dest`]s, `latency(op)` cycles later |
//! | `spN` ([`SpSlot`]) | `spN.addr` (offset), `spN.data` (write data) | scratchpad read or write at `base + offset` | reads: to [`Dest`]s after `scratchpad_read` cycles |
//! | `commN` ([`CommSlot`]) | `commN.data`, `commN.perm` (per-cluster source) | sends one word per cluster over the intercluster network | the word from the source cluster, to [`Dest`]s after `comm` cycles |
//! | `sinN` ([`StreamIn`]) | — | takes the next element of an input stream (conditionally: only clusters whose condition code is set) | to [`Dest`]s after `stream` cycles |
//! | `sout` ([`StreamOut`]) | `sout.data` | appends to an output stream (conditionally: only clusters whose condition code is set, order kept) | the stream buffer |
//! | `imm` ([`Immediate`]) | — | a constant, or the cluster's index | to [`Dest`]s the next cycle |
//!
//! A [`Dest`] is an LRF entry, a condition code, or an output stream (a result may be
//! appended to a stream directly from the switch).
//!
//! Every slot carries a software-pipeline `stage`. In a loop whose body is marked with
//! `stages = S` and which runs `N` iterations, the microcontroller runs `N + S − 1` passes
//! and squashes (suppresses the writes and stream accesses of) every op of stage `s` in pass
//! `p` unless `s ≤ p < N + s`: the prologue and epilogue of a modulo-scheduled loop come
//! for free from one copy of the kernel (Rau 1994; Imagine's microcontroller did the same).
//! A loop body may be a single instruction whose [`Control`] field both begins and ends the
//! loop, so a modulo-scheduled loop can start an iteration every cycle (initiation interval
//! 1). A body may also hold several passes (`pass_end` marks where each but the last ends):
//! with no rotating register file, modulo variable expansion unrolls the kernel `K` times,
//! each copy naming different LRF entries for values that live longer than the initiation
//! interval (Lam 1988), and the microcontroller counts a pass, and may leave the loop, at
//! every pass boundary.
//!
//! [`layout`] packs instructions into bit words whose fields and widths follow from the
//! machine description; [`asm`] is the text form.

pub mod asm;
pub mod check;
pub mod image;
pub mod layout;

pub use asm::{AsmError, assemble, disassemble};
pub use check::{MAX_STAGES, MicrocodeError};
pub use layout::InstructionLayout;

use crate::ops::Op;

/// Where a result is written through the intracluster switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dest {
    /// Entry `entry` of LRF number `lrf` (index into `MachineDesc::lrf_names`).
    Lrf { lrf: u16, entry: u16 },
    /// Condition code `index`: bit 0 of the result.
    Cc { index: u16 },
    /// Appended to the kernel's stream `stream` (an output stream).
    Stream { stream: u16 },
}

/// Up to two destinations of one result.
pub type Dests = [Option<Dest>; 2];

/// An arithmetic op on an adder, multiplier or divide/sqrt unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FuSlot {
    pub op: Op,
    /// Entries of the unit's `a` and `b` LRFs (unused inputs are 0).
    pub a: u16,
    pub b: u16,
    /// Condition code that `select` tests (0 for other ops).
    pub cc: u16,
    pub dests: Dests,
    pub stage: u8,
}

/// Scratchpad access at `base + offset`, the offset read from the `spN.addr` LRF (or 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpSlot {
    pub write: bool,
    pub base: u16,
    /// Entry of `spN.addr` holding the offset; `None` means offset 0.
    pub offset: Option<u16>,
    /// Entry of `spN.data` holding the word to write (writes only).
    pub data: u16,
    /// Where a read's word goes (reads only).
    pub dests: Dests,
    pub stage: u8,
}

/// Where each cluster takes its word from on the intercluster network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Permutation {
    /// Cluster `c` receives from cluster `(c + k) mod C` (a pattern from the microcontroller).
    Rotate(u16),
    /// Cluster `c` receives from cluster `c xor k` (butterfly).
    Xor(u16),
    /// Every cluster receives cluster `k`'s word.
    Broadcast(u16),
    /// Cluster `c` receives from the cluster named by entry `e` of its `commN.perm` LRF
    /// (computed per cluster, modulo the cluster count).
    PerCluster(u16),
}

/// A word sent over the intercluster network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommSlot {
    /// Entry of `commN.data` holding the word to send.
    pub data: u16,
    pub perm: Permutation,
    pub dests: Dests,
    pub stage: u8,
}

/// Read the next element of an input stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamIn {
    pub stream: u16,
    /// Conditional input: only clusters whose condition code is set receive an element,
    /// in cluster order; the others' destinations are not written.
    pub cond: Option<u16>,
    pub dests: Dests,
    pub stage: u8,
}

/// Append a word from `sout.data` to an output stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamOut {
    pub stream: u16,
    /// Entry of `sout.data`.
    pub data: u16,
    /// Conditional output: only clusters whose condition code is set append, in cluster order.
    pub cond: Option<u16>,
    pub stage: u8,
}

/// A constant written through the switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImmValue {
    Const(u32),
    /// The cluster's own index.
    ClusterId,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Immediate {
    pub value: ImmValue,
    pub dests: Dests,
    pub stage: u8,
}

/// How a loop decides whether to run again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopKind {
    /// A fixed number of iterations.
    Counted(u32),
    /// One iteration per `clusters` elements of an input stream, until it is exhausted.
    UntilStreamEmpty(u16),
    /// Until condition code `cc` is set in every cluster (tested at the end of each pass).
    UntilCc(u16),
}

/// The microcontroller's field: which loop, if any, this instruction begins and whether it
/// ends one, a pass of one, or the kernel.
///
/// A loop body holds one or more *passes*. Ordinarily it is one pass, from `begin` to `end`.
/// A software-pipelined body unrolled `K` times for modulo variable expansion (Lam 1988:
/// each copy of the kernel uses its own LRF entries for values that outlive the initiation
/// interval, as there is no rotating register file) holds `K` passes: `pass_end` marks the
/// last instruction of each but the last, which ends at `end`. The microcontroller counts a
/// pass, and tests whether the loop goes on, at every pass end; a loop that is done at a
/// `pass_end` leaves its body there, for the instruction after its `end`.
///
/// Rules ([`Program::check`] enforces them):
///
/// * at most one loop begins and at most one ends per instruction; loops nest properly, so
///   loops that would begin (or end) on the same instruction need a `nop` between them;
/// * `begin` and `end` together make a one-instruction loop body: the instruction ends the
///   loop it begins (a software-pipelined loop with an initiation interval of 1);
/// * `pass_end` is inside a loop and belongs to the innermost one (for an instruction that
///   begins a loop, the loop it begins: `begin` with `pass_end` is a first pass of one
///   instruction); it is never with `end`, which already ends the body's last pass (the two
///   would leave that pass empty), nor with `done`;
/// * in a loop over a stream, every pass reads the same number of unconditional words of
///   that stream (the loop's iteration count is the stream's rows divided by that number);
/// * `done` is exclusive: the kernel's last instruction is outside every loop, so it neither
///   begins nor ends one (a loop that would close on the last instruction is followed by an
///   empty instruction carrying `done`, which is what the assembler's `done` after `end`
///   gives).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Control {
    /// This instruction starts a loop body (its first instruction).
    pub begin: Option<LoopBegin>,
    /// This instruction is the last of the innermost loop body.
    pub end: bool,
    /// This instruction ends a pass of the innermost loop without ending its body (a body
    /// unrolled `K` times holds `K` passes; the last ends at `end`).
    pub pass_end: bool,
    /// This instruction is the kernel's last: output streams are flushed when its results
    /// land.
    pub done: bool,
}

/// The loop an instruction begins: it runs to the matching `end`; `stages` is its
/// software-pipeline depth (1 for an ordinary loop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopBegin {
    pub kind: LoopKind,
    pub stages: u8,
}

impl Control {
    /// No loop begins or ends here; the next instruction follows.
    pub const NEXT: Control = Control {
        begin: None,
        end: false,
        pass_end: false,
        done: false,
    };
    /// The last instruction of the innermost loop body.
    pub const END: Control = Control {
        begin: None,
        end: true,
        pass_end: false,
        done: false,
    };
    /// The last instruction of a pass of the innermost loop, not of its body: the next
    /// pass starts on the next instruction.
    pub const PASS_END: Control = Control {
        begin: None,
        end: false,
        pass_end: true,
        done: false,
    };
    /// The kernel's last instruction.
    pub const DONE: Control = Control {
        begin: None,
        end: false,
        pass_end: false,
        done: true,
    };

    /// The first instruction of a loop body.
    pub const fn begin(kind: LoopKind, stages: u8) -> Control {
        Control {
            begin: Some(LoopBegin { kind, stages }),
            end: false,
            pass_end: false,
            done: false,
        }
    }

    /// The only instruction of a loop body: it begins and ends the loop.
    pub const fn begin_end(kind: LoopKind, stages: u8) -> Control {
        Control {
            begin: Some(LoopBegin { kind, stages }),
            end: true,
            pass_end: false,
            done: false,
        }
    }

    /// The first instruction of a loop body that is also the whole of its first pass.
    pub const fn begin_pass_end(kind: LoopKind, stages: u8) -> Control {
        Control {
            begin: Some(LoopBegin { kind, stages }),
            end: false,
            pass_end: true,
            done: false,
        }
    }

    /// A loop's pass ends here (`end` or `pass_end`).
    pub const fn ends_pass(self) -> bool {
        self.end || self.pass_end
    }

    /// No loop begins or ends here, no pass ends, and the kernel goes on.
    pub const fn is_next(self) -> bool {
        self.begin.is_none() && !self.end && !self.pass_end && !self.done
    }
}

/// One VLIW instruction.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Instruction {
    pub control: Control,
    /// Adders, then multipliers, then divide/sqrt units, as the machine counts them.
    pub fu: Vec<Option<FuSlot>>,
    pub sp: Vec<Option<SpSlot>>,
    pub comm: Vec<Option<CommSlot>>,
    pub sin: Vec<Option<StreamIn>>,
    pub sout: Option<StreamOut>,
    pub imm: Option<Immediate>,
}

/// Direction of a kernel stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamDir {
    In,
    Out,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StreamDecl {
    pub name: String,
    pub dir: StreamDir,
}

/// A microcode program: the kernel's streams and its instructions.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Program {
    pub name: String,
    pub streams: Vec<StreamDecl>,
    pub code: Vec<Instruction>,
}
