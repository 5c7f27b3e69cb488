//! The pipelined units (`Adder`, `Multiplier`): values equal `Op::eval`, exact latencies from
//! the machine description, one issue per cycle, and the contract errors.

use std::collections::VecDeque;

use imagine_hdl::{Design, Violation, default_domains};
use imagine_units::arith::flags::Flags;
use imagine_units::arith::fp32::testgen::{SplitMix64, biased_f32, biased_i32};
use imagine_units::desc::MachineDesc;
use imagine_units::fu::{Adder, Issue, Multiplier, Pipelined, PipelinedKind};
use imagine_units::ops::{Op, UnitClass};

fn design() -> Design {
    Design::new("top", default_domains()).unwrap()
}

fn adder(lanes: usize, desc: &MachineDesc) -> Adder {
    let mut d = design();
    Adder::new(&mut d.scope(), "add0", lanes, desc)
}

fn multiplier(lanes: usize, desc: &MachineDesc) -> Multiplier {
    let mut d = design();
    Multiplier::new(&mut d.scope(), "mul1", lanes, desc)
}

fn word(op: Op, rng: &mut SplitMix64) -> u32 {
    if op.name().starts_with('f') {
        biased_f32(rng)
    } else {
        biased_i32(rng)
    }
}

/// An issued op and what it must produce.
struct Expected {
    tag: u16,
    op: Op,
    due: u64,
    values: Vec<u32>,
    flags: Vec<Flags>,
}

/// Streams `count` random ops of the unit's class through it, issuing whenever the unit
/// accepts the next op (so every cycle unless a writeback conflict forces a bubble), and
/// checks each result: value and flags equal `Op::eval` per lane, completion exactly at
/// issue cycle + latency. Returns the number of cycles taken.
fn stream<K: PipelinedKind>(unit: &mut Pipelined<K>, desc: &MachineDesc, count: usize) -> u64 {
    let lanes = unit.lanes();
    let mode = desc.fp_mode();
    let ops: Vec<Op> = Op::ALL
        .iter()
        .copied()
        .filter(|o| o.unit() == K::CLASS)
        .collect();
    let mut rng = SplitMix64::new(0xADD5 + lanes as u64);
    let mut pending: VecDeque<Expected> = VecDeque::new();
    let mut issued = 0usize;
    let mut next = ops[0];
    let mut tag = 0u16;
    while issued < count || !pending.is_empty() {
        let now = unit.cycle();
        // Completions first (order within the cycle must not matter; see below).
        match unit.completed() {
            Some(c) => {
                let pos = pending
                    .iter()
                    .position(|e| e.tag == c.tag)
                    .expect("completion of an issued op");
                let e = pending.remove(pos).unwrap();
                assert_eq!(e.due, now, "{} completed at the wrong cycle", e.op);
                assert_eq!(c.op, e.op);
                assert_eq!(c.values, &e.values[..], "{} values", e.op);
                assert_eq!(c.flags, &e.flags[..], "{} flags", e.op);
            }
            None => assert!(pending.iter().all(|e| e.due != now), "missing completion"),
        }
        if issued < count && unit.can_issue(next) {
            let mut operands = [vec![0; lanes], vec![0; lanes], vec![0; lanes]];
            for v in operands.iter_mut() {
                for x in v.iter_mut() {
                    *x = word(next, &mut rng);
                }
            }
            if rng.below(4) == 0 {
                operands[1] = operands[0].clone();
            }
            let [a, b, c] = &operands;
            let (values, flags) = (0..lanes)
                .map(|i| next.eval(a[i], b[i], c[i], mode))
                .unzip();
            unit.issue(Issue {
                op: next,
                a,
                b,
                c,
                tag,
            })
            .unwrap();
            pending.push_back(Expected {
                tag,
                op: next,
                due: now + u64::from(next.latency(&desc.latency)),
                values,
                flags,
            });
            issued += 1;
            tag = tag.wrapping_add(1);
            next = ops[rng.below(ops.len() as u32) as usize];
        }
        unit.commit();
        assert!(unit.cycle() < 100 * count as u64 + 100, "stuck");
    }
    unit.cycle()
}

#[test]
fn adder_results_equal_op_eval_on_1_and_8_lanes() {
    for desc in [MachineDesc::gold8(), {
        let mut d = MachineDesc::gold8();
        d.arithmetic.flush_to_zero = true;
        d
    }] {
        for lanes in [1, 8] {
            stream(&mut adder(lanes, &desc), &desc, 3000);
        }
    }
}

