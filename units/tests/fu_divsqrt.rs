//! The divide/sqrt unit: results bit-identical to `fp32::div` / `fp32::sqrt` (values and
//! flags, IEEE and flush-to-zero), latencies and issue interval from the machine description,
//! and the busy / writeback-conflict contract.

use imagine_hdl::{Design, Violation, default_domains};
use imagine_units::arith::fp32::testgen::{SplitMix64, biased_f32, biased_pair};
use imagine_units::arith::fp32::{self, FpMode};
use imagine_units::desc::MachineDesc;
use imagine_units::fu::{DivSqrt, Issue};
use imagine_units::ops::{Op, UnitClass};

fn dsq(lanes: usize, desc: &MachineDesc) -> DivSqrt {
    let mut d = Design::new("top", default_domains()).unwrap();
    DivSqrt::new(&mut d.scope(), "dsq0", lanes, desc)
}

fn desc_with(div: u32, sqrt: u32, interval: u32, ftz: bool) -> MachineDesc {
    let mut d = MachineDesc::gold8();
    d.latency.div = div;
    d.latency.sqrt = sqrt;
    d.latency.divsqrt_issue_interval = interval;
    d.arithmetic.flush_to_zero = ftz;
    d.validate().unwrap();
    d
}

struct Expected {
    tag: u16,
    due: u64,
    values: Vec<u32>,
    flags: Vec<imagine_units::arith::flags::Flags>,
}

/// Issues `count` random fdiv/fsqrt ops as fast as the unit accepts them and checks every
/// result against `fp32::div` / `fp32::sqrt` and its completion cycle. Returns the cycles.
fn stream(unit: &mut DivSqrt, desc: &MachineDesc, count: usize, seed: u64) -> u64 {
    let lanes = unit.lanes();
    let mode = desc.fp_mode();
    let mut rng = SplitMix64::new(seed);
    let mut pending: Vec<Expected> = vec![];
    let mut issued = 0;
    let mut next = Op::FDiv;
    while issued < count || !pending.is_empty() {
        let now = unit.cycle();
        if let Some(c) = unit.completed() {
            let pos = pending.iter().position(|e| e.tag == c.tag).unwrap();
            let e = pending.swap_remove(pos);
            assert_eq!(e.due, now, "{} tag {}", c.op, c.tag);
            assert_eq!(c.values, &e.values[..], "{} tag {} values", c.op, c.tag);
            assert_eq!(c.flags, &e.flags[..], "{} tag {} flags", c.op, c.tag);
        } else {
            assert!(pending.iter().all(|e| e.due != now));
        }
        if issued < count && unit.can_issue(next) {
            let (a, b): (Vec<u32>, Vec<u32>) = (0..lanes)
                .map(|_| {
                    if next == Op::FSqrt {
                        let x = biased_f32(&mut rng);
                        // Mostly non-negative radicands so the recurrence runs.
                        (
                            if rng.below(4) == 0 {
                                x
                            } else {
                                x & 0x7FFF_FFFF
                            },
                            0,
                        )
                    } else {
                        biased_pair(&mut rng)
                    }
                })
                .unzip();
            let (values, flags) = a
                .iter()
                .zip(&b)
                .map(|(&x, &y)| match next {
                    Op::FDiv => fp32::div(x, y, mode),
                    _ => fp32::sqrt(x, mode),
                })
                .unzip();
            let is = if next == Op::FDiv {
                Issue::binary(next, &a, &b, issued as u16)
            } else {
                Issue::unary(next, &a, issued as u16)
            };
            unit.issue(is).unwrap();
            pending.push(Expected {
                tag: issued as u16,
                due: now + u64::from(next.latency(&desc.latency)),
                values,
                flags,
            });
            issued += 1;
            next = if rng.below(2) == 0 {
                Op::FDiv
            } else {
                Op::FSqrt
            };
        }
        unit.commit();
    }
    unit.cycle()
}

