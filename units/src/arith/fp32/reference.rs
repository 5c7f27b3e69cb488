//! Reference model: Berkeley SoftFloat 3 (RISC-V specialisation) through `softfloat-wrapper`.
//!
//! Only built with the `softfloat` feature (it compiles SoftFloat's C sources). SoftFloat
//! keeps its rounding mode and exception flags in `_Thread_local` globals (softfloat-sys
//! builds with `THREAD_LOCAL=_Thread_local`), so each call here clears the calling thread's
//! flags, runs the function, and reads them back; threads do not interfere.
//!
//! * conversions to integer use `exact = true` (inexact raised, as RISC-V `fcvt` does);
//! * `f32_min`/`f32_max` are built on `f32_lt_quiet`/`f32_eq` the way the RISC-V reference
//!   simulator (Spike) implements `fmin.s`/`fmax.s`;
//! * [`eval_ftz`] defines flush-to-zero in terms of SoftFloat: flush subnormal operands to
//!   signed zero, run the IEEE op, and replace a subnormal result of an arithmetic op by a
//!   signed zero with underflow | inexact added.

use super::testfloat::{Kind, Op};
use super::{Flags, is_nan, is_subnormal};
use softfloat_wrapper::{ExceptionFlags, F32, Float, RoundingMode};

const RNE: RoundingMode = RoundingMode::TiesToEven;

fn with_flags(f: impl FnOnce() -> u32) -> (u32, Flags) {
    ExceptionFlags::from_bits(0).set();
    let r = f();
    let mut fl = ExceptionFlags::default();
    fl.get();
    (r, Flags::from_bits(fl.to_bits()))
}

fn f(x: u32) -> F32 {
    F32::from_bits(x)
}

/// Evaluate `op` with SoftFloat (IEEE mode). `b` is ignored by unary ops.
pub fn eval(op: Op, a: u32, b: u32) -> (u32, Flags) {
    with_flags(|| match op {
        Op::Add => f(a).add(f(b), RNE).to_bits(),
        Op::Sub => f(a).sub(f(b), RNE).to_bits(),
        Op::Mul => f(a).mul(f(b), RNE).to_bits(),
        Op::Div => f(a).div(f(b), RNE).to_bits(),
        Op::Sqrt => f(a).sqrt(RNE).to_bits(),
        Op::Lt => f(a).lt(f(b)) as u32,
        Op::Le => f(a).le(f(b)) as u32,
        Op::Eq => Float::eq(&f(a), f(b)) as u32,
        Op::Min => {
            // Spike fmin.s: less = lt_quiet(a, b) || (eq(a, b) && sign(a)).
            let less = f(a).lt_quiet(f(b)) || (Float::eq(&f(a), f(b)) && a >> 31 != 0);
            if is_nan(a) && is_nan(b) {
                super::CANONICAL_NAN
            } else if less || is_nan(b) {
                a
            } else {
                b
            }
        }
        Op::Max => {
            // Spike fmax.s: greater = lt_quiet(b, a) || (eq(b, a) && sign(b)).
            let greater = f(b).lt_quiet(f(a)) || (Float::eq(&f(b), f(a)) && b >> 31 != 0);
            if is_nan(a) && is_nan(b) {
                super::CANONICAL_NAN
            } else if greater || is_nan(b) {
                a
            } else {
                b
            }
        }
        Op::ToI32 => f(a).to_i32(RNE, true) as u32,
        Op::ToI32Rtz => f(a).to_i32(RoundingMode::TowardZero, true) as u32,
        Op::FromI32 => F32::from_i32(a as i32, RNE).to_bits(),
    })
}

/// Flush-to-zero reference built on SoftFloat (see the module doc).
pub fn eval_ftz(op: Op, a: u32, b: u32) -> (u32, Flags) {
    let flush = |x: u32| {
        if x & super::EXP_MASK == 0 {
            x & super::SIGN
        } else {
            x
        }
    };
    let (a, b) = if op.operand_kind() == Kind::F32 {
        (flush(a), flush(b))
    } else {
        (a, b)
    };
    let (r, fl) = eval(op, a, b);
    let arithmetic = matches!(op, Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Sqrt);
    if arithmetic && is_subnormal(r) {
        (r & super::SIGN, fl | Flags::UNDERFLOW | Flags::INEXACT)
    } else {
        (r, fl)
    }
}
