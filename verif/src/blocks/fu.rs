//! Testbench of the functional-unit pipelines (`units::fu`): an adder, a multiplier and the
//! divide/sqrt unit of the machine, each issued random ops of its class every cycle, biased
//! to back-to-back issue and to mixing latencies.
//!
//! Reference, per unit: an op issued in cycle `t` completes in cycle `t + L`, `L` the
//! latency the machine description gives its class (worked out here from the op's name,
//! not from the unit's table); one result port, so an issue whose result would leave with
//! an earlier op's is refused (a writeback conflict); the divide/sqrt unit also refuses an
//! issue before `divsqrt_issue_interval` cycles after the last. Values and flags come from
//! the op functions ([`Op::eval`]), the one thing shared with the block.

use std::collections::BTreeMap;

use imagine_units::arith::fp32::FpMode;
use imagine_units::desc::{Latency, MachineDesc};
use imagine_units::fu::{Adder, DivSqrt, FunctionalUnit, Issue, Multiplier};
use imagine_units::ops::{Op, UnitClass};

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

/// The coverage bins of a unit called `label`: those its machine can reach (writeback
/// conflicts need ops of two latencies, a busy core an issue interval over 1).
fn bins(label: &str, mixed_latencies: bool, interval: u32) -> Vec<String> {
    let mut b = vec![
        "issue",
        "second issue in a cycle refused",
        "two ops in flight",
    ];
    if interval == 1 {
        b.push("back-to-back issue");
    }
    if mixed_latencies {
        b.extend([
            "shorter op after a longer one",
            "writeback conflict refused",
        ]);
    }
    if interval > 1 {
        b.extend([
            "issue refused while the core is busy",
            "issue exactly one interval after the last",
        ]);
    }
    b.iter().map(|b| format!("{label}: {b}")).collect()
}

/// The latency of `op` under `l`, from what the op is (its mnemonic).
pub(crate) fn reference_latency(op: Op, l: &Latency) -> u32 {
    match op.name() {
        "fdiv" => l.div,
        "fsqrt" => l.sqrt,
        n if n.contains("mul") => l.mul,
        n if n.starts_with('f') || n == "i32tof" => l.fp_add,
        _ => l.int,
    }
}

/// A result the reference expects: op, tag, and per cluster the word and flag bits.
type Expected = (Op, u16, Vec<(u32, u8)>);

/// One unit under test with its reference model.
struct UnitBench<U> {
    label: &'static str,
    unit: U,
    ops: Vec<Op>,
    /// Cycles between accepted issues (1: fully pipelined).
    interval: u64,
    due: BTreeMap<u64, Expected>,
    last_issue: Option<(u64, u32)>,
    tag: u16,
}

/// What the loop over units needs of the machine.
struct Env<'a> {
    lanes: usize,
    latency: &'a Latency,
    mode: FpMode,
}

impl<U: FunctionalUnit> UnitBench<U> {
    fn new(label: &'static str, unit: U, class: UnitClass, interval: u32) -> Self {
        UnitBench {
            label,
            unit,
            ops: Op::ALL
                .iter()
                .copied()
                .filter(|o| o.unit() == class)
                .collect(),
            interval: u64::from(interval),
            due: BTreeMap::new(),
            last_issue: None,
            tag: 0,
        }
    }

    fn accepts(&self, cycle: u64, latency: u32) -> bool {
        let core_free = self
            .last_issue
            .is_none_or(|(t, _)| cycle >= t + self.interval);
        core_free && !self.due.contains_key(&(cycle + u64::from(latency)))
    }

