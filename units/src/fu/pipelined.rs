//! Fully pipelined units: the [`Adder`] and the [`Multiplier`], both a [`Pipelined`] unit
//! of a [`UnitClass`], differing only in which ops they accept.
//!
//! A pipelined unit accepts one op per cycle, whatever its latency; ops of different latency
//! (an adder's 2-cycle integer ops and 4-cycle fp ops) travel down the same pipeline and leave
//! through one result port, so an issue whose result would leave in the same cycle as an
//! earlier op's is a writeback conflict (e.g. `iadd` two cycles after `fadd` on a
//! 2-cycle-int/4-cycle-fp adder).
//!
//! The value is computed at issue by [`Op::eval_lanes`] and held in the stage registers until
//! the op's latency has elapsed. The stage registers are a ring of per-cycle slots, each with
//! a preallocated word and flag buffer for every lane: no allocation after construction, one
//! slot write per issue and an index increment per commit. The probes `stage{k}.valid` and
//! `stage{k}.op` show, after each clock edge, the op issued `k` cycles ago (stage 1 is the
//! first register after the operand latch; stage `L` is the op's output register).

use std::marker::PhantomData;

use imagine_hdl::{ContractError, Scope, Trace};

use super::{
    Completion, Issue, IssueLatch, Ring, Slot, UnitProbes, issue_path, operands, second_issue,
    wrong_class,
};
use crate::arith::flags::Flags;
use crate::arith::fp32::FpMode;
use crate::desc::MachineDesc;
use crate::lanes::count;
use crate::ops::{Datapath, Op, UnitClass};

/// The unit class of a [`Pipelined`] unit, at the type level.
pub trait PipelinedKind: 'static {
    const CLASS: UnitClass;
}

/// Marker of [`Adder`].
#[derive(Debug)]
pub enum AdderKind {}
/// Marker of [`Multiplier`].
#[derive(Debug)]
pub enum MultiplierKind {}

impl PipelinedKind for AdderKind {
    const CLASS: UnitClass = UnitClass::Adder;
}
impl PipelinedKind for MultiplierKind {
    const CLASS: UnitClass = UnitClass::Multiplier;
}

/// A cluster adder slot in every cluster.
pub type Adder = Pipelined<AdderKind>;
/// A cluster multiplier slot in every cluster.
pub type Multiplier = Pipelined<MultiplierKind>;

/// A fully pipelined unit of class `K::CLASS`, one copy per lane (cluster).
pub struct Pipelined<K: PipelinedKind> {
    path: String,
    lanes: usize,
    mode: FpMode,
    /// Latency of each opcode on this unit; 0 for ops of other classes.
    latency: Box<[u32]>,
    max_latency: u32,
    ring: Ring,
    /// Per slot, `lanes` result words / flags.
    values: Vec<u32>,
    flags: Vec<Flags>,
    /// An op was issued in the current cycle.
    issued: bool,
    /// A tracer is attached: the issue latch is kept for the probes, and the bit-level
    /// datapath computes every op, whatever `datapath` says.
    tracing: bool,
    /// What computes `fadd`, `fsub` and `fmul` without a tracer.
    datapath: Datapath,
    latch: IssueLatch,
    probes: UnitProbes,
    _kind: PhantomData<K>,
}

/// The unit's state: what is in flight and the values on their way (not the probes'
/// latches, which only a tracer reads).
impl<K: PipelinedKind> std::fmt::Debug for Pipelined<K> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipelined")
            .field("path", &self.path)
            .field("ring", &self.ring)
            .field("values", &self.values)
            .field("flags", &self.flags)
            .field("issued", &self.issued)
            .finish()
    }
}

impl<K: PipelinedKind> Pipelined<K> {
    /// The unit slot `name` (e.g. `add0`) in `lanes` clusters, with the latencies and fp mode
    /// of `desc`; probes under `<scope>.cluster{c}.{name}`.
    pub fn new(scope: &mut Scope<'_>, name: &str, lanes: usize, desc: &MachineDesc) -> Self {
        assert!(lanes > 0, "unit `{name}` needs at least one lane");
        let class = K::CLASS;
        let latency: Box<[u32]> = Op::ALL
            .iter()
            .map(|op| {
                if op.unit() == class {
                    op.latency(&desc.latency)
                } else {
                    0
                }
            })
            .collect();
        let max_latency = latency.iter().copied().max().unwrap_or(1).max(1);
        let ports = Op::ALL
            .iter()
            .filter(|op| op.unit() == class)
            .map(|op| op.arity())
            .max()
            .unwrap_or(1);
        let ring = Ring::new(max_latency);
        let depth = ring.slots.len();
        Pipelined {
            path: issue_path(scope, name),
            lanes,
            mode: desc.fp_mode(),
            latency,
            max_latency,
            ring,
            values: vec![0; depth * lanes],
            flags: vec![Flags::NONE; depth * lanes],
            issued: false,
            tracing: true,
            datapath: Datapath::Host,
            latch: IssueLatch::new(lanes),
            probes: UnitProbes::new(scope, name, lanes, ports, 1..=max_latency),
            _kind: PhantomData,
        }
    }

    /// Issues an op in the current cycle (see the [module](super) doc for the contract).
    #[inline]
    pub fn issue(&mut self, is: Issue<'_>) -> Result<(), ContractError> {
        if self.issued {
            return Err(second_issue(&self.path));
        }
        if self.latency[is.op.opcode() as usize] == 0 {
            return Err(wrong_class(&self.path, is.op, K::CLASS));
        }
        let (a, b, c) = operands(&self.path, self.lanes, &is)?;
        self.issue_checked::<0>(is.op, [a, b, c], is.tag)
    }

