//! Floating-point square root: radix-4 digit recurrence (IEEE 754-2008 §5.4.1 squareRoot).
//!
//! Structure (Ercegovac & Lang ch. 6, "Square root by digit recurrence"):
//!
//! * **setup** ([`sqrt_setup`]): special operands (NaN, ±0, +inf, negative → invalid),
//!   leading-zero normalisation of a subnormal, and exponent halving. An odd unbiased exponent
//!   moves one factor 2 into the radicand, so the radicand `X` lies in `[1, 4)` and the root
//!   in `[1, 2)` with integer digit 1.
//! * **recurrence** ([`SqrtRecurrence`]): a *radix-4 restoring* digit-by-digit root in
//!   integer form. With `P[j]` the radicand truncated to its first `j` radix-16 digit groups
//!   beyond the integer part, root `S[j] = ⌊√P[j]⌋` and remainder `r[j] = P[j] − S[j]²`,
//!   a step appends the next 4 radicand bits `n`: `16·r + n − (8·S·q + q²)` is formed in
//!   parallel for `q = 1, 2, 3` (subtrahends `8S + 1`, `16S + 4`, `24S + 9` — shifts of the
//!   partial root with a constant in the low bits), the digit is the largest `q` with a
//!   non-negative trial, and `S[j+1] = 4·S[j] + q`. Invariant: `0 ≤ r ≤ 2S`. Each step
//!   retires 2 root bits; [`SQRT_STEPS`] = 12 steps give 24 fraction bits plus a round bit.
//!   The same three-trial-subtractor shape as the divider's [`step`](super::div::DivRecurrence::step),
//!   so a combined DivSqrt unit shares the adders and the digit mux.
//! * **round** ([`sqrt_finish`]): root bits with sticky `r ≠ 0` into the shared
//!   [`round_pack`]. The root of a binary32 is always a normal
//!   number, so only inexact can be raised.

use super::round::round_pack;
use super::{FpMode, POS_INF, SIGN, Setup, flush_input, is_nan};
use crate::arith::flags::Flags;

/// Number of radix-4 recurrence steps after the integer root digit.
pub const SQRT_STEPS: u32 = 12;

/// State of the radix-4 square-root recurrence: the stage register of the iterative core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SqrtRecurrence {
    /// Radicand bits not yet consumed, left-aligned: the next 4 bits are bits 63..60.
    pub radicand: u64,
    /// Partial root `S[j]` (integer digit 1 followed by 2 bits per step).
    pub root: u32,
    /// Partial remainder `r[j] = P[j] − S[j]²`, `0 ≤ r ≤ 2·S[j]`.
    pub rem: u32,
    /// Number of steps performed.
    pub steps: u32,
}

impl SqrtRecurrence {
    /// Start the root of `X = int_part + frac / 2^64` with integer part `int_part ∈ {1, 2, 3}`
    /// and the fraction bits left-aligned in `frac`: retires the integer root digit 1.
    #[inline]
    pub fn new(int_part: u32, frac: u64) -> SqrtRecurrence {
        debug_assert!((1..4).contains(&int_part));
        SqrtRecurrence {
            radicand: frac,
            root: 1,
            rem: int_part - 1,
            steps: 0,
        }
    }

    /// One radix-4 step: two more root bits.
    #[inline(always)]
    pub fn step(&mut self) {
        let s = self.root;
        let n = (self.radicand >> 60) as u32;
        self.radicand <<= 4;
        let r16 = (self.rem << 4) | n; // < 2^30
        let t1 = r16.wrapping_sub((s << 3) + 1) as i32;
        let t2 = r16.wrapping_sub((s << 4) + 4) as i32;
        let t3 = r16.wrapping_sub((s << 4) + (s << 3) + 9) as i32;
        let q = (t1 >= 0) as u32 + (t2 >= 0) as u32 + (t3 >= 0) as u32;
        self.rem = if t3 >= 0 {
            t3 as u32
        } else if t2 >= 0 {
            t2 as u32
        } else if t1 >= 0 {
            t1 as u32
        } else {
            r16
        };
        self.root = (s << 2) | q;
        self.steps += 1;
    }

    /// True once all [`SQRT_STEPS`] steps have been performed.
    #[inline]
    pub fn is_done(&self) -> bool {
        self.steps >= SQRT_STEPS
    }

