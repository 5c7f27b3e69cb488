//! The divide/square-root unit: one radix-4 digit-recurrence core shared by `fdiv` and
//! `fsqrt`, not fully pipelined (ARCHITECTURE §4).
//!
//! Structure, for an op issued in cycle `t` with latency `L` (`latency.div` or
//! `latency.sqrt`) and issue interval `I` (`latency.divsqrt_issue_interval`, `I ≤ L`):
//!
//! * **setup** (cycle `t`, at issue): [`div_setup`] / [`sqrt_setup`] per lane — special
//!   operands give their result at once ([`Setup::Done`]) and ride along; the rest become a
//!   recurrence job;
//! * **recurrence core** (cycles `t+1 ..= t+I`): the job sits in the core register, which
//!   after the edge ending cycle `t+s-1` holds the state after `min(k·s, steps)` recurrence
//!   steps, `k = ⌈steps / I⌉` ([`DIV_STEPS`] = [`SQRT_STEPS`] = 12); the core holds one job,
//!   so the next op may issue in cycle `t+I` at the earliest;
//! * **result stages** (cycles `t+I+1 ..= t+L`): the finished job waits `L − I` cycles; the
//!   edge that brings it to cycle `t+L` rounds it ([`div_finish`] / [`sqrt_finish`]) into
//!   the result register, read by [`DivSqrt::completed`] in cycle `t+L`.
//!
//! With gold8 (`L = 16`, `I = 8`, `k = 2`) two ops can be in flight; with `I = 1` (the +F
//! machines) the core does all 12 steps in one cycle and the unit accepts an op every cycle.
//! Issuing while the core is busy, or so that the result would leave in the same cycle as an
//! earlier op's (possible when `latency.div ≠ latency.sqrt`), is a [`ContractError`] with
//! [`Violation::Busy`].
//!
//! Probes, per cluster under `<scope>.cluster{c}.{name}`: the common unit probes, the core
//! register `core.valid`, `core.op`, `core.rem` (partial remainder), `core.quotient` (quotient
//! or root digits so far) and `core.step` (steps done), and `stage{k}.valid` / `stage{k}.op`
//! of the result stages `k = I+1 ..= L`.

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

use super::{
    Completion, Issue, IssueLatch, Ring, Slot, UnitProbes, issue_path, operands, second_issue,
    wrong_class,
};
use crate::arith::flags::Flags;
use crate::arith::fp32::div::{DIV_STEPS, DivJob, div_finish, div_setup};
use crate::arith::fp32::sqrt::{SQRT_STEPS, SqrtJob, sqrt_finish, sqrt_setup};
use crate::arith::fp32::{FpMode, Setup};
use crate::desc::MachineDesc;
use crate::lanes::count;
use crate::ops::{Datapath, Op, UnitClass};

/// Recurrence steps of the longer op.
const STEPS: u32 = if DIV_STEPS > SQRT_STEPS {
    DIV_STEPS
} else {
    SQRT_STEPS
};
/// Width of the quotient/root register: the integer digit and 2 bits per step.
const QUOTIENT_BITS: u32 = 1 + 2 * STEPS;
/// Width of the partial-remainder register (the root's remainder is at most twice the root).
const REM_BITS: u32 = QUOTIENT_BITS + 1;

/// One lane's op in flight.
#[derive(Clone, Copy, Debug)]
enum LaneJob {
    /// Special operands: the result is known at setup.
    Done(u32, Flags),
    Div(DivJob),
    Sqrt(SqrtJob),
}

impl LaneJob {
    /// Up to `k` more recurrence steps (none past the last).
    #[inline(always)]
    fn step(&mut self, k: u32) {
        match self {
            LaneJob::Done(..) => {}
            LaneJob::Div(j) => {
                for _ in 0..k.min(DIV_STEPS.saturating_sub(j.rec.steps)) {
                    j.rec.step();
                }
            }
            LaneJob::Sqrt(j) => {
                for _ in 0..k.min(SQRT_STEPS.saturating_sub(j.rec.steps)) {
                    j.rec.step();
                }
            }
        }
    }

    #[inline(always)]
    fn finish(&self, mode: FpMode) -> (u32, Flags) {
        match self {
            LaneJob::Done(r, f) => (*r, *f),
            LaneJob::Div(j) => div_finish(j, mode),
            LaneJob::Sqrt(j) => sqrt_finish(j, mode),
        }
    }

    /// `(rem, quotient, steps)` of the recurrence register.
    fn core_state(&self) -> (u32, u32, u32) {
        match self {
            LaneJob::Done(..) => (0, 0, 0),
            LaneJob::Div(j) => (j.rec.rem, j.rec.quotient, j.rec.steps),
            LaneJob::Sqrt(j) => (j.rec.rem, j.rec.root, j.rec.steps),
        }
    }
}