    /// [`issue`](Self::issue) for an op whose unit class and operands are known good (the
    /// cluster issues only programs that passed the microcode check): `operands` are one
    /// word per lane each, any of them where the op reads fewer. Still refused: a second
    /// issue in a cycle and a writeback conflict, which depend on timing. Compiled for `L`
    /// lanes ([`crate::lanes`]).
    #[inline(always)]
    pub(crate) fn issue_checked<const L: usize>(
        &mut self,
        op: Op,
        operands: [&[u32]; 3],
        tag: u16,
    ) -> Result<(), ContractError> {
        if self.issued {
            return Err(second_issue(&self.path));
        }
        let lat = self.latency[op.opcode() as usize];
        debug_assert!(lat > 0, "`{op}` checked for this unit class");
        #[cfg(feature = "inject-bugs")]
        let lat = if lat < self.max_latency
            && imagine_hdl::inject::active(imagine_hdl::inject::Bug::PipelineShortOpsOneCycleLate)
        {
            lat + 1
        } else {
            lat
        };
        let [a, b, c] = operands;
        let s = self.ring.slot_after(lat);
        if self.ring.slots[s].valid {
            return Err(self.ring.conflict(&self.path, op, lat));
        }
        let n = count::<L>(self.lanes);
        let range = s * n..(s + 1) * n;
        // A waveform shows the model of record: the bit-level datapath.
        let datapath = if self.tracing {
            Datapath::BitLevel
        } else {
            self.datapath
        };
        op.eval_lanes_fixed::<L>(
            datapath,
            [a, b, c],
            self.mode,
            &mut self.values[range.clone()],
            &mut self.flags[range],
        );
        #[cfg(feature = "inject-bugs")]
        if op == Op::Add16x2
            && imagine_hdl::inject::active(imagine_hdl::inject::Bug::PackedAddCarriesAcrossLanes)
        {
            for (v, (&x, &y)) in self.values[s * n..(s + 1) * n]
                .iter_mut()
                .zip(a.iter().zip(b))
            {
                *v = x.wrapping_add(y);
            }
        }
        self.ring.slots[s] = Slot {
            valid: true,
            op,
            tag,
            latency: lat,
            issued: self.ring.cycle,
        };
        if self.tracing {
            self.latch.capture(&Issue { op, a, b, c, tag });
        }
        self.issued = true;
        Ok(())
    }

    /// Whether a tracer is attached (see [`imagine_hdl::Module::set_tracing`]): without
    /// one the operands of each issue are not latched for the probes.
    pub fn set_tracing(&mut self, on: bool) {
        self.tracing = on;
    }

    /// What computes `fadd`, `fsub` and `fmul` when no tracer is attached (the host fast
    /// path unless told otherwise; the same words and flags either way).
    pub fn set_datapath(&mut self, datapath: Datapath) {
        self.datapath = datapath;
    }

    /// The op completing in the current cycle, if any (from committed state).
    #[inline]
    pub fn completed(&self) -> Option<Completion<'_>> {
        let s = self.ring.current()?;
        let n = self.lanes;
        let range = self.ring.head * n..(self.ring.head + 1) * n;
        Some(Completion {
            op: s.op,
            tag: s.tag,
            values: &self.values[range.clone()],
            flags: &self.flags[range],
        })
    }

    /// Ends the cycle: every op moves one stage on; the completed op (if any) leaves.
    #[inline]
    pub fn commit(&mut self) {
        self.ring.advance();
        self.latch.valid = self.issued;
        self.issued = false;
    }

    /// Whether nothing is in flight or issued this cycle, so that cycles only turn the ring.
    pub fn is_quiet(&self) -> bool {
        !self.issued && self.ring.in_flight() == 0
    }

    /// Brings a quiet unit over `n ≥ 1` cycles, as `n` commits without issues would.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.is_quiet() && n > 0);
        self.ring.skip_idle(n);
        self.latch.valid = false;
    }

    /// Reports every probe (after a commit).
    pub fn trace(&self, t: &mut Trace) {
        let stages = self.ring.stages(self.max_latency);
        self.probes.trace(t, &self.latch, self.completed(), &stages);
    }

    /// The latency of `op` on this unit, or `None` if the unit does not execute it.
    pub fn latency_of(&self, op: Op) -> Option<u32> {
        Some(self.latency[op.opcode() as usize]).filter(|&l| l > 0)
    }

    /// Whether issuing `op` now would be accepted (no issue yet this cycle, right class, no
    /// writeback conflict).
    pub fn can_issue(&self, op: Op) -> bool {
        self.latency_of(op)
            .is_some_and(|l| !self.issued && !self.ring.slots[self.ring.slot_after(l)].valid)
    }

    /// The unit's class.
    pub fn class(&self) -> UnitClass {
        K::CLASS
    }

    /// The path that errors name: `<scope>.cluster*.<name>.issue`.
    pub fn path(&self) -> &str {
        &self.path
    }

    pub fn lanes(&self) -> usize {
        self.lanes
    }

    /// Cycles committed since construction.
    pub fn cycle(&self) -> u64 {
        self.ring.cycle
    }

    /// Ops issued and not yet completed-and-committed.
    pub fn in_flight(&self) -> usize {
        self.ring.in_flight()
    }
}

super::impl_functional_unit!([K: PipelinedKind] Pipelined<K>);