#[test]
fn multiplier_results_equal_op_eval_on_1_and_8_lanes() {
    let mut ftz = MachineDesc::gold8();
    ftz.arithmetic.flush_to_zero = true;
    for desc in [MachineDesc::gold8(), ftz] {
        for lanes in [1, 8] {
            let mut m = multiplier(lanes, &desc);
            // One latency for every multiply: never a bubble.
            let cycles = stream(&mut m, &desc, 2000);
            assert_eq!(cycles, 2000 + u64::from(desc.latency.mul));
        }
    }
}

#[test]
fn mixed_latencies_with_other_descriptions() {
    let mut desc = MachineDesc::gold8();
    desc.latency.int = 1;
    desc.latency.fp_add = 6;
    desc.latency.mul = 3;
    for lanes in [1, 8] {
        stream(&mut adder(lanes, &desc), &desc, 1500);
        stream(&mut multiplier(lanes, &desc), &desc, 1500);
    }
}

/// Issues `op` once at cycle 0 and returns the cycle its result appears in, checking that it
/// appears exactly once.
fn completion_cycle<K: PipelinedKind>(unit: &mut Pipelined<K>, op: Op) -> u64 {
    let a = vec![0x3F80_0000; unit.lanes()];
    let b = vec![0x4000_0000; unit.lanes()];
    let c = vec![1; unit.lanes()];
    let start = unit.cycle();
    unit.issue(Issue {
        op,
        a: &a,
        b: &b,
        c: &c,
        tag: 77,
    })
    .unwrap();
    let mut seen = None;
    for _ in 0..300 {
        if let Some(done) = unit.completed() {
            assert!(seen.is_none(), "{op} completed twice");
            assert_eq!(done.tag, 77);
            seen = Some(unit.cycle() - start);
        }
        unit.commit();
    }
    seen.expect("completed")
}

#[test]
fn latency_per_op_class_comes_from_the_description() {
    let gold = MachineDesc::gold8();
    let mut other = MachineDesc::gold8();
    other.latency.int = 3;
    other.latency.fp_add = 7;
    other.latency.mul = 5;
    for desc in [gold, other] {
        let l = &desc.latency;
        let mut add = adder(8, &desc);
        let mut mul = multiplier(8, &desc);
        for (op, want) in [
            (Op::IAdd, l.int),
            (Op::Select, l.int),
            (Op::Shl, l.int),
            (Op::AddSat16x2S, l.int),
            (Op::Max8x4U, l.int),
            (Op::FAdd, l.fp_add),
            (Op::FLt, l.fp_add),
            (Op::FToI32, l.fp_add),
            (Op::I32ToF, l.fp_add),
            (Op::FAbs, l.fp_add),
        ] {
            assert_eq!(completion_cycle(&mut add, op), u64::from(want), "{op}");
            assert_eq!(add.latency_of(op), Some(want));
        }
        for op in [Op::FMul, Op::IMulLo, Op::IMulHiSU, Op::Mul16x2HiS] {
            assert_eq!(completion_cycle(&mut mul, op), u64::from(l.mul), "{op}");
        }
        assert_eq!(add.latency_of(Op::FMul), None);
        assert_eq!(mul.latency_of(Op::FAdd), None);
    }
}

#[test]
fn back_to_back_fadd_every_cycle() {
    let desc = MachineDesc::gold8();
    let mut add = adder(8, &desc);
    let lat = u64::from(desc.latency.fp_add);
    let n = 200u64;
    let mut got = 0u64;
    for t in 0..n + lat {
        if let Some(c) = add.completed() {
            assert_eq!(u64::from(c.tag), t - lat);
            let k = c.tag as u32;
            // (k + lane) + 1.0 for small integers is exact.
            for (lane, v) in c.values.iter().enumerate() {
                let want = Op::I32ToF.eval(k + lane as u32 + 1, 0, 0, desc.fp_mode()).0;
                assert_eq!(*v, want);
            }
            got += 1;
        } else {
            assert!(t < lat, "a bubble at cycle {t}");
        }
        if t < n {
            let a: Vec<u32> = (0..8)
                .map(|lane| Op::I32ToF.eval(t as u32 + lane, 0, 0, desc.fp_mode()).0)
                .collect();
            let b = [0x3F80_0000u32; 8];
            add.issue(Issue::binary(Op::FAdd, &a, &b, t as u16))
                .unwrap();
            assert_eq!(add.in_flight() as u64, (t + 1).min(lat + 1));
        }
        add.commit();
    }
    assert_eq!(got, n);
    assert_eq!(add.in_flight(), 0);
}

