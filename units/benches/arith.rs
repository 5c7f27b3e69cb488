//! Throughput of the fp32 combinational datapath (one core, release).
//!
//! `cargo bench -p imagine-units --bench arith`
//!
//! Each benchmark runs an op over a fixed pre-generated array of [`N`] operand pairs: 15/16
//! normal values with exponents spread over `[2^-27, 2^28)` (the common case), 1/16 drawn
//! from the special/boundary list (zeros, subnormals, infinities, NaNs, extremes). Results
//! are folded into an XOR so iterations are independent (throughput, not latency), and the
//! mode is opaque to the optimiser, as it is a machine parameter at run time.
//!
//! The `eval_lanes_8` group measures the machine simulator's inner loop: one
//! [`Op::eval_lanes`] call on 8 lanes (one unit slot across the 8 clusters) of mixed normal
//! operands, and (`fadd/host`, ...) the same call through [`Op::eval_lanes_host`], the host
//! floating-point fast path. Its throughput is in calls, so `1 / thrpt` is the time of one
//! 8-lane call.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use imagine_units::arith::fp32::testgen::{SPECIALS, SplitMix64};
use imagine_units::arith::fp32::{self as fp, Flags, FpMode};
use imagine_units::ops::Op;
use std::hint::black_box;
use std::time::Duration;

const N: usize = 4096;
/// Lanes of one `eval_lanes` call (the 8 clusters).
const LANES: usize = 8;
/// Distinct 8-lane operand sets per `eval_lanes_8` iteration (`N` operand pairs in all).
const SETS: usize = N / LANES;

/// A normal number with a random sign and fraction and an exponent in `[2^-27, 2^28)`.
fn normal(rng: &mut SplitMix64) -> u32 {
    let sign = rng.next_u32() & 0x8000_0000;
    let exp = 100 + rng.below(55);
    sign | (exp << 23) | (rng.next_u32() & 0x007F_FFFF)
}

fn operand(rng: &mut SplitMix64) -> u32 {
    if rng.below(16) == 0 {
        SPECIALS[rng.below(SPECIALS.len() as u32) as usize]
    } else {
        normal(rng)
    }
}

fn operands() -> Vec<(u32, u32)> {
    let mut rng = SplitMix64::new(0x1234_5678);
    (0..N)
        .map(|_| (operand(&mut rng), operand(&mut rng)))
        .collect()
}

fn ints() -> Vec<(u32, u32)> {
    let mut rng = SplitMix64::new(0x9ABC_DEF0);
    (0..N)
        .map(|_| {
            let x = rng.next_u32() >> rng.below(32);
            (
                if rng.below(2) == 0 {
                    x
                } else {
                    x.wrapping_neg()
                },
                0,
            )
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let floats = operands();
    let ints = ints();
    let mut g = c.benchmark_group("fp32");
    g.throughput(Throughput::Elements(N as u64));
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(2));

    macro_rules! op {
        ($name:literal, $data:expr, |$a:ident, $b:ident, $m:ident| $body:expr) => {
            g.bench_function($name, |bch| {
                let data = black_box(&$data[..]);
                bch.iter(|| {
                    let $m = black_box(FpMode::IEEE);
                    let mut acc = 0u32;
                    for &($a, $b) in data {
                        let (r, f): (u32, Flags) = $body;
                        acc ^= r ^ f.bits() as u32;
                    }
                    acc
                })
            });
        };
    }
    let cmp = |(r, f): (bool, Flags)| (r as u32, f);
    op!("add", floats, |a, b, m| fp::add(a, b, m));
    op!("sub", floats, |a, b, m| fp::sub(a, b, m));
    op!("mul", floats, |a, b, m| fp::mul(a, b, m));
    op!("div", floats, |a, b, m| fp::div(a, b, m));
    op!("sqrt", floats, |a, _b, m| fp::sqrt(a, m));
    op!("lt", floats, |a, b, m| cmp(fp::lt(a, b, m)));
    op!("le", floats, |a, b, m| cmp(fp::le(a, b, m)));
    op!("eq", floats, |a, b, m| cmp(fp::eq(a, b, m)));
    op!("min", floats, |a, b, m| fp::min(a, b, m));
    op!("max", floats, |a, b, m| fp::max(a, b, m));
    op!("to_i32", floats, |a, _b, m| fp::to_i32(a, m));
    op!("to_i32_rtz", floats, |a, _b, m| fp::to_i32_rtz(a, m));
    op!("from_i32", ints, |a, _b, _m| fp::from_i32(a));
    g.finish();

    // `Op::eval_lanes` on 8 lanes of mixed normal operands: one element = one call.
    let mut rng = SplitMix64::new(0x0F0F_1234);
    let mut lanes = || -> Vec<[u32; LANES]> {
        (0..SETS)
            .map(|_| std::array::from_fn(|_| normal(&mut rng)))
            .collect()
    };
    let (a, b) = (lanes(), lanes());
    let mut g = c.benchmark_group("eval_lanes_8");
    g.throughput(Throughput::Elements(SETS as u64));
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(2));
    for (op, host) in [Op::FAdd, Op::FSub, Op::FMul]
        .map(|op| [(op, false), (op, true)])
        .concat()
    {
        let mut out = [0u32; LANES];
        let mut flags = [Flags::NONE; LANES];
        let name = format!("{op}{}", if host { "/host" } else { "" });
        g.bench_function(name, |bch| {
            let (a, b) = (black_box(&a[..]), black_box(&b[..]));
            bch.iter(|| {
                // The op and mode are run-time values, as in the machine.
                let (op, mode) = black_box((op, FpMode::IEEE));
                for (a, b) in a.iter().zip(b) {
                    // Opaque outputs: every lane must be computed and stored.
                    let (out, flags) = (black_box(&mut out), black_box(&mut flags));
                    if host {
                        op.eval_lanes_host(a, b, a, mode, out, flags);
                    } else {
                        op.eval_lanes(a, b, a, mode, out, flags);
                    }
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