/// Per-cluster probes of the recurrence core.
#[derive(Clone, Debug)]
struct CoreIds {
    valid: SignalId,
    op: SignalId,
    rem: SignalId,
    quotient: SignalId,
    step: SignalId,
}

/// The divide/sqrt unit slot `name` in every cluster.
pub struct DivSqrt {
    path: String,
    lanes: usize,
    mode: FpMode,
    latency_div: u32,
    latency_sqrt: u32,
    interval: u32,
    /// Recurrence steps per cycle.
    steps_per_cycle: u32,
    ring: Ring,
    /// Per ring slot, `lanes` jobs.
    jobs: Vec<LaneJob>,
    /// The last issue: its cycle and ring slot (the only job that can be in the core).
    last: Option<(u64, usize)>,
    /// The result register: valid when the ring's current slot is.
    values: Vec<u32>,
    flags: Vec<Flags>,
    issued: bool,
    /// A tracer is attached: the recurrence core steps cycle by cycle and the issue latch
    /// is kept, for the probes. Without one each lane's result is computed at issue, on
    /// `datapath`, and only the timing is modelled: the bit-level datapath is the same
    /// recurrence run to its end ([`fp32::div`], [`fp32::sqrt`]: the same setup, steps and
    /// rounding), the host fast path gives the same bits and flags ([`fp32::host`]).
    ///
    /// [`fp32::div`]: crate::arith::fp32::div
    /// [`fp32::sqrt`]: crate::arith::fp32::sqrt
    /// [`fp32::host`]: crate::arith::fp32::host
    tracing: bool,
    datapath: Datapath,
    /// The results computed at issue, before they become the lanes' jobs.
    values_at_issue: Vec<u32>,
    flags_at_issue: Vec<Flags>,
    latch: IssueLatch,
    probes: UnitProbes,
    core_ids: Vec<CoreIds>,
}

/// The unit's state: what is in flight, each lane's job as the result it gives (a job in
/// the recurrence core and one computed at issue are the same op on its way), and the
/// result register; not the probes' latches or the core's digits, which only a tracer
/// reads.
impl std::fmt::Debug for DivSqrt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.lanes;
        let in_flight: Vec<_> = (self.ring.slots.iter().enumerate())
            .filter(|(_, s)| s.valid)
            .map(|(i, s)| {
                let results: Vec<_> = self.jobs[i * n..(i + 1) * n]
                    .iter()
                    .map(|j| {
                        let mut j = *j;
                        j.step(STEPS);
                        j.finish(self.mode)
                    })
                    .collect();
                (i, s, results)
            })
            .collect();
        f.debug_struct("DivSqrt")
            .field("path", &self.path)
            .field("ring_head", &self.ring.head)
            .field("ring_cycle", &self.ring.cycle)
            .field("in_flight", &in_flight)
            .field("last", &self.last)
            .field("values", &self.values)
            .field("flags", &self.flags)
            .field("issued", &self.issued)
            .finish()
    }
}

impl DivSqrt {
    /// The divide/sqrt slot `name` (e.g. `dsq0`) in `lanes` clusters, with the latencies,
    /// issue interval and fp mode of `desc`; probes under `<scope>.cluster{c}.{name}`.
    pub fn new(scope: &mut Scope<'_>, name: &str, lanes: usize, desc: &MachineDesc) -> Self {
        assert!(lanes > 0, "unit `{name}` needs at least one lane");
        let l = &desc.latency;
        let (latency_div, latency_sqrt) = (l.div.max(1), l.sqrt.max(1));
        let max_latency = latency_div.max(latency_sqrt);
        let interval = l
            .divsqrt_issue_interval
            .clamp(1, latency_div.min(latency_sqrt));
        let ring = Ring::new(max_latency);
        let depth = ring.slots.len();
        let probes = UnitProbes::new(scope, name, lanes, 2, interval + 1..=max_latency);
        let core_ids = (0..lanes)
            .map(|c| {
                let mut cl = scope.child(&format!("cluster{c}"));
                let mut u = cl.child(name);
                let mut s = u.child("core");
                CoreIds {
                    valid: s.signal("valid", 1, SignalKind::Reg),
                    op: s.signal_shown("op", Op::OPCODE_BITS, SignalKind::Reg, Op::display()),
                    rem: s.signal("rem", REM_BITS, SignalKind::Reg),
                    quotient: s.signal("quotient", QUOTIENT_BITS, SignalKind::Reg),
                    step: s.signal("step", bits_for(u64::from(STEPS)), SignalKind::Reg),
                }
            })
            .collect();
        DivSqrt {
            path: issue_path(scope, name),
            lanes,
            mode: desc.fp_mode(),
            latency_div,
            latency_sqrt,
            interval,
            steps_per_cycle: STEPS.div_ceil(interval),
            ring,
            jobs: vec![LaneJob::Done(0, Flags::NONE); depth * lanes],
            last: None,
            values: vec![0; lanes],
            flags: vec![Flags::NONE; lanes],
            issued: false,
            tracing: true,
            datapath: Datapath::Host,
            values_at_issue: vec![0; lanes],
            flags_at_issue: vec![Flags::NONE; lanes],
            latch: IssueLatch::new(lanes),
            probes,
            core_ids,
        }
    }

