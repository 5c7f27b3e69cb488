//! Cost of clocking the lane-batched functional units: one element = one unit-cycle (read the
//! completion, issue, commit) of an 8-lane unit, i.e. that unit slot in all 8 clusters.
//! `adder_fadd` (fadd issued every cycle) is the headline figure; the others show the
//! integer path, the multiplier and the divide/sqrt unit (gold8: an issue every 8 cycles;
//! `+F`-style interval 1: every cycle).

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main};
use imagine_hdl::{Design, default_domains};
use imagine_units::arith::fp32::testgen::{SplitMix64, biased_f32};
use imagine_units::desc::MachineDesc;
use imagine_units::fu::{Adder, DivSqrt, FunctionalUnit, Issue, Multiplier};
use imagine_units::ops::{Op, UnitClass};

const LANES: usize = 8;
const CYCLES: usize = 1024;
/// Distinct operand sets cycled through.
const SETS: usize = 16;

fn operand_sets(seed: u64, op: Op) -> Vec<[u32; LANES]> {
    let mut rng = SplitMix64::new(seed);
    (0..SETS)
        .map(|_| {
            std::array::from_fn(|_| {
                if op.name().starts_with('f') {
                    biased_f32(&mut rng) & 0x7FFF_FFFF
                } else {
                    rng.next_u32()
                }
            })
        })
        .collect()
}

/// One cycle as the owner of a unit runs it: read the completion, issue, commit. The
/// pipelined units accept an op every cycle; the divide/sqrt unit's owner must wait out the
/// issue interval (`wait`).
#[inline]
fn cycle<U: FunctionalUnit>(u: &mut U, wait: bool, op: Op, a: &[u32], b: &[u32], tag: u16) -> u32 {
    let out = u
        .completed()
        .map_or(0, |c| c.values[0] ^ c.values[LANES - 1]);
    if !wait || u.can_issue(op) {
        u.issue(Issue::binary(op, a, b, tag)).unwrap();
    }
    u.commit();
    out
}

fn run<U: FunctionalUnit>(g: &mut BenchmarkGroup<'_, WallTime>, name: &str, mut unit: U, op: Op) {
    let a = operand_sets(1, op);
    let b = operand_sets(2, op);
    let wait = unit.class() == UnitClass::DivSqrt;
    g.bench_function(name, |bench| {
        bench.iter(|| {
            let mut acc = 0u32;
            for i in 0..CYCLES {
                let k = i % SETS;
                acc ^= cycle(
                    &mut unit,
                    wait,
                    op,
                    black_box(&a[k]),
                    black_box(&b[k]),
                    i as u16,
                );
            }
            black_box(acc)
        })
    });
}

fn units(c: &mut Criterion) {
    let gold8 = MachineDesc::gold8();
    let mut plus_f = MachineDesc::gold8();
    plus_f.latency.divsqrt_issue_interval = 1;
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut top = design.scope();

    let mut g = c.benchmark_group("fu_8lanes");
    g.throughput(Throughput::Elements(CYCLES as u64));
    let add = |top: &mut imagine_hdl::Scope<'_>, n: &str| Adder::new(top, n, LANES, &gold8);
    let mul = |top: &mut imagine_hdl::Scope<'_>, n: &str| Multiplier::new(top, n, LANES, &gold8);
    run(&mut g, "adder_fadd", add(&mut top, "add0"), Op::FAdd);
    run(&mut g, "adder_iadd", add(&mut top, "add1"), Op::IAdd);
    run(&mut g, "multiplier_fmul", mul(&mut top, "mul0"), Op::FMul);
    run(
        &mut g,
        "multiplier_imul_lo",
        mul(&mut top, "mul1"),
        Op::IMulLo,
    );
    let dsq = DivSqrt::new(&mut top, "dsq0", LANES, &gold8);
    run(&mut g, "divsqrt_fdiv_gold8", dsq, Op::FDiv);
    let dsq = DivSqrt::new(&mut top, "dsq1", LANES, &plus_f);
    run(&mut g, "divsqrt_fdiv_interval1", dsq, Op::FDiv);
    let dsq = DivSqrt::new(&mut top, "dsq2", LANES, &plus_f);
    run(&mut g, "divsqrt_fsqrt_interval1", dsq, Op::FSqrt);
    g.finish();

    // The same work without a unit: `Op::eval_lanes` on 8 lanes per element, the floor the
    // units' bookkeeping adds to.
    let mut g = c.benchmark_group("eval_8lanes");
    g.throughput(Throughput::Elements(CYCLES as u64));
    for op in [Op::FAdd, Op::IAdd, Op::FMul, Op::FDiv, Op::FSqrt] {
        let a = operand_sets(1, op);
        let b = operand_sets(2, op);
        let mode = gold8.fp_mode();
        let mut out = [0u32; LANES];
        let mut flags = [imagine_units::arith::flags::Flags::NONE; LANES];
        g.bench_function(op.name(), |bench| {
            bench.iter(|| {
                let mut acc = 0u32;
                for i in 0..CYCLES {
                    let k = i % SETS;
                    let (a, b) = (black_box(&a[k]), black_box(&b[k]));
                    op.eval_lanes(a, b, a, mode, &mut out, &mut flags);
                    acc ^= out[0] ^ out[LANES - 1];
                }
                black_box(acc)
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1))
        .sample_size(30);
    targets = units
}
criterion_main!(benches);