    /// The root in the rounder's format: leading one at bit 30, sticky in bit 0.
    /// Meaningful once [`is_done`](Self::is_done).
    #[inline]
    pub fn significand(&self) -> u32 {
        (self.root << 6) | (self.rem != 0 || self.radicand != 0) as u32
    }
}

/// A square root in flight: the exponent waits beside the recurrence (the sign is `+`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SqrtJob {
    /// Result exponent for a root significand in `[1, 2)` (the rounder's convention).
    pub exp: i32,
    /// The iterative core.
    pub rec: SqrtRecurrence,
}

/// Setup stage of `sqrt(a)`: special cases, or the job for the recurrence.
#[inline]
pub fn sqrt_setup(a: u32, mode: FpMode) -> Setup<SqrtJob> {
    let a = flush_input(a, mode);
    if a.wrapping_sub(1) >= POS_INF - 1 {
        // Not a positive finite non-zero number.
        return sqrt_special(a);
    }
    let (e, m) = super::unpack_normalised(a);
    // Unbiased exponent u = e − 127; X = m·2^-23 (u even) or m·2^-22 (u odd).
    let u = e - 127;
    let odd = (u & 1) as u32;
    // Radicand with 2 integer bits: m has its leading one at bit 23.
    let x = (m as u64) << (39 + odd); // leading one at bit 62 (+odd); integer part bits 63..62
    let rec = SqrtRecurrence::new((x >> 62) as u32, x << 2);
    Setup::Run(SqrtJob {
        exp: (u >> 1) + 127,
        rec,
    })
}

/// Round stage: pack a finished [`SqrtJob`].
#[inline]
pub fn sqrt_finish(job: &SqrtJob, mode: FpMode) -> (u32, Flags) {
    debug_assert!(job.rec.is_done());
    round_pack(0, job.exp, job.rec.significand(), mode)
}

/// `sqrt(a)`, rounded to nearest even: setup, [`SQRT_STEPS`] recurrence steps, round.
#[inline]
pub fn sqrt(a: u32, mode: FpMode) -> (u32, Flags) {
    match sqrt_setup(a, mode) {
        Setup::Done(r, f) => (r, f),
        Setup::Run(mut job) => {
            for _ in 0..SQRT_STEPS {
                job.rec.step();
            }
            sqrt_finish(&job, mode)
        }
    }
}

/// Special operands: ±0 → ±0, +inf → +inf, NaN → canonical NaN, negative → invalid.
#[cold]
#[inline(never)]
fn sqrt_special(a: u32) -> Setup<SqrtJob> {
    if is_nan(a) {
        let (r, f) = super::propagate_nan(a, a);
        return Setup::Done(r, f);
    }
    if a & !SIGN == 0 || a == POS_INF {
        return Setup::Done(a, Flags::NONE);
    }
    Setup::Done(super::CANONICAL_NAN, Flags::INVALID)
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;

    #[test]
    fn roots() {
        assert_eq!(sqrt(0x4080_0000, M), (0x4000_0000, Flags::NONE)); // 4
        assert_eq!(sqrt(0x4110_0000, M), (0x4040_0000, Flags::NONE)); // 9
        assert_eq!(sqrt(0x4000_0000, M), (0x3FB5_04F3, Flags::INEXACT)); // sqrt 2
        assert_eq!(sqrt(0x8000_0000, M), (0x8000_0000, Flags::NONE));
        assert_eq!(sqrt(0xBF80_0000, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(sqrt(0xFF80_0000, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(sqrt(0x7F80_0000, M), (0x7F80_0000, Flags::NONE));
        assert_eq!(sqrt(0x7F80_0001, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(sqrt(0xFFC0_0000, M), (0x7FC0_0000, Flags::NONE));
        // Smallest subnormal 2^-149: sqrt = 2^-74.5.
        assert_eq!(sqrt(1, M), (0x1A35_04F3, Flags::INEXACT));
        // 2^-148 → 2^-74 exact.
        assert_eq!(sqrt(2, M), (0x1A80_0000, Flags::NONE));
        // FTZ: a negative subnormal is -0, whose root is -0.
        assert_eq!(sqrt(0x8000_0001, FpMode::FTZ), (0x8000_0000, Flags::NONE));
        assert_eq!(sqrt(0x8000_0001, M), (0x7FC0_0000, Flags::INVALID));
    }
}
