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
//!
//! The bit-level datapath is checked one operation at a time (`testfloat::Op::eval`). The ops
//! with a host fast path ([`HOST_OPS`]) are checked again, on the same cases, through
//! `Op::eval_lanes_host` in vectors of [`LANE_COUNTS`] lanes in turn (whole groups of the host
//! path's vectors and leftover lanes).
#![cfg(feature = "softfloat")]

use imagine_units::arith::fp32::testfloat::{Case, Op, format_case};
use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::arith::fp32::{Flags, FpMode, reference};
use imagine_units::ops::Op as MachineOp;
use std::time::Instant;

const BIASED: usize = 2_000_000;
const UNIFORM: usize = 2_000_000;
const FTZ: usize = 1_000_000;

/// The ops with a host fast path, and the machine ops that carry them.
const HOST_OPS: [(Op, MachineOp); 5] = [
    (Op::Add, MachineOp::FAdd),
    (Op::Sub, MachineOp::FSub),
    (Op::Mul, MachineOp::FMul),
    (Op::Div, MachineOp::FDiv),
    (Op::Sqrt, MachineOp::FSqrt),
];

/// The lane counts of the host path's vectors, in turn.
const LANE_COUNTS: [usize; 6] = [1, 3, 8, 16, 32, 37];

/// How operands are drawn for an op.
type Draw = fn(Op, &mut SplitMix64) -> (u32, u32);

/// The parts of one op's cross-check: how many cases, drawn how, in which mode.
const PARTS: [(usize, Draw, FpMode); 3] = [
    (BIASED, Op::biased_operands, FpMode::IEEE),
    (UNIFORM, Op::uniform_operands, FpMode::IEEE),
    (FTZ, Op::biased_operands, FpMode::FTZ),
];

/// SoftFloat's result and flags for `op` on `(a, b)` under `mode`.
fn softfloat(op: Op, a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    if mode.flush_to_zero {
        reference::eval_ftz(op, a, b)
    } else {
        reference::eval(op, a, b)
    }
}

/// The cases of one cross-check that differ from SoftFloat: a count and the first few.
#[derive(Default)]
struct Mismatches {
    failed: usize,
    shown: Vec<String>,
}

impl Mismatches {
    /// Compare our `got` for `op` on `(a, b)` under `mode` with SoftFloat's.
    fn check(&mut self, op: Op, (a, b): (u32, u32), mode: FpMode, got: (u32, Flags)) {
        let want = softfloat(op, a, b, mode);
        if got == want {
            return;
        }
        self.failed += 1;
        if self.shown.len() < 10 {
            let case = Case {
                a,
                b,
                result: want.0,
                flags: want.1,
            };
            self.shown.push(format!(
                "{}{}  got {:08X} {}",
                if mode.flush_to_zero { "[ftz] " } else { "" },
                format_case(op, &case),
                got.0,
                got.1
            ));
        }
    }

    /// Report the tally of `what` (e.g. `f32_add`) and fail on any mismatch.
    fn finish(self, what: &str, start: Instant) {
        let total: usize = PARTS.iter().map(|&(n, _, _)| n).sum();
        let failed = self.failed;
        eprintln!(
            "{what}: {} passed, {failed} failed ({:.2?})",
            total - failed,
            start.elapsed()
        );
        assert!(
            failed == 0,
            "{what}: {failed} of {total} cases differ from SoftFloat \
             (expected result and flags shown, then ours):\n{}",
            self.shown.join("\n")
        );
    }
}

/// The bit-level datapath, one operation at a time.
fn check(op: Op, seed: u64) {
    let start = Instant::now();
    let mut rng = SplitMix64::new(seed);
    let mut mismatches = Mismatches::default();
    for (cases, draw, mode) in PARTS {
        for _ in 0..cases {
            let (a, b) = draw(op, &mut rng);
            mismatches.check(op, (a, b), mode, op.eval(a, b, mode));
        }
    }
    mismatches.finish(op.name(), start);
}

/// The host fast path (`eval_lanes_host`) of `machine_op`, which carries `op`, on the cases
/// [`check`] draws from the same seed, in vectors of [`LANE_COUNTS`] lanes in turn.
fn check_host(op: Op, machine_op: MachineOp, seed: u64) {
    let start = Instant::now();
    let mut rng = SplitMix64::new(seed);
    let mut mismatches = Mismatches::default();
    let mut lane_counts = LANE_COUNTS.into_iter().cycle();
    let (mut out, mut flags) = ([0; 37], [Flags::NONE; 37]);
    for (cases, draw, mode) in PARTS {
        let mut left = cases;
        while left > 0 {
            let n = lane_counts.next().expect("a cycle").min(left);
            let (a, b): (Vec<u32>, Vec<u32>) = (0..n).map(|_| draw(op, &mut rng)).unzip();
            machine_op.eval_lanes_host(&a, &b, &a, mode, &mut out[..n], &mut flags[..n]);
            for i in 0..n {
                mismatches.check(op, (a[i], b[i]), mode, (out[i], flags[i]));
            }
            left -= n;
        }
    }
    mismatches.finish(&format!("{} (host, lanes)", op.name()), start);
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

/// The host fast path of each op that has one, on the cases of its bit-level cross-check.
macro_rules! cross_check_host {
    ($($name:ident => $index:expr, $seed:expr;)*) => {
        $(
            #[test]
            fn $name() {
                let (op, machine_op) = HOST_OPS[$index];
                check_host(op, machine_op, $seed);
            }
        )*
    };
}

cross_check_host! {
    host_f32_add => 0, 1;
    host_f32_sub => 1, 2;
    host_f32_mul => 2, 3;
    host_f32_div => 3, 4;
    host_f32_sqrt => 4, 5;
}

/// Every op with a host fast path has a cross-check above, on the right op.
#[test]
fn every_host_op_is_cross_checked() {
    assert_eq!(HOST_OPS.len(), 5);
    for (op, machine_op) in HOST_OPS {
        assert_eq!(
            machine_op.eval(0x3F80_0000, 0x4000_0000, 0, FpMode::IEEE),
            op.eval(0x3F80_0000, 0x4000_0000, FpMode::IEEE)
        );
    }
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
