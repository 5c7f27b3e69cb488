//! Floating-point divider: radix-4 digit recurrence (IEEE 754-2008 §5.4.1 division).
//!
//! Structure (Ercegovac & Lang ch. 5, "Division by digit recurrence"):
//!
//! * **setup** ([`div_setup`]): sign XOR, special operands (NaN, inf, zero), leading-zero
//!   normalisation of subnormal significands, exponent subtract `ea − eb + bias`, and a
//!   1-bit pre-shift of the dividend when `ma < mb`, so that the quotient lies in `[1, 2)`
//!   and its integer digit is always 1.
//! * **recurrence** ([`DivRecurrence`]): a *radix-4 restoring* recurrence with digit set
//!   `{0, 1, 2, 3}`. Each [`step`](DivRecurrence::step) forms `4·w[j]` and, in parallel, the
//!   three trial remainders `4·w[j] − q·d` for `q = 1, 2, 3` (the multiples `d`, `2d`, `3d`
//!   are a wire shift and one pre-computed adder); the digit is the largest `q` whose trial
//!   remainder is non-negative (three sign bits, a priority mux), and that trial becomes
//!   `w[j+1]`. Invariant: `0 ≤ w[j] < d`. Each step retires 2 quotient bits;
//!   [`DIV_STEPS`] = 12 steps after the integer digit give the 24 fraction bits plus one
//!   round bit.
//! * **round** ([`div_finish`]): the 25 quotient bits with a sticky bit `w ≠ 0` (the
//!   remainder is the exact "is there more" information) go through the shared
//!   [`round_pack`].
//!
//! The stepped form lets a pipelined `DivSqrt` unit hold a [`DivJob`] in its stage registers
//! and advance it `k` steps per cycle.

use super::round::round_pack;
use super::{EXP_MASK, FpMode, SIGN, Setup, flush_input, is_nan};
use crate::arith::flags::Flags;

/// Number of radix-4 recurrence steps after the integer quotient digit.
pub const DIV_STEPS: u32 = 12;

/// State of the radix-4 division recurrence: the stage register of the iterative core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DivRecurrence {
    /// Partial remainder `w[j]`, `0 ≤ w < divisor`.
    pub rem: u32,
    /// Divisor significand `d`, leading one at bit 23.
    pub divisor: u32,
    /// Quotient digits developed so far (the integer digit 1 followed by 2 bits per step).
    pub quotient: u32,
    /// Number of steps performed.
    pub steps: u32,
}

impl DivRecurrence {
    /// Start dividing `dividend` by `divisor` (both integers with `divisor ≤ dividend <
    /// 2·divisor`, divisor < 2^24): retires the integer quotient digit 1.
    #[inline]
    pub fn new(dividend: u32, divisor: u32) -> DivRecurrence {
        debug_assert!(divisor <= dividend && dividend < 2 * divisor && divisor < 1 << 24);
        DivRecurrence {
            rem: dividend - divisor,
            divisor,
            quotient: 1,
            steps: 0,
        }
    }

    /// One radix-4 step: two more quotient bits.
    #[inline(always)]
    pub fn step(&mut self) {
        let d = self.divisor;
        let w4 = self.rem << 2; // < 4d < 2^26
        let t1 = w4.wrapping_sub(d) as i32;
        let t2 = w4.wrapping_sub(d << 1) as i32;
        let t3 = w4.wrapping_sub(d + (d << 1)) as i32;
        let q = (t1 >= 0) as u32 + (t2 >= 0) as u32 + (t3 >= 0) as u32;
        self.rem = if t3 >= 0 {
            t3 as u32
        } else if t2 >= 0 {
            t2 as u32
        } else if t1 >= 0 {
            t1 as u32
        } else {
            w4
        };
        self.quotient = (self.quotient << 2) | q;
        self.steps += 1;
    }

    /// True once all [`DIV_STEPS`] steps have been performed.
    #[inline]
    pub fn is_done(&self) -> bool {
        self.steps >= DIV_STEPS
    }

    /// The quotient in the rounder's format: leading one at bit 30, sticky in bit 0.
    /// Meaningful once [`is_done`](Self::is_done).
    #[inline]
    pub fn significand(&self) -> u32 {
        (self.quotient << 6) | (self.rem != 0) as u32
    }
}

/// A division in flight: sign and exponent wait beside the recurrence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DivJob {
    /// Result sign (`0` or `SIGN`).
    pub sign: u32,
    /// Result exponent for a quotient significand in `[1, 2)` (the rounder's convention).
    pub exp: i32,
    /// The iterative core.
    pub rec: DivRecurrence,
}

