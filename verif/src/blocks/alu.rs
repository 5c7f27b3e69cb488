//! Testbench of the integer and packed datapath of the cluster units: every integer,
//! logic, shift, select and packed (2×16, 4×8) op issued to a real adder and multiplier,
//! with operands biased to the lane boundaries, and each result compared with a reference
//! written here in plain Rust from the ops' definitions (nothing of `units::arith`).

use std::collections::VecDeque;

use imagine_units::desc::MachineDesc;
use imagine_units::fu::{Adder, FunctionalUnit, Issue, Multiplier};
use imagine_units::ops::{Op, UnitClass};

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const CORNER_BINS: &[&str] = &[
    "wrapping 32-bit add or subtract",
    "shift amount of 32 or more",
    "iabs of the most negative word",
    "select on an even non-zero condition",
    "packed lane wraps",
    "packed lane saturates",
];

/// The integer and packed ops: everything the adders and multipliers do that is not fp32.
fn integer_ops() -> Vec<Op> {
    Op::ALL
        .iter()
        .copied()
        .filter(|o| {
            o.unit() != UnitClass::DivSqrt && !o.name().starts_with('f') && o.name() != "i32tof"
        })
        .collect()
}

/// The reference result of `op` and whether a packed lane wrapped or saturated.
pub(crate) fn reference(op: Op, a: u32, b: u32, c: u32) -> (u32, bool) {
    let name = op.name();
    if let Some(width) = [(16, "_16x2"), (8, "_8x4")]
        .iter()
        .find(|(_, tag)| name.contains(tag))
    {
        return packed(&name.replace(width.1, ""), width.0, a, b);
    }
    let (sa, sb) = (a as i32, b as i32);
    let word = match name {
        "iadd" => a.wrapping_add(b),
        "isub" => a.wrapping_sub(b),
        "ineg" => 0u32.wrapping_sub(a),
        "iabs" => sa.wrapping_abs() as u32,
        "and" => a & b,
        "or" => a | b,
        "xor" => a ^ b,
        "not" => !a,
        "shl" => a << (b % 32),
        "shr" => a >> (b % 32),
        "sra" => (sa >> (b % 32)) as u32,
        "ieq" => u32::from(a == b),
        "ine" => u32::from(a != b),
        "ilt_s" => u32::from(sa < sb),
        "ile_s" => u32::from(sa <= sb),
        "ilt_u" => u32::from(a < b),
        "ile_u" => u32::from(a <= b),
        "imin_s" => sa.min(sb) as u32,
        "imax_s" => sa.max(sb) as u32,
        "imin_u" => a.min(b),
        "imax_u" => a.max(b),
        "select" => {
            if a % 2 == 1 {
                b
            } else {
                c
            }
        }
        "imul_lo" => a.wrapping_mul(b),
        "imul_hi_s" => ((i64::from(sa) * i64::from(sb)) >> 32) as u32,
        "imul_hi_u" => ((u64::from(a) * u64::from(b)) >> 32) as u32,
        "imul_hi_su" => ((i64::from(sa) * i64::from(b)) >> 32) as u32,
        "mov" => a,
        other => panic!("no reference for op `{other}`"),
    };
    (word, false)
}