#[test]
fn results_equal_fp32_div_and_sqrt_bit_for_bit() {
    for ftz in [false, true] {
        for (div, sqrt, interval) in [(16, 16, 8), (16, 12, 4), (9, 11, 3), (5, 5, 5), (4, 7, 1)] {
            let desc = desc_with(div, sqrt, interval, ftz);
            for lanes in [1, 8] {
                let mut u = dsq(lanes, &desc);
                stream(&mut u, &desc, 400, 0xD1 + lanes as u64 + u64::from(div));
            }
        }
    }
}

#[test]
fn ftz_mode_flushes_like_fp32() {
    let desc = desc_with(16, 16, 8, true);
    assert_eq!(desc.fp_mode(), FpMode::FTZ);
    let mut u = dsq(4, &desc);
    // Subnormal operand, subnormal quotient, tiny root input.
    let a = [0x0000_0001, 0x0080_0000, 0x3F80_0000, 0x0040_0000];
    let b = [0x3F80_0000, 0x4000_0000, 0x0000_0003, 0x3F80_0000];
    u.issue(Issue::binary(Op::FDiv, &a, &b, 1)).unwrap();
    for _ in 0..8 {
        u.commit();
    }
    u.issue(Issue::unary(Op::FSqrt, &a, 2)).unwrap();
    let mut got = vec![];
    for _ in 0..30 {
        if let Some(c) = u.completed() {
            got.push((c.tag, c.values.to_vec(), c.flags.to_vec()));
        }
        u.commit();
    }
    let div: (Vec<_>, Vec<_>) = (0..4).map(|i| fp32::div(a[i], b[i], FpMode::FTZ)).unzip();
    let sqrt: (Vec<_>, Vec<_>) = (0..4).map(|i| fp32::sqrt(a[i], FpMode::FTZ)).unzip();
    assert_eq!(got, vec![(1, div.0, div.1), (2, sqrt.0, sqrt.1)]);
    // And they differ from IEEE mode somewhere, so the mode really reached the unit.
    assert_ne!(
        fp32::div(a[1], b[1], FpMode::IEEE),
        fp32::div(a[1], b[1], FpMode::FTZ)
    );
}

#[test]
fn gold8_two_in_flight_and_a_third_issue_is_busy() {
    let desc = MachineDesc::gold8(); // div 16, sqrt 16, interval 8
    let mut u = dsq(8, &desc);
    assert_eq!(u.issue_interval(), 8);
    assert_eq!(u.steps_per_cycle(), 2);
    let x = [0x4040_0000u32; 8];
    let y = [0x4000_0000u32; 8];
    u.issue(Issue::binary(Op::FDiv, &x, &y, 1)).unwrap(); // cycle 0
    for t in 1..8 {
        u.commit();
        assert!(u.busy(), "cycle {t}");
        let e = u.issue(Issue::unary(Op::FSqrt, &x, 9)).unwrap_err();
        assert_eq!(e.module, "top.cluster*.dsq0");
        let Violation::Busy { detail } = &e.violation else {
            panic!("{e}")
        };
        assert!(detail.contains("recurrence core is busy"), "{detail}");
        assert!(detail.contains("next issue may be in cycle 8"), "{detail}");
    }
    u.commit(); // cycle 8
    assert!(!u.busy());
    u.issue(Issue::unary(Op::FSqrt, &x, 2)).unwrap(); // second in flight
    assert_eq!(u.in_flight(), 2);
    u.commit(); // cycle 9: a third op within the interval
    let e = u.issue(Issue::binary(Op::FDiv, &x, &y, 3)).unwrap_err();
    assert!(matches!(e.violation, Violation::Busy { .. }), "{e}");
    assert!(e.to_string().contains("top.cluster*.dsq0"), "{e}");
    assert!(e.to_string().contains("`fsqrt`"), "{e}");
    let mut done = vec![];
    for _ in 9..40 {
        if let Some(c) = u.completed() {
            done.push((u.cycle(), c.tag, c.values[0]));
        }
        u.commit();
    }
    let q = fp32::div(0x4040_0000, 0x4000_0000, FpMode::IEEE).0;
    let r = fp32::sqrt(0x4040_0000, FpMode::IEEE).0;
    assert_eq!(done, vec![(16, 1, q), (24, 2, r)]);
}

