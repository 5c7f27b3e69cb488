//! Clocked arithmetic functional units of the clusters (ARCHITECTURE §4): pipelined
//! [`Adder`]s and [`Multiplier`]s ([`pipelined`]) and the iterative [`DivSqrt`] unit
//! ([`divsqrt`]).
//!
//! # Lane batching
//!
//! The microcontroller issues the same VLIW word to every cluster, so one unit object models
//! one unit *slot* (say `add0`) in every cluster at once: an issue carries one op and one
//! operand word per cluster ("lane"), and the unit's pipeline registers hold a word per lane.
//! Probes are still registered per cluster, as the hardware has them
//! (`top.cluster3.add0.result`); errors name the slot in every cluster
//! (`top.cluster*.add0`).
//!
//! # Cycle protocol
//!
//! Two-phase, like [`imagine_hdl::Module`]: during a cycle the owner may
//!
//! * read [`completed`](Pipelined::completed) — the result of the op issued `L` cycles ago
//!   (`L` its latency), computed from committed state, so it does not matter whether this
//!   happens before or after an issue in the same cycle;
//! * call [`issue`](Pipelined::issue) at most once;
//!
//! and then calls `commit()` once to end the cycle. An op issued in cycle `t` with latency `L`
//! completes in cycle `t + L`.
//!
//! Results are broadcast on the unit's single result port to the intracluster switch. A
//! result that nobody routes to a register file is simply dropped (it is not a contract
//! violation, unlike an unread [`imagine_hdl::PipeRx`] value): the switch, not the unit,
//! decides what is written.
//!
//! # Contract errors
//!
//! An issue is rejected with a [`ContractError`] located at `<unit path>.issue`, before it
//! changes any state, when
//!
//! * it is the second issue in the cycle ([`Violation::OverBandwidth`]);
//! * the op belongs to another unit class, or an operand slice does not have one word per
//!   lane ([`Violation::Other`]);
//! * its result would leave in the same cycle as an op already in flight (ops of different
//!   latencies share one result port: a *writeback conflict*), or, for the [`DivSqrt`], the
//!   recurrence core is still busy with the previous op ([`Violation::Busy`]).
//!
//! # Functional vs timing
//!
//! [`Adder`] and [`Multiplier`] compute the value with [`Op::eval_lanes`] (the interpreter's
//! function) at issue and carry it through their stage registers. [`DivSqrt`] computes as the
//! hardware does: setup at issue, digit-recurrence steps per cycle, rounding at the end.

pub mod divsqrt;
pub mod pipelined;

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation};

use crate::arith::flags::Flags;
use crate::ops::{Op, UnitClass};
use crate::ring_position;

pub use divsqrt::DivSqrt;
pub use pipelined::{Adder, AdderKind, Multiplier, MultiplierKind, Pipelined, PipelinedKind};

/// One issue to a unit: the op, one operand word per lane, and an owner-chosen tag that comes
/// back with the result.
///
/// Operands beyond the op's arity may be empty slices. `c` is only read by [`Op::Select`]
/// (whose operands are `(cond, a, b)` = `(a, b, c)` here).
#[derive(Clone, Copy, Debug)]
pub struct Issue<'a> {
    pub op: Op,
    pub a: &'a [u32],
    pub b: &'a [u32],
    pub c: &'a [u32],
    pub tag: u16,
}

impl<'a> Issue<'a> {
    /// A one-operand issue.
    pub fn unary(op: Op, a: &'a [u32], tag: u16) -> Self {
        Issue {
            op,
            a,
            b: &[],
            c: &[],
            tag,
        }
    }

    /// A two-operand issue.
    pub fn binary(op: Op, a: &'a [u32], b: &'a [u32], tag: u16) -> Self {
        Issue {
            op,
            a,
            b,
            c: &[],
            tag,
        }
    }
}

/// A result leaving a unit this cycle: one word and one flag set per lane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Completion<'a> {
    pub op: Op,
    pub tag: u16,
    pub values: &'a [u32],
    pub flags: &'a [Flags],
}

