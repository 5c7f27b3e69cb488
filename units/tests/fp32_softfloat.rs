//! Live cross-check of the fp32 datapath against Berkeley SoftFloat 3 (RISC-V
//! specialisation), feature `softfloat` (needs a C compiler; run in release):
//!
//! ```text
//! cargo test -p imagine-units --release --features softfloat --test fp32_softfloat
//! cargo test -p imagine-units --release --features softfloat --test fp32_softfloat \
//!     -- --ignored exhaustive_sqrt --nocapture      # all 2^32 inputs of f32_sqrt
//! ```
//!
//! Per op: [`BIASED`] operands from `testgen` (hard cases) plus [`UNIFORM`] uniformly random
//! bit patterns in IEEE mode, and [`FTZ`] biased cases in flush-to-zero mode against the
//! SoftFloat-based FTZ reference (`reference::eval_ftz`). Result bits and all five flags must
//! match exactly.
#![cfg(feature = "softfloat")]

use imagine_units::arith::fp32::testfloat::{Case, Op, format_case};
use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::arith::fp32::{FpMode, reference};
use std::time::Instant;

const BIASED: usize = 2_000_000;
const UNIFORM: usize = 2_000_000;
const FTZ: usize = 1_000_000;

fn check(op: Op, seed: u64) {
    let start = Instant::now();
    let mut rng = SplitMix64::new(seed);
    let mut failures = Vec::new();
    let mut failed = 0usize;
    let mut run = |a: u32, b: u32, mode: FpMode| {
        let want = if mode.flush_to_zero {
            reference::eval_ftz(op, a, b)
        } else {
            reference::eval(op, a, b)
        };
        let got = op.eval(a, b, mode);
        if got != want {
            failed += 1;
            if failures.len() < 10 {
                let c = Case {
                    a,
                    b,
                    result: want.0,
                    flags: want.1,
                };
                failures.push(format!(
                    "{}{}  got {:08X} {}",
                    if mode.flush_to_zero { "[ftz] " } else { "" },
                    format_case(op, &c),
                    got.0,
                    got.1
                ));
            }
        }
    };
    for _ in 0..BIASED {
        let (a, b) = op.biased_operands(&mut rng);
        run(a, b, FpMode::IEEE);
    }
    for _ in 0..UNIFORM {
        let (a, b) = op.uniform_operands(&mut rng);
        run(a, b, FpMode::IEEE);
    }
    for _ in 0..FTZ {
        let (a, b) = op.biased_operands(&mut rng);
        run(a, b, FpMode::FTZ);
    }
    let total = BIASED + UNIFORM + FTZ;
    eprintln!(
        "{op}: {} passed, {failed} failed ({:.2?})",
        total - failed,
        start.elapsed()
    );
    assert!(
        failed == 0,
        "{op}: {failed} of {total} cases differ from SoftFloat \
         (expected result and flags shown, then ours):\n{}",
        failures.join("\n")
    );
}

macro_rules! cross_check {
    ($($name:ident => $op:expr, $seed:expr;)*) => {
        $(
            #[test]
            fn $name() {
                check($op, $seed);
            }
        )*
    };
}

cross_check! {
    f32_add => Op::Add, 1;
    f32_sub => Op::Sub, 2;
    f32_mul => Op::Mul, 3;
    f32_div => Op::Div, 4;
    f32_sqrt => Op::Sqrt, 5;
    f32_lt => Op::Lt, 6;
    f32_le => Op::Le, 7;
    f32_eq => Op::Eq, 8;
    f32_min => Op::Min, 9;
    f32_max => Op::Max, 10;
    f32_to_i32 => Op::ToI32, 11;
    f32_to_i32_r_min_mag => Op::ToI32Rtz, 12;
    i32_to_f32 => Op::FromI32, 13;
}

/// Every op in the catalogue has a cross-check above.
#[test]
fn every_op_is_cross_checked() {
    assert_eq!(Op::ALL.len(), 13);
}

/// All 2^32 inputs of `f32_sqrt` (IEEE mode), split over the available cores.
#[test]
#[ignore = "exhaustive: 2^32 cases, minutes in release"]
fn exhaustive_sqrt() {
    let start = Instant::now();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let chunk = (1u64 << 32) / threads;
    let handles: Vec<_> = (0..threads)
        .map(|t| {
            std::thread::spawn(move || {
                let lo = t * chunk;
                let hi = if t + 1 == threads {
                    1u64 << 32
                } else {
                    lo + chunk
                };
                let mut failed = 0u64;
                let mut first = Vec::new();
                for x in lo..hi {
                    let a = x as u32;
                    let want = reference::eval(Op::Sqrt, a, 0);
                    let got = Op::Sqrt.eval(a, 0, FpMode::IEEE);
                    if got != want {
                        failed += 1;
                        if first.len() < 10 {
                            first.push(format!(
                                "{a:08X}: want {:08X} {} got {:08X} {}",
                                want.0, want.1, got.0, got.1
                            ));
                        }
                    }
                }
                (failed, first)
            })
        })
        .collect();
    let mut failed = 0;
    let mut first = Vec::new();
    for h in handles {
        let (f, v) = h.join().expect("worker panicked");
        failed += f;
        first.extend(v);
    }
    eprintln!(
        "f32_sqrt exhaustive: {} passed, {failed} failed in {:.1?} on {threads} threads",
        (1u64 << 32) - failed,
        start.elapsed()
    );
    assert_eq!(failed, 0, "first mismatches:\n{}", first.join("\n"));
}