/// Setup stage of `a / b`: special cases, or the job for the recurrence.
#[inline]
pub fn div_setup(a: u32, b: u32, mode: FpMode) -> Setup<DivJob> {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    let sign = (a ^ b) & SIGN;
    // Only an operand with an all-ones or all-zeros exponent can be special.
    let unusual = |x: u32| x & EXP_MASK == EXP_MASK || x & EXP_MASK == 0;
    if (unusual(a) || unusual(b))
        && let Some((r, f)) = div_special(a, b)
    {
        return Setup::Done(r, f);
    }
    let (ea, ma) = super::unpack_normalised(a);
    let (eb, mb) = super::unpack_normalised(b);
    // Pre-shift so the quotient is in [1, 2).
    let small = (ma < mb) as u32;
    let rec = DivRecurrence::new(ma << small, mb);
    Setup::Run(DivJob {
        sign,
        exp: ea - eb + 127 - small as i32,
        rec,
    })
}

/// Round stage: pack a finished [`DivJob`].
#[inline]
pub fn div_finish(job: &DivJob, mode: FpMode) -> (u32, Flags) {
    debug_assert!(job.rec.is_done());
    round_pack(job.sign, job.exp, job.rec.significand(), mode)
}

/// `a / b`, rounded to nearest even: setup, [`DIV_STEPS`] recurrence steps, round.
#[inline]
pub fn div(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    match div_setup(a, b, mode) {
        Setup::Done(r, f) => (r, f),
        Setup::Run(mut job) => {
            for _ in 0..DIV_STEPS {
                job.rec.step();
            }
            div_finish(&job, mode)
        }
    }
}

/// Special operands: NaN, infinities, zeros. `None` for finite non-zero operands (which may
/// be subnormal).
#[cold]
#[inline(never)]
fn div_special(a: u32, b: u32) -> Option<(u32, Flags)> {
    let sign = (a ^ b) & SIGN;
    if is_nan(a) || is_nan(b) {
        return Some(super::propagate_nan(a, b));
    }
    let a_inf = a & !SIGN == super::POS_INF;
    let b_inf = b & !SIGN == super::POS_INF;
    let a_zero = a & !SIGN == 0;
    let b_zero = b & !SIGN == 0;
    if (a_inf && b_inf) || (a_zero && b_zero) {
        return Some((super::CANONICAL_NAN, Flags::INVALID));
    }
    if a_inf {
        return Some((sign | super::POS_INF, Flags::NONE));
    }
    if b_zero {
        // Finite non-zero / 0: exact infinity, divide-by-zero.
        return Some((sign | super::POS_INF, Flags::INFINITE));
    }
    if b_inf || a_zero {
        return Some((sign, Flags::NONE));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;

    #[test]
    fn quotients() {
        assert_eq!(div(0x40C0_0000, 0x4040_0000, M), (0x4000_0000, Flags::NONE));
        // 1/3.
        assert_eq!(
            div(0x3F80_0000, 0x4040_0000, M),
            (0x3EAA_AAAB, Flags::INEXACT)
        );
        // 2/3.
        assert_eq!(
            div(0x4000_0000, 0x4040_0000, M),
            (0x3F2A_AAAB, Flags::INEXACT)
        );
        assert_eq!(div(0x3F80_0000, 0, M), (0x7F80_0000, Flags::INFINITE));
        assert_eq!(div(0x8000_0000, 0, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(div(0x7F80_0000, 0x8000_0001, M), (0xFF80_0000, Flags::NONE));
        assert_eq!(div(1, 0x7F80_0000, M), (0, Flags::NONE));
        // Subnormal / 2 -> tie to even.
        assert_eq!(
            div(3, 0x4000_0000, M),
            (2, Flags::INEXACT | Flags::UNDERFLOW)
        );
    }

    #[test]
    fn recurrence_steps_retire_two_bits() {
        // 7/5 in 24-bit significands.
        let d = 5 << 21;
        let mut r = DivRecurrence::new(7 << 21, d);
        for i in 0..DIV_STEPS {
            assert!(r.rem < d);
            assert_eq!(r.steps, i);
            r.step();
        }
        assert!(r.is_done());
        // floor(7/5 * 2^24) = 23488102 (7*2^24 = 117440512; /5 = 23488102.4)
        assert_eq!(r.quotient, ((7u64 << 24) / 5) as u32);
        assert_eq!(r.significand() & 1, 1);
    }
}