    /// Issues `fdiv` or `fsqrt` in the current cycle (see the [module](self) doc).
    #[inline]
    pub fn issue(&mut self, is: Issue<'_>) -> Result<(), ContractError> {
        if self.issued {
            return Err(second_issue(&self.path));
        }
        if !matches!(is.op, Op::FDiv | Op::FSqrt) {
            return Err(wrong_class(&self.path, is.op, UnitClass::DivSqrt));
        }
        let (a, b, c) = operands(&self.path, self.lanes, &is)?;
        self.issue_checked::<0>(is.op, [a, b, c], is.tag)
    }

    /// [`issue`](Self::issue) for an op known to be `fdiv` or `fsqrt` with one word per lane
    /// in each operand (the cluster issues only programs that passed the microcode check).
    /// Still refused: a second issue in a cycle, an issue while the core is busy and a
    /// writeback conflict, which depend on timing. Compiled for `L` lanes
    /// ([`crate::lanes`]).
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
        let lat = if op == Op::FDiv {
            self.latency_div
        } else {
            self.latency_sqrt
        };
        let [a, b, c] = operands;
        let is = Issue { op, a, b, c, tag };
        if let Some((t0, s0)) = self.last
            && self.ring.cycle < t0 + u64::from(self.interval)
        {
            return Err(self.core_busy(is.op, t0, s0));
        }
        let s = self.ring.slot_after(lat);
        if self.ring.slots[s].valid {
            return Err(self.ring.conflict(&self.path, is.op, lat));
        }
        let n = count::<L>(self.lanes);
        let (jobs, mode) = (&mut self.jobs[s * n..(s + 1) * n], self.mode);
        let (a, b) = (&a[..n], &b[..n]);
        if !self.tracing {
            let (values, flags) = (
                &mut self.values_at_issue[..n],
                &mut self.flags_at_issue[..n],
            );
            op.eval_lanes_fixed::<L>(self.datapath, [a, b, a], mode, values, flags);
            for ((j, &r), &f) in jobs.iter_mut().zip(&*values).zip(&*flags) {
                *j = LaneJob::Done(r, f);
            }
        } else if is.op == Op::FDiv {
            for ((j, &x), &y) in jobs.iter_mut().zip(a).zip(b) {
                *j = match div_setup(x, y, mode) {
                    Setup::Done(r, f) => LaneJob::Done(r, f),
                    Setup::Run(job) => LaneJob::Div(job),
                };
            }
        } else {
            for (j, &x) in jobs.iter_mut().zip(a) {
                *j = match sqrt_setup(x, mode) {
                    Setup::Done(r, f) => LaneJob::Done(r, f),
                    Setup::Run(job) => LaneJob::Sqrt(job),
                };
            }
        }
        self.ring.slots[s] = Slot {
            valid: true,
            op: is.op,
            tag: is.tag,
            latency: lat,
            issued: self.ring.cycle,
        };
        self.last = Some((self.ring.cycle, s));
        if self.tracing {
            self.latch.capture(&is);
        }
        self.issued = true;
        Ok(())
    }

    /// Whether a tracer is attached (see the field's doc and
    /// [`imagine_hdl::Module::set_tracing`]).
    pub fn set_tracing(&mut self, on: bool) {
        if self.tracing && !on {
            // Jobs in the core would no longer be stepped: run them to their end now.
            self.jobs.iter_mut().for_each(|j| j.step(STEPS));
        }
        self.tracing = on;
    }

    /// What computes results at issue when no tracer is attached (the host fast path unless
    /// told otherwise; the same words and flags either way).
    pub fn set_datapath(&mut self, datapath: Datapath) {
        self.datapath = datapath;
    }

    #[cold]
    #[inline(never)]
    fn core_busy(&self, op: Op, t0: u64, s0: usize) -> ContractError {
        let prev = &self.ring.slots[s0];
        ContractError::at(
            &self.path,
            Violation::Busy {
                detail: format!(
                    "`{op}` issued in cycle {} while the recurrence core is busy with `{}` \
                     (tag {}) issued in cycle {t0}; the issue interval is {} cycles, so the \
                     next issue may be in cycle {}",
                    self.ring.cycle,
                    prev.op,
                    prev.tag,
                    self.interval,
                    t0 + u64::from(self.interval)
                ),
            },
        )
    }

    /// The op completing in the current cycle, if any (from committed state).
    #[inline]
    pub fn completed(&self) -> Option<Completion<'_>> {
        let s = self.ring.current()?;
        Some(Completion {
            op: s.op,
            tag: s.tag,
            values: &self.values,
            flags: &self.flags,
        })
    }

    /// Ends the cycle: the core advances its job by `k` recurrence steps, and the op reaching
    /// its last stage is rounded into the result register.
    #[inline]
    pub fn commit(&mut self) {
        self.ring.advance();
        self.latch.valid = self.issued;
        self.issued = false;
        let n = self.lanes;
        if let Some((t0, s)) = self.last {
            let age = self.ring.cycle - t0;
            if age > u64::from(self.interval) {
                self.last = None;
            } else if self.tracing {
                let k = self.steps_per_cycle;
                for j in &mut self.jobs[s * n..(s + 1) * n] {
                    j.step(k);
                }
            }
        }
        if self.ring.current().is_some() {
            let h = self.ring.head;
            let mode = self.mode;
            for ((j, v), f) in self.jobs[h * n..(h + 1) * n]
                .iter()
                .zip(&mut self.values)
                .zip(&mut self.flags)
            {
                (*v, *f) = j.finish(mode);
            }
        }
    }

    /// Whether nothing is in flight, issued this cycle or in the recurrence core, so that
    /// cycles only turn the ring.
    pub fn is_quiet(&self) -> bool {
        !self.issued && self.ring.in_flight() == 0 && self.last.is_none()
    }

    /// Brings a quiet unit over `n ≥ 1` cycles, as `n` commits without issues would.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.is_quiet() && n > 0);
        self.ring.skip_idle(n);
        self.latch.valid = false;
    }

    /// Whether the recurrence core holds a job that blocks an issue in the current cycle.
    pub fn busy(&self) -> bool {
        self.last
            .is_some_and(|(t0, _)| self.ring.cycle < t0 + u64::from(self.interval))
    }

    /// The job in the recurrence core after the last edge: its ring slot.
    fn core_slot(&self) -> Option<usize> {
        self.last.and_then(|(t0, s)| {
            let age = self.ring.cycle - t0;
            (1..=u64::from(self.interval)).contains(&age).then_some(s)
        })
    }

    /// Reports every probe (after a commit).
    pub fn trace(&self, t: &mut Trace) {
        let stages = self.ring.stages(self.ring.slots.len() as u32 - 1);
        self.probes.trace(t, &self.latch, self.completed(), &stages);
        let core = self.core_slot();
        for (c, ids) in self.core_ids.iter().enumerate() {
            t.value(ids.valid, core.is_some() as u64);
            if let Some(s) = core {
                t.value(ids.op, u64::from(self.ring.slots[s].op.opcode()));
                let (rem, quotient, step) = self.jobs[s * self.lanes + c].core_state();
                t.value(ids.rem, u64::from(rem));
                t.value(ids.quotient, u64::from(quotient));
                t.value(ids.step, u64::from(step));
            }
        }
    }

    /// The latency of `op` on this unit, or `None` if the unit does not execute it.
    pub fn latency_of(&self, op: Op) -> Option<u32> {
        match op {
            Op::FDiv => Some(self.latency_div),
            Op::FSqrt => Some(self.latency_sqrt),
            _ => None,
        }
    }

    /// Whether issuing `op` now would be accepted.
    pub fn can_issue(&self, op: Op) -> bool {
        self.latency_of(op).is_some_and(|l| {
            !self.issued && !self.busy() && !self.ring.slots[self.ring.slot_after(l)].valid
        })
    }

    /// Cycles between issues (1 = fully pipelined).
    pub fn issue_interval(&self) -> u32 {
        self.interval
    }

    /// Recurrence steps the core performs per cycle.
    pub fn steps_per_cycle(&self) -> u32 {
        self.steps_per_cycle
    }

    pub fn class(&self) -> UnitClass {
        UnitClass::DivSqrt
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

super::impl_functional_unit!([] DivSqrt);
