//! Comparator, min and max (IEEE 754-2008 §5.11 comparison predicates, §5.3.1 minNum/maxNum
//! as refined by the RISC-V F extension, v2.2 `fmin.s`/`fmax.s`).
//!
//! Datapath: ordered comparison of binary32 values is an integer comparison of a *key* —
//! positive numbers get the sign bit set, negative numbers are bit-inverted — after which
//! `-0 < +0`. The IEEE predicates treat `-0 == +0`, so an "both zero" detector overrides the
//! key comparator; min/max use the key order as is (so `min(-0, +0) = -0`). A NaN detector
//! gates the result and the invalid flag:
//!
//! * [`lt`], [`le`] are *signalling* predicates: any NaN operand raises invalid (SoftFloat
//!   `f32_lt`, `f32_le`);
//! * [`eq`] is *quiet*: only a signalling NaN raises invalid (SoftFloat `f32_eq`);
//! * [`min`], [`max`]: a single NaN operand yields the other operand, two NaNs yield the
//!   canonical NaN, and a signalling NaN raises invalid (RISC-V semantics as obtained from
//!   SoftFloat `f32_lt_quiet`/`f32_eq`).

use super::{CANONICAL_NAN, FpMode, SIGN, flush_input, is_nan, is_snan};
use crate::arith::flags::Flags;

/// Total-order key of a non-NaN binary32 (`-0` sorts just below `+0`).
#[inline(always)]
fn key(a: u32) -> u32 {
    if a & SIGN != 0 { !a } else { a | SIGN }
}

#[inline(always)]
fn both_zero(a: u32, b: u32) -> bool {
    (a | b) & !SIGN == 0
}

/// `a < b` (signalling: invalid on any NaN operand; false when unordered).
#[inline]
pub fn lt(a: u32, b: u32, mode: FpMode) -> (bool, Flags) {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    if is_nan(a) || is_nan(b) {
        return (false, Flags::INVALID);
    }
    (key(a) < key(b) && !both_zero(a, b), Flags::NONE)
}

/// `a <= b` (signalling: invalid on any NaN operand; false when unordered).
#[inline]
pub fn le(a: u32, b: u32, mode: FpMode) -> (bool, Flags) {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    if is_nan(a) || is_nan(b) {
        return (false, Flags::INVALID);
    }
    (key(a) <= key(b) || both_zero(a, b), Flags::NONE)
}

/// `a == b` (quiet: invalid only on a signalling NaN operand; false when unordered).
#[inline]
pub fn eq(a: u32, b: u32, mode: FpMode) -> (bool, Flags) {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    if is_nan(a) || is_nan(b) {
        return (false, Flags::when(is_snan(a) || is_snan(b), Flags::INVALID));
    }
    (a == b || both_zero(a, b), Flags::NONE)
}

/// NaN handling shared by min and max; `None` when neither operand is a NaN.
#[inline(always)]
fn minmax_nan(a: u32, b: u32) -> Option<(u32, Flags)> {
    let (an, bn) = (is_nan(a), is_nan(b));
    if !(an || bn) {
        return None;
    }
    let flags = Flags::when(is_snan(a) || is_snan(b), Flags::INVALID);
    Some(match (an, bn) {
        (true, true) => (CANONICAL_NAN, flags),
        (true, false) => (b, flags),
        _ => (a, flags),
    })
}

/// RISC-V `fmin.s`: the smaller operand, `-0 < +0`; a NaN operand yields the other one.
#[inline]
pub fn min(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    if let Some(r) = minmax_nan(a, b) {
        return r;
    }
    (if key(a) < key(b) { a } else { b }, Flags::NONE)
}

/// RISC-V `fmax.s`: the larger operand, `-0 < +0`; a NaN operand yields the other one.
#[inline]
pub fn max(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    if let Some(r) = minmax_nan(a, b) {
        return r;
    }
    (if key(a) > key(b) { a } else { b }, Flags::NONE)
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;
    const ONE: u32 = 0x3F80_0000;
    const TWO: u32 = 0x4000_0000;
    const QNAN: u32 = 0x7FC0_0000;
    const SNAN: u32 = 0x7F80_0001;

    #[test]
    fn predicates() {
        assert_eq!(lt(ONE, TWO, M), (true, Flags::NONE));
        assert_eq!(lt(TWO, ONE, M), (false, Flags::NONE));
        assert_eq!(lt(ONE | SIGN, ONE, M), (true, Flags::NONE));
        assert_eq!(lt(TWO | SIGN, ONE | SIGN, M), (true, Flags::NONE));
        assert_eq!(lt(SIGN, 0, M), (false, Flags::NONE));
        assert_eq!(le(SIGN, 0, M), (true, Flags::NONE));
        assert_eq!(eq(SIGN, 0, M), (true, Flags::NONE));
        assert_eq!(lt(QNAN, ONE, M), (false, Flags::INVALID));
        assert_eq!(le(ONE, QNAN, M), (false, Flags::INVALID));
        assert_eq!(eq(QNAN, QNAN, M), (false, Flags::NONE));
        assert_eq!(eq(ONE, SNAN, M), (false, Flags::INVALID));
        assert_eq!(eq(1, 0, M), (false, Flags::NONE));
        assert_eq!(eq(1, 0, FpMode::FTZ), (true, Flags::NONE));
        assert_eq!(lt(0x8000_0001, 0, FpMode::FTZ), (false, Flags::NONE));
    }

    #[test]
    fn min_max() {
        assert_eq!(min(ONE, TWO, M), (ONE, Flags::NONE));
        assert_eq!(max(ONE, TWO, M), (TWO, Flags::NONE));
        assert_eq!(min(SIGN, 0, M), (SIGN, Flags::NONE));
        assert_eq!(min(0, SIGN, M), (SIGN, Flags::NONE));
        assert_eq!(max(SIGN, 0, M), (0, Flags::NONE));
        assert_eq!(max(0, SIGN, M), (0, Flags::NONE));
        assert_eq!(min(QNAN, TWO, M), (TWO, Flags::NONE));
        assert_eq!(max(TWO, SNAN, M), (TWO, Flags::INVALID));
        assert_eq!(max(QNAN | SIGN, SNAN, M), (QNAN, Flags::INVALID));
        assert_eq!(min(0x8000_0001, 0, FpMode::FTZ), (SIGN, Flags::NONE));
        assert_eq!(
            max(0x8000_0001, 0x8000_0000, FpMode::FTZ),
            (SIGN, Flags::NONE)
        );
    }
}
