//! The kernel IR (ARCHITECTURE §5): what KernelC was to Imagine, as a Rust builder.
//!
//! A kernel runs on every cluster at once (SIMD). Its values are SSA: each is defined once,
//! holds one 32-bit word per cluster and has a [`Ty`]. A kernel has three regions run in
//! order: straight-line code before its main loop ([`Region::Pre`]), the main loop body
//! ([`Region::Loop`]) and straight-line code after it ([`Region::Post`]).
//!
//! * Streams are word streams. An unconditional read gives every cluster its next word, in
//!   cluster order: a record of `k` words is `k` reads, and element `e`'s word `j` sits at
//!   `(e / C)·k·C + j·C + e mod C` in the stream (`C` clusters). A conditional read gives the
//!   next words only to clusters whose condition holds (in cluster order) and an `otherwise`
//!   value to the rest; a conditional write appends only the words of clusters whose
//!   condition holds.
//! * The main loop runs once per row (`C` elements) of its driving input stream until it is
//!   exhausted, or a fixed number of times. Loop-carried values ([`KernelBuilder::carried`])
//!   take an initial value from the code before the loop and their next value from the
//!   body; after the loop they hold their last value.
//! * Per-kernel constants are immediates; per-kernel parameters ([`KernelBuilder::param`])
//!   are words given when the kernel is started, the same in every cluster.
//! * Scratchpad accesses are at `base + offset` in each cluster's own scratchpad; they keep
//!   program order. Comm permutations move a word between clusters.
//!
//! The [`interp`] module runs this IR on the op functions of the units; [`crate::compile`]
//! turns it into microcode.

pub mod builder;
pub mod interp;
pub mod requirement;
pub mod verify;

use std::fmt;

use imagine_units::ops::Op;

pub use builder::KernelBuilder;
pub use interp::{InterpError, KernelInputs, interpret};
pub use requirement::{MachineRequirementError, Needs};
pub use verify::VerifyError;

/// The type of a value. `Word` is an untyped 32-bit word, accepted wherever a data type is;
/// `Cc` is a condition (a compare's result: 1 or 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Ty {
    Word,
    F32,
    I32,
    P16,
    P8,
    Cc,
}

impl Ty {
    pub const fn name(self) -> &'static str {
        match self {
            Ty::Word => "word",
            Ty::F32 => "fp32",
            Ty::I32 => "int32",
            Ty::P16 => "packed16",
            Ty::P8 => "packed8",
            Ty::Cc => "cc",
        }
    }

    /// Whether a value of type `self` may be passed where `want` is expected.
    pub fn fits(self, want: Ty) -> bool {
        self == want || (want != Ty::Cc && self == Ty::Word) || (want == Ty::Word && self != Ty::Cc)
    }
}