/// What every functional unit offers its owner (the cluster), for code generic over units.
/// The inherent methods of [`Pipelined`] and [`DivSqrt`] are the same functions.
pub trait FunctionalUnit {
    /// The unit's class.
    fn class(&self) -> UnitClass;
    /// Clusters the unit object spans.
    fn lanes(&self) -> usize;
    /// The latency of `op` on this unit, or `None` if the unit does not execute it.
    fn latency_of(&self, op: Op) -> Option<u32>;
    /// Whether [`issue`](Self::issue) of `op` would be accepted in the current cycle.
    fn can_issue(&self, op: Op) -> bool;
    /// Issues an op in the current cycle.
    fn issue(&mut self, is: Issue<'_>) -> Result<(), ContractError>;
    /// The op completing in the current cycle, if any (from committed state).
    fn completed(&self) -> Option<Completion<'_>>;
    /// Ends the cycle.
    fn commit(&mut self);
    /// Reports every probe (after a commit).
    fn trace(&self, t: &mut Trace);
}

macro_rules! impl_functional_unit {
    ($([$($gen:tt)*] $t:ty),*) => {$(
        impl<$($gen)*> $crate::fu::FunctionalUnit for $t {
            fn class(&self) -> $crate::ops::UnitClass {
                <$t>::class(self)
            }
            fn lanes(&self) -> usize {
                <$t>::lanes(self)
            }
            fn latency_of(&self, op: $crate::ops::Op) -> Option<u32> {
                <$t>::latency_of(self, op)
            }
            fn can_issue(&self, op: $crate::ops::Op) -> bool {
                <$t>::can_issue(self, op)
            }
            #[inline]
            fn issue(
                &mut self,
                is: $crate::fu::Issue<'_>,
            ) -> Result<(), imagine_hdl::ContractError> {
                <$t>::issue(self, is)
            }
            #[inline]
            fn completed(&self) -> Option<$crate::fu::Completion<'_>> {
                <$t>::completed(self)
            }
            #[inline]
            fn commit(&mut self) {
                <$t>::commit(self)
            }
            fn trace(&self, t: &mut imagine_hdl::Trace) {
                <$t>::trace(self, t)
            }
        }
    )*};
}
pub(crate) use impl_functional_unit;

// ---- contract checks shared by the units -----------------------------------------------

/// The error path of a unit's issue port.
pub(crate) fn issue_path(scope: &Scope<'_>, name: &str) -> String {
    format!("{}.cluster*.{name}.issue", scope.path())
}

#[cold]
#[inline(never)]
pub(crate) fn second_issue(path: &str) -> ContractError {
    ContractError::over_bandwidth(path, 1)
}

#[cold]
#[inline(never)]
pub(crate) fn wrong_class(path: &str, op: Op, class: UnitClass) -> ContractError {
    ContractError::at(
        path,
        Violation::Other(format!(
            "op `{op}` is executed by the {}s, not by this {class}",
            op.unit()
        )),
    )
}

#[cold]
#[inline(never)]
fn bad_operand(path: &str, op: Op, which: char, len: usize, lanes: usize) -> ContractError {
    let need = if (which as usize - 'a' as usize) < op.arity() {
        format!("{lanes} words")
    } else {
        format!("0 or {lanes} words")
    };
    ContractError::at(
        path,
        Violation::Other(format!(
            "op `{op}` (arity {}) issued with {len} words in operand {which}, needs {need} \
             (one per lane)",
            op.arity()
        )),
    )
}

/// The `(a, b, c)` operand slices of an issue, one word per lane each.
pub(crate) type Operands<'a> = (&'a [u32], &'a [u32], &'a [u32]);

/// Checks the operand slices of `is` against `lanes` and returns `(a, b, c)`, each exactly
/// `lanes` long; operands beyond the arity that were left empty are replaced by `a` (they
/// are not read).
#[inline]
pub(crate) fn operands<'a>(
    path: &str,
    lanes: usize,
    is: &Issue<'a>,
) -> Result<Operands<'a>, ContractError> {
    let arity = is.op.arity();
    let pick = |s: &'a [u32], idx: usize, which: char| {
        if s.len() == lanes {
            Ok(s)
        } else if s.is_empty() && arity <= idx {
            Ok(is.a)
        } else {
            Err(bad_operand(path, is.op, which, s.len(), lanes))
        }
    };
    let a = pick(is.a, 0, 'a')?;
    let b = pick(is.b, 1, 'b')?;
    let c = pick(is.c, 2, 'c')?;
    Ok((a, b, c))
}