#[test]
fn writeback_conflict_is_detected_at_issue() {
    let desc = MachineDesc::gold8(); // int 2, fp 4
    let mut add = adder(8, &desc);
    let x = [1u32; 8];
    add.issue(Issue::binary(Op::FAdd, &x, &x, 1)).unwrap(); // cycle 0, done in 4
    add.commit();
    add.commit();
    assert!(!add.can_issue(Op::IAdd));
    assert!(add.can_issue(Op::FSub));
    let e = add
        .issue(Issue::binary(Op::IAdd, &x, &x, 2)) // cycle 2, would be done in 4
        .unwrap_err();
    assert_eq!(e.module, "top.cluster*.add0");
    assert_eq!(e.signal, "issue");
    let Violation::Busy { detail } = &e.violation else {
        panic!("{e}")
    };
    assert!(detail.contains("writeback conflict"), "{detail}");
    assert!(
        detail.contains("`iadd`") && detail.contains("`fadd`"),
        "{detail}"
    );
    assert!(detail.contains("cycle 4"), "{detail}");
    // The rejected issue changed nothing: the unit still accepts an op this cycle.
    add.issue(Issue::binary(Op::FSub, &x, &x, 3)).unwrap();
    add.commit();
    add.issue(Issue::binary(Op::IAdd, &x, &x, 4)).unwrap(); // cycle 3, done in 5
    add.commit();
    let mut tags = vec![];
    for _ in 0..6 {
        if let Some(c) = add.completed() {
            tags.push((add.cycle(), c.tag));
        }
        add.commit();
    }
    assert_eq!(tags, vec![(4, 1), (5, 4), (6, 3)]);
}

#[test]
fn contract_errors_name_the_unit() {
    let desc = MachineDesc::gold8();
    let mut add = adder(8, &desc);
    let mut mul = multiplier(8, &desc);
    let x = [0x3F80_0000u32; 8];

    for (op, e) in [
        (Op::FMul, add.issue(Issue::binary(Op::FMul, &x, &x, 0))),
        (Op::FDiv, add.issue(Issue::binary(Op::FDiv, &x, &x, 0))),
        (Op::FAdd, mul.issue(Issue::binary(Op::FAdd, &x, &x, 0))),
        (Op::Select, mul.issue(Issue::binary(Op::Select, &x, &x, 0))),
    ] {
        let e = e.unwrap_err();
        assert!(
            e.module.ends_with("add0") || e.module.ends_with("mul1"),
            "{e}"
        );
        assert!(matches!(e.violation, Violation::Other(_)), "{e}");
        assert!(e.to_string().contains(&format!("`{op}`")), "{e}");
    }
    assert_eq!(add.class(), UnitClass::Adder);
    assert_eq!(mul.class(), UnitClass::Multiplier);

    // Lanes mismatch: too few words, a missing operand, a stray short operand.
    let short = [0u32; 7];
    for is in [
        Issue::binary(Op::FAdd, &short, &x, 0),
        Issue::binary(Op::FAdd, &x, &short, 0),
        Issue::unary(Op::FAdd, &x, 0),
        Issue::binary(Op::FNeg, &x, &short, 0),
        Issue {
            op: Op::Select,
            a: &x,
            b: &x,
            c: &[],
            tag: 0,
        },
    ] {
        let e = add.issue(is).unwrap_err();
        assert_eq!(e.module, "top.cluster*.add0");
        assert!(e.to_string().contains("one per lane"), "{e}");
    }

    // A unary op may leave b empty; a second issue in the same cycle is over bandwidth.
    add.issue(Issue::unary(Op::FNeg, &x, 0)).unwrap();
    let e = add.issue(Issue::unary(Op::FNeg, &x, 1)).unwrap_err();
    assert_eq!(
        e.violation,
        Violation::OverBandwidth {
            written: 2,
            bandwidth: 1
        }
    );
    assert!(e.to_string().contains("top.cluster*.add0"), "{e}");
    add.commit();
    add.issue(Issue::unary(Op::FNeg, &x, 1)).unwrap();
}

#[test]
fn unread_results_are_dropped_and_reads_do_not_depend_on_issue_order() {
    let mut desc = MachineDesc::gold8();
    desc.latency.int = 1;
    let mut add = adder(2, &desc);
    let (a, b) = ([5u32, 6], [1u32, 2]);
    // Nobody reads these results: no error, the unit drains.
    for t in 0..10 {
        add.issue(Issue::binary(Op::IAdd, &a, &b, t)).unwrap();
        add.commit();
    }
    for _ in 0..3 {
        add.commit();
    }
    assert_eq!(add.in_flight(), 0);
    // Latency 1: an issue in cycle t does not disturb what completed() shows in cycle t.
    add.issue(Issue::binary(Op::ISub, &a, &b, 100)).unwrap();
    assert!(add.completed().is_none());
    add.commit();
    let before = add.completed().map(|c| (c.tag, c.values.to_vec()));
    add.issue(Issue::binary(Op::IAdd, &a, &b, 101)).unwrap();
    let after = add.completed().map(|c| (c.tag, c.values.to_vec()));
    assert_eq!(before, Some((100, vec![4, 4])));
    assert_eq!(before, after);
}