#[test]
fn interval_one_accepts_every_cycle() {
    let desc = desc_with(16, 16, 1, false);
    let mut u = dsq(8, &desc);
    assert_eq!(u.steps_per_cycle(), 12);
    let cycles = stream(&mut u, &desc, 300, 5);
    assert_eq!(cycles, 300 + 16, "no bubbles");
}

#[test]
fn busy_interval_and_latencies_follow_the_description() {
    for (div, sqrt, interval) in [(16, 16, 8), (9, 11, 3), (12, 12, 12), (20, 6, 6)] {
        let desc = desc_with(div, sqrt, interval, false);
        let mut u = dsq(2, &desc);
        assert_eq!(u.steps_per_cycle(), 12u32.div_ceil(interval));
        for op in [Op::FDiv, Op::FSqrt] {
            let start = u.cycle();
            let x = [0x4110_0000u32, 0x3F80_0000];
            u.issue(Issue::binary(op, &x, &x, 7)).unwrap();
            let mut accepted_at = None;
            let mut done_at = None;
            for _ in 0..40 {
                u.commit();
                if accepted_at.is_none() && u.can_issue(op) {
                    accepted_at = Some(u.cycle() - start);
                }
                if u.completed().is_some() {
                    assert!(done_at.is_none());
                    done_at = Some(u.cycle() - start);
                }
            }
            let lat = if op == Op::FDiv { div } else { sqrt };
            assert_eq!(done_at, Some(u64::from(lat)), "{op} {desc:?}");
            assert_eq!(accepted_at, Some(u64::from(interval)), "{op}");
        }
    }
}

#[test]
fn writeback_conflict_between_div_and_sqrt() {
    let desc = desc_with(16, 12, 4, false);
    let mut u = dsq(1, &desc);
    let x = [0x4000_0000u32];
    u.issue(Issue::binary(Op::FDiv, &x, &x, 1)).unwrap(); // done in 16
    for _ in 0..4 {
        u.commit();
    }
    assert!(!u.busy());
    assert!(!u.can_issue(Op::FSqrt));
    let e = u.issue(Issue::unary(Op::FSqrt, &x, 2)).unwrap_err(); // would be done in 16
    let Violation::Busy { detail } = &e.violation else {
        panic!("{e}")
    };
    assert!(detail.contains("writeback conflict"), "{detail}");
    assert!(detail.contains("cycle 16"), "{detail}");
    u.issue(Issue::binary(Op::FDiv, &x, &x, 3)).unwrap(); // done in 20
}

#[test]
fn wrong_ops_and_lanes_are_rejected() {
    let desc = MachineDesc::gold8();
    let mut u = dsq(8, &desc);
    assert_eq!(u.class(), UnitClass::DivSqrt);
    let x = [0u32; 8];
    for op in [Op::FAdd, Op::FMul, Op::IAdd] {
        let e = u.issue(Issue::binary(op, &x, &x, 0)).unwrap_err();
        assert_eq!(e.module, "top.cluster*.dsq0");
        assert!(matches!(e.violation, Violation::Other(_)), "{e}");
    }
    let e = u.issue(Issue::unary(Op::FDiv, &x, 0)).unwrap_err();
    assert!(e.to_string().contains("one per lane"), "{e}");
    let e = u.issue(Issue::unary(Op::FSqrt, &x[..3], 0)).unwrap_err();
    assert!(e.to_string().contains("one per lane"), "{e}");
    assert!(!u.busy(), "rejected issues leave no trace");
    u.issue(Issue::unary(Op::FSqrt, &x, 0)).unwrap();
    let e = u.issue(Issue::unary(Op::FSqrt, &x, 0)).unwrap_err();
    assert!(
        matches!(e.violation, Violation::OverBandwidth { .. }),
        "{e}"
    );
}