// ---- the completion ring -----------------------------------------------------------------

/// Bookkeeping of one in-flight op.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slot {
    pub valid: bool,
    pub op: Op,
    pub tag: u16,
    pub latency: u32,
    pub issued: u64,
}

/// In-flight ops of a unit, indexed by the cycle they complete in (modulo the depth). A unit
/// with one result port completes at most one op per cycle, so a slot holds at most one op,
/// and an issue whose slot is taken is exactly a writeback conflict.
///
/// The slot being read (`head`, the current cycle) is never the one written by an issue
/// (latency ≥ 1 and ≤ depth − 1), so the ring is its own `q`/`d` pair.
#[derive(Clone, Debug)]
pub(crate) struct Ring {
    pub slots: Vec<Slot>,
    pub head: usize,
    pub cycle: u64,
}

impl Ring {
    pub fn new(max_latency: u32) -> Self {
        let empty = Slot {
            valid: false,
            op: Op::ALL[0],
            tag: 0,
            latency: 0,
            issued: 0,
        };
        Ring {
            slots: vec![empty; max_latency as usize + 1],
            head: 0,
            cycle: 0,
        }
    }

    /// The slot of an op completing `latency` cycles from now.
    #[inline(always)]
    pub fn slot_after(&self, latency: u32) -> usize {
        ring_position::after(self.head, latency as usize, self.slots.len())
    }

    /// The op completing in the current cycle.
    #[inline(always)]
    pub fn current(&self) -> Option<&Slot> {
        let s = &self.slots[self.head];
        s.valid.then_some(s)
    }

    /// Ends the cycle: the op that completed leaves.
    #[inline(always)]
    pub fn advance(&mut self) {
        self.slots[self.head].valid = false;
        self.head = ring_position::next(self.head, self.slots.len());
        self.cycle += 1;
    }

    /// Brings an empty ring over `n` cycles: the position turns and the cycle counts on.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert_eq!(self.in_flight(), 0);
        self.head = ring_position::after_many(self.head, n, self.slots.len());
        self.cycle += n;
    }

    /// The conflict error for an op of `latency` whose slot is taken.
    #[cold]
    #[inline(never)]
    pub fn conflict(&self, path: &str, op: Op, latency: u32) -> ContractError {
        let other = &self.slots[self.slot_after(latency)];
        ContractError::at(
            path,
            Violation::Busy {
                detail: format!(
                    "writeback conflict: `{op}` (latency {latency}) issued in cycle {} would \
                     complete in cycle {}, the cycle `{}` (tag {}, latency {}) issued in cycle \
                     {} completes in; the unit has one result port",
                    self.cycle,
                    self.cycle + u64::from(latency),
                    other.op,
                    other.tag,
                    other.latency,
                    other.issued,
                ),
            },
        )
    }

    pub fn in_flight(&self) -> usize {
        self.slots.iter().filter(|s| s.valid).count()
    }

    /// The op in each pipeline stage, by stage number: an op issued `k` cycles ago is in
    /// stage `k` (1 ≤ k ≤ its latency; stage `latency` is its output register).
    pub fn stages(&self, max_latency: u32) -> Vec<Option<Op>> {
        let mut by_stage = vec![None; max_latency as usize + 1];
        for s in self.slots.iter().filter(|s| s.valid) {
            let age = self.cycle - s.issued;
            debug_assert!((1..=u64::from(s.latency)).contains(&age));
            by_stage[age as usize] = Some(s.op);
        }
        by_stage
    }
}

// ---- probes shared by the units ------------------------------------------------------------

/// Operands of the last issue, held for the probes (an input latch). Written by `issue`,
/// read only by `trace` after `commit`.
#[derive(Clone, Debug)]
pub(crate) struct IssueLatch {
    /// An op was issued in the cycle that just ended (committed).
    pub valid: bool,
    pub op: Op,
    pub operands: [Vec<u32>; 3],
}

impl IssueLatch {
    pub fn new(lanes: usize) -> Self {
        IssueLatch {
            valid: false,
            op: Op::ALL[0],
            operands: [vec![0; lanes], vec![0; lanes], vec![0; lanes]],
        }
    }