    /// One cycle: maybe an issue (and a second), the completion check, the edge.
    fn cycle(
        &mut self,
        cycle: u64,
        drive: bool,
        env: &Env<'_>,
        rng: &mut Rng,
        sb: &mut Scoreboard,
        cov: &mut Coverage,
    ) {
        let label = self.label;
        let bin = |b: &str| format!("{label}: {b}");
        if drive && rng.chance(75) {
            sb.transaction();
            let op = self.pick_op(rng, env.latency);
            let latency = reference_latency(op, env.latency);
            let accepted = self.accepts(cycle, latency);
            sb.check(
                cycle,
                || format!("{label} can_issue({op})"),
                accepted,
                self.unit.can_issue(op),
            );
            let a = rng.lane_words(env.lanes);
            let b = rng.lane_words(env.lanes);
            let c = rng.lane_words(env.lanes);
            self.tag = self.tag.wrapping_add(1);
            let issue = Issue {
                op,
                a: &a,
                b: &b,
                c: &c,
                tag: self.tag,
            };
            let got = self.unit.issue(issue).is_ok();
            sb.check(
                cycle,
                || format!("{label} issue of {op} (latency {latency}) accepted"),
                accepted,
                got,
            );
            let previous = self.last_issue;
            if accepted {
                let values = (0..env.lanes)
                    .map(|i| {
                        let (v, f) = op.eval(a[i], b[i], c[i], env.mode);
                        (v, f.bits())
                    })
                    .collect();
                self.due
                    .insert(cycle + u64::from(latency), (op, self.tag, values));
                self.last_issue = Some((cycle, latency));
                cov.hit(&bin("issue"));
                cov.hit_if(self.due.len() >= 2, &bin("two ops in flight"));
                if let Some((t, l)) = previous {
                    cov.hit_if(t + 1 == cycle, &bin("back-to-back issue"));
                    cov.hit_if(latency < l, &bin("shorter op after a longer one"));
                    cov.hit_if(
                        self.interval > 1 && t + self.interval == cycle,
                        &bin("issue exactly one interval after the last"),
                    );
                }
            } else {
                let busy = previous.is_some_and(|(t, _)| cycle < t + self.interval);
                cov.hit_if(busy, &bin("issue refused while the core is busy"));
                cov.hit_if(!busy, &bin("writeback conflict refused"));
            }
            if rng.chance(5) {
                sb.transaction();
                let refused = self
                    .unit
                    .issue(Issue {
                        op,
                        a: &a,
                        b: &b,
                        c: &c,
                        tag: 0,
                    })
                    .is_err();
                sb.check(
                    cycle,
                    || format!("{label} second issue in a cycle refused"),
                    true,
                    refused,
                );
                cov.hit(&bin("second issue in a cycle refused"));
            }
        }
        let expected = self.due.remove(&cycle);
        let got = self.unit.completed().map(|d| {
            let words = d
                .values
                .iter()
                .zip(d.flags)
                .map(|(&v, f)| (v, f.bits()))
                .collect();
            (d.op, d.tag, words)
        });
        sb.check(cycle, || format!("{label} result leaving"), expected, got);
        self.unit.commit();
    }

    /// An op of the unit's class, half the time of another latency than the last issue's
    /// (to provoke writeback conflicts).
    fn pick_op(&self, rng: &mut Rng, l: &Latency) -> Op {
        if let Some((_, last)) = self.last_issue
            && rng.chance(50)
        {
            let others: Vec<Op> = self
                .ops
                .iter()
                .copied()
                .filter(|&o| reference_latency(o, l) != last)
                .collect();
            if !others.is_empty() {
                return rng.pick(&others);
            }
        }
        rng.pick(&self.ops)
    }

    fn busy(&self) -> bool {
        !self.due.is_empty()
    }

    fn bins(&self, l: &Latency) -> Vec<String> {
        let first = reference_latency(self.ops[0], l);
        let mixed = self.ops.iter().any(|&o| reference_latency(o, l) != first);
        bins(self.label, mixed, self.interval as u32)
    }
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let env = Env {
        lanes,
        latency: &desc.latency,
        mode: desc.fp_mode(),
    };
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let mut d = design();
    let mut scope = d.scope();
    let mut adder = UnitBench::new(
        "adder",
        Adder::new(&mut scope, "add0", lanes, desc),
        UnitClass::Adder,
        1,
    );
    let mut multiplier = UnitBench::new(
        "multiplier",
        Multiplier::new(&mut scope, "mul0", lanes, desc),
        UnitClass::Multiplier,
        1,
    );
    let mut divsqrt = (desc.cluster.divsqrt > 0).then(|| {
        let unit = DivSqrt::new(&mut scope, "dsq0", lanes, desc);
        let interval = unit.issue_interval();
        sb.check(
            0,
            || "divsqrt issue interval".into(),
            desc.latency.divsqrt_issue_interval,
            interval,
        );
        UnitBench::new(
            "divsqrt",
            unit,
            UnitClass::DivSqrt,
            desc.latency.divsqrt_issue_interval,
        )
    });
    let mut names = adder.bins(&desc.latency);
    names.extend(multiplier.bins(&desc.latency));
    if let Some(u) = &divsqrt {
        names.extend(u.bins(&desc.latency));
    }
    let mut cov = Coverage::new(&names);
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0;
    loop {
        let drive = sb.transactions < config.transactions;
        let busy = adder.busy() || multiplier.busy() || divsqrt.as_ref().is_some_and(|u| u.busy());
        if !drive && !busy {
            break;
        }
        adder.cycle(cycle, drive, &env, &mut rng, &mut sb, &mut cov);
        multiplier.cycle(cycle, drive, &env, &mut rng, &mut sb, &mut cov);
        if let Some(u) = &mut divsqrt {
            u.cycle(cycle, drive, &env, &mut rng, &mut sb, &mut cov);
        }
        waves.cycle(cycle, |t| {
            adder.unit.trace(t);
            multiplier.unit.trace(t);
            if let Some(u) = &divsqrt {
                u.unit.trace(t);
            }
        });
        cycle += 1;
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