impl fmt::Display for Ty {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An SSA value of a kernel: an index into [`Kernel::nodes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Value(pub u32);

impl Value {
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "%{}", self.0)
    }
}

/// A kernel stream: an index into [`Kernel::streams`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StreamId(pub u16);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dir {
    In,
    Out,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stream {
    pub name: String,
    pub dir: Dir,
}

/// Where a node runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Region {
    Pre,
    Loop,
    Post,
}

impl Region {
    pub const fn name(self) -> &'static str {
        match self {
            Region::Pre => "before the loop",
            Region::Loop => "in the loop",
            Region::Post => "after the loop",
        }
    }
}

/// How the main loop decides to run again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopSpec {
    /// Once per row of this input stream's words (one word per cluster per read), until
    /// every word is read: the body must read it unconditionally the same number of times
    /// in every iteration.
    OverStream(StreamId),
    /// A fixed number of iterations.
    Counted(u32),
}

/// Where each cluster takes a word from in a [`Node::Comm`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Perm {
    /// Cluster `c` receives from cluster `(c + k) mod C`.
    Rotate(u16),
    /// Cluster `c` receives from cluster `c xor k` (`k` < `C`).
    Xor(u16),
    /// Every cluster receives cluster `k`'s word.
    Broadcast(u16),
    /// Cluster `c` receives from the cluster this value names (mod `C`).
    PerCluster(Value),
}

/// One operation of a kernel. Nodes that define no value (writes) still have an index.
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    /// A constant (an immediate of the microcode).
    Const(u32),
    /// The cluster's index, `0..C`.
    ClusterId,
    /// Per-kernel parameter `i`: the same word in every cluster, given at start.
    Param(u16),
    /// An arithmetic op of the machine; `Select` takes `[cond, a, b]`.
    Op { op: Op, args: Vec<Value> },
    /// The same word under another type (no code).
    Cast { value: Value },
    /// The next word of an input stream (conditional: only where `cond` holds, the other
    /// clusters get `otherwise`).
    Read {
        stream: StreamId,
        cond: Option<(Value, Value)>,
    },
    /// Append a word to an output stream (conditional: only where `cond` holds).
    Write {
        stream: StreamId,
        value: Value,
        cond: Option<Value>,
    },
    /// Scratchpad word `base + offset`.
    SpRead { base: u16, offset: Option<Value> },
    SpWrite {
        base: u16,
        offset: Option<Value>,
        data: Value,
    },
    /// A word from another cluster.
    Comm { value: Value, perm: Perm },
    /// A loop-carried value: `init` before the first iteration, then the `next` value the
    /// previous iteration computed (set by [`KernelBuilder::set_next`]).
    Carried { init: Value, next: Option<Value> },
}

impl Node {
    /// The values this node reads (for a carried value, only its initial value: its next
    /// value is read at the end of the iteration).
    pub fn operands(&self) -> Vec<Value> {
        match self {
            Node::Const(_) | Node::ClusterId | Node::Param(_) => vec![],
            Node::Op { args, .. } => args.clone(),
            Node::Cast { value } => vec![*value],
            Node::Read { cond, .. } => cond.map(|(c, o)| vec![c, o]).unwrap_or_default(),
            Node::Write { value, cond, .. } => std::iter::once(*value).chain(*cond).collect(),
            Node::SpRead { offset, .. } => offset.iter().copied().collect(),
            Node::SpWrite { offset, data, .. } => offset.iter().copied().chain([*data]).collect(),
            Node::Comm { value, perm } => match perm {
                Perm::PerCluster(p) => vec![*value, *p],
                _ => vec![*value],
            },
            Node::Carried { init, .. } => vec![*init],
        }
    }

    /// Whether the node defines a value.
    pub fn defines(&self) -> bool {
        !matches!(self, Node::Write { .. } | Node::SpWrite { .. })
    }

    pub fn describe(&self) -> String {
        match self {
            Node::Const(x) => format!("const {x:#x}"),
            Node::ClusterId => "cluster_id".into(),
            Node::Param(i) => format!("param {i}"),
            Node::Op { op, .. } => op.name().into(),
            Node::Cast { .. } => "cast".into(),
            Node::Read { cond: None, .. } => "read".into(),
            Node::Read { cond: Some(_), .. } => "conditional read".into(),
            Node::Write { cond: None, .. } => "write".into(),
            Node::Write { cond: Some(_), .. } => "conditional write".into(),
            Node::SpRead { .. } => "scratchpad read".into(),
            Node::SpWrite { .. } => "scratchpad write".into(),
            Node::Comm { .. } => "comm".into(),
            Node::Carried { .. } => "carried".into(),
        }
    }
}

/// A node, its type (`None` if it defines no value) and region.
#[derive(Clone, Debug, PartialEq)]
pub struct Def {
    pub node: Node,
    pub ty: Option<Ty>,
    pub region: Region,
    /// A name for listings and errors (may be empty).
    pub name: String,
}

/// A kernel: streams, parameters, nodes in program order, and its main loop.
#[derive(Clone, Debug, PartialEq)]
pub struct Kernel {
    pub name: String,
    pub streams: Vec<Stream>,
    pub params: Vec<String>,
    pub nodes: Vec<Def>,
    pub main_loop: Option<LoopSpec>,
}

impl Kernel {
    pub fn def(&self, v: Value) -> &Def {
        &self.nodes[v.index()]
    }

    pub fn ty(&self, v: Value) -> Option<Ty> {
        self.def(v).ty
    }

    /// How a value is named in messages: `%12 (fadd "dist")`.
    pub fn describe(&self, v: Value) -> String {
        let d = self.def(v);
        if d.name.is_empty() {
            format!("{v} ({})", d.node.describe())
        } else {
            format!("{v} ({} `{}`)", d.node.describe(), d.name)
        }
    }

    /// Unconditional reads of `stream` per iteration of the loop.
    pub fn loop_reads(&self, stream: StreamId) -> usize {
        self.nodes
            .iter()
            .filter(|d| {
                d.region == Region::Loop
                    && matches!(d.node, Node::Read { stream: s, cond: None } if s == stream)
            })
            .count()
    }

    /// Arithmetic ops (`Node::Op`) in a region.
    pub fn op_count(&self, region: Region) -> usize {
        self.nodes
            .iter()
            .filter(|d| d.region == region && matches!(d.node, Node::Op { .. }))
            .count()
    }
}