    /// Records an issue's operands (only those within the arity are copied; the others
    /// read as 0).
    #[inline]
    pub fn capture(&mut self, is: &Issue<'_>) {
        self.op = is.op;
        let arity = is.op.arity();
        for (dst, src) in self.operands.iter_mut().zip([is.a, is.b, is.c]).take(arity) {
            crate::lanes::copy_lanes::<0>(dst, src);
        }
    }

    /// Operand `k` of lane `lane` as the probe shows it.
    #[inline]
    pub fn operand(&self, k: usize, lane: usize) -> u32 {
        if k < self.op.arity() {
            self.operands[k][lane]
        } else {
            0
        }
    }
}

/// Probes of one cluster's copy of a unit.
#[derive(Clone, Debug)]
struct LaneIds {
    op: SignalId,
    issue: SignalId,
    operands: Vec<SignalId>,
    result: SignalId,
    flags: SignalId,
    valid: SignalId,
    /// `(valid, op)` of each pipeline stage in `stage_range`.
    stages: Vec<(SignalId, SignalId)>,
}

/// The probes every unit has, per cluster: `op`, `issue`, operand ports `a`, `b` (`c`),
/// `result`, `flags`, `valid`, and `stage{k}.valid` / `stage{k}.op` for its pipeline stages.
#[derive(Clone, Debug)]
pub(crate) struct UnitProbes {
    lanes: Vec<LaneIds>,
    first_stage: u32,
}

impl UnitProbes {
    /// Registers the probes of unit `name` in every cluster: `<scope>.cluster{c}.{name}.…`,
    /// with `ports` operand ports and stage registers `stages`.
    pub fn new(
        scope: &mut Scope<'_>,
        name: &str,
        lanes: usize,
        ports: usize,
        stages: std::ops::RangeInclusive<u32>,
    ) -> Self {
        let first_stage = *stages.start();
        let lanes = (0..lanes)
            .map(|c| {
                let mut cl = scope.child(&format!("cluster{c}"));
                let mut u = cl.child(name);
                let op = u.signal_shown("op", Op::OPCODE_BITS, SignalKind::Reg, Op::display());
                u.glance(op);
                let issue = u.signal("issue", 1, SignalKind::Reg);
                let operands = ["a", "b", "c"][..ports]
                    .iter()
                    .map(|p| u.signal(p, 32, SignalKind::Reg))
                    .collect();
                let result = u.signal("result", 32, SignalKind::Reg);
                let flags = u.signal("flags", 5, SignalKind::Reg);
                let valid = u.signal("valid", 1, SignalKind::Reg);
                let stages = stages
                    .clone()
                    .map(|k| {
                        let mut s = u.child(&format!("stage{k}"));
                        (
                            s.signal("valid", 1, SignalKind::Reg),
                            s.signal_shown("op", Op::OPCODE_BITS, SignalKind::Reg, Op::display()),
                        )
                    })
                    .collect();
                LaneIds {
                    op,
                    issue,
                    operands,
                    result,
                    flags,
                    valid,
                    stages,
                }
            })
            .collect();
        UnitProbes { lanes, first_stage }
    }

    /// Reports the issue latch, the result leaving this cycle and the stage registers
    /// (`by_stage[k]`: the op in stage `k`). Words of an invalid result, latch or stage are
    /// not reported, so a waveform shows them holding their last value.
    pub fn trace(
        &self,
        t: &mut Trace,
        latch: &IssueLatch,
        done: Option<Completion<'_>>,
        by_stage: &[Option<Op>],
    ) {
        for (c, ids) in self.lanes.iter().enumerate() {
            t.value(ids.issue, latch.valid as u64);
            if latch.valid {
                t.value(ids.op, u64::from(latch.op.opcode()));
                for (k, id) in ids.operands.iter().enumerate() {
                    t.value(*id, u64::from(latch.operand(k, c)));
                }
            }
            t.value(ids.valid, done.is_some() as u64);
            if let Some(d) = done {
                t.value(ids.result, u64::from(d.values[c]));
                t.value(ids.flags, u64::from(d.flags[c].bits()));
            }
            for (k, (valid, op)) in ids.stages.iter().enumerate() {
                let in_stage = by_stage[self.first_stage as usize + k];
                t.value(*valid, in_stage.is_some() as u64);
                if let Some(o) = in_stage {
                    t.value(*op, u64::from(o.opcode()));
                }
            }
        }
    }
}
