//! Floating-point adder/subtracter (IEEE 754-2008 §5.4.1 addition, subtraction; §6.3 sign of
//! an exact zero sum).
//!
//! Datapath (Ercegovac & Lang §8.2, single-path adder):
//!
//! 1. *swap*: order the operands by magnitude (an integer compare of the 31 low bits), so the
//!    larger operand's exponent is the result exponent and the subtraction never goes
//!    negative;
//! 2. *align*: shift the smaller significand right by the exponent difference through a
//!    jamming shifter (everything shifted out ORs into a sticky bit);
//! 3. *add/subtract* the significands, held with 6 guard bits (leading one at bit 29) so
//!    that a carry-out fits below bit 31;
//! 4. *normalise* with a leading-zero counter (massive cancellation shifts left, a carry-out
//!    needs none), then the shared [`round_pack`].
//!
//! Special operands (NaN, infinity) branch off before the significand path; an exact zero sum
//! of opposite-signed operands is `+0` (round-to-nearest).

use super::round::{round_pack, shift_right_jam32};
use super::{EXP_MASK, FRAC_MASK, FpMode, HIDDEN, SIGN, exp_field, flush_input, is_nan};
use crate::arith::flags::Flags;

/// `a + b`, rounded to nearest even.
#[inline]
pub fn add(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    add_core(flush_input(a, mode), flush_input(b, mode), mode)
}

/// `a − b`, rounded to nearest even (the adder with the sign of `b` inverted).
#[inline]
pub fn sub(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    add_core(flush_input(a, mode), flush_input(b, mode) ^ SIGN, mode)
}

#[inline(always)]
fn add_core(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    if a & EXP_MASK == EXP_MASK || b & EXP_MASK == EXP_MASK {
        return add_special(a, b);
    }
    // Swap so |big| >= |small| (finite values order like their magnitude bits).
    let (big, small) = if a & !SIGN >= b & !SIGN {
        (a, b)
    } else {
        (b, a)
    };
    let sign = big & SIGN;
    let subtract = (a ^ b) & SIGN != 0;
    let eb = exp_field(big);
    let es = exp_field(small);
    // Significands with the hidden bit; a subnormal uses exponent 1 and no hidden bit.
    let mb = ((big & FRAC_MASK) | if eb != 0 { HIDDEN } else { 0 }) << 6;
    let ms = ((small & FRAC_MASK) | if es != 0 { HIDDEN } else { 0 }) << 6;
    let eb = eb.max(1);
    let es = es.max(1);
    let ms = shift_right_jam32(ms, (eb - es) as u32);
    let sum = if subtract { mb - ms } else { mb + ms };
    if sum == 0 {
        // Exact zero: x + (-x) = +0; (±0) + (±0) of equal signs keeps the sign.
        return (if subtract { 0 } else { sign }, Flags::NONE);
    }
    // Normalise: bring the leading one to bit 30. `mb` has it at bit 29, so the exponent is
    // eb + 1 − (shift).
    let shift = sum.leading_zeros() - 1;
    round_pack(sign, eb + 1 - shift as i32, sum << shift, mode)
}

/// NaN and infinity operands.
#[cold]
#[inline(never)]
fn add_special(a: u32, b: u32) -> (u32, Flags) {
    if is_nan(a) || is_nan(b) {
        return super::propagate_nan(a, b);
    }
    if a & EXP_MASK == EXP_MASK && b & EXP_MASK == EXP_MASK {
        // inf + inf: same sign gives that inf; opposite signs are invalid.
        if (a ^ b) & SIGN != 0 {
            return (super::CANONICAL_NAN, Flags::INVALID);
        }
        return (a, Flags::NONE);
    }
    (if a & EXP_MASK == EXP_MASK { a } else { b }, Flags::NONE)
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;

    #[test]
    fn simple_sums() {
        assert_eq!(add(0x3F80_0000, 0x4000_0000, M), (0x4040_0000, Flags::NONE));
        assert_eq!(sub(0x3F80_0000, 0x4000_0000, M), (0xBF80_0000, Flags::NONE));
        assert_eq!(add(0x3F80_0000, 0xBF80_0000, M), (0, Flags::NONE));
        assert_eq!(add(0x8000_0000, 0x8000_0000, M), (0x8000_0000, Flags::NONE));
        assert_eq!(add(0x8000_0000, 0, M), (0, Flags::NONE));
        // 1 + 2^-24: tie, rounds to even (1.0).
        assert_eq!(
            add(0x3F80_0000, 0x3380_0000, M),
            (0x3F80_0000, Flags::INEXACT)
        );
        // Subnormal + subnormal, exact.
        assert_eq!(add(1, 1, M), (2, Flags::NONE));
        assert_eq!(add(0x007F_FFFF, 1, M), (0x0080_0000, Flags::NONE));
        // Overflow.
        assert_eq!(
            add(0x7F7F_FFFF, 0x7F7F_FFFF, M),
            (0x7F80_0000, Flags::OVERFLOW | Flags::INEXACT)
        );
        // inf - inf.
        assert_eq!(
            sub(0x7F80_0000, 0x7F80_0000, M),
            (0x7FC0_0000, Flags::INVALID)
        );
        assert_eq!(add(0x7F80_0001, 0, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(add(0xFFC0_0001, 0, M), (0x7FC0_0000, Flags::NONE));
    }

    #[test]
    fn ftz() {
        // Subnormal inputs are zeros; 2^-126 - 2^-126*(1-2^-23)... would be subnormal.
        assert_eq!(add(1, 1, FpMode::FTZ), (0, Flags::NONE));
        assert_eq!(
            sub(0x0080_0001, 0x0080_0000, FpMode::FTZ),
            (0, Flags::UNDERFLOW | Flags::INEXACT)
        );
        assert_eq!(
            sub(0x0080_0001, 0x0080_0000, FpMode::IEEE),
            (1, Flags::NONE)
        );
    }
}