/// A packed op (`kind` is the mnemonic without its lane shape) on lanes of `width` bits.
fn packed(kind: &str, width: u32, a: u32, b: u32) -> (u32, bool) {
    let lane_mask = (1u32 << width) - 1;
    let (max_s, min_s) = ((1i64 << (width - 1)) - 1, -(1i64 << (width - 1)));
    let signed = |x: u32| {
        let x = i64::from(x);
        if x > max_s { x - (1 << width) } else { x }
    };
    let all = |cond: bool| if cond { lane_mask } else { 0 };
    let mut out = 0;
    let mut clamped = false;
    for lane in 0..32 / width {
        let x = (a >> (lane * width)) & lane_mask;
        let y = (b >> (lane * width)) & lane_mask;
        let (sx, sy) = (signed(x), signed(y));
        let (ux, uy) = (i64::from(x), i64::from(y));
        let clamp = |v: i64, lo: i64, hi: i64, clamped: &mut bool| {
            *clamped |= v < lo || v > hi;
            v.clamp(lo, hi)
        };
        let r: i64 = match kind {
            "add" => {
                clamped |= ux + uy > i64::from(lane_mask);
                ux + uy
            }
            "sub" => {
                clamped |= ux < uy;
                ux - uy
            }
            "add_sat_s" => clamp(sx + sy, min_s, max_s, &mut clamped),
            "add_sat_u" => clamp(ux + uy, 0, i64::from(lane_mask), &mut clamped),
            "sub_sat_s" => clamp(sx - sy, min_s, max_s, &mut clamped),
            "sub_sat_u" => clamp(ux - uy, 0, i64::from(lane_mask), &mut clamped),
            "eq" => i64::from(all(x == y)),
            "lt_s" => i64::from(all(sx < sy)),
            "le_s" => i64::from(all(sx <= sy)),
            "lt_u" => i64::from(all(x < y)),
            "le_u" => i64::from(all(x <= y)),
            "min_s" => sx.min(sy),
            "max_s" => sx.max(sy),
            "min_u" => ux.min(uy),
            "max_u" => ux.max(uy),
            "mul_lo" => ux * uy,
            "mul_hi_s" => (sx * sy) >> width,
            "mul_hi_u" => (ux * uy) >> width,
            other => panic!("no reference for packed op `{other}`"),
        };
        out |= (r as u32 & lane_mask) << (lane * width);
    }
    (out, clamped)
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let ops = integer_ops();
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let mut names: Vec<String> = ops.iter().map(|o| format!("op {o}")).collect();
    names.extend(CORNER_BINS.iter().map(|b| b.to_string()));
    let mut cov = Coverage::new(&names);
    let mut d = design();
    let mut scope = d.scope();
    let mut adder = Adder::new(&mut scope, "add0", lanes, desc);
    let mut multiplier = Multiplier::new(&mut scope, "mul0", lanes, desc);
    let (adder_ops, multiplier_ops): (Vec<Op>, Vec<Op>) =
        ops.iter().partition(|o| o.unit() == UnitClass::Adder);
    // Expected results by unit, in issue order (each unit's ops here share one latency).
    let mut expected: [VecDeque<(u16, Op, Vec<u32>)>; 2] = [VecDeque::new(), VecDeque::new()];
    let mut tag = 0u16;
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0u64;
    while sb.transactions < config.transactions || expected.iter().any(|q| !q.is_empty()) {
        let drive = sb.transactions < config.transactions;
        let units: [(&mut dyn FunctionalUnit, &[Op]); 2] =
            [(&mut adder, &adder_ops), (&mut multiplier, &multiplier_ops)];
        for (k, (unit, unit_ops)) in units.into_iter().enumerate() {
            if drive && !unit_ops.is_empty() && rng.chance(90) {
                sb.transaction();
                let op = rng.pick(unit_ops);
                let (a, b, c) = (
                    rng.lane_words(lanes),
                    rng.lane_words(lanes),
                    rng.lane_words(lanes),
                );
                tag = tag.wrapping_add(1);
                let accepted = unit
                    .issue(Issue {
                        op,
                        a: &a,
                        b: &b,
                        c: &c,
                        tag,
                    })
                    .is_ok();
                sb.check(cycle, || format!("issue of {op} accepted"), true, accepted);
                let mut words = Vec::with_capacity(lanes);
                for i in 0..lanes {
                    let (word, clamped) = reference(op, a[i], b[i], c[i]);
                    words.push(word);
                    let n = op.name();
                    cov.hit_if(clamped && n.contains("sat"), "packed lane saturates");
                    cov.hit_if(clamped && !n.contains("sat"), "packed lane wraps");
                    cov.hit_if(
                        matches!(n, "shl" | "shr" | "sra") && b[i] >= 32,
                        "shift amount of 32 or more",
                    );
                    cov.hit_if(
                        n == "iadd" && a[i].checked_add(b[i]).is_none(),
                        "wrapping 32-bit add or subtract",
                    );
                    cov.hit_if(
                        n == "isub" && a[i].checked_sub(b[i]).is_none(),
                        "wrapping 32-bit add or subtract",
                    );
                    cov.hit_if(
                        n == "iabs" && a[i] == 0x8000_0000,
                        "iabs of the most negative word",
                    );
                    cov.hit_if(
                        n == "select" && a[i] != 0 && a[i] % 2 == 0,
                        "select on an even non-zero condition",
                    );
                }
                cov.hit(&format!("op {op}"));
                if accepted {
                    expected[k].push_back((tag, op, words));
                }
            }
            if let Some(done) = unit.completed() {
                let want = expected[k].pop_front();
                let got = (done.tag, done.op, done.values.to_vec());
                let (op, a) = (done.op, want.as_ref().map(|w| w.0));
                sb.check(
                    cycle,
                    || format!("result of {op} (tag {a:?})"),
                    want,
                    Some(got),
                );
                sb.assert(cycle, done.flags.iter().all(|f| f.bits() == 0), || {
                    format!("{op} raises no flags")
                });
            }
            unit.commit();
        }
        waves.cycle(cycle, |t| {
            adder.trace(t);
            multiplier.trace(t);
        });
        cycle += 1;
        if cycle > 64 * (config.transactions + 64) {
            sb.assert(cycle, false, || "every issued op completes".into());
            break;
        }
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
