//! Throughput of the integer and packed-subword datapath functions over fixed operand arrays
//! (elements = one op applied to one operand pair). Groups `int` and `packed` map each op over
//! the arrays (independent elements; the compiler may vectorise), group `chained` feeds each
//! result into the next op (serial per-op latency).

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main};
use imagine_units::arith::{int, packed};

const N: usize = 4096;

/// Deterministic operands: an xorshift sequence salted with boundary values.
fn operands() -> (Vec<u32>, Vec<u32>) {
    const EDGES: [u32; 8] = [
        0,
        1,
        0xFFFF_FFFF,
        0x7FFF_FFFF,
        0x8000_0000,
        0x7FFF_8000,
        0x8080_7F7F,
        0xFF00_00FF,
    ];
    let mut x = 0x9E37_79B9u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    let a = (0..N)
        .map(|i| {
            if i % 16 == 0 {
                EDGES[(i / 16) % 8]
            } else {
                next()
            }
        })
        .collect();
    let b = (0..N)
        .map(|i| {
            if i % 16 == 3 {
                EDGES[(i / 16 + 3) % 8]
            } else {
                next()
            }
        })
        .collect();
    (a, b)
}

/// Benchmark one op over the operand arrays. Generic over the op so it is inlined into the
/// loop, as it is in the interpreter and the clocked units.
fn run(
    g: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    (a, b): &(Vec<u32>, Vec<u32>),
    op: impl Fn(u32, u32) -> u32,
) {
    let mut out = vec![0u32; N];
    g.bench_function(name, |bench| {
        bench.iter(|| {
            let (a, b) = (black_box(a), black_box(b));
            for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
                *o = op(x, y);
            }
            black_box(&mut out);
        })
    });
}

/// Benchmark one op as a dependent chain (`acc = op(acc, b[i]) ^ b[i]`; the XOR stops the
/// compiler from reassociating a chain of adds or multiplies into a vector reduction): no
/// vectorisation and no overlap between elements, so this is an upper bound on the per-op
/// latency the clocked model sees when it evaluates one op at a time.
fn run_chained(
    g: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    (_, b): &(Vec<u32>, Vec<u32>),
    op: impl Fn(u32, u32) -> u32,
) {
    g.bench_function(name, |bench| {
        bench.iter(|| {
            let mut acc = black_box(0x1234_5678u32);
            for &y in black_box(b) {
                acc = op(acc, y) ^ y;
            }
            black_box(acc)
        })
    });
}

fn int_ops(c: &mut Criterion) {
    let v = operands();
    let mut g = c.benchmark_group("int");
    g.throughput(Throughput::Elements(N as u64));
    run(&mut g, "add", &v, int::add);
    run(&mut g, "sub", &v, int::sub);
    run(&mut g, "xor", &v, int::xor);
    run(&mut g, "shift_left", &v, int::shift_left);
    run(&mut g, "shift_right_arith", &v, int::shift_right_arith);
    run(&mut g, "lt_s", &v, |a, b| int::lt_s(a, b) as u32);
    run(&mut g, "lt_u", &v, |a, b| int::lt_u(a, b) as u32);
    run(&mut g, "select", &v, |a, b| int::select(a & 1 != 0, a, b));
    run(&mut g, "min_s", &v, int::min_s);
    run(&mut g, "max_u", &v, int::max_u);
    run(&mut g, "abs_s", &v, |a, _| int::abs_s(a));
    run(&mut g, "mul_lo", &v, int::mul_lo);
    run(&mut g, "mul_hi_s", &v, int::mul_hi_s);
    run(&mut g, "mul_hi_u", &v, int::mul_hi_u);
    run(&mut g, "mul_hi_su", &v, int::mul_hi_su);
    g.finish();
}

fn packed_ops(c: &mut Criterion) {
    let v = operands();
    let mut g = c.benchmark_group("packed");
    g.throughput(Throughput::Elements(N as u64));
    run(&mut g, "add_16x2", &v, packed::add_16x2);
    run(&mut g, "sub_8x4", &v, packed::sub_8x4);
    run(&mut g, "add_sat_s_16x2", &v, packed::add_sat_s_16x2);
    run(&mut g, "add_sat_u_8x4", &v, packed::add_sat_u_8x4);
    run(&mut g, "sub_sat_s_8x4", &v, packed::sub_sat_s_8x4);
    run(&mut g, "sub_sat_u_16x2", &v, packed::sub_sat_u_16x2);
    run(&mut g, "eq_8x4", &v, packed::eq_8x4);
    run(&mut g, "lt_s_16x2", &v, packed::lt_s_16x2);
    run(&mut g, "le_u_8x4", &v, packed::le_u_8x4);
    run(&mut g, "min_s_8x4", &v, packed::min_s_8x4);
    run(&mut g, "max_u_16x2", &v, packed::max_u_16x2);
    run(&mut g, "mul_lo_16x2", &v, packed::mul_lo_16x2);
    run(&mut g, "mul_hi_s_16x2", &v, packed::mul_hi_s_16x2);
    run(&mut g, "mul_hi_u_16x2", &v, packed::mul_hi_u_16x2);
    g.finish();
}

fn chained_ops(c: &mut Criterion) {
    let v = operands();
    let mut g = c.benchmark_group("chained");
    g.throughput(Throughput::Elements(N as u64));
    run_chained(&mut g, "int_add", &v, int::add);
    run_chained(&mut g, "int_shift_right_arith", &v, int::shift_right_arith);
    run_chained(&mut g, "int_lt_s_select", &v, |a, b| {
        int::select(int::lt_s(a, b), a, b)
    });
    run_chained(&mut g, "int_min_s", &v, int::min_s);
    run_chained(&mut g, "int_mul_lo", &v, int::mul_lo);
    run_chained(&mut g, "int_mul_hi_s", &v, int::mul_hi_s);
    run_chained(&mut g, "packed_add_16x2", &v, packed::add_16x2);
    run_chained(&mut g, "packed_add_sat_s_16x2", &v, packed::add_sat_s_16x2);
    run_chained(&mut g, "packed_sub_sat_u_8x4", &v, packed::sub_sat_u_8x4);
    run_chained(&mut g, "packed_lt_s_8x4", &v, packed::lt_s_8x4);
    run_chained(&mut g, "packed_min_s_8x4", &v, packed::min_s_8x4);
    run_chained(&mut g, "packed_mul_lo_16x2", &v, packed::mul_lo_16x2);
    run_chained(&mut g, "packed_mul_hi_s_16x2", &v, packed::mul_hi_s_16x2);
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1))
        .sample_size(30);
    targets = int_ops, packed_ops, chained_ops
}
criterion_main!(benches);
